// The detectors on random images: the first two bytes give the width and height (1..256 each),
// the third the pixel type (8-bit gray, BGR, BGRA, 16-bit gray), the rest the pixels (repeated
// to fill the image). Odd shapes (2000x1 was a crash) come from width x height.
#include <algorithm>
#include <memory>

#include "detect/detector.h"
#include "fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const std::unique_ptr<waymark::MarkerDetector> detector = waymark::CreateMultiDetector(
      waymark::ParseFamilyList("qr,datamatrix,apriltag-36h11"), waymark::DetectorOptions{});
  if (size < 4) return 0;
  static const int kTypes[4] = {CV_8UC1, CV_8UC3, CV_8UC4, CV_16UC1};
  // Widths up to 4096 for thin strips, otherwise up to 256 a side.
  const bool strip = (data[2] & 0x80) != 0;
  const int width = strip ? 1 + data[0] * 16 : 1 + data[0];
  const int height = strip ? 1 + data[1] % 4 : 1 + data[1];
  cv::Mat image(height, width, kTypes[data[2] % 4]);
  const size_t bytes = image.total() * image.elemSize();
  for (size_t i = 0; i < bytes; ++i) image.data[i] = data[3 + i % (size - 3)];
  detector->Detect(image);
  return 0;
}
