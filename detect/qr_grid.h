// A decoded QR code's module grid, and its sides fitted on the dark outer modules only.
//
// The outermost row and column of a QR code hold data modules next to the finders: where
// one is light, the nearest light-to-dark edge is a module further in, and on a side with
// few dark outer modules a line fit over the whole side can lean towards those inner edges
// (rendered drone codes: corners 0.5-0.7 px off). With the module grid known, each side is
// fitted only where its outer module is dark:
//   - grid: the homography H_image_module maps module coordinates (u, v) in [0, n]^2
//     (u right, v down on the upright symbol, pixel edges of the symbol) onto the quad of
//     the corners (docs/design.md order). n (21, 25, ..., 97) is the count that maximizes
//     min(ring contrast, timing contrast) in gray levels, sampled at module centres
//     (u, v) = (c + 0.5, r + 0.5): ring contrast = the finders' light ring minus their dark
//     ring, timing contrast = the light minus the dark modules of the timing patterns
//     (row 6 and column 6, modules 8 .. n-9, dark at even indices);
//   - sides: every module of the outer row/column darker than the midpoint of those two
//     references gives an edge point at its centre, and one at its boundary with a dark
//     predecessor (detect/refine.h FitEdgeThroughBoth); each side is the mean of two lines
//     fitted to those profiles: one from the derivative centroids (steady, but pulled
//     outwards by a thin dark bar: +0.1-0.2 px for a 2 px module) and one from the thin-bar
//     model (unbiased, noisier on 2 px modules); corners are the intersections of adjacent
//     lines. Rendered, the mean did better than either line alone (worst corner of the
//     drone codes 0.36 / 0.38 px -> 0.28 px, of the ceiling codes 0.63 / 0.35 -> 0.36 px;
//     corner bench pooled RMS 0.106 / 0.131 -> 0.105 px).
// Pixel convention: OpenCV pixel centres (detect/common.h).
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>
#include <optional>
#include <vector>

#include "detect/common.h"

namespace waymark {

struct QrGridEstimate {
  int modules = 0;             // n: 17 + 4 * version
  double timing_contrast = 0;  // (light - dark timing modules) / (light ring - dark ring)
  double dark_level = 0.0;     // mean gray level of finder dark-ring module centres
  double light_level = 0.0;    // mean gray level of finder light-ring module centres
};

// H_image_module: module coordinates (pixel edges of an n x n symbol, 0 .. n) to image pixels,
// through the homography of the symbol's four outer corners (design.md order).
cv::Matx33d ImageFromModules(const Quad2d& corners_px, int n);

// The module grid of the upright code with corners `corners_px` in `gray` (8-bit), or
// nullopt when the best module count's timing contrast is under 0.4 of its ring contrast
// or its rings differ by less than 20 gray levels, or a sample leaves the image. Module counts
// whose modules would be under 1 px are not tried.
std::optional<QrGridEstimate> EstimateQrGrid(const cv::Mat& gray, const Quad2d& corners_px);

// The corners from lines fitted on the dark outer modules (see above), or nullopt when a
// side has fewer than 6 edge points or under 60 % of them on its line, or a corner would
// move more than max(1 px, half a module).
std::optional<Quad2d> FitQrSidesOnDarkModules(const cv::Mat& gray, const Quad2d& corners_px,
                                              const QrGridEstimate& grid);

// The module pattern of the code with corners `corners_px` and grid `grid`: n * n entries,
// row-major (row v, column u of the upright code), 1 where the module's centre is darker
// than the midpoint of the grid's finder rings; empty if a centre leaves the image.
std::vector<uint8_t> SampleQrModules(const cv::Mat& gray, const Quad2d& corners_px,
                                     const QrGridEstimate& grid);

}  // namespace waymark
