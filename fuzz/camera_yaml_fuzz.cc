// cameras/<name>.yaml (io/camera_io.h): arbitrary text.
#include "fuzz/fuzz_util.h"
#include "io/camera_io.h"
#include "io/util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  waymark::ReadWarnings warnings;
  try {
    const waymark::CameraInfo camera =
        waymark::ParseCameraYaml(waymark::fuzz::Text(data, size), "cam0.yaml", "cam0", &warnings);
    // What was read must write back and read back the same.
    const std::string text = waymark::FormatCameraYaml(camera);
    const waymark::CameraInfo again = waymark::ParseCameraYaml(text, "again.yaml", "cam0");
    if (waymark::FormatCameraYaml(again) != text) __builtin_trap();
  } catch (const waymark::FormatError&) {
  }
  return 0;
}
