// The detectors on arbitrary image file bytes (PNG, JPEG, ... through runner/image.h's
// DecodeImage, as `waymark detect` reads files): every family at once.
#include <memory>

#include "detect/detector.h"
#include "fuzz/fuzz_util.h"
#include "runner/image.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const std::unique_ptr<waymark::MarkerDetector> detector = waymark::CreateMultiDetector(
      waymark::ParseFamilyList("qr,datamatrix,apriltag-36h11"), waymark::DetectorOptions{});
  std::string why;
  const cv::Mat image = waymark::DecodeImage(waymark::fuzz::Text(data, size), &why);
  if (image.empty()) {
    if (why.empty()) __builtin_trap();  // an empty image always says why
    return 0;
  }
  detector->Detect(image);
  return 0;
}
