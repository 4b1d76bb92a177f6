// TUM trajectories (io/tum_io.h): arbitrary text.
#include "fuzz/fuzz_util.h"
#include "io/tum_io.h"
#include "io/util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    const waymark::Trajectory trajectory = waymark::ParseTum(waymark::fuzz::Text(data, size), "odometry.tum");
    const std::string text = waymark::FormatTum(trajectory);
    if (waymark::FormatTum(waymark::ParseTum(text, "again.tum")) != text) __builtin_trap();
  } catch (const waymark::FormatError&) {
  }
  return 0;
}
