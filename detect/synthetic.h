// Synthetic code images with exact corners, for the detector tests and the benchmark:
// a symbol's module image (one pixel per module) from the encoders themselves, drawn
// into a canvas through the homography that puts its outer corners on given pixels.
// Truth is exact: corner k of docs/design.md order lands on corners_px[k] (OpenCV pixel
// centres), and each pixel is the average of 4x4 sub-pixel samples (anti-aliased edges).
#pragma once

#include <opencv2/core.hpp>
#include <string>

#include "detect/common.h"

namespace waymark {

struct SymbolImage {
  cv::Mat modules;  // 8-bit, one pixel per module: 0 dark, 255 light, quiet zone included
  cv::Rect symbol;  // the symbol without its quiet zone, in modules
};

// cv::QRCodeEncoder (byte mode, error correction L). Throws if it fails.
SymbolImage QrSymbol(const std::string& text);
// libdmtx's encoder, square symbol of the smallest size that fits. Throws if it fails.
SymbolImage DataMatrixSymbol(const std::string& text);
// The tag's bits from libapriltag's family tables; `family` as in "apriltag-36h11".
// The symbol is libapriltag's detection square (width_at_border modules).
SymbolImage AprilTagSymbol(const std::string& family, int id);

// Draws `symbol` (quiet zone included) into `canvas` (8-bit gray), dark modules at
// `dark` and light ones at `light`, so that its symbol corners land on `corners_px`
// (docs/design.md order). Pixels outside the module image are left as they are.
void DrawSymbol(const SymbolImage& symbol, const Quad2d& corners_px, cv::Mat* canvas, int dark = 20,
                int light = 235);

// Adds white Gaussian sensor noise of `sigma` gray levels (drawn from `rng`, one value per
// pixel, row by row) to `image` (8-bit gray), saturating at 0 and 255.
void AddSensorNoise(cv::RNG& rng, double sigma, cv::Mat* image);

// A square quad of side `side_px` centred at `center_px`, rotated by `angle_rad`
// (clockwise on screen), with a perspective squeeze: the right side is `squeeze` times
// as long as the left (1 = none).
Quad2d MakeQuad(const Eigen::Vector2d& center_px, double side_px, double angle_rad, double squeeze = 1.0);

}  // namespace waymark
