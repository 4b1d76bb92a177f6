// detections.jsonl (io/detections_io.h): arbitrary text, with and without camera sizes.
#include "fuzz/fuzz_util.h"
#include "io/detections_io.h"
#include "io/util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text = waymark::fuzz::Text(data, size);
  waymark::CameraInfo camera;
  camera.name = "cam0";
  camera.width = 640;
  camera.height = 480;
  const std::map<std::string, waymark::CameraInfo> cameras = {{"cam0", camera}};
  waymark::ReadWarnings warnings;
  try {
    const std::vector<waymark::DetectionFrame> frames =
        waymark::ParseDetections(text, "detections.jsonl", &warnings, &cameras);
    const std::string again = waymark::FormatDetections(frames);
    if (waymark::FormatDetections(waymark::ParseDetections(again, "again.jsonl", nullptr, &cameras)) !=
        again) {
      __builtin_trap();
    }
  } catch (const waymark::FormatError&) {
  }
  try {
    waymark::ParseDetections(text, "detections.jsonl", nullptr, nullptr);
  } catch (const waymark::FormatError&) {
  } catch (const std::invalid_argument&) {  // FormatDetections of what a camera-less read kept
  }
  return 0;
}
