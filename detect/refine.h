// Sub-pixel corner refinement from a code's outer edges.
//
// Decoders give corners to about a pixel (zxing-cpp rounds to integers; libdmtx fits a
// grid). A printed code is a dark symbol on a light quiet zone, so each side of the
// symbol is a straight light-to-dark step wherever the outermost module is dark (all of
// an AprilTag border, the QR finder patterns, the DataMatrix L finder, every other module
// of a DataMatrix timing pattern). For each side i (corner i -> corner i+1, corners in
// docs/design.md order, clockwise on screen) with outward normal n:
//   1. at K points p_k along the side (10 % .. 90 % of its length), sample the intensity
//      profile I(p_k + s n) for s in [-w, w] (bilinear), and take the outermost local
//      maximum of dI/ds > 0 (light outside, dark inside) at least half as strong as the
//      strongest, refined to sub-pixel by a parabola through its neighbours;
//   2. fit a line to those edge points: RANSAC with a fixed seed (inlier band 0.6 px),
//      then total least squares on the inliers;
// and each refined corner is the intersection of the lines of its two sides. Two rounds
// are run, the second with a narrower window around the first result.
// Pixel convention: the centre of pixel (c, r) is at (c, r).
#pragma once

#include <opencv2/core.hpp>
#include <optional>
#include <vector>

#include "detect/common.h"

namespace waymark {

struct RefineOptions {
  // First-round half window along the normal: max(search_px, search_fraction * shortest
  // side), at most a sixth of the shortest side; the second round uses 1.25 px.
  double search_px = 3.0;
  double search_fraction = 0.08;
  double min_step = 12.0;            // minimum edge strength, gray levels per px
  double min_inlier_fraction = 0.3;  // per side, else the refinement fails
  // A refined corner may move at most max(max_shift_px, 1.5 * first window).
  double max_shift_px = 4.0;
  // Second round: each edge point from FitEdgeModel (kept from the first estimate where the
  // fit fails).
  bool fit_edge_model = true;
};

struct RefinedQuad {
  Quad2d corners_px;
  double inlier_fraction = 0.0;  // worst side: edge samples on the fitted line / samples
};

// One edge on the intensity profile I(point + s outward), s in [-half_window, half_window]
// (px, bilinear samples every 0.25 px): the outermost strong light-outside step.
struct EdgeHit {
  double offset_px = 0.0;  // s of the edge
  double strength = 0.0;   // the step's peak derivative, gray levels per px
};
std::optional<EdgeHit> FindOuterEdge(const cv::Mat& gray, const Eigen::Vector2d& point_px,
                                     const Eigen::Vector2d& outward, double half_window_px, double min_step);

// The edge's offset along `outward` from `point_px`, corrected for a thin dark bar, from a
// first estimate `offset_px` (FindOuterEdge). The derivative's centroid is unbiased for an
// isolated blurred step, but next to a thin dark bar, such as a QR finder's 1-module ring
// or a dark data module of the outer row, the bar's inner edge pulls it outwards (+0.13 px
// for a 2.3 px bar under a 0.7 px blur, +0.22 px for 1.9 px). When the profile shows such
// an inner edge (a falling step at least 15 % of the outer one, at most 3.5 px inside),
// the profile from 4 px inside to 2.5 px outside (bilinear, every 0.25 px; inside at most
// 0.75 px past the inner edge) is fitted by a blurred dark bar on a light ground,
//   I(s) = L - A [Phi((e - s) / sigma) - Phi((e - w - s) / sigma)],
// [e, sigma, L, A, w] by Levenberg-Marquardt, and e is returned. Otherwise, and when a
// sample reads a saturated pixel (>= 254: L is then undetermined), offset_px is returned
// unchanged. nullopt if the profile leaves the image or the fit fails or moves more than
// 0.75 px.
std::optional<double> FitEdgeModel(const cv::Mat& gray, const Eigen::Vector2d& point_px,
                                   const Eigen::Vector2d& outward, double offset_px);

struct Line2d {
  Eigen::Vector2d point = Eigen::Vector2d::Zero();
  Eigen::Vector2d direction = Eigen::Vector2d::UnitX();  // unit
  double inlier_fraction = 0.0;                          // edge samples on the line / profiles taken
};

// The outer edge line of the part t in [t0, t1] (fractions of its length) of the side
// from_px -> to_px of a clockwise quad (outward normal on its left, y down): edge points
// (FindOuterEdge) every 0.5 px, RANSAC and total least squares as for a whole side.
std::optional<Line2d> FitSideSegment(const cv::Mat& gray, const Eigen::Vector2d& from_px,
                                     const Eigen::Vector2d& to_px, double t0, double t1,
                                     double half_window_px, double min_step);

// The outer edge line through edge points found at `points_px` (FindOuterEdge along
// `outward`, a unit vector, within +-half_window_px; each point's offset then corrected by
// FitEdgeModel when `fit_model`), by RANSAC and total least squares as for a whole side.
// For sides whose outermost modules are known: the caller passes points on dark modules only.
std::optional<Line2d> FitEdgeThrough(const cv::Mat& gray, const std::vector<Eigen::Vector2d>& points_px,
                                     const Eigen::Vector2d& outward, double half_window_px, double min_step,
                                     bool fit_model);

// FitEdgeThrough with and without the model from one pass over the profiles (each point's
// FindOuterEdge taken once): the same two lines as the two calls give.
struct EdgeLinePair {
  std::optional<Line2d> modelled;  // fit_model = true
  std::optional<Line2d> centroid;  // fit_model = false
};
EdgeLinePair FitEdgeThroughBoth(const cv::Mat& gray, const std::vector<Eigen::Vector2d>& points_px,
                                const Eigen::Vector2d& outward, double half_window_px, double min_step);

// Intersection of two lines, or nullopt when they are within ~6 degrees of parallel.
std::optional<Eigen::Vector2d> IntersectLines(const Line2d& a, const Line2d& b);

// Refined corners, or nullopt when a side has too few edge samples on one line (blur,
// occlusion, a light outermost row) or a corner would move more than max_shift_px.
// `gray` is 8-bit single channel.
std::optional<RefinedQuad> RefineQuadCorners(const cv::Mat& gray, const Quad2d& corners_px,
                                             const RefineOptions& options = {});

}  // namespace waymark
