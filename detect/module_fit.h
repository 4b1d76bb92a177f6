// Photometric fit of a decoded symbol's module grid: corners from every module edge at once.
//
// The side fits of detect/refine.h and detect/qr_grid.h measure each side on its outer edge
// only, a one-sided measurement: on small symbols (modules of about 2 px under a blur of
// 0.5-1 px) the edge of a thin dark module is pulled outwards by its inner edge, and a
// model of that pull is itself biased where the next module inwards is close (issue 14:
// QR codes of 40-60 px had every corner 0.1-0.3 px outwards along its diagonal). Once the
// symbol is decoded its module pattern is known, and the whole image of the symbol can be
// predicted: every pixel x near the symbol is modelled as
//   I(x) = a + b B(x) + c x' + d y',
//   B(x) = sum over modules (i, j) of dark(i, j) * P(i, j | x),
// where (u, v) = G(x) are the module coordinates of x (G the homography from normalized
// image coordinates x' = (x - centre) / mean side, to module coordinates [0, n]^2), and
// P(i, j | x) is the share of a Gaussian blur of sigma px around x that falls in module
// (i, j): a product of two one-dimensional differences of normal CDFs, with the blur carried
// into module coordinates through the local Jacobian of G (its correlation between the two
// module axes is neglected). Modules outside the symbol are light (the quiet zone). The
// eight entries of G and sigma are fitted by Levenberg-Marquardt with Huber weights; a, b,
// c, d (offset, contrast, lighting gradient) are solved linearly at every step. Every module
// edge pulls on the fit from both of its sides with the same blur model, so the fitted grid
// does not depend on the blur model being exact the way a one-sided edge does.
// Pixel convention: OpenCV pixel centres (detect/common.h); a pixel's footprint is part of
// the fitted sigma.
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>
#include <optional>
#include <vector>

#include "detect/common.h"

namespace waymark {

struct ModuleFitOptions {
  int max_iterations = 12;
  // Light modules modelled around the symbol (its quiet zone), in modules.
  double quiet_modules = 1.0;
  // A fitted corner may move at most max(max_shift_px, max_shift_modules * module) from
  // the start.
  double max_shift_px = 0.75;
  double max_shift_modules = 0.4;
  // About this many pixels of the symbol and its quiet zone enter the fit: one in
  // ceil(pixels / target_pixels), picked by a hash of the position (the work per code is
  // bounded; the corners' precision is limited by the model, not by the pixel count).
  int target_pixels = 1200;
  // Symbols whose box holds more pixels than this are not fitted.
  int max_box_pixels = 250000;
};

struct ModuleFit {
  Quad2d corners_px;          // the symbol's outer corners (docs/design.md order)
  double blur_px = 0.0;       // fitted Gaussian sigma (blur and pixel footprint)
  double contrast = 0.0;      // light minus dark gray level (-b)
  double residual_rms = 0.0;  // gray levels, unweighted
  double start_rms = 0.0;     // the same at the starting corners (blur 0.8 px)
  int pixels = 0;
  int iterations = 0;
};

// The symbol of n x n modules whose outer corners are near `corners_px`, with module (u, v)
// (column u, row v of the upright symbol) dark where dark[v * n + u] != 0, fitted to
// `gray` (8-bit, single channel). nullopt when the symbol is not inside the image with its
// quiet zone, the fit does not converge to a blur of 0.15-4 px with the dark modules darker,
// or a corner would move further than the options allow.
std::optional<ModuleFit> FitModuleGrid(const cv::Mat& gray, const Quad2d& corners_px, int n,
                                       const std::vector<uint8_t>& dark,
                                       const ModuleFitOptions& options = {});

}  // namespace waymark
