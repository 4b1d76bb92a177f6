#include "detect/qr_finder.h"

#include <Eigen/LU>
#include <Eigen/QR>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <numeric>
#include <opencv2/imgproc.hpp>
#include <optional>

#include "detect/common.h"
#include "detect/components.h"
#include "detect/qr_modules.h"
#include "detect/refine.h"
#include "detect/zxing.h"

namespace waymark {
namespace {

// Binarization: dark where the pixel is below the local mean (box of about a quarter of
// the region's shorter side, so that it spans a finder) by more than kThresholdOffset.
constexpr int kThresholdOffset = 4;
// ... or one noise sigma of the frame when that is more (NoiseAwareThreshold): under twice the
// recall bench's noise the specks of a noisy region made the finder search 2.5 times as long.
constexpr double kThresholdOffsetPerSigma = 1.0;
// Finder checks on contour areas (upscaled pixels). The traced outlines of the 7x7 ring,
// its 5x5 hole and the 3x3 centre give area ratios near 49 : 25 : 9, shifted by blur and
// by the binarization threshold.
constexpr double kMinFinderArea = 60.0;
constexpr double kMinOuterToCentre = 2.5, kMaxOuterToCentre = 14.0;
constexpr double kMinHoleToCentre = 1.3, kMaxHoleToCentre = 7.0;
constexpr double kMinConvexity = 0.85;     // outer area / convex hull area
constexpr double kMaxCentreOffset = 0.15;  // centroid distance / sqrt(outer area)
// Finders found by their hole (IsFinderHole): the 5x5 light ring's area (upscaled pixels),
// the area of the hole's other children (noise) at most this fraction of the centre's, the
// centre's convexity; the outer outline is the hole's scaled by 7/5 about the centre.
constexpr double kMinHoleArea = 30.0;
constexpr double kMaxStrayFraction = 0.25;
constexpr double kMinCentreConvexity = 0.75;
constexpr double kOuterToHoleSide = 7.0 / 5.0;
// A dark quad is a finder candidate with kQuadFinderSolidSides sides this dark and none under
// kQuadFinderWeakestSide (QrCandidatesFromQuads).
constexpr double kQuadFinderSolid = 0.85;
constexpr double kQuadFinderWeakestSide = 0.2;
constexpr int kQuadFinderSolidSides = 2;
// ... and its inside varied (the light ring around the dark centre; a filled box is even).
constexpr double kQuadFinderMinSpread = 0.2;
// The light ring's contrast against the dark ring and centre, fraction of the quad's.
constexpr double kMinRingContrast = 0.1;
// The module-grid reader (detect/qr_modules.h) for codes whose rectified read failed with
// modules under this many pixels (zxing reads larger ones when it can read them at all).
constexpr double kMaxGridReaderModulePx = 3.0;
// Whole small codes among the dark quads (SmallQrCodeQuads).
constexpr double kSmallCodeMaxScale = 0.5;
// Every side at least kSmallCodeMinSideDark dark, one under kSmallCodeMaxSideDark (four
// solid sides: a filled box or an AprilTag's border).
constexpr double kSmallCodeMinSideDark = 0.45, kSmallCodeMaxSideDark = 0.97;
constexpr double kSmallCodeMinSpread = 0.2, kSmallCodeMaxSpread = 1.5;
// Two finders whose centres are closer than this fraction of the smaller's width are one.
constexpr double kSameFinderFraction = 0.3;
// Triples: finder widths within this ratio, distances A-B and A-C within kMaxArmRatio
// (an oblique view foreshortens one axis), the angle at A within [kMinAngleDeg,
// 180 - kMinAngleDeg], and A-B at least kMinArmToWidth finder widths (2 in version 1,
// about 1.3 foreshortened) and at most kMaxArmToWidth (version 10: 7.1).
constexpr double kMaxWidthRatio = 1.8;
constexpr double kMaxArmRatio = 3.0;
constexpr double kMinAngleDeg = 40.0;
constexpr double kMinArmToWidth = 1.2, kMaxArmToWidth = 10.0;
// Each arm of the corner finder within this angle of one of its outline's edges.
constexpr double kMaxArmToEdgeDeg = 20.0;

// Fraction of a side next to a finder pattern that the finder's outer ring covers in every
// version up to 3 (7 of 4 v + 17 modules: 0.33 at version 1, 0.24 at version 3); in larger
// versions the rest of the segment is the separator and format modules, rejected as
// outliers by the line fit.
constexpr double kFinderFraction = 0.24;
// Half window (px) of the edge search along the finders' outer edges: at least this, or
// a tenth of the side (the fourth corner can be off by a few modules).
constexpr double kFinderWindowPx = 2.5;

double SignedArea(const std::array<Eigen::Vector2d, 4>& q) {
  double a = 0.0;
  for (int i = 0; i < 4; ++i) a += q[i].x() * q[(i + 1) % 4].y() - q[(i + 1) % 4].x() * q[i].y();
  return 0.5 * a;
}

// The contour reduced to four corners: its convex hull simplified with a growing tolerance,
// or its minimum-area rectangle when no tolerance gives four.
std::array<cv::Point2f, 4> FourCorners(const std::vector<cv::Point>& contour) {
  std::vector<cv::Point> hull;
  cv::convexHull(contour, hull);
  const double perimeter = cv::arcLength(hull, true);
  for (const double fraction : {0.02, 0.04, 0.06, 0.09, 0.12}) {
    std::vector<cv::Point> approx;
    cv::approxPolyDP(hull, approx, fraction * perimeter, true);
    if (approx.size() == 4) {
      return {cv::Point2f(approx[0]), cv::Point2f(approx[1]), cv::Point2f(approx[2]), cv::Point2f(approx[3])};
    }
    if (approx.size() < 4) break;
  }
  std::array<cv::Point2f, 4> box;
  cv::minAreaRect(contour).points(box.data());
  return box;
}

cv::Point2d Centroid(const std::vector<cv::Point>& contour) {
  const cv::Moments m = cv::moments(contour);
  if (m.m00 <= 0.0) return cv::Point2d(contour[0]);
  return {m.m10 / m.m00, m.m01 / m.m00};
}

// True if outer contour o, hole h (child of o) and centre k (child of h) look like a finder
// (area_x: cv::contourArea of contour x).
bool IsFinder(const std::vector<cv::Point>& o, double area_o, double area_h, const std::vector<cv::Point>& k,
              double area_k) {
  if (area_o < kMinFinderArea || area_k <= 0.0) return false;
  const double outer_ratio = area_o / area_k, hole_ratio = area_h / area_k;
  if (outer_ratio < kMinOuterToCentre || outer_ratio > kMaxOuterToCentre) return false;
  if (hole_ratio < kMinHoleToCentre || hole_ratio > kMaxHoleToCentre || area_h >= area_o) return false;
  const cv::Point2d offset = Centroid(o) - Centroid(k);
  if (std::hypot(offset.x, offset.y) > kMaxCentreOffset * std::sqrt(area_o)) return false;
  std::vector<cv::Point> hull;
  cv::convexHull(o, hull);
  return area_o >= kMinConvexity * cv::contourArea(hull);
}

// True if hole h and centre k (child of h) look like a finder's light ring and dark centre,
// whatever the ring's outer contour: blur and low contrast join the dark ring to the data
// modules or the quiet zone's surroundings (its outline is then no square), while the light
// 5x5 ring inside it stays closed around the 3x3 centre. The centre must be the hole's only
// sizeable child, concentric with it, and the hole convex.
bool IsFinderHole(const std::vector<cv::Point>& h, double area_h, const std::vector<cv::Point>& k,
                  double area_k, double other_children_area) {
  if (area_h < kMinHoleArea || area_k <= 0.0 || other_children_area > kMaxStrayFraction * area_k)
    return false;
  const double hole_ratio = area_h / area_k;
  if (hole_ratio < kMinHoleToCentre || hole_ratio > kMaxHoleToCentre) return false;
  const cv::Point2d offset = Centroid(h) - Centroid(k);
  if (std::hypot(offset.x, offset.y) > kMaxCentreOffset * std::sqrt(area_h)) return false;
  std::vector<cv::Point> hull;
  cv::convexHull(h, hull);
  if (area_h < kMinConvexity * cv::contourArea(hull)) return false;
  cv::convexHull(k, hull);
  return area_k >= kMinCentreConvexity * cv::contourArea(hull);
}

// The region binarized (dark = 255) at `scale` times its resolution; `*work_out` is the
// region at that scale.
cv::Mat BinarizeRegion(const cv::Mat& gray, const cv::Rect& region, double scale, cv::Mat* work_out) {
  cv::Mat work;
  if (scale > 1.0) {
    cv::resize(gray(region), work, cv::Size(), scale, scale, cv::INTER_LINEAR);
  } else {
    work = gray(region);
  }
  const int side = std::min(work.cols, work.rows);
  const int block = std::clamp(side / 8, 9, 101) | 1;
  // cv::adaptiveThreshold's bits (mean of the block, THRESH_BINARY_INV), in integers.
  cv::Mat binary = DarkerThanLocalMean(
      work, block, NoiseAwareThreshold(kThresholdOffset, NoiseSigma(gray), kThresholdOffsetPerSigma));
  if (work_out) *work_out = work;
  return binary;
}

// Where a finder can be (FindQrFinderPatterns): tracing every contour of a cluttered,
// noisy region (noise under the local-mean threshold makes a field of specks, each a
// contour) was most of the finder search, so the binary image is first cleared outside
// windows around the places that can be a finder's centre, found from runs. A row or a column
// through a finder's centre reads dark ring, light ring, dark centre, light ring, dark ring:
// 1 : 1 : 3 : 1 : 1 modules head on, any affine view keeping the ratios along a line
// (FinderRuns; loosely: blur and the threshold shift the ratios, the outer dark runs may
// join data modules or other dark pixels). A row's pattern counts when
//   - its light runs are lighter in `gray` than its centre run by kMinLightOverCentre gray
//     levels on average (a light ring's modules against the dark centre's; specks of noise
//     differ by a few levels, which the threshold offset of 4 cuts into runs),
//   - the column through the centre run's middle reads the same pattern, and
//   - the larger of the two hole lengths (light + centre + light) is at least
//     kMinHoleModules modules of kMinFinderModulePx pixels of the original image;
// it keeps a window of kWindowToHole hole lengths plus kWindowSlackPx on every side of the
// centre run's middle, in cells of kWindowCellPx. A finder's outline (7/5 of the hole, at
// most 0.7 hole lengths from its centre in any affine view), hole and centre lie inside the
// windows of the rows through its centre.
constexpr int kMinCentreRunPx = 2;
constexpr double kMaxLightToCentre = 0.85, kLightSlackPx = 1.5;
constexpr double kMinRingToCentre = 0.1;
constexpr double kMinLightOverCentre = 8.0;
constexpr double kMinHoleModules = 3.5, kMinFinderModulePx = 1.0, kMinHolePx = 5.0;
constexpr double kWindowToHole = 1.6;
constexpr int kWindowSlackPx = 4;
constexpr int kWindowCellPx = 8;

// True if the runs across a finder's middle can be one: dark ring, light ring, dark centre,
// light ring, dark ring. The centre at least kMinCentreRunPx; each light run at most
// kMaxLightToCentre of it plus kLightSlackPx (the light 5x5 ring's area is 1.3-7 times the
// centre's in the finder test), the two about equal (through the centre of a finder seen in
// any affine view they are); the dark ring's runs at least kMinRingToCentre of the centre's
// (a ring of a module thinned by the threshold against a centre of three thickened: a dark box
// in light surroundings flanked by specks of noise is no finder).
bool FinderRuns(int ring1, int light1, int centre, int light2, int ring2) {
  if (centre < kMinCentreRunPx) return false;
  const double max_light = kMaxLightToCentre * centre + kLightSlackPx;
  if (light1 > max_light || light2 > max_light) return false;
  if (std::abs(light1 - light2) > 0.5 * std::max(light1, light2) + 1.0) return false;
  const double min_ring = std::max(1.0, kMinRingToCentre * centre);
  return ring1 >= min_ring && ring2 >= min_ring;
}

// The light + dark + light length of the column through (x, y) when its runs there are
// FinderRuns with the centre holding (x, y); nothing otherwise.
std::optional<int> VerticalFinderHole(const cv::Mat& binary, int x, int y) {
  const auto dark = [&](int r) { return binary.ptr<uint8_t>(r)[x] != 0; };
  // The length of the run of `value` from row r on by `step`, counted up to `cap`.
  const auto run = [&](int r, int step, bool value, int cap) {
    int n = 0;
    while (n < cap && r >= 0 && r < binary.rows && dark(r) == value) ++n, r += step;
    return n;
  };
  int top = y, bottom = y;
  while (top > 0 && dark(top - 1)) --top;
  while (bottom + 1 < binary.rows && dark(bottom + 1)) ++bottom;
  const int centre = bottom - top + 1;
  if (centre < kMinCentreRunPx) return std::nullopt;
  const int light_cap = static_cast<int>(kMaxLightToCentre * centre + kLightSlackPx) + 2;
  const int up = run(top - 1, -1, false, light_cap), down = run(bottom + 1, 1, false, light_cap);
  const int ring_cap = static_cast<int>(std::ceil(std::max(1.0, kMinRingToCentre * centre)));
  const int ring_up = run(top - 1 - up, -1, true, ring_cap);
  const int ring_down = run(bottom + 1 + down, 1, true, ring_cap);
  if (!FinderRuns(ring_up, up, centre, down, ring_down)) return std::nullopt;
  return up + centre + down;
}

// Appends to `starts` the first pixel of every run of equal values of the row, then `cols`;
// eight pixels at a time (SkipEqual).
void RunStarts(const uint8_t* row, int cols, std::vector<int>* starts) {
  starts->clear();
  for (int x = 0; x < cols; x = SkipEqual(row, x, cols, row[x])) starts->push_back(x);
  starts->push_back(cols);
}

// `binary` (CV_8UC1, 0 or 255, the local-mean threshold of `gray`, the same size) cleared
// outside the windows above; returns the bounding box of what is kept (empty if nothing).
cv::Rect KeepFinderWindows(const cv::Mat& gray, double scale, cv::Mat* binary) {
  const int rows = binary->rows, cols = binary->cols;
  const double min_hole_px = std::max(kMinHolePx, kMinHoleModules * kMinFinderModulePx * scale);
  const int cell_rows = (rows + kWindowCellPx - 1) / kWindowCellPx;
  const int cell_cols = (cols + kWindowCellPx - 1) / kWindowCellPx;
  std::vector<uint8_t> keep(static_cast<size_t>(cell_rows) * cell_cols, 0);
  std::vector<int> starts;
  const auto mean = [](const uint8_t* g, int from, int to) {
    int sum = 0;
    for (int x = from; x < to; ++x) sum += g[x];
    return static_cast<double>(sum) / (to - from);
  };
  for (int y = 0; y < rows; ++y) {
    const uint8_t* row = binary->ptr<uint8_t>(y);
    RunStarts(row, cols, &starts);
    const int runs = static_cast<int>(starts.size()) - 1;
    const uint8_t* g = gray.ptr<uint8_t>(y);
    // Dark runs i with light runs i - 1, i + 1 and dark runs i - 2, i + 2.
    for (int i = (row[0] != 0) ? 2 : 3; i + 2 < runs; i += 2) {
      const int centre = starts[i + 1] - starts[i];
      const int left = starts[i] - starts[i - 1], right = starts[i + 2] - starts[i + 1];
      if (!FinderRuns(starts[i - 1] - starts[i - 2], left, centre, right, starts[i + 3] - starts[i + 2])) {
        continue;
      }
      const double centre_gray = mean(g, starts[i], starts[i + 1]);
      if (std::min(mean(g, starts[i - 1], starts[i]), mean(g, starts[i + 1], starts[i + 2])) - centre_gray <
          kMinLightOverCentre) {
        continue;
      }
      const int mx = (starts[i] + starts[i + 1] - 1) / 2;
      const std::optional<int> vertical_hole = VerticalFinderHole(*binary, mx, y);
      if (!vertical_hole) continue;
      const int hole = std::max(left + centre + right, *vertical_hole);
      if (hole < min_hole_px) continue;
      const double half = kWindowToHole * hole + kWindowSlackPx;
      const int x0 = std::max(0, static_cast<int>(std::floor((mx - half) / kWindowCellPx)));
      const int x1 = std::min(cell_cols - 1, static_cast<int>(std::floor((mx + half) / kWindowCellPx)));
      const int y0 = std::max(0, static_cast<int>(std::floor((y - half) / kWindowCellPx)));
      const int y1 = std::min(cell_rows - 1, static_cast<int>(std::floor((y + half) / kWindowCellPx)));
      for (int cy = y0; cy <= y1; ++cy) {
        std::fill(keep.begin() + static_cast<size_t>(cy) * cell_cols + x0,
                  keep.begin() + static_cast<size_t>(cy) * cell_cols + x1 + 1, uint8_t{1});
      }
    }
  }
  int kept_x0 = cell_cols, kept_x1 = -1, kept_y0 = cell_rows, kept_y1 = -1;
  for (int cy = 0; cy < cell_rows; ++cy) {
    for (int cx = 0; cx < cell_cols; ++cx) {
      if (!keep[static_cast<size_t>(cy) * cell_cols + cx]) continue;
      kept_x0 = std::min(kept_x0, cx), kept_x1 = std::max(kept_x1, cx);
      kept_y0 = std::min(kept_y0, cy), kept_y1 = std::max(kept_y1, cy);
    }
  }
  for (int y = 0; y < rows; ++y) {
    uint8_t* row = binary->ptr<uint8_t>(y);
    const uint8_t* cells = keep.data() + static_cast<size_t>(y / kWindowCellPx) * cell_cols;
    for (int cx = 0; cx < cell_cols; ++cx) {
      if (cells[cx]) continue;
      const int x0 = cx * kWindowCellPx;
      std::memset(row + x0, 0, std::min(kWindowCellPx, cols - x0));
    }
  }
  if (kept_x1 < 0) return {};
  return cv::Rect(kept_x0 * kWindowCellPx, kept_y0 * kWindowCellPx, (kept_x1 - kept_x0 + 1) * kWindowCellPx,
                  (kept_y1 - kept_y0 + 1) * kWindowCellPx) &
         cv::Rect(0, 0, cols, rows);
}

// |sin| of the angle between `direction` and the nearest edge of the finder's outline.
double EdgeMisalignment(const QrFinderPattern& finder, const Eigen::Vector2d& direction) {
  const Eigen::Vector2d u = direction.normalized();
  double best = 1.0;
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector2d e = (finder.outer_px[(i + 1) % 4] - finder.outer_px[i]).normalized();
    best = std::min(best, std::abs(u.x() * e.y() - u.y() * e.x()));
  }
  return best;
}

// Score of the triple with right-angle corner a (lower is better), or +inf if it cannot
// be a QR code's three finders.
double TripleScore(const QrFinderPattern& a, const QrFinderPattern& b, const QrFinderPattern& c) {
  const double w_max = std::max({a.width_px, b.width_px, c.width_px});
  const double w_min = std::min({a.width_px, b.width_px, c.width_px});
  const Eigen::Vector2d ab = b.centre_px - a.centre_px, ac = c.centre_px - a.centre_px;
  const double d_ab = ab.norm(), d_ac = ac.norm();
  constexpr double kInf = std::numeric_limits<double>::infinity();
  if (w_max > kMaxWidthRatio * w_min || d_ab <= 0.0 || d_ac <= 0.0) return kInf;
  const double arm_ratio = std::max(d_ab, d_ac) / std::min(d_ab, d_ac);
  const double w_mean = (a.width_px + b.width_px + c.width_px) / 3.0;
  if (arm_ratio > kMaxArmRatio || std::min(d_ab, d_ac) < kMinArmToWidth * w_mean ||
      std::max(d_ab, d_ac) > kMaxArmToWidth * w_mean) {
    return kInf;
  }
  const double cos_angle = ab.dot(ac) / (d_ab * d_ac);
  if (std::abs(cos_angle) > std::cos(kMinAngleDeg * M_PI / 180.0)) return kInf;
  // The arms run along the corner finder's own edges (a wrong corner sees a diagonal).
  const double misalignment = std::max(EdgeMisalignment(a, ab), EdgeMisalignment(a, ac));
  if (misalignment > std::sin(kMaxArmToEdgeDeg * M_PI / 180.0)) return kInf;
  return std::abs(cos_angle) + 0.5 * std::log(arm_ratio) + std::log(w_max / w_min) + 2.0 * misalignment;
}

// Index of the vertex of `quad` with the largest weight_s * s + weight_t * t, where (s, t)
// are its affine coordinates in the code's axes: v = origin + s * axis_s + t * axis_t.
// Affine coordinates keep their order under the shear and foreshortening of an oblique
// view, where distances do not.
int Extreme(const std::array<Eigen::Vector2d, 4>& quad, const Eigen::Vector2d& origin,
            const Eigen::Vector2d& axis_s, const Eigen::Vector2d& axis_t, double weight_s, double weight_t) {
  Eigen::Matrix2d basis;
  basis << axis_s, axis_t;
  const Eigen::Matrix2d inverse = basis.inverse();
  int best = 0;
  double best_value = -std::numeric_limits<double>::infinity();
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector2d st = inverse * (quad[i] - origin);
    const double value = weight_s * st.x() + weight_t * st.y();
    if (value > best_value) best_value = value, best = i;
  }
  return best;
}

Line2d LineThrough(const Eigen::Vector2d& p, const Eigen::Vector2d& q) {
  Line2d line;
  line.point = p;
  line.direction = (q - p).normalized();
  return line;
}

// The code's corners from finders a (top-left), b (top-right), c (bottom-left): in the
// affine frame of the arms a->b (s) and a->c (t), a's vertex of least s + t, b's of
// greatest s - t, c's of greatest t - s.
Quad2d CodeCorners(const QrFinderPattern& a, const QrFinderPattern& b, const QrFinderPattern& c) {
  const Eigen::Vector2d ab = b.centre_px - a.centre_px, ac = c.centre_px - a.centre_px;
  const int ia = Extreme(a.outer_px, a.centre_px, ab, ac, -1.0, -1.0);
  const int ib = Extreme(b.outer_px, a.centre_px, ab, ac, 1.0, -1.0);
  const int ic = Extreme(c.outer_px, a.centre_px, ab, ac, -1.0, 1.0);
  Quad2d q;
  q[0] = a.outer_px[ia];
  q[1] = b.outer_px[ib];
  q[3] = c.outer_px[ic];
  q[2] = q[1] + q[3] - q[0];  // the parallelogram, unless the finders' edges do better
  // Right edge of b: its corner and the next vertex clockwise; bottom edge of c: its corner
  // and the previous vertex clockwise.
  const std::optional<Eigen::Vector2d> corner =
      IntersectLines(LineThrough(b.outer_px[ib], b.outer_px[(ib + 1) % 4]),
                     LineThrough(c.outer_px[ic], c.outer_px[(ic + 3) % 4]));
  if (corner && (*corner - q[2]).norm() < 0.3 * QuadMeanSide(q)) q[2] = *corner;
  return q;
}

// The three finders of a rectified code (the symbol at quiet .. quiet + side pixel edges,
// kRectifiedModulePx pixels per module): for each, the mean gray level of its light 5x5
// ring's modules minus that of its dark modules (7x7 ring and 3x3 centre), each module
// sampled at its central 2x2 pixels; the smallest of the three. A code placed right has
// light rings lighter than the dark modules even when small and blurred (every candidate
// zxing read on the recall bench: at least 4 gray levels); three quarters of the candidates
// not read (clutter triples, candidates whose corners are modules off) are at or under 0.
// Only the three finders' 7 x 7 module patches of the canvas are resampled (issue 14's tenth
// speed round): the whole canvas, up to 420 px square in bicubic, was most of a clutter
// triple's cost, and most clutter triples stop here.
constexpr double kMinRectifiedFinderContrast = 0.0;
double FinderContrastOnPatches(const cv::Mat& gray, const cv::Matx33d& H_rect_image, double quiet,
                               double side) {
  constexpr double m = kRectifiedModulePx;
  const int patch = static_cast<int>(7.0 * m);
  const double far = quiet + side - 7.0 * m;
  double worst = std::numeric_limits<double>::infinity();
  cv::Mat rectified;
  for (const auto& [x0, y0] : {std::pair<double, double>{quiet, quiet}, {far, quiet}, {quiet, far}}) {
    // The canvas' pixels x0 .. x0 + 7 m: the same homography shifted by the patch's origin.
    const cv::Matx33d shift(1.0, 0.0, -x0, 0.0, 1.0, -y0, 0.0, 0.0, 1.0);
    cv::warpPerspective(gray, rectified, cv::Mat(shift * H_rect_image), cv::Size(patch, patch),
                        cv::INTER_CUBIC, cv::BORDER_REPLICATE);
    const auto module = [&](int u, int v) {
      const int x = static_cast<int>((u + 0.5) * m - 1.0), y = static_cast<int>((v + 0.5) * m - 1.0);
      return (rectified.at<uint8_t>(y, x) + rectified.at<uint8_t>(y, x + 1) +
              rectified.at<uint8_t>(y + 1, x) + rectified.at<uint8_t>(y + 1, x + 1)) /
             4.0;
    };
    double dark = 0.0, light = 0.0;
    int dark_n = 0, light_n = 0;
    for (int v = 0; v < 7; ++v) {
      for (int u = 0; u < 7; ++u) {
        const double g = module(u, v);
        if (std::max(std::abs(u - 3), std::abs(v - 3)) == 2) {
          light += g, ++light_n;
        } else {
          dark += g, ++dark_n;
        }
      }
    }
    worst = std::min(worst, light / light_n - dark / dark_n);
  }
  return worst;
}

// Where ReadRectifiedQr resamples a candidate: the refined quad, the module count, the
// canvas and the homography from `gray` onto it.
struct RectifiedPlacement {
  Quad2d quad;
  double modules = 0.0, side = 0.0, quiet = 0.0;
  int canvas = 0;
  cv::Mat H_rect_image;
};
std::optional<RectifiedPlacement> PlaceRectified(const cv::Mat& gray, const QrCandidate& candidate) {
  if (gray.empty() || gray.type() != CV_8UC1 || !(candidate.module_px > 0.0)) return std::nullopt;
  RectifiedPlacement p;
  p.modules = std::clamp(QuadMeanSide(candidate.corners_px) / candidate.module_px, 21.0, 97.0);
  p.side = std::round(p.modules * kRectifiedModulePx);
  p.quiet = kRectifiedQuietModules * kRectifiedModulePx;
  p.canvas = static_cast<int>(p.side + 2.0 * p.quiet);
  // Symbol edges at quiet .. quiet + side (pixel edges), i.e. centres 0.5 px less.
  const double lo = p.quiet - 0.5, hi = p.quiet + p.side - 0.5;
  std::vector<cv::Point2f> src,
      dst = {{float(lo), float(lo)}, {float(hi), float(lo)}, {float(hi), float(hi)}, {float(lo), float(hi)}};
  p.quad = candidate.corners_px;
  QrCornerFromFinderEdges(gray, &p.quad);
  // The finders' outlines are a binarization's, a pixel or so off on a blurred small code
  // (a third of a module at 2 px per module: enough to sample the module grid wrongly);
  // the symbol's own edges place it better, with a first window under a module (the outer
  // row's light modules leave edges a module inside).
  RefineOptions refine;
  refine.search_px = 1.25;
  refine.search_fraction = 0.035;
  if (const std::optional<RefinedQuad> refined = RefineQuadCorners(gray, p.quad, refine)) {
    p.quad = refined->corners_px;
  }
  for (const Eigen::Vector2d& c : p.quad) src.emplace_back(c.x(), c.y());
  p.H_rect_image = cv::getPerspectiveTransform(src, dst);
  return p;
}

// zxing on the rectified code: as it is, then sharpened (unsharp mask, I + a (I - G_s * I)
// with s = kSharpenSigmaModules modules and a = kSharpenAmount: a blur of half a module
// merges the light gaps between dark modules, which zxing's local-average binarizer then
// misses), then with the global-histogram binarizer.
constexpr double kSharpenSigmaModules = 0.4;
constexpr double kSharpenAmount = 1.0;
std::vector<MarkerObservation> ReadUpright(const cv::Mat& rectified) {
  std::vector<MarkerObservation> read = ReadWithZxing(rectified, ZxingSymbology::kQrCode, ZxingPass{});
  if (!read.empty()) return read;
  cv::Mat blurred, sharpened;
  cv::GaussianBlur(rectified, blurred, cv::Size(), kSharpenSigmaModules * kRectifiedModulePx);
  cv::addWeighted(rectified, 1.0 + kSharpenAmount, blurred, -kSharpenAmount, 0.0, sharpened);
  read = ReadWithZxing(sharpened, ZxingSymbology::kQrCode, ZxingPass{});
  if (!read.empty()) return read;
  ZxingPass global;
  global.local_average_binarizer = false;
  return ReadWithZxing(rectified, ZxingSymbology::kQrCode, global);
}

}  // namespace

void QrCornerFromFinderEdges(const cv::Mat& gray, Quad2d* corners_px) {
  Quad2d& c = *corners_px;
  double shortest = std::numeric_limits<double>::infinity();
  for (int i = 0; i < 4; ++i) shortest = std::min(shortest, (c[(i + 1) % 4] - c[i]).norm());
  const double window = std::min(std::max(kFinderWindowPx, 0.1 * shortest), shortest / 6.0);
  constexpr double kMinStep = 12.0;  // gray levels per px, as RefineOptions::min_step
  const std::optional<Line2d> right =
      FitSideSegment(gray, c[1], c[2], 0.02, kFinderFraction, window, kMinStep);
  const std::optional<Line2d> bottom =
      FitSideSegment(gray, c[2], c[3], 1.0 - kFinderFraction, 0.98, window, kMinStep);
  if (!right || !bottom || right->inlier_fraction < 0.5 || bottom->inlier_fraction < 0.5) return;
  const std::optional<Eigen::Vector2d> corner = IntersectLines(*right, *bottom);
  if (corner && (*corner - c[2]).norm() < 0.2 * shortest) c[2] = *corner;
}

std::vector<QrFinderPattern> FindQrFinderPatterns(const cv::Mat& gray, const cv::Rect& region_in,
                                                  int max_patterns) {
  const cv::Rect region = region_in & cv::Rect(0, 0, gray.cols, gray.rows);
  if (gray.empty() || gray.type() != CV_8UC1 || region.width < 16 || region.height < 16) return {};
  const double scale =
      std::clamp(kFinderWorkSidePx / std::min(region.width, region.height), 1.0, kMaxFinderUpscale);
  cv::Mat work_gray;
  cv::Mat binary = BinarizeRegion(gray, region, scale, &work_gray);
  const cv::Rect kept = KeepFinderWindows(work_gray, scale, &binary);
  if (kept.empty()) return {};
  // Isolated dark pixels (four in ten of the contours traced on the recall bench's issue
  // frames) are one-point contours no finder test can use (no area, no children): cleared first.
  cv::Mat roi = binary(kept);
  ClearIsolatedPixels(&roi);
  std::vector<std::vector<cv::Point>> contours;
  std::vector<cv::Vec4i> hierarchy;  // next, previous, first child, parent
  cv::findContours(roi, contours, hierarchy, cv::RETR_TREE, cv::CHAIN_APPROX_SIMPLE, kept.tl());
  // Up-scaled pixel centres back to the full image: (p + 0.5) / scale - 0.5 + offset.
  const auto to_full = [&](const cv::Point2d& p) {
    return Eigen::Vector2d((p.x + 0.5) / scale - 0.5 + region.x, (p.y + 0.5) / scale - 0.5 + region.y);
  };
  // Each contour's area computed once (a hole's children are tried against its outline in turn).
  std::vector<double> areas(contours.size(), -1.0);
  const auto area_of = [&](int i) {
    if (areas[i] < 0.0) areas[i] = cv::contourArea(contours[i]);
    return areas[i];
  };
  std::vector<QrFinderPattern> found;
  for (size_t o = 0; o < contours.size(); ++o) {
    if (contours[o].size() < 4) continue;
    for (int h = hierarchy[o][2]; h >= 0; h = hierarchy[h][0]) {
      int k = hierarchy[h][2];  // the hole's children: the first that completes a finder
      while (k >= 0 &&
             !IsFinder(contours[o], area_of(static_cast<int>(o)), area_of(h), contours[k], area_of(k))) {
        k = hierarchy[k][0];
      }
      QrFinderPattern f;
      if (k >= 0) {
        f.centre_px = to_full(Centroid(contours[k]));
        f.width_px = std::sqrt(area_of(static_cast<int>(o))) / scale;
        const std::array<cv::Point2f, 4> corners = FourCorners(contours[o]);
        for (int i = 0; i < 4; ++i) f.outer_px[i] = to_full(cv::Point2d(corners[i]));
      } else {
        // The ring's outline is not a finder's (joined to other dark pixels): the hole and
        // its largest child may still be one.
        int largest = -1;
        double largest_area = 0.0, total_area = 0.0;
        for (int c = hierarchy[h][2]; c >= 0; c = hierarchy[c][0]) {
          const double area = area_of(c);
          total_area += area;
          if (area > largest_area) largest_area = area, largest = c;
        }
        if (largest < 0 || !IsFinderHole(contours[h], area_of(h), contours[largest], largest_area,
                                         total_area - largest_area)) {
          continue;
        }
        const cv::Point2d centre = Centroid(contours[largest]);
        f.centre_px = to_full(centre);
        f.width_px = kOuterToHoleSide * std::sqrt(area_of(h)) / scale;
        const std::array<cv::Point2f, 4> corners = FourCorners(contours[h]);
        for (int i = 0; i < 4; ++i) {
          // The hole's outline runs through the centres of the ring's inner pixels, half a
          // pixel beyond the hole's edge (0.7 at a corner); the ring's outer edge is a
          // module (1/5 of the hole's side) beyond that edge.
          const cv::Point2d d = cv::Point2d(corners[i]) - centre;
          const double length = std::hypot(d.x, d.y);
          const cv::Point2d edge = length > 0.7 ? d * ((length - 0.7) / length) : d;
          f.outer_px[i] = to_full(centre + edge * kOuterToHoleSide);
        }
      }
      if (SignedArea(f.outer_px) < 0.0) std::reverse(f.outer_px.begin(), f.outer_px.end());
      found.push_back(f);
      break;
    }
  }
  // One finder seen twice (an outline joined to neighbouring dark pixels passes the loose
  // area test, and its hole is found again on its own): the smaller is kept, since a
  // joined outline only grows.
  std::sort(found.begin(), found.end(),
            [](const QrFinderPattern& x, const QrFinderPattern& y) { return x.width_px < y.width_px; });
  std::vector<QrFinderPattern> distinct;
  for (const QrFinderPattern& f : found) {
    const bool seen = std::any_of(distinct.begin(), distinct.end(), [&f](const QrFinderPattern& d) {
      return (d.centre_px - f.centre_px).norm() < kSameFinderFraction * d.width_px;
    });
    if (!seen) distinct.push_back(f);
  }
  found = std::move(distinct);
  std::stable_sort(found.begin(), found.end(), [](const QrFinderPattern& x, const QrFinderPattern& y) {
    return x.width_px > y.width_px;
  });
  if (static_cast<int>(found.size()) > max_patterns) found.resize(max_patterns);
  return found;
}

std::vector<QrCandidate> GroupQrFinders(const std::vector<QrFinderPattern>& finders,
                                        const cv::Size& image_size) {
  struct Triple {
    double score;
    int a, b, c;
  };
  std::vector<Triple> triples;
  const int n = static_cast<int>(finders.size());
  // Each finder's possible partners first (similar width, within the arm lengths a code
  // allows): triples are formed only among them, so that a frame's hundred finder-like
  // quads cost no million triples.
  std::vector<std::vector<int>> partners(finders.size());
  for (int a = 0; a < n; ++a) {
    for (int b = 0; b < n; ++b) {
      const double wa = finders[a].width_px, wb = finders[b].width_px;
      if (a == b || std::max(wa, wb) > kMaxWidthRatio * std::min(wa, wb)) continue;
      const double d = (finders[b].centre_px - finders[a].centre_px).norm();
      if (d < kMinArmToWidth * std::min(wa, wb) / kMaxWidthRatio ||
          d > kMaxArmToWidth * std::max(wa, wb) * kMaxWidthRatio) {
        continue;
      }
      partners[a].push_back(b);
    }
  }
  for (int a = 0; a < n; ++a) {
    for (size_t i = 0; i < partners[a].size(); ++i) {
      for (size_t j = i + 1; j < partners[a].size(); ++j) {
        const int b = std::min(partners[a][i], partners[a][j]), c = std::max(partners[a][i], partners[a][j]);
        const double score = TripleScore(finders[a], finders[b], finders[c]);
        if (!std::isfinite(score)) continue;
        const Eigen::Vector2d ab = finders[b].centre_px - finders[a].centre_px;
        const Eigen::Vector2d ac = finders[c].centre_px - finders[a].centre_px;
        // Clockwise on screen (y down): top-right then bottom-left.
        const bool clockwise = ab.x() * ac.y() - ab.y() * ac.x() > 0.0;
        triples.push_back({score, a, clockwise ? b : c, clockwise ? c : b});
      }
    }
  }
  std::sort(triples.begin(), triples.end(),
            [](const Triple& x, const Triple& y) { return x.score < y.score; });
  std::vector<bool> used(finders.size(), false);
  std::vector<QrCandidate> out;
  for (const Triple& t : triples) {
    if (used[t.a] || used[t.b] || used[t.c]) continue;
    QrCandidate candidate;
    candidate.corners_px = CodeCorners(finders[t.a], finders[t.b], finders[t.c]);
    candidate.module_px = (finders[t.a].width_px + finders[t.b].width_px + finders[t.c].width_px) / 21.0;
    if (!QuadIsValid(candidate.corners_px, image_size, 10.0)) continue;
    used[t.a] = used[t.b] = used[t.c] = true;
    out.push_back(candidate);
  }
  return out;
}

namespace {

double Bilinear(const cv::Mat& gray, const Eigen::Vector2d& p) {
  const double x = std::clamp(p.x(), 0.0, gray.cols - 1.001), y = std::clamp(p.y(), 0.0, gray.rows - 1.001);
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  const double fx = x - x0, fy = y - y0;
  const double a = gray.at<uint8_t>(y0, x0), b = gray.at<uint8_t>(y0, x0 + 1);
  const double c = gray.at<uint8_t>(y0 + 1, x0), d = gray.at<uint8_t>(y0 + 1, x0 + 1);
  return (1 - fy) * ((1 - fx) * a + fx * b) + fy * ((1 - fx) * c + fx * d);
}

// True if the quad's profile from each side's middle to its centre reads as a finder's
// dark ring, light ring and dark centre (modules 0-1, 1-2 and 2-3.5 of the 3.5 from edge to
// centre): the light ring lighter than both by kMinRingContrast of the quad's contrast
// (the separator just outside minus the dark ring). AprilTags, DataMatrix symbols, framed
// or filled boxes are rarely so.
bool HasFinderProfile(const cv::Mat& gray, const Quad2d& q) {
  const Eigen::Vector2d centre = QuadCenter(q);
  double outside = 0.0, ring = 0.0, hole = 0.0;
  for (int k = 0; k < 4; ++k) {
    const Eigen::Vector2d mid = 0.5 * (q[k] + q[(k + 1) % 4]);
    const Eigen::Vector2d inward = centre - mid;  // 3.5 modules
    outside += Bilinear(gray, mid - inward * (0.5 / 3.5));
    ring += Bilinear(gray, mid + inward * (0.5 / 3.5));
    hole += Bilinear(gray, mid + inward * (1.5 / 3.5));
  }
  outside /= 4.0, ring /= 4.0, hole /= 4.0;
  const double middle = Bilinear(gray, centre);
  const double contrast = outside - ring;
  return contrast > 0.0 && hole - ring >= kMinRingContrast * contrast &&
         hole - middle >= kMinRingContrast * contrast;
}

}  // namespace

namespace {

// A finder pair's possible layouts: the top-left module of each finder's 7 x 7 outline in an
// N x N code (module coordinates, x right, y down as on screen).
struct PairLayout {
  Eigen::Vector2d a_origin, b_origin;
};

// The outline of a finder whose top-left module is at `origin` (module coordinates): its 7 x 7
// modules' corners, clockwise on screen from the top-left.
std::array<Eigen::Vector2d, 4> FinderModuleOutline(const Eigen::Vector2d& origin) {
  return {origin, origin + Eigen::Vector2d(7, 0), origin + Eigen::Vector2d(7, 7),
          origin + Eigen::Vector2d(0, 7)};
}

// The affine map from module coordinates to the image that puts the two finders' outlines
// (7 x 7 modules each) at their places in `layout`, over the labellings of the outlines'
// corners the one with the least squared error; nullopt when it is over kMaxPairFitRmsModules
// modules (RMS). Affine, not a homography: the outlines span 7 of the code's modules across
// the pair, and perspective terms fitted on them throw the far side several modules off.
constexpr double kMaxPairFitRmsModules = 1.0;
std::optional<Eigen::Matrix<double, 2, 3>> PairLayoutAffine(const QrFinderPattern& a,
                                                            const QrFinderPattern& b,
                                                            const PairLayout& layout, double module_px) {
  const std::array<Eigen::Vector2d, 4> a_modules = FinderModuleOutline(layout.a_origin),
                                       b_modules = FinderModuleOutline(layout.b_origin);
  double best_error = std::numeric_limits<double>::infinity();
  Eigen::Matrix<double, 2, 3> best = Eigen::Matrix<double, 2, 3>::Zero();
  // Both outlines are clockwise on screen, as the module outlines are: only their starting
  // corners are unknown.
  for (int sa = 0; sa < 4; ++sa) {
    for (int sb = 0; sb < 4; ++sb) {
      Eigen::Matrix<double, 8, 3> src;
      Eigen::Matrix<double, 8, 2> dst;
      for (int i = 0; i < 4; ++i) {
        src.row(2 * i) = a_modules[i].homogeneous().transpose();
        dst.row(2 * i) = a.outer_px[(i + sa) % 4].transpose();
        src.row(2 * i + 1) = b_modules[i].homogeneous().transpose();
        dst.row(2 * i + 1) = b.outer_px[(i + sb) % 4].transpose();
      }
      const Eigen::Matrix<double, 3, 2> x = src.colPivHouseholderQr().solve(dst);
      const double error = (src * x - dst).squaredNorm();
      if (error < best_error) best_error = error, best = x.transpose();
    }
  }
  if (!std::isfinite(best_error) || std::sqrt(best_error / 8.0) > kMaxPairFitRmsModules * module_px) {
    return std::nullopt;
  }
  return best;
}

// True if `p` is inside the clockwise (on screen) convex quad.
bool InsideQuad(const Quad2d& quad, const Eigen::Vector2d& p) {
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector2d side = quad[(i + 1) % 4] - quad[i], to_p = p - quad[i];
    if (side.x() * to_p.y() - side.y() * to_p.x() < 0.0) return false;
  }
  return true;
}

// The top-left module of the finder pattern nearest `expected` (module coordinates of the
// pair's map `to_image`) within kThirdFinderReachModules modules: the 9 x 9 modules of a
// finder and its light separator sampled (bilinear, module centres) at shifts of half a module,
// the one whose samples correlate best with the pattern (dark ring, light ring, dark 3 x 3
// centre, light separator), kept when that correlation is at least kMinThirdFinderCorrelation.
constexpr double kMinThirdFinderCorrelation = 0.6;
std::optional<Eigen::Vector2d> FindThirdFinder(const cv::Mat& gray,
                                               const Eigen::Matrix<double, 2, 3>& to_image,
                                               const Eigen::Vector2d& expected) {
  static const std::array<double, 81> pattern = [] {
    std::array<double, 81> p{};
    for (int v = -1; v <= 7; ++v) {
      for (int u = -1; u <= 7; ++u) {
        const int ring =
            std::min(std::min(u, v), std::min(6 - u, 6 - v));  // -1 separator, 0 dark, 1 light, >= 2 centre
        p[(v + 1) * 9 + (u + 1)] = (ring == 0 || ring >= 2) ? 1.0 : 0.0;
      }
    }
    const double mean = std::accumulate(p.begin(), p.end(), 0.0) / 81.0;
    double norm = 0.0;
    for (double& x : p) x -= mean, norm += x * x;
    for (double& x : p) x /= std::sqrt(norm);
    return p;
  }();
  const int steps = static_cast<int>(2.0 * kThirdFinderReachModules);
  double best = kMinThirdFinderCorrelation;
  std::optional<Eigen::Vector2d> best_origin;
  std::array<double, 81> samples;
  for (int sv = -steps; sv <= steps; ++sv) {
    for (int su = -steps; su <= steps; ++su) {
      const Eigen::Vector2d origin = expected + 0.5 * Eigen::Vector2d(su, sv);
      double mean = 0.0;
      for (int v = -1; v <= 7; ++v) {
        for (int u = -1; u <= 7; ++u) {
          const Eigen::Vector2d p = to_image * (origin + Eigen::Vector2d(u + 0.5, v + 0.5)).homogeneous();
          // Dark is 1 in the pattern: the samples negated.
          const double x = -Bilinear(gray, p);
          samples[(v + 1) * 9 + (u + 1)] = x;
          mean += x;
        }
      }
      mean /= 81.0;
      double dot = 0.0, norm = 0.0;
      for (int k = 0; k < 81; ++k) {
        const double x = samples[k] - mean;
        dot += x * pattern[k];
        norm += x * x;
      }
      if (norm <= 0.0) continue;
      const double correlation = dot / std::sqrt(norm);
      if (correlation > best) best = correlation, best_origin = origin;
    }
  }
  return best_origin;
}

}  // namespace

std::vector<QrCandidate> QrCandidatesFromFinderPairs(const cv::Mat& gray,
                                                     const std::vector<QrFinderPattern>& finders,
                                                     const std::vector<QrCandidate>& triples,
                                                     double max_width_px) {
  if (gray.empty() || gray.type() != CV_8UC1) return {};
  // Version 1 and 2: the small codes whose third finder blurs away.
  constexpr int kPairModules[] = {21, 25};
  // Widths (square roots of areas) shrink by sqrt(cos t) under a tilt t, distances along the
  // tilt by cos t: at up to 60 deg the pair's distance in modules is within a factor sqrt(2).
  const double kForeshortening = std::sqrt(2.0);
  std::vector<int> unmatched;
  for (size_t i = 0; i < finders.size(); ++i) {
    if (finders[i].width_px > max_width_px) continue;
    const bool in_triple = std::any_of(triples.begin(), triples.end(), [&](const QrCandidate& c) {
      return InsideQuad(c.corners_px, finders[i].centre_px);
    });
    if (!in_triple) unmatched.push_back(static_cast<int>(i));
  }
  std::vector<QrCandidate> out;
  const auto seen = [&out](const QrCandidate& c) {
    return std::any_of(out.begin(), out.end(), [&c](const QrCandidate& o) {
      return (QuadCenter(o.corners_px) - QuadCenter(c.corners_px)).norm() < 0.25 * QuadMeanSide(o.corners_px);
    });
  };
  for (size_t i = 0; i < unmatched.size(); ++i) {
    for (size_t j = i + 1; j < unmatched.size(); ++j) {
      const QrFinderPattern& a = finders[unmatched[i]];
      const QrFinderPattern& b = finders[unmatched[j]];
      const double wa = a.width_px, wb = b.width_px;
      if (!(wa > 0.0) || !(wb > 0.0) || std::max(wa, wb) > kMaxPairWidthRatio * std::min(wa, wb)) continue;
      const double module_px = (wa + wb) / 14.0;
      const double d = (b.centre_px - a.centre_px).norm() / module_px;  // centres, in modules
      // Each layout: the finders' places and the third finder's (top-left module of each).
      struct Layout {
        PairLayout places;
        Eigen::Vector2d third;
      };
      std::vector<Layout> layouts;
      for (const int n : kPairModules) {
        const double spacing = n - 7;
        if (d >= spacing / kForeshortening && d <= spacing * kForeshortening) {
          // a, then b, as the corner finder, the other as the top-right or the bottom-left one.
          const Eigen::Vector2d corner(0, 0), right(spacing, 0), below(0, spacing);
          layouts.push_back({{corner, right}, below});
          layouts.push_back({{corner, below}, right});
          layouts.push_back({{right, corner}, below});
          layouts.push_back({{below, corner}, right});
        }
        const double diagonal = std::sqrt(2.0) * spacing;
        if (d >= diagonal / kForeshortening && d <= diagonal * kForeshortening) {
          // The diagonal's two ends, the corner finder on either side of it.
          layouts.push_back(
              {{Eigen::Vector2d(spacing, 0), Eigen::Vector2d(0, spacing)}, Eigen::Vector2d(0, 0)});
          layouts.push_back(
              {{Eigen::Vector2d(0, spacing), Eigen::Vector2d(spacing, 0)}, Eigen::Vector2d(0, 0)});
        }
      }
      for (const Layout& layout : layouts) {
        const std::optional<Eigen::Matrix<double, 2, 3>> to_image =
            PairLayoutAffine(a, b, layout.places, module_px);
        if (!to_image) continue;
        const std::optional<Eigen::Vector2d> origin = FindThirdFinder(gray, *to_image, layout.third);
        if (!origin) continue;
        // The third finder's outline: its 7 x 7 modules through the pair's map.
        QrFinderPattern c;
        const std::array<Eigen::Vector2d, 4> outline = FinderModuleOutline(*origin);
        for (int k = 0; k < 4; ++k) c.outer_px[k] = *to_image * outline[k].homogeneous();
        c.centre_px = *to_image * (*origin + Eigen::Vector2d(3.5, 3.5)).homogeneous();
        c.width_px = 7.0 * std::sqrt(std::abs(to_image->leftCols<2>().determinant()));
        for (const QrCandidate& candidate : GroupQrFinders({a, b, c}, gray.size())) {
          if (!seen(candidate)) out.push_back(candidate);
        }
      }
    }
  }
  return out;
}

std::vector<QrCandidate> QrCandidatesFromQuads(const cv::Mat& gray, const std::vector<DarkQuad>& quads) {
  const cv::Size image_size = gray.size();
  std::vector<QrFinderPattern> finders;
  for (const DarkQuad& q : quads) {
    if (q.l_completion) continue;  // a DataMatrix L's completion, not a hull
    int solid = 0;
    double weakest = 1.0;
    for (const double dark : q.side_dark) {
      solid += dark >= kQuadFinderSolid;
      weakest = std::min(weakest, dark);
    }
    if (solid < kQuadFinderSolidSides || weakest < kQuadFinderWeakestSide ||
        q.interior_spread < kQuadFinderMinSpread)
      continue;
    if (!HasFinderProfile(gray, q.corners_px)) continue;
    QrFinderPattern f;
    f.centre_px = QuadCenter(q.corners_px);
    f.width_px = std::sqrt(std::abs(SignedArea(q.corners_px)));
    f.outer_px = q.corners_px;
    // Quads come level by level, finest first: a finder already seen is not added again.
    const bool seen = std::any_of(finders.begin(), finders.end(), [&f](const QrFinderPattern& g) {
      return (g.centre_px - f.centre_px).norm() < kSameFinderFraction * std::min(g.width_px, f.width_px);
    });
    if (!seen && f.width_px > 0.0) finders.push_back(f);
  }
  std::vector<QrCandidate> candidates = GroupQrFinders(finders, image_size);
  // Small codes with one finder lost to blur: their pairs, after every triple.
  const std::vector<QrCandidate> completed =
      QrCandidatesFromFinderPairs(gray, finders, candidates, kMaxPairFinderWidthPx);
  candidates.insert(candidates.end(), completed.begin(), completed.end());
  return candidates;
}

namespace {

// True if `centre` is within 0.3 of the quad's mean side of its centre: the same code (found
// at two levels, or by two of the small-code tests).
bool NearQuad(const DarkQuad& quad, const Eigen::Vector2d& centre) {
  return (QuadCenter(quad.corners_px) - centre).norm() < 0.3 * QuadMeanSide(quad.corners_px);
}

// SmallQrCodeQuads with the least dark side in [min_side_dark, max_side_dark), none near a
// quad of `taken`.
std::vector<DarkQuad> SmallCodeQuadsWithSides(const std::vector<DarkQuad>& quads, double min_side_dark,
                                              double max_side_dark, const std::vector<DarkQuad>& taken,
                                              int max_quads) {
  std::vector<DarkQuad> out;
  for (const DarkQuad& q : quads) {
    if (static_cast<int>(out.size()) >= max_quads) break;
    if (q.l_completion) continue;  // a DataMatrix L's completion, not a hull
    const double side = QuadMeanSide(q.corners_px);
    if (q.scale > kSmallCodeMaxScale || side < kMinSmallCodeSidePx || side > kMaxSmallCodeSidePx) continue;
    const double lo = *std::min_element(q.side_dark.begin(), q.side_dark.end());
    if (lo < min_side_dark || lo > max_side_dark) continue;
    if (q.interior_spread < kSmallCodeMinSpread || q.interior_spread > kSmallCodeMaxSpread) continue;
    // The same code found at two levels counts once.
    const Eigen::Vector2d centre = QuadCenter(q.corners_px);
    const auto near = [&](const DarkQuad& o) { return NearQuad(o, centre); };
    if (std::none_of(out.begin(), out.end(), near) && std::none_of(taken.begin(), taken.end(), near))
      out.push_back(q);
  }
  return out;
}

}  // namespace

std::vector<DarkQuad> SmallQrCodeQuads(const std::vector<DarkQuad>& quads, int max_quads) {
  return SmallCodeQuadsWithSides(quads, kSmallCodeMinSideDark, kSmallCodeMaxSideDark, {}, max_quads);
}

std::vector<DarkQuad> ThinSideSmallQrCodeQuads(const std::vector<DarkQuad>& quads,
                                               const std::vector<DarkQuad>& taken, int max_quads) {
  // The upper bound is exclusive in effect: a quad at exactly kSmallCodeMinSideDark is
  // SmallQrCodeQuads' (and near one of `taken`).
  return SmallCodeQuadsWithSides(quads, kSmallCodeMinThinSideDark, kSmallCodeMinSideDark, taken, max_quads);
}

namespace {

// Four corners of a convex hull, clockwise on screen: the four of its vertices that span the
// largest quadrilateral (every choice tried: a hull of a small code has a few dozen vertices
// at most, and more are thinned to every k-th first); nullopt for fewer than four.
std::optional<Quad2d> FourCornersOfHull(const std::vector<cv::Point>& hull) {
  constexpr size_t kMaxVertices = 24;
  if (hull.size() < 4) return std::nullopt;
  std::vector<Eigen::Vector2d> p;
  const size_t stride = (hull.size() + kMaxVertices - 1) / kMaxVertices;
  for (size_t i = 0; i < hull.size(); i += stride) p.emplace_back(hull[i].x, hull[i].y);
  if (p.size() < 4) return std::nullopt;
  const auto cross = [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return a.x() * b.y() - a.y() * b.x();
  };
  double best = -1.0;
  std::array<size_t, 4> pick{};
  for (size_t a = 0; a < p.size(); ++a) {
    for (size_t b = a + 1; b < p.size(); ++b) {
      for (size_t c = b + 1; c < p.size(); ++c) {
        for (size_t d = c + 1; d < p.size(); ++d) {
          // In hull order the quad is convex: twice its area is the cross of its diagonals.
          const double area = std::abs(cross(p[c] - p[a], p[d] - p[b]));
          if (area > best) {
            best = area;
            pick = {a, b, c, d};
          }
        }
      }
    }
  }
  Quad2d quad = {p[pick[0]], p[pick[1]], p[pick[2]], p[pick[3]]};
  if (cross(quad[1] - quad[0], quad[2] - quad[1]) < 0) std::swap(quad[1], quad[3]);
  return quad;
}

}  // namespace

std::vector<DarkQuad> MergedFragmentQrCodeQuads(const std::vector<DarkQuad>& quads,
                                                const std::vector<DarkQuad>& taken, int max_quads) {
  std::vector<DarkQuad> out;
  if (max_quads <= 0) return out;
  // Fragments, by level.
  std::vector<size_t> fragments;
  for (size_t i = 0; i < quads.size(); ++i) {
    const double side = QuadMeanSide(quads[i].corners_px);
    if (!quads[i].l_completion && side >= kMinFragmentSidePx && side <= kMaxFragmentSidePx)
      fragments.push_back(i);
  }
  // Union-find over the fragments of one level (a fixed function of the order found).
  std::vector<size_t> parent(fragments.size());
  for (size_t k = 0; k < parent.size(); ++k) parent[k] = k;
  const auto root = [&parent](size_t k) {
    while (parent[k] != k) k = parent[k] = parent[parent[k]];
    return k;
  };
  for (size_t a = 0; a < fragments.size(); ++a) {
    const DarkQuad& qa = quads[fragments[a]];
    for (size_t b = a + 1; b < fragments.size(); ++b) {
      const DarkQuad& qb = quads[fragments[b]];
      if (qa.scale != qb.scale) continue;
      const double reach =
          kFragmentJoinFraction * (QuadMeanSide(qa.corners_px) + QuadMeanSide(qb.corners_px));
      if ((QuadCenter(qa.corners_px) - QuadCenter(qb.corners_px)).squaredNorm() < reach * reach) {
        const size_t ra = root(a), rb = root(b);
        if (ra != rb) parent[std::max(ra, rb)] = std::min(ra, rb);
      }
    }
  }
  for (size_t g = 0; g < fragments.size() && static_cast<int>(out.size()) < max_quads; ++g) {
    if (root(g) != g) continue;  // each group once, at its first fragment
    std::vector<cv::Point> points;
    int members = 0;
    for (size_t k = g; k < fragments.size(); ++k) {
      if (root(k) != g) continue;
      ++members;
      for (const Eigen::Vector2d& c : quads[fragments[k]].corners_px)
        points.emplace_back(static_cast<int>(std::lround(c.x())), static_cast<int>(std::lround(c.y())));
    }
    if (members < 2) continue;
    std::vector<cv::Point> hull;
    cv::convexHull(points, hull);
    const std::optional<Quad2d> quad = FourCornersOfHull(hull);
    if (!quad) continue;
    const double side = QuadMeanSide(*quad);
    if (side < kMinSmallCodeSidePx || side > kMaxFragmentCodeSidePx) continue;
    const Eigen::Vector2d centre = QuadCenter(*quad);
    const auto near_centre = [&](const DarkQuad& o) { return NearQuad(o, centre); };
    if (std::any_of(taken.begin(), taken.end(), near_centre) ||
        std::any_of(out.begin(), out.end(), near_centre))
      continue;
    DarkQuad merged;
    merged.corners_px = *quad;
    merged.scale = quads[fragments[g]].scale;
    out.push_back(merged);
  }
  return out;
}

double RectifiedQrFinderContrast(const cv::Mat& gray, const QrCandidate& candidate) {
  const std::optional<RectifiedPlacement> p = PlaceRectified(gray, candidate);
  if (!p) return -std::numeric_limits<double>::infinity();
  return FinderContrastOnPatches(gray, cv::Matx33d(p->H_rect_image), p->quiet, p->side);
}

std::vector<MarkerObservation> ReadRectifiedQr(const cv::Mat& gray, const QrCandidate& candidate) {
  const std::optional<RectifiedPlacement> placed = PlaceRectified(gray, candidate);
  if (!placed) return {};
  const Quad2d& quad = placed->quad;
  const double modules = placed->modules, side = placed->side;
  const int canvas = placed->canvas;
  const cv::Mat& H_rect_image = placed->H_rect_image;
  // A candidate whose rectified finders are no finders (clutter, or corners a few modules
  // off) is not read: nearly every failed read (zxing three times, the module grid).
  if (FinderContrastOnPatches(gray, cv::Matx33d(H_rect_image), placed->quiet, side) <=
      kMinRectifiedFinderContrast) {
    return {};
  }
  cv::Mat rectified;
  cv::warpPerspective(gray, rectified, H_rect_image, cv::Size(canvas, canvas), cv::INTER_CUBIC,
                      cv::BORDER_REPLICATE);
  std::vector<MarkerObservation> read = ReadUpright(rectified);
  if (read.empty() && QuadMeanSide(quad) / modules < kMaxGridReaderModulePx) {
    // Small modules under blur: read the module grid itself (detect/qr_modules.h).
    const int n = 17 + 4 * static_cast<int>(std::lround((modules - 17.0) / 4.0));
    if (n <= kMaxGridModules) return ReadQrModuleGrid(gray, quad, n);
  }
  const Eigen::Vector2d middle(0.5 * (canvas - 1), 0.5 * (canvas - 1));
  const auto nearest = std::min_element(read.begin(), read.end(), [&](const auto& x, const auto& y) {
    return (QuadCenter(x.corners_px) - middle).norm() < (QuadCenter(y.corners_px) - middle).norm();
  });
  if (nearest == read.end() || (QuadCenter(nearest->corners_px) - middle).norm() > 0.25 * side) return {};
  MarkerObservation obs = *nearest;
  cv::Mat H_image_rect = H_rect_image.inv();
  for (Eigen::Vector2d& c : obs.corners_px) {
    const cv::Vec3d p = cv::Matx33d(H_image_rect) * cv::Vec3d(c.x(), c.y(), 1.0);
    c = Eigen::Vector2d(p[0] / p[2], p[1] / p[2]);
  }
  return {obs};
}

}  // namespace waymark
