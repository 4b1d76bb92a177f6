#include "detect/refine.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

namespace waymark {
namespace {

constexpr double kStepPx = 0.25;       // profile sampling step along the normal
constexpr double kInlierBandPx = 0.6;  // RANSAC inlier distance
constexpr int kRansacIterations = 64;
constexpr double kCentroidLevel = 0.5;   // centroid of the derivative above this fraction of its peak
constexpr double kHalfBaselinePx = 0.5;  // the derivative is a central difference over 1 px
constexpr double kBarLobe = 0.15;        // an inner edge at least this fraction of the outer one makes a bar
constexpr double kMaxBarPx = 3.5;
// The edge-strength minimum of a dim code: this fraction of its border contrast, not under
// kMinAdaptiveStep gray levels per px (RefineQuadCorners).
constexpr double kAdaptiveStepFraction = 0.25;
constexpr double kMinAdaptiveStep = 4.0;  // wider bars leave the outer edge's centroid unbiased

// True if Bilinear reads (x, y) inside the image.
inline bool InsideForBilinear(const cv::Mat& gray, double x, double y) {
  return x >= 0.0 && y >= 0.0 && x <= gray.cols - 1.0 && y <= gray.rows - 1.0 && gray.cols >= 2 &&
         gray.rows >= 2;
}

// The four pixels a bilinear sample at (x, y) reads and its offsets from the first, where
// InsideForBilinear holds.
struct BilinearCell {
  uint8_t p00, p01, p10, p11;  // (x0, y0), (x0 + 1, y0), (x0, y0 + 1), (x0 + 1, y0 + 1)
  double fx, fy;
  double Value() const { return (1 - fy) * ((1 - fx) * p00 + fx * p01) + fy * ((1 - fx) * p10 + fx * p11); }
};
inline BilinearCell CellAt(const cv::Mat& gray, double x, double y) {
  const int x0 = std::min(static_cast<int>(x), gray.cols - 2);
  const int y0 = std::min(static_cast<int>(y), gray.rows - 2);
  const uint8_t* r0 = gray.ptr<uint8_t>(y0);
  const uint8_t* r1 = gray.ptr<uint8_t>(y0 + 1);
  return {r0[x0], r0[x0 + 1], r1[x0], r1[x0 + 1], x - x0, y - y0};
}

// Bilinear at (x, y) where InsideForBilinear holds.
inline double BilinearInside(const cv::Mat& gray, double x, double y) { return CellAt(gray, x, y).Value(); }

// Bilinear intensity at (x, y); NaN outside the image.
double Bilinear(const cv::Mat& gray, double x, double y) {
  return InsideForBilinear(gray, x, y) ? BilinearInside(gray, x, y)
                                       : std::numeric_limits<double>::quiet_NaN();
}

// The edge points whose step is at least kFullContrast times the typical step of the
// side's line (80th percentile over its inliers). On a dashed side (DataMatrix timing pattern, QR data
// modules) the profiles near the end of a dark module see a weaker step, displaced along the normal when the
// module's end is slanted (perspective); mid-module profiles see the whole step.
constexpr double kFullContrast = 0.75;
std::vector<Eigen::Vector2d> KeepFullContrast(const std::vector<Eigen::Vector2d>& points,
                                              const std::vector<double>& strengths) {
  if (points.empty()) return points;
  std::vector<double> sorted = strengths;
  const size_t rank = static_cast<size_t>(0.8 * (sorted.size() - 1));
  std::nth_element(sorted.begin(), sorted.begin() + rank, sorted.end());
  const double typical = sorted[rank];
  std::vector<Eigen::Vector2d> kept;
  for (size_t i = 0; i < points.size(); ++i) {
    if (strengths[i] >= kFullContrast * typical) kept.push_back(points[i]);
  }
  return kept;
}

double Distance(const Line2d& line, const Eigen::Vector2d& q) {
  const Eigen::Vector2d d = q - line.point;
  return std::abs(d.x() * line.direction.y() - d.y() * line.direction.x());
}

// Total least squares line through `points`.
Line2d FitTls(const std::vector<Eigen::Vector2d>& points) {
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const auto& q : points) mean += q;
  mean /= static_cast<double>(points.size());
  Eigen::Matrix2d scatter = Eigen::Matrix2d::Zero();
  for (const auto& q : points) scatter += (q - mean) * (q - mean).transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> solver(scatter);
  return {mean, solver.eigenvectors().col(1).normalized(), 0.0};
}

// RANSAC (deterministic sample pairs), then TLS on the inliers with a full-contrast step
// (KeepFullContrast). `samples` is the number of profiles taken, including those without
// an edge; the inlier fraction counts every RANSAC inlier.
std::optional<Line2d> FitEdgeLine(const std::vector<Eigen::Vector2d>& points,
                                  const std::vector<double>& strengths, int samples) {
  if (points.size() < 4) return std::nullopt;
  uint32_t state = 12345u;  // fixed seed: the result does not depend on anything else
  auto next = [&state](size_t n) {
    state = state * 1664525u + 1013904223u;
    return static_cast<size_t>((state >> 8) % n);
  };
  Line2d best;
  size_t best_count = 0;
  for (int it = 0; it < kRansacIterations; ++it) {
    const size_t i = next(points.size());
    const size_t j = next(points.size());
    if (i == j || (points[i] - points[j]).norm() < 1.0) continue;
    const Line2d line{points[i], (points[j] - points[i]).normalized(), 0.0};
    size_t count = 0;
    for (const auto& q : points) count += Distance(line, q) < kInlierBandPx;
    if (count > best_count) best_count = count, best = line;
  }
  if (best_count < 4) return std::nullopt;
  std::vector<Eigen::Vector2d> inliers;
  std::vector<double> inlier_strengths;
  inliers.reserve(best_count), inlier_strengths.reserve(best_count);
  for (size_t i = 0; i < points.size(); ++i) {
    if (Distance(best, points[i]) < kInlierBandPx)
      inliers.push_back(points[i]), inlier_strengths.push_back(strengths[i]);
  }
  const std::vector<Eigen::Vector2d> full = KeepFullContrast(inliers, inlier_strengths);
  Line2d fitted = FitTls(full.size() >= 4 ? full : inliers);
  fitted.inlier_fraction = static_cast<double>(inliers.size()) / samples;
  return fitted;
}

// Edge points of the side a -> b between fractions t0 and t1 of its length, `samples` profiles.
void SideEdgePoints(const cv::Mat& gray, const Eigen::Vector2d& a, const Eigen::Vector2d& b, double t0,
                    double t1, int samples, double half_window, double min_step, bool fit_model,
                    std::vector<Eigen::Vector2d>* points, std::vector<double>* strengths) {
  const Eigen::Vector2d along = (b - a).normalized();
  const Eigen::Vector2d outward(along.y(), -along.x());  // clockwise quad, y down
  points->reserve(points->size() + samples), strengths->reserve(strengths->size() + samples);
  for (int k = 0; k < samples; ++k) {
    const Eigen::Vector2d p = a + (t0 + (t1 - t0) * k / (samples - 1.0)) * (b - a);
    if (const std::optional<EdgeHit> hit = FindOuterEdge(gray, p, outward, half_window, min_step)) {
      const std::optional<double> fitted =
          fit_model ? FitEdgeModel(gray, p, outward, hit->offset_px) : std::optional<double>();
      points->push_back(p + fitted.value_or(hit->offset_px) * outward), strengths->push_back(hit->strength);
    }
  }
}

// One round: edge points along each side within +-half_window, lines, intersections.
std::optional<RefinedQuad> RefineOnce(const cv::Mat& gray, const Quad2d& corners, double half_window,
                                      bool fit_model, const RefineOptions& options) {
  std::array<Line2d, 4> lines;
  double worst = 1.0;
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector2d a = corners[i];
    const Eigen::Vector2d b = corners[(i + 1) % 4];
    const int samples = std::clamp(static_cast<int>((b - a).norm() / 1.5), 8, 96);
    std::vector<Eigen::Vector2d> points;
    std::vector<double> strengths;
    SideEdgePoints(gray, a, b, 0.1, 0.9, samples, half_window, options.min_step, fit_model, &points,
                   &strengths);
    const std::optional<Line2d> line = FitEdgeLine(points, strengths, samples);
    if (!line || line->inlier_fraction < options.min_inlier_fraction) return std::nullopt;
    lines[i] = *line;
    worst = std::min(worst, line->inlier_fraction);
  }
  RefinedQuad out;
  out.inlier_fraction = worst;
  for (int i = 0; i < 4; ++i) {
    // Corner i joins side i-1 (ending at i) and side i (starting at i).
    const std::optional<Eigen::Vector2d> c = IntersectLines(lines[(i + 3) % 4], lines[i]);
    if (!c || (*c - corners[i]).norm() > options.max_shift_px) return std::nullopt;
    out.corners_px[i] = *c;
  }
  return out;
}

// The bilinear intensity at (x, y) as Bilinear gives it, and whether a pixel it reads is
// saturated (>= kClippedLevel), from one read of the four pixels; NaN (and false) outside
// the image.
constexpr int kClippedLevel = 254;
double BilinearClipped(const cv::Mat& gray, double x, double y, bool* clipped) {
  *clipped = false;
  if (!InsideForBilinear(gray, x, y)) return std::numeric_limits<double>::quiet_NaN();
  const BilinearCell cell = CellAt(gray, x, y);
  *clipped = std::max({cell.p00, cell.p01, cell.p10, cell.p11}) >= kClippedLevel;
  return cell.Value();
}

// Blurred dark bar model of a profile along the outward normal (see the header):
//   I(s) = L - A [Phi((e - s) / sigma) - Phi((e - w - s) / sigma)]
// parameters x = [e, sigma, L, A, w] (w dropped when `fit_width` is false).
struct BarModel {
  double e, sigma, light, amplitude, width;
};

double NormalCdf(double u) { return 0.5 * std::erfc(-u / std::sqrt(2.0)); }
double NormalPdf(double u) { return std::exp(-0.5 * u * u) / std::sqrt(2.0 * M_PI); }

// FitEdgeModel's profile: kInnerPx inside to kOuterPx outside of the first estimate, every
// kStepPx (27 samples; the buffers hold a few more).
constexpr double kInnerPx = 4.0, kOuterPx = 2.5;
constexpr int kMaxProfile = static_cast<int>((kInnerPx + kOuterPx) / kStepPx) + 6;

// The model's standardized distances to its two edges and their normal CDFs at every sample.
struct BarValues {
  std::array<double, kMaxProfile> u1, u2, cdf1, cdf2;
};

// Levenberg-Marquardt on the `count` samples (s_k, I_k); returns false if it did not converge
// to a plausible model (sigma in [0.2, 4] px, positive amplitude, e within the samples).
bool FitBarModel(const double* s, const double* intensity, int count, bool fit_width, BarModel* m) {
  const int n = fit_width ? 5 : 4;
  double lambda = 1e-3;
  // The values of the current model's cost are kept for its Jacobian (the same values: erfc
  // was most of the fit's time when each was computed three times).
  BarValues values[2];
  BarValues* current_values = &values[0];
  BarValues* next_values = &values[1];
  auto cost = [&](const BarModel& b, BarValues* v) {
    double c = 0.0;
    for (int k = 0; k < count; ++k) {
      v->u1[k] = (b.e - s[k]) / b.sigma;
      v->u2[k] = (b.e - b.width - s[k]) / b.sigma;
      v->cdf1[k] = NormalCdf(v->u1[k]);
      v->cdf2[k] = NormalCdf(v->u2[k]);
      const double r = b.light - b.amplitude * (v->cdf1[k] - v->cdf2[k]) - intensity[k];
      c += r * r;
    }
    return c;
  };
  double current = cost(*m, current_values);
  // J^T J and J^T r of the current model: kept over rejected steps (the model is unchanged).
  // Only the lower triangle is summed (j_a j_b = j_b j_a exactly), then mirrored.
  Eigen::Matrix<double, 5, 5> jtj;
  Eigen::Matrix<double, 5, 1> jtr;
  bool normal_current = false;
  for (int it = 0; it < 20; ++it) {
    if (!normal_current) {
      jtj.setZero();
      jtr.setZero();
      const BarValues& v = *current_values;
      for (int k = 0; k < count; ++k) {
        const double u1 = v.u1[k], u2 = v.u2[k];
        const double p1 = NormalPdf(u1), p2 = NormalPdf(u2);
        const double r = m->light - m->amplitude * (v.cdf1[k] - v.cdf2[k]) - intensity[k];
        const double j[5] = {-m->amplitude * (p1 - p2) / m->sigma,
                             m->amplitude * (p1 * u1 - p2 * u2) / m->sigma, 1.0, -(v.cdf1[k] - v.cdf2[k]),
                             fit_width ? -m->amplitude * p2 / m->sigma : 0.0};
        for (int a = 0; a < 5; ++a) {
          for (int b = 0; b <= a; ++b) jtj(a, b) += j[a] * j[b];
          jtr[a] += j[a] * r;
        }
      }
      for (int a = 0; a < 5; ++a) {
        for (int b = 0; b < a; ++b) jtj(b, a) = jtj(a, b);
      }
      if (!fit_width) jtj(4, 4) = 1.0;
      normal_current = true;
    }
    Eigen::Matrix<double, 5, 5> damped = jtj;
    for (int i = 0; i < n; ++i) damped(i, i) *= 1.0 + lambda;
    const Eigen::Matrix<double, 5, 1> dx = -damped.ldlt().solve(jtr);
    BarModel next{m->e + dx[0], m->sigma + dx[1], m->light + dx[2], m->amplitude + dx[3], m->width + dx[4]};
    const double next_cost =
        next.sigma > 0.1 ? cost(next, next_values) : std::numeric_limits<double>::infinity();
    if (next_cost < current) {
      *m = next, current = next_cost, lambda *= 0.3;
      std::swap(current_values, next_values);
      normal_current = false;
      if (std::abs(dx[0]) < 1e-4) break;
    } else {
      lambda *= 10.0;
      if (lambda > 1e6) break;
    }
  }
  return m->sigma >= 0.2 && m->sigma <= 4.0 && m->amplitude > 0.0 && m->e >= s[0] && m->e <= s[count - 1];
}

}  // namespace

std::optional<double> FitEdgeModel(const cv::Mat& gray, const Eigen::Vector2d& p, const Eigen::Vector2d& n,
                                   double offset_px) {
  // Samples from kInnerPx inside to kOuterPx outside of the first estimate.
  std::array<double, kMaxProfile> s_all, profile;
  std::array<bool, kMaxProfile> clipped;
  bool any_clipped = false;
  int size = 0;
  for (double t = offset_px - kInnerPx; t <= offset_px + kOuterPx + 1e-9 && size < kMaxProfile;
       t += kStepPx) {
    const Eigen::Vector2d q = p + t * n;
    const double value = BilinearClipped(gray, q.x(), q.y(), &clipped[size]);
    if (std::isnan(value)) return std::nullopt;
    any_clipped = any_clipped || clipped[size];
    s_all[size] = t, profile[size] = value, ++size;
  }
  // The bar's inner edge: the most negative derivative (1 px baseline) inside the estimate.
  const int h = static_cast<int>(std::round(kHalfBaselinePx / kStepPx));
  const int at = static_cast<int>(std::round(kInnerPx / kStepPx));
  double peak = 0.0, trough = 0.0;
  int trough_k = -1;
  for (int k = h; k + h < size; ++k) {
    const double d = profile[k + h] - profile[k - h];
    if (std::abs(k - at) <= 2 * h) peak = std::max(peak, d);
    if (k < at - h && d < trough) trough = d, trough_k = k;
  }
  if (peak <= 0.0) return std::nullopt;
  const bool bar = trough_k >= 0 && trough < -kBarLobe * peak;
  // Only a thin bar biases the first estimate; a clipped profile leaves L undetermined.
  if (!bar || s_all[at] - s_all[trough_k] > kMaxBarPx) return offset_px;
  if (any_clipped) return offset_px;
  BarModel m{offset_px, 0.8, 0.0, 0.0, bar ? s_all[at] - s_all[trough_k] : 1e3};
  // Samples used: unclipped, and inside at most half a pixel past the inner edge.
  std::array<double, kMaxProfile> s, intensity;
  int used = 0;
  double dark = 255.0;
  for (int k = 0; k < size; ++k) {
    if (clipped[k] || (bar && s_all[k] < offset_px - m.width - 0.75)) continue;
    s[used] = s_all[k], intensity[used] = profile[k], ++used;
    if (s_all[k] < offset_px) dark = std::min(dark, profile[k]);
    if (s_all[k] > offset_px) m.light = std::max(m.light, profile[k]);
  }
  if (used < 10 || m.light <= dark) return std::nullopt;
  m.amplitude = m.light - dark;
  if (!FitBarModel(s.data(), intensity.data(), used, bar, &m)) return std::nullopt;
  if (std::abs(m.e - offset_px) > 0.75) return std::nullopt;
  return m.e;
}

std::optional<Eigen::Vector2d> IntersectLines(const Line2d& a, const Line2d& b) {
  const double det = a.direction.x() * b.direction.y() - a.direction.y() * b.direction.x();
  if (std::abs(det) < 0.1) return std::nullopt;  // sides closer than ~6 degrees to parallel
  const Eigen::Vector2d d = b.point - a.point;
  const double t = (d.x() * b.direction.y() - d.y() * b.direction.x()) / det;
  return a.point + t * a.direction;
}

std::optional<Line2d> FitSideSegment(const cv::Mat& gray, const Eigen::Vector2d& from_px,
                                     const Eigen::Vector2d& to_px, double t0, double t1,
                                     double half_window_px, double min_step) {
  if (gray.empty() || gray.type() != CV_8UC1 || !(t1 > t0)) return std::nullopt;
  const int samples = std::clamp(static_cast<int>((t1 - t0) * (to_px - from_px).norm() / 0.5), 8, 96);
  std::vector<Eigen::Vector2d> points;
  std::vector<double> strengths;
  SideEdgePoints(gray, from_px, to_px, t0, t1, samples, half_window_px, min_step, false, &points, &strengths);
  return FitEdgeLine(points, strengths, samples);
}

std::optional<Line2d> FitEdgeThrough(const cv::Mat& gray, const std::vector<Eigen::Vector2d>& points_px,
                                     const Eigen::Vector2d& outward, double half_window_px, double min_step,
                                     bool fit_model) {
  if (gray.empty() || gray.type() != CV_8UC1) return std::nullopt;
  std::vector<Eigen::Vector2d> points;
  std::vector<double> strengths;
  for (const Eigen::Vector2d& p : points_px) {
    const std::optional<EdgeHit> hit = FindOuterEdge(gray, p, outward, half_window_px, min_step);
    if (!hit) continue;
    const std::optional<double> fitted =
        fit_model ? FitEdgeModel(gray, p, outward, hit->offset_px) : std::optional<double>();
    points.push_back(p + fitted.value_or(hit->offset_px) * outward), strengths.push_back(hit->strength);
  }
  return FitEdgeLine(points, strengths, static_cast<int>(points_px.size()));
}

EdgeLinePair FitEdgeThroughBoth(const cv::Mat& gray, const std::vector<Eigen::Vector2d>& points_px,
                                const Eigen::Vector2d& outward, double half_window_px, double min_step) {
  if (gray.empty() || gray.type() != CV_8UC1) return {};
  std::vector<Eigen::Vector2d> modelled, centroid;
  std::vector<double> strengths;
  modelled.reserve(points_px.size()), centroid.reserve(points_px.size()), strengths.reserve(points_px.size());
  for (const Eigen::Vector2d& p : points_px) {
    const std::optional<EdgeHit> hit = FindOuterEdge(gray, p, outward, half_window_px, min_step);
    if (!hit) continue;
    const std::optional<double> fitted = FitEdgeModel(gray, p, outward, hit->offset_px);
    modelled.push_back(p + fitted.value_or(hit->offset_px) * outward);
    centroid.push_back(p + hit->offset_px * outward);
    strengths.push_back(hit->strength);
  }
  const int samples = static_cast<int>(points_px.size());
  return {FitEdgeLine(modelled, strengths, samples), FitEdgeLine(centroid, strengths, samples)};
}

std::optional<EdgeHit> FindOuterEdge(const cv::Mat& gray, const Eigen::Vector2d& p, const Eigen::Vector2d& n,
                                     double half_window, double min_step) {
  const int count = static_cast<int>(std::round(2.0 * (half_window + 0.5) / kStepPx)) + 1;
  if (count < 1) return std::nullopt;
  // The profile and its derivative: on the stack for windows up to kInlineProfile samples (every
  // second-round window and most first ones), else on the heap.
  constexpr int kInlineProfile = 64;
  std::array<double, 2 * kInlineProfile> inline_buffer;
  std::vector<double> heap_buffer;
  double* profile = inline_buffer.data();
  if (count > kInlineProfile)
    heap_buffer.resize(2 * static_cast<size_t>(count)), profile = heap_buffer.data();
  double* step = profile + count;
  // The sample points run monotonically along x and y (each coordinate p + t n rounds
  // monotonically in t): with both ends inside the image, all are, and no sample is tested.
  const Eigen::Vector2d first = p + (-half_window - 0.5 + 0 * kStepPx) * n;
  const Eigen::Vector2d last = p + (-half_window - 0.5 + (count - 1) * kStepPx) * n;
  if (InsideForBilinear(gray, first.x(), first.y()) && InsideForBilinear(gray, last.x(), last.y())) {
    for (int k = 0; k < count; ++k) {
      const Eigen::Vector2d q = p + (-half_window - 0.5 + k * kStepPx) * n;
      profile[k] = BilinearInside(gray, q.x(), q.y());
    }
  } else {
    for (int k = 0; k < count; ++k) {
      const Eigen::Vector2d q = p + (-half_window - 0.5 + k * kStepPx) * n;
      profile[k] = Bilinear(gray, q.x(), q.y());
      if (std::isnan(profile[k])) return std::nullopt;
    }
  }
  const int h = static_cast<int>(std::round(kHalfBaselinePx / kStepPx));
  std::fill(step, step + count, 0.0);
  double strongest = 0.0;
  for (int k = h; k + h < count; ++k) {
    step[k] = profile[k + h] - profile[k - h];
    strongest = std::max(strongest, step[k]);
  }
  if (strongest < min_step) return std::nullopt;
  for (int k = count - h - 2; k > h; --k) {  // outermost first
    if (step[k] < 0.5 * strongest || step[k] < step[k - 1] || step[k] < step[k + 1]) continue;
    // Centroid of the derivative above half its peak around k: unbiased for a symmetric
    // blur, and well defined on the plateau a sharp step makes under bilinear sampling.
    const double half = kCentroidLevel * step[k];
    double weight_sum = 0.0;
    double moment = 0.0;
    for (int j = k; j >= h && step[j] > half; --j)
      weight_sum += step[j] - half, moment += (step[j] - half) * j;
    for (int j = k + 1; j + h < count && step[j] > half; ++j)
      weight_sum += step[j] - half, moment += (step[j] - half) * j;
    if (weight_sum <= 0.0) continue;
    return EdgeHit{-half_window - 0.5 + (moment / weight_sum) * kStepPx, step[k]};
  }
  return std::nullopt;
}

namespace {

// The code's contrast at its border: the median gray level just outside its sides (2 px
// out: the quiet zone) minus the lower quartile just inside them (1.5 px in: the dark
// border, or a dashed side's dark modules). NaN when too few samples fall in the image.
double BorderContrast(const cv::Mat& gray, const Quad2d& q) {
  std::vector<double> inside, outside;
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector2d a = q[i], b = q[(i + 1) % 4];
    const Eigen::Vector2d along = (b - a).normalized();
    const Eigen::Vector2d outward(along.y(), -along.x());  // clockwise quad, y down
    for (int k = 1; k < 10; ++k) {
      const Eigen::Vector2d p = a + 0.1 * k * (b - a);
      const double in = Bilinear(gray, p.x() - 1.5 * outward.x(), p.y() - 1.5 * outward.y());
      const double out = Bilinear(gray, p.x() + 2.0 * outward.x(), p.y() + 2.0 * outward.y());
      if (!std::isnan(in)) inside.push_back(in);
      if (!std::isnan(out)) outside.push_back(out);
    }
  }
  if (inside.size() < 12 || outside.size() < 12) return std::numeric_limits<double>::quiet_NaN();
  std::nth_element(inside.begin(), inside.begin() + inside.size() / 4, inside.end());
  std::nth_element(outside.begin(), outside.begin() + outside.size() / 2, outside.end());
  return outside[outside.size() / 2] - inside[inside.size() / 4];
}

}  // namespace

std::optional<RefinedQuad> RefineQuadCorners(const cv::Mat& gray, const Quad2d& corners_px,
                                             const RefineOptions& options_in) {
  if (gray.empty() || gray.type() != CV_8UC1) return std::nullopt;
  // A dim code (low light: a contrast of 30-60 gray levels) has edges whose step over 1 px
  // is under the usual minimum: the minimum scales down with the border's contrast.
  RefineOptions options = options_in;
  const double contrast = BorderContrast(gray, corners_px);
  if (std::isfinite(contrast)) {
    options.min_step =
        std::min(options.min_step, std::max(kMinAdaptiveStep, kAdaptiveStepFraction * contrast));
  }
  // The first window scales with the symbol (decoders can be off by most of a module on
  // rotated symbols) and stays well inside it: a sixth of the shortest side at most.
  double shortest = std::numeric_limits<double>::infinity();
  for (int i = 0; i < 4; ++i) shortest = std::min(shortest, (corners_px[(i + 1) % 4] - corners_px[i]).norm());
  const double window =
      std::min(std::max(options.search_px, options.search_fraction * shortest), shortest / 6.0);
  if (!(window >= 0.75)) return std::nullopt;
  RefineOptions round = options;
  round.max_shift_px = std::max(options.max_shift_px, 1.5 * window);
  const std::optional<RefinedQuad> first = RefineOnce(gray, corners_px, window, false, round);
  if (!first) return std::nullopt;
  std::optional<RefinedQuad> second =
      RefineOnce(gray, first->corners_px, std::min(window, 1.25), options.fit_edge_model, round);
  if (!second) return first;
  for (int i = 0; i < 4; ++i) {
    if ((second->corners_px[i] - corners_px[i]).norm() > round.max_shift_px) return first;
  }
  return second;
}

}  // namespace waymark
