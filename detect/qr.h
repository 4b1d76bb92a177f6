// QR code detector (family "qr").
//
// Pass 1, whole frame: zxing-cpp (local-average binarizer, try-harder).
// Pass 2, bounded by counts (DetectorOptions::max_candidates regions,
// max_qr_finder_candidates finder triples; see detect/detector.h): candidate regions
// (the whole image first when it is at most 640x480, then FindCodeCandidates) that hold no
// decoded code yet are cropped and tried, stopping at the first success, with
//   a. zxing on the inverted crop (light-on-dark codes),
//   b. zxing on the crop upscaled 2x (small modules),
//   c. zxing with its global-histogram binarizer (uneven contrast),
//   d. OpenCV's WeChat QR decoder (no CNN model: its own binarizers on the crop), whose
//      corners come from cv::QRCodeDetector on the same crop (dropped if it finds none);
//      only on close-ups (the whole image, <= 640x480): it costs milliseconds per crop.
// Every quad is refined (detect/refine.h) and validated (QuadIsValid).
#pragma once

#include <memory>

#include "detect/detector.h"

namespace waymark {

std::unique_ptr<MarkerDetector> CreateQrDetector(const DetectorOptions& options);

}  // namespace waymark
