// Detection files, detections.jsonl (docs/design.md "Contracts"): one JSON object per line, one
// line per processed image of one camera (frames without markers still get a line):
//
//   {"t": 12.345, "camera": "cam0", "image": "images/0001.png", "frame": 17,
//    "markers": [{"family": "qr", "id": "0/2/10", "quality": 0.93,
//                 "corners_px": [[x, y], [x, y], [x, y], [x, y]]}]}
//
// Required: t (finite seconds), camera (non-empty string), markers (array, may be empty);
// each marker: family, id (strings) and corners_px (4 points of 2 numbers, docs/design.md corner
// order, pixel coordinates). Optional: image (string), frame (integer), quality (number).
// Stamps never decrease per camera (equal stamps are allowed: photos without a time).
//
// Errors (FormatError "path:line: field: what was expected"): a line that is not valid JSON,
// a missing or mistyped field, a wrong count, a camera not in the dataset, a stamp smaller
// than the camera's previous one. Counted warnings (ReadWarnings; the marker is dropped, the
// frame kept): a marker with an unknown family ("unknown family"), a non-finite corner ("non-finite corner",
// NaN/Infinity written as NaN, Infinity or null), a corner outside the camera's image
// ("corner outside image", when camera sizes are given). Unknown keys are counted warnings.
//
// Limits (issue 18: a line of 10^6 markers made localize and map build run for minutes): at
// most kMaxMarkersPerFrame markers in one line (more is an error), and a code seen twice in
// one frame is ambiguous: every copy of it is dropped with the counted warning "duplicate
// marker in frame" (the writer writes such frames: they are what a detector saw).
#pragma once

#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "geometry/types.h"

namespace waymark {

// The most markers one detections line (one camera frame) may hold.
inline constexpr size_t kMaxMarkersPerFrame = 1000;

// Parses detections.jsonl text; `path` names the file in messages. When `cameras` is not
// null, every frame's camera must be one of them and corners must lie inside its image.
std::vector<DetectionFrame> ParseDetections(const std::string& text, const std::filesystem::path& path,
                                            ReadWarnings* warnings,
                                            const std::map<std::string, CameraInfo>* cameras = nullptr);
std::vector<DetectionFrame> ReadDetections(const std::filesystem::path& path, ReadWarnings* warnings,
                                           const std::map<std::string, CameraInfo>* cameras = nullptr);

// One line of detections.jsonl (without the newline), full double precision. Throws
// std::invalid_argument for a frame the reader would reject or warn about (non-finite
// numbers, empty camera, unknown family, empty id).
std::string FormatDetectionLine(const DetectionFrame& frame);
// All lines; throws std::invalid_argument when stamps decrease for a camera.
std::string FormatDetections(const std::vector<DetectionFrame>& frames);
// FormatDetections written atomically.
void WriteDetections(const std::filesystem::path& path, const std::vector<DetectionFrame>& frames);

}  // namespace waymark
