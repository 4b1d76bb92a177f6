// zxing-cpp 1.4 behind Waymark's types, shared by the QR and DataMatrix detectors.
// zxing reports each symbol's position as (top-left, top-right, bottom-right, bottom-left)
// of the upright symbol, docs/design.md's order, in integer pixel-edge coordinates, shifted
// here by -0.5 to OpenCV's pixel centres; the detectors refine them.
#pragma once

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "geometry/types.h"

namespace waymark {

enum class ZxingSymbology { kQrCode, kDataMatrix };

struct ZxingPass {
  bool local_average_binarizer = true;  // false: global histogram
  bool try_harder = true;
  bool try_downscale = false;
  bool pure = false;  // a clean, upright symbol filling the image with its quiet zone
};

// Decoded symbols of one symbology in `gray` (8-bit, one channel), with family set to
// "qr" or "datamatrix", id to the decoded text (UTF-8; see TextToId), corners as zxing
// gives them and no quality. Undecodable symbols are not returned.
std::vector<MarkerObservation> ReadWithZxing(const cv::Mat& gray, ZxingSymbology symbology,
                                             const ZxingPass& pass);

// `bytes` if they are valid UTF-8, else the bytes read as ISO-8859-1 (the default
// character set of QR and DataMatrix) re-encoded as UTF-8. Ids are always valid UTF-8.
std::string TextToId(const std::string& bytes);

bool IsValidUtf8(const std::string& text);

}  // namespace waymark
