// Sub-pixel corner refinement from a code's outer edges.
//
// Decoders give corners to about a pixel (zxing-cpp rounds to integers; libdmtx fits a
// grid). A printed code is a dark symbol on a light quiet zone, so each side of the
// symbol is a straight light-to-dark step wherever the outermost module is dark (all of
// an AprilTag border, the QR finder patterns, the DataMatrix L finder, every other module
// of a DataMatrix timing pattern). For each side i (corner i -> corner i+1, corners in
// DESIGN.md order, clockwise on screen) with outward normal n:
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

#include <optional>

#include <opencv2/core.hpp>

#include "core/detect_common.h"

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
};

struct RefinedQuad {
  Quad2d corners_px;
  double inlier_fraction = 0.0;  // worst side: edge samples on the fitted line / samples
};

// Refined corners, or nullopt when a side has too few edge samples on one line (blur,
// occlusion, a light outermost row) or a corner would move more than max_shift_px.
// `gray` is 8-bit single channel.
std::optional<RefinedQuad> RefineQuadCorners(const cv::Mat& gray, const Quad2d& corners_px,
                                             const RefineOptions& options = {});

}  // namespace waymark
