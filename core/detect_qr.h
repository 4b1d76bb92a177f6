// QR code detector (family "qr").
//
// Pass 1, whole frame: zxing-cpp (local-average binarizer, try-harder).
// Pass 2, while the frame is within DetectorOptions::time_budget_ms: candidate regions
// (FindCodeCandidates; the whole image too when it is at most 640x480) that hold no
// decoded code yet are cropped and tried, stopping at the first success, with
//   a. zxing on the inverted crop (light-on-dark codes),
//   b. zxing on the crop upscaled 2x (small modules),
//   c. OpenCV's WeChat QR decoder (no CNN model: its own binarizers on the crop), whose
//      corners come from cv::QRCodeDetector on the same crop (dropped if it finds none).
// Every quad is refined (core/detect_refine.h) and validated (QuadIsValid).
#pragma once

#include <memory>

#include "core/detector.h"

namespace waymark {

std::unique_ptr<MarkerDetector> CreateQrDetector(const DetectorOptions& options);

}  // namespace waymark
