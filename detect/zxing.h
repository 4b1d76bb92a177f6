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

constexpr int kZxingMinDynamicRange = 24;  // zxing-cpp 1.4's HybridBinarizer MIN_DYNAMIC_RANGE

struct ZxingPass {
  bool local_average_binarizer = true;  // false: global histogram
  bool try_harder = true;
  bool pure = false;  // a clean, upright symbol filling the image with its quiet zone
  // The local-average binarizer's flat-block range (ZxingHybridBlackMask): zxing's 24, or more
  // on a noisy whole frame (NoiseAwareThreshold), where noise alone spans more than that.
  int min_dynamic_range = kZxingMinDynamicRange;
};

// Decoded symbols of one symbology in `gray` (8-bit, one channel), with family set to
// "qr" or "datamatrix", id to the decoded text (UTF-8; see TextToId), corners as zxing
// gives them and no quality. Undecodable symbols are not returned.
std::vector<MarkerObservation> ReadWithZxing(const cv::Mat& gray, ZxingSymbology symbology,
                                             const ZxingPass& pass);

// zxing-cpp 1.4's local-average binarization (its HybridBinarizer) of `gray` (8-bit, one
// channel, at least kZxingHybridMinSide pixels each way), as an image zxing reads back with
// its BoolCast binarizer: 0 where HybridBinarizer says black, 255 elsewhere, bit for bit.
// zxing's own loop takes a byte at a time (2.7 ms for a 1280x960 frame); this one builds each
// 8-row band's per-pixel threshold row once and compares whole rows (0.45 ms), so that
// ReadWithZxing gives the same symbols for a sixth of the binarization's time.
//
// The rule (HybridBinarizer.cpp of zxing-cpp 1.4.0): the image is cut into 8x8 blocks, the
// last block of a row or column of blocks pulled back inside the image (overlapping its
// neighbour; a pixel takes the later block's threshold). A block's black point is its mean
// (integer division) when its range max - min exceeds 24; otherwise min / 2, or, for a block
// with a neighbour above and to the left, the neighbours' (up + 2 left + up-left) / 4 when
// that is above min. A block's threshold is the integer mean of the 5x5 black points around
// it (the window shifted inside the grid at its edges); a pixel is black when <= threshold.
//
// `min_dynamic_range` replaces the 24 (the same bits as zxing's with 24): a block of noise
// alone spans about 5 noise sigmas, so with fixed 24 a flat area under noise of 5 gray levels
// or more becomes speckle of the mean, which zxing's finder search then walks (two thirds of a
// whole-frame read's time on such frames).
constexpr int kZxingHybridMinSide = 40;
cv::Mat ZxingHybridBlackMask(const cv::Mat& gray, int min_dynamic_range = kZxingMinDynamicRange);

// `bytes` if they are valid UTF-8, else the bytes read as ISO-8859-1 (the default
// character set of QR and DataMatrix) re-encoded as UTF-8. Ids are always valid UTF-8.
std::string TextToId(const std::string& bytes);

bool IsValidUtf8(const std::string& text);

}  // namespace waymark
