// Reading a small, blurred QR code from its module grid (detect/qr_finder.cc, after the
// rectified read failed).
//
// zxing-cpp binarizes the image and samples one pixel per module: at 1.2-2 px per module
// under a blur of 0.5-1 px a module's gray level is as much its neighbours' as its own, and
// 1 in 10 modules comes out wrong, far beyond what version 1-L corrects (3 codewords). Here:
//   1. grid fit (FitQrModuleGrid): the homography from module coordinates (u, v) in [0, n]^2
//      to the image, started at the candidate's corners and moved corner by corner (steps of
//      0.4, 0.2, 0.1 module, a fixed number of rounds) to maximize the contrast between the
//      function-pattern modules known light and known dark (finders, separators, timing,
//      alignment pattern, the dark module);
//   2. blur model: each module's gray level y (a centre sample and four at a quarter module,
//      weighted) is fitted by least squares on the known modules as
//      y = a + a_u u + a_v v + b0 d + b1 (sum of the 4 edge neighbours' d) + b2 (4 diagonal)
//      + b3 (4 at two modules), d = 1 dark, 0 light (outside the symbol: light);
//   3. deconvolution: the unknown modules' d in [0, 1] minimizing the squared residual of
//      that model over all modules (coordinate descent, a fixed number of sweeps), then
//      made binary by iterated conditional modes (each module the value of lower residual);
//   4. the binary matrix rendered as a clean image (kRenderModulePx per module, a 4-module
//      quiet zone) and read by zxing (its Reed-Solomon correction is the decoder of record),
//      and, if that fails, again with each of the kSoftFlips least certain modules flipped
//      (one at a time).
// Work per call is a fixed function of the inputs (no clock).
#pragma once

#include <opencv2/core.hpp>
#include <optional>
#include <vector>

#include "detect/common.h"

namespace waymark {

// Module counts the grid reader handles: versions 1-6 (one alignment pattern at most).
inline constexpr int kMinGridModules = 21;
inline constexpr int kMaxGridModules = 41;

struct QrModuleGrid {
  int modules = 0;        // n
  Quad2d corners_px;      // the symbol's outer corners, docs/design.md order
  double contrast = 0.0;  // mean known-light minus mean known-dark sample, gray levels
};

// The grid of n modules fitted near `corners_px` (see above), or nullopt when a sample
// leaves the image or the known modules show no contrast (light not lighter than dark).
std::optional<QrModuleGrid> FitQrModuleGrid(const cv::Mat& gray, const Quad2d& corners_px, int modules);

// Module darkness in [0, 1] (row-major, n x n) of the fitted grid after the deconvolution
// (steps 2 and 3, before ICM); known function-pattern modules hold their known value.
// nullopt when the blur model cannot be fitted (too few known modules, or a dark module
// does not darken its own sample).
std::optional<std::vector<double>> DeconvolveQrModules(const cv::Mat& gray, const QrModuleGrid& grid);

// The n x n binary matrix (1 = dark) rendered upright: kRenderModulePx px per module and
// a 4-module light quiet zone.
inline constexpr int kRenderModulePx = 6;
cv::Mat RenderQrModules(const std::vector<uint8_t>& dark, int modules);

// The code read from its module grid (steps 1-4), corners mapped back to `gray`; module
// counts tried: `modules` (21, 25, ... up to kMaxGridModules). Empty if nothing reads.
std::vector<MarkerObservation> ReadQrModuleGrid(const cv::Mat& gray, const Quad2d& corners_px, int modules);

// The same from a quad of unknown orientation (a whole code's outline, e.g. a dark quad of
// the candidate stage, a module or so off): the four rotations and 21 or 25 modules are
// ranked by the known modules' contrast at the quad's corners, the best kUnorientedFits
// fitted (step 1) and read in order of fitted contrast; if none reads, the best fitted grid's
// corners are searched again (perspective search: smaller steps, maximizing the known-module
// contrast plus twice the standard deviation of the data modules' samples; the known modules
// leave the finder-less corner loose) and that grid read once more.
std::vector<MarkerObservation> ReadUnorientedQrModuleGrid(const cv::Mat& gray, const Quad2d& corners_px);

// The known modules' contrast of the best of those hypotheses before any fit (mean light
// minus mean dark, gray levels; -infinity when none can be sampled): ReadUnorientedQrModuleGrid
// fits nothing under kMinUnorientedRawContrast. Cheap (no fit): used to rank such quads.
inline constexpr double kMinUnorientedRawContrast = 5.0;
double UnorientedKnownModuleContrast(const cv::Mat& gray, const Quad2d& corners_px);

// How much of the quad's variation its known modules explain, before any fit: the known
// modules' contrast over the standard deviation of the data modules' samples, the best of the
// hypotheses ReadUnorientedQrModuleGrid would fit (-infinity when none can be sampled). A code's
// data modules are about half dark at about the known modules' contrast, so blur and a
// module's misplacement aside the ratio is about 2 (recall bench, issue and hard seeds 1-3:
// the 12 codes read 0.31-1.32); on text and noise the samples vary a lot and the known modules
// little (the clutter quads fitted: median 0.16). ReadUnorientedQrModuleGrid fits nothing under
// kMinUnorientedCodeLikeness, about half the weakest code's.
inline constexpr double kMinUnorientedCodeLikeness = 0.15;
double UnorientedCodeLikeness(const cv::Mat& gray, const Quad2d& corners_px);

// The best hypothesis' known-module contrast (UnorientedKnownModuleContrast) times the code
// likeness (UnorientedCodeLikeness), from one ranking of the hypotheses; 0 when either is not
// positive or the quad cannot be sampled. Ranks quads that no other test singled out.
double UnorientedCodeEvidence(const cv::Mat& gray, const Quad2d& corners_px);

// ReadUnorientedQrModuleGrid fits nothing whose code evidence (UnorientedCodeEvidence) is under
// this (issue 14's tenth speed round): the two grid fits of a quad cost about 3 ms, and nearly
// every quad fitted is clutter. A code has known modules of tens of gray levels that explain
// much of its data modules' spread (likeness about 0.3-2); on the recall bench (issue seeds 1-3,
// QR-only issue seeds 4-7, hard seeds 1-2: 15 quads read, 1021 fitted in vain) every quad read
// scored 5.7-66, about twice this at least, and 74 % of the clutter quads fitted under it.
inline constexpr double kMinUnorientedFitEvidence = 3.0;

}  // namespace waymark
