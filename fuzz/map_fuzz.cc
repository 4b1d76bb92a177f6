// Maps, map.json (io/map_io.h): arbitrary text, poses required and optional.
#include "fuzz/fuzz_util.h"
#include "io/map_io.h"
#include "io/util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text = waymark::fuzz::Text(data, size);
  waymark::ReadWarnings warnings;
  try {
    const waymark::MarkerMap map = waymark::ParseMap(text, "map.json", &warnings);
    const std::string again = waymark::FormatMap(map);
    if (waymark::FormatMap(waymark::ParseMap(again, "again.json")) != again) __builtin_trap();
  } catch (const waymark::FormatError&) {
  }
  try {
    waymark::ParseMap(text, "markers.json", &warnings, waymark::MapPoses::kOptional);
  } catch (const waymark::FormatError&) {
  }
  return 0;
}
