// Detector of the large square ceiling marker (family `square`, geometry/square_marker.h) in an
// infrared LED pair: the method of Seki, Kawai, Hikizu (IJAT 15(2), 2021, section 5), then a
// sub-pixel refinement of the four lines on the image itself.
//
//   1. diff = on - off (negative -> 0): the retro-reflective tape is bright only with the LEDs on.
//   2. Rectify diff onto the ceiling plane z = ceiling_height_m of the camera frame (assumed
//      level): rectified pixel (j, i) <- the image of the ceiling point
//      ((j - c) s, (i - c) s, Z), s = rectified_mm_per_px, bilinear (the paper rectifies by its
//      eqs. 1-2 before the Hough transform).
//   3. Blur lightly (Gaussian, 1 px), binarize (diff > diff_threshold), erode then dilate (an
//      opening wider than the tape: the tape vanishes, large blobs stay) and subtract the opened
//      image from the binary one (a top-hat: almost only the tape is left); pieces smaller than
//      half a dash are dropped.
//   4. Hough lines (cv::HoughLines, 1 px, 1 deg, hough_votes; the paper's threshold is 80 on its
//      ~200 px side, ours 40 by default, see below), by votes: the strongest is taken
//      as the solid side (rho1, theta1); its parallel is searched at rho1 +- d (d = side_m) within
//      distance_gate d and angle_gate_deg, a perpendicular near theta1 +- 90 deg, and its parallel
//      at rho3 +- d. If the strongest line has no such square around it, the next strongest is
//      tried (up to 16). The corners are the lines' intersections.
//   5. The solid side is checked, not assumed: along each side's centreline (its ends, where the
//      perpendicular tape lies, left out) the longest unbroken run of tape in the top-hat image is
//      measured; exactly one side must have a run longer than 2 dash_m + gap_m (a dashed side
//      cannot: its dashes are dash_m long) while the three others stay below it. Otherwise (the
//      solid side hidden, or confused) there is no detection: a wrong solid side would flip the
//      orientation.
//   6. Refinement on the image: every side is sampled from corner to corner (ends left out); at
//      each sample the diff image's profile across the tape (normal to the side's image) gives
//      the tape's centre as the centroid of the profile above its background (twice, re-centred),
//      samples with a peak below diff_threshold (gaps, occlusion) are skipped; the centres are
//      taken back to the ceiling plane (Camera::Unproject) where a straight line is fitted (total
//      least squares, then again without points beyond 3 median deviations). A plane-to-plane
//      projection keeps lines straight, so an error in the assumed height or level only moves
//      points along the fitted lines' plane, not off them. The corners are the refined lines'
//      intersections, projected to the image. Done twice, the second time along the first
//      refined lines.
//   7. Corners solid side first (geometry/square_marker.h): A -> B along the solid side, then C
//      (next to B) and D, in the order that turns clockwise in the image (the sign of the cross
//      product AB x AC of the paper).
//
// At most one square per pair (the one around the strongest line). Occlusion of up to about half
// of each side is survived (the Hough votes of what is left, and the solid side's remaining run).
#pragma once

#include <Eigen/Core>
#include <array>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "geometry/camera.h"
#include "geometry/types.h"

namespace waymark {

struct SquareDetectorOptions {
  double side_m = 2.0;            // d, between the tape's centrelines
  SquareTape tape;                // tape width and dash pattern (solid side: taken from the image)
  double ceiling_height_m = 2.0;  // Z: ceiling above the camera, along its optical axis
  double rectified_mm_per_px = 10.0;
  double rectified_half_extent_m = 4.0;  // the rectified image covers +- this around the axis
  int diff_threshold = 20;               // gray levels of on - off
  // Vote threshold (rectified pixels on a line). The paper's 80 (of its ~200 px side) is for its
  // tape; a dashed side of ours (half its length taped) with half of it hidden has ~50 votes.
  int hough_votes = 40;
  double distance_gate = 0.10;  // of d
  double angle_gate_deg = 10.0;
  bool refine = true;  // step 6

  // True if usable; otherwise false with the reason in *why (when why != nullptr).
  bool Check(std::string* why) const;
};

struct SquareDetection {
  std::array<Eigen::Vector2d, 4> corners_px;  // solid side first
  std::array<double, 4> longest_run_m{};      // per side, solid first (A-B, B-C, C-D, D-A)
  std::array<int, 4> refined_samples{};       // profile samples used per side (0: Hough line kept)
};

class SquareDetector {
 public:
  // Precomputes the rectification for `camera` (its calibration). Throws std::invalid_argument
  // for options that fail Check.
  SquareDetector(const Camera& camera, const SquareDetectorOptions& options);

  // The square in the pair, if found. Throws std::invalid_argument (one line) for an empty
  // image, a pair whose sizes differ, a size other than the camera's, or a pixel type other
  // than 8-bit gray.
  std::vector<SquareDetection> Detect(const cv::Mat& on, const cv::Mat& off) const;

  // The intermediate images of the last steps, for tests and --annotate: the rectified top-hat.
  cv::Mat RectifiedTopHat(const cv::Mat& on, const cv::Mat& off) const;

  const SquareDetectorOptions& options() const { return options_; }

 private:
  struct Line {  // x cos(theta) + y sin(theta) = rho on the ceiling plane (camera frame, metres)
    double theta = 0.0, rho = 0.0;
  };
  cv::Mat Diff(const cv::Mat& on, const cv::Mat& off) const;
  cv::Mat TopHat(const cv::Mat& diff) const;
  double LongestRun(const cv::Mat& tophat, const Eigen::Vector2d& a, const Eigen::Vector2d& b) const;
  int RefineLine(const cv::Mat& diff, const Eigen::Vector2d& a, const Eigen::Vector2d& b, Line* line) const;
  Eigen::Vector2d ToImage(const Eigen::Vector2d& plane) const;

  Camera camera_;
  SquareDetectorOptions options_;
  cv::Mat map_x_, map_y_;  // rectification
  int rect_size_ = 0;
};

// The ceiling height above a camera for square detection: the highest square of `map` above
// the camera's mount height (T_robot_camera z; the robot frame on the floor, z = 0), or nullopt
// if the map has no square with a pose.
std::optional<double> SquareCeilingHeight(const MarkerMap& map, const CameraInfo& camera);

}  // namespace waymark
