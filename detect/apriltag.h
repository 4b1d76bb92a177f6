// AprilTag detector (families "apriltag-<name>") on libapriltag 3.3.
//
// libapriltag's corners p[0..3] wrap the tag starting at the bottom-left of the upright
// tag: (bottom-left, bottom-right, top-right, top-left) in image pixels (checked with
// rendered tags of known orientation in tests/detect/apriltag_test.cc), so docs/design.md
// order is (p[3], p[2], p[1], p[0]). Its pixel centres are at +0.5 (pixel (c, r) covers
// [c, c+1] x [r, r+1]); 0.5 is subtracted to reach OpenCV's convention. Families whose
// black border is the outermost ring (36h11, 36h10, 25h9, 16h5) are then refined on that
// ring's outer edge (detect/refine.h); for the others (reversed border: Circle*,
// Standard*, Custom48h12) the quad is libapriltag's border square, kept as it is.
#pragma once

#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "detect/detector.h"

namespace waymark {

// Names after "apriltag-": 16h5, 25h9, 36h10, 36h11, circle21h7, circle49h12,
// custom48h12, standard41h12, standard52h13.
std::vector<std::string> AprilTagFamilyNames();

// `family` is the full name, e.g. "apriltag-36h11". Throws std::invalid_argument for an
// unknown family.
std::unique_ptr<MarkerDetector> CreateAprilTagDetector(const std::string& family,
                                                       const DetectorOptions& options);

// The tag's module image, one pixel per module (0 dark, 255 light), total_width modules
// wide (36h11: 10, its white border included), drawn from the family's code table and
// bit positions; *symbol receives libapriltag's detection square (width_at_border).
// Throws std::invalid_argument for an unknown family or an id outside the family.
cv::Mat AprilTagModuleImage(const std::string& family, int id, cv::Rect* symbol);

}  // namespace waymark
