// QR candidates without decoding, and reading them rectified (detect/qr.cc, pass 2).
//
// zxing-cpp 1.4 misses QR codes of under ~2 px per module and oblique version-1 codes
// (its sampling grid is the finders' parallelogram). Here a candidate region is searched
// for finder patterns on its own, the code's quadrilateral is built from them, and the
// code is resampled upright at kRectifiedModulePx pixels per module for zxing:
//   1. finder patterns (FindQrFinderPatterns): the region, upscaled to at least
//      ~kFinderWorkSidePx, binarized with a local mean threshold, then kept only in windows
//      around rows and columns whose runs cross a finder's middle (dark, light, dark centre,
//      light, dark; the light runs lighter than the centre in gray); a finder is a dark
//      contour whose hole holds one dark blob (the 7x7 ring, the 5x5 light ring and the
//      3x3 centre: areas 49 : 25 : 9), checked by area ratios, concentricity and
//      convexity; its outer contour is reduced to a quadrilateral;
//   2. triples (GroupQrFinders): three finders of similar size where one (the top-left)
//      sees the two others at similar distances, at 40-140 deg, each along one of its own
//      outline's edges (within 20 deg; a wrong corner sees a diagonal), ordered clockwise on
//      screen (top-right, then bottom-left: cross(B - A, C - A) > 0 with y down); the
//      code's corners are the outermost corners of the three finders (extreme in the
//      affine frame of the arms B - A and C - A) and, for the
//      bottom-right, the intersection of the top-right finder's right edge and the
//      bottom-left finder's bottom edge;
//   3. rectification (ReadRectifiedQr): the bottom-right corner re-found on the image's
//      edges (QrCornerFromFinderEdges), the homography H maps the quad onto a square of
//      n * kRectifiedModulePx pixels (n = the module count estimated from the finder
//      width, 7 modules) inside a kRectifiedQuietModules-module quiet zone, the image is
//      resampled through H^-1 (bicubic), zxing reads it (as it is, sharpened, or with its
//      global-histogram binarizer), and its corners are mapped back with H^-1. Corners stay approximate (the
//      caller refines them in the original image).
// All coordinates are OpenCV pixel centres of the full image (detect/common.h).
#pragma once

#include <Eigen/Core>
#include <array>
#include <opencv2/core.hpp>
#include <vector>

#include "detect/common.h"
#include "detect/quads.h"
#include "geometry/types.h"

namespace waymark {

inline constexpr double kFinderWorkSidePx = 240.0;  // shorter side of the upscaled region
inline constexpr double kMaxFinderUpscale = 4.0;
inline constexpr double kRectifiedModulePx = 4.0;
inline constexpr int kRectifiedQuietModules = 4;

struct QrFinderPattern {
  Eigen::Vector2d centre_px = Eigen::Vector2d::Zero();
  double width_px = 0.0;  // square root of the outer contour's area: 7 modules
  // Outer contour reduced to four corners, clockwise on screen (x right, y down).
  std::array<Eigen::Vector2d, 4> outer_px;
};

// Finder patterns inside `region` of `gray` (8-bit, one channel), in full-image pixels.
// At most `max_patterns`, largest first. Empty for a region under 16 px.
std::vector<QrFinderPattern> FindQrFinderPatterns(const cv::Mat& gray, const cv::Rect& region,
                                                  int max_patterns = 12);

struct QrCandidate {
  Quad2d corners_px;       // docs/design.md order (top-left, top-right, bottom-right, bottom-left)
  double module_px = 0.0;  // mean finder width / 7
};

// Codes made of three finders each, best-shaped triple first, each finder used once.
// Candidates whose quad is not valid (QuadIsValid, sides >= 10 px) are dropped.
std::vector<QrCandidate> GroupQrFinders(const std::vector<QrFinderPattern>& finders,
                                        const cv::Size& image_size);

// QR candidates from two finders whose third was not found (a small oblique code whose third
// finder's rings blur into its data modules: recall bench issue seed 13 frame 127): the
// finders of `finders` of width at most `max_width_px` whose centres lie in no candidate of
// `triples` (GroupQrFinders' codes) are paired (widths within kMaxPairWidthRatio), and each
// layout their distance allows (version 1 or 2, tilts up to 60 deg: either finder as the
// corner one and the other as its right or lower neighbour, or the two as the ends of the
// code's diagonal) maps module coordinates to `gray` by the affine map that puts the
// two finders' outlines (7 x 7 modules) where the layout has them (least squares over the
// labellings of their corners, at most a module RMS off: blurred outlines are rough). The
// third finder is looked for in `gray` through that map, up to kThirdFinderReachModules
// modules from where the layout puts it (the 9 x 9 modules of finder and separator correlated
// with their pattern at half-module shifts, at least 0.6), and completes the triple
// (GroupQrFinders). In the order of the pairs, each code once; empty for an empty or
// non-8-bit `gray`.
inline constexpr double kMaxPairWidthRatio = 1.5;
inline constexpr double kThirdFinderReachModules = 2.0;
// The widest finder paired, px (QrCandidatesFromQuads, and detect/qr.cc's finder searches): 7
// modules of a version-1 code of about 70 px; larger codes' finders are found whole.
inline constexpr double kMaxPairFinderWidthPx = 24.0;
std::vector<QrCandidate> QrCandidatesFromFinderPairs(const cv::Mat& gray,
                                                     const std::vector<QrFinderPattern>& finders,
                                                     const std::vector<QrCandidate>& triples,
                                                     double max_width_px);

// QR candidates from the shared candidate stage (FindDarkQuads, detect/quads.h), for codes in
// no candidate region: a finder's dark 7x7 ring is a dark component whose quad has at least
// two solid sides (>= 85 % dark just inside them; the others >= 20 %: blur or a thin
// separator joins data modules to it) and a varied inside (the light ring around the dark centre: spread >=
// 0.2, as SolidBorderQuads; a filled box is even) and a finder's profile in `gray` (from each side's middle
// to the centre: the light ring lighter than the dark ring and the centre by a tenth of the contrast to the
// light outside); those quads, as finders (centre, width = square root of the quad's area, outline = the
// quad), are grouped like FindQrFinderPatterns' (GroupQrFinders). The same finder found at two levels counts
// once (the finer level's).
std::vector<QrCandidate> QrCandidatesFromQuads(const cv::Mat& gray, const std::vector<DarkQuad>& quads);

// Dark quads that may be a whole small QR code (QR codes of about 18-80 px, whose finders
// are too small or too blurred for the finder quads above): a component found at a coarse
// level (scale <= 0.5, where the code's modules merge into one blob), of mean side
// kMinSmallCodeSidePx-kMaxSmallCodeSidePx, every side at least 45 % dark (the finders at its
// ends, the data modules between) and one under 97 % (a solid box or an AprilTag border is
// dark all round; a code's side with light outer modules is not)
// and a varied inside (spread 0.2-1.5); in the order found, at most `max_quads`.
inline constexpr double kMinSmallCodeSidePx = 18.0, kMaxSmallCodeSidePx = 80.0;
std::vector<DarkQuad> SmallQrCodeQuads(const std::vector<DarkQuad>& quads, int max_quads);

// The same with the least dark side at kSmallCodeMinThinSideDark up to 45 % dark, none near a
// quad of `taken` (SmallQrCodeQuads' own): the side of a version-1 code opposite a finder
// pair holds 7 finder modules of 21 and 14 data modules, which can be mostly light (recall
// bench issue seed 2 frame 133: 40 %). Read after SmallQrCodeQuads' quads, within their own
// bounds, so that they take nothing from those.
inline constexpr double kSmallCodeMinThinSideDark = 0.35;
std::vector<DarkQuad> ThinSideSmallQrCodeQuads(const std::vector<DarkQuad>& quads,
                                               const std::vector<DarkQuad>& taken, int max_quads);

// Small codes whose modules fall apart into several dark components at every level (an oblique
// code of 25-40 px, 1.2-1.7 px per module across the tilt: recall bench issue seeds 4-10): the
// quads of one level with a mean side of kMinFragmentSidePx up to kMaxFragmentSidePx (not an L
// completion) are joined where their centres are closer than kFragmentJoinFraction of their
// two mean sides added, and each group of at least two gives the quad of the convex hull of
// its corners (the four of its vertices that span the largest quadrilateral) when its mean side is
// kMinSmallCodeSidePx-kMaxFragmentCodeSidePx; none near a quad of `taken` or near one of another group; in
// the order of each group's first quad, at most `max_quads`.
inline constexpr double kMinFragmentSidePx = 6.0, kMaxFragmentSidePx = 36.0;
inline constexpr double kFragmentJoinFraction = 0.6;
inline constexpr double kMaxFragmentCodeSidePx = 60.0;
std::vector<DarkQuad> MergedFragmentQrCodeQuads(const std::vector<DarkQuad>& quads,
                                                const std::vector<DarkQuad>& taken, int max_quads);

// The bottom-right corner from the symbol's own edges: the intersection of the outer edge
// of the top-right finder (right side, next to the top-right corner) and of the
// bottom-left finder (bottom side, next to the bottom-left corner), found in `gray` within
// max(2.5 px, a tenth of the shortest side) of the quad's sides. zxing places that corner
// from the alignment pattern, or, in version 1 (no alignment pattern), by completing the
// parallelogram of the three finders, a few pixels off under perspective; GroupQrFinders
// from the finders' own (coarse) outlines. Keeps the corner when an edge is not found or
// the corner would move more than a fifth of the shortest side.
void QrCornerFromFinderEdges(const cv::Mat& gray, Quad2d* corners_px);

// The evidence ReadRectifiedQr reads a candidate on (step 3, after the corners are re-found and
// refined): in the upright canvas, the mean gray level of each finder's light 5x5 ring minus
// that of its dark 7x7 ring and 3x3 centre (each module at its central 2x2 pixels), the least
// of the three finders; only those three 7 x 7 module patches are resampled. A code has light
// rings lighter than its dark modules, also small and blurred (every candidate zxing read on
// the recall bench: >= 4.3 gray levels); a clutter triple (boxes, frames) or corners modules
// off mostly do not: ReadRectifiedQr resamples and reads nothing at or under 0 (-infinity for
// bad input).
double RectifiedQrFinderContrast(const cv::Mat& gray, const QrCandidate& candidate);

// The code of `candidate` read from `gray` resampled upright (see above); at most one
// observation (the one nearest the rectified centre), corners mapped back to `gray`.
std::vector<MarkerObservation> ReadRectifiedQr(const cv::Mat& gray, const QrCandidate& candidate);

}  // namespace waymark
