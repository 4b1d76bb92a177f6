#include "core/detect_refine.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include <Eigen/Eigenvalues>

namespace waymark {
namespace {

constexpr double kStepPx = 0.25;      // profile sampling step along the normal
constexpr double kInlierBandPx = 0.6;  // RANSAC inlier distance
constexpr int kRansacIterations = 64;
constexpr double kCentroidLevel = 0.5;  // centroid of the derivative above this fraction of its peak
constexpr double kHalfBaselinePx = 0.5;  // the derivative is a central difference over 1 px

// Bilinear intensity at (x, y); NaN outside the image.
double Bilinear(const cv::Mat& gray, double x, double y) {
  if (!(x >= 0.0 && y >= 0.0 && x <= gray.cols - 1.0 && y <= gray.rows - 1.0) || gray.cols < 2 || gray.rows < 2) {
    return std::numeric_limits<double>::quiet_NaN();
  }
  const int x0 = std::min(static_cast<int>(x), gray.cols - 2);
  const int y0 = std::min(static_cast<int>(y), gray.rows - 2);
  const int x1 = x0 + 1;
  const int y1 = y0 + 1;
  const double fx = x - x0;
  const double fy = y - y0;
  const uint8_t* r0 = gray.ptr<uint8_t>(y0);
  const uint8_t* r1 = gray.ptr<uint8_t>(y1);
  return (1 - fy) * ((1 - fx) * r0[x0] + fx * r0[x1]) + fy * ((1 - fx) * r1[x0] + fx * r1[x1]);
}

// Offset s along the outward normal `n` of the outermost strong light-outside edge near
// `p`, or NaN. The derivative is a central difference over 1 px.
// *strength receives the step's peak derivative (gray levels per px).
double EdgeOffset(const cv::Mat& gray, const Eigen::Vector2d& p, const Eigen::Vector2d& n, double half_window,
                  double min_step, double* strength) {
  const int count = static_cast<int>(std::round(2.0 * (half_window + 0.5) / kStepPx)) + 1;
  std::vector<double> profile(count);
  for (int k = 0; k < count; ++k) {
    const Eigen::Vector2d q = p + (-half_window - 0.5 + k * kStepPx) * n;
    profile[k] = Bilinear(gray, q.x(), q.y());
    if (std::isnan(profile[k])) return std::numeric_limits<double>::quiet_NaN();
  }
  const int h = static_cast<int>(std::round(kHalfBaselinePx / kStepPx));
  std::vector<double> step(count, 0.0);
  double strongest = 0.0;
  for (int k = h; k + h < count; ++k) {
    step[k] = profile[k + h] - profile[k - h];
    strongest = std::max(strongest, step[k]);
  }
  if (strongest < min_step) return std::numeric_limits<double>::quiet_NaN();
  for (int k = count - h - 2; k > h; --k) {  // outermost first
    if (step[k] < 0.5 * strongest || step[k] < step[k - 1] || step[k] < step[k + 1]) continue;
    // Centroid of the derivative above half its peak around k: unbiased for a symmetric
    // blur, and well defined on the plateau a sharp step makes under bilinear sampling.
    const double half = kCentroidLevel * step[k];
    double weight_sum = 0.0;
    double moment = 0.0;
    for (int j = k; j >= h && step[j] > half; --j) weight_sum += step[j] - half, moment += (step[j] - half) * j;
    for (int j = k + 1; j + h < count && step[j] > half; ++j) weight_sum += step[j] - half, moment += (step[j] - half) * j;
    if (weight_sum <= 0.0) continue;
    *strength = step[k];
    return -half_window - 0.5 + (moment / weight_sum) * kStepPx;
  }
  return std::numeric_limits<double>::quiet_NaN();
}

// The edge points whose step is at least kFullContrast times the typical step of the
// side's line (80th percentile over its inliers). On a dashed side (DataMatrix timing pattern, QR data modules) the
// profiles near the end of a dark module see a weaker step, displaced along the normal when
// the module's end is slanted (perspective); mid-module profiles see the whole step.
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

struct Line2d {
  Eigen::Vector2d point;
  Eigen::Vector2d direction;  // unit
  double inlier_fraction = 0.0;
};

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
std::optional<Line2d> FitEdgeLine(const std::vector<Eigen::Vector2d>& points, const std::vector<double>& strengths,
                                  int samples) {
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
  for (size_t i = 0; i < points.size(); ++i) {
    if (Distance(best, points[i]) < kInlierBandPx) inliers.push_back(points[i]), inlier_strengths.push_back(strengths[i]);
  }
  const std::vector<Eigen::Vector2d> full = KeepFullContrast(inliers, inlier_strengths);
  Line2d fitted = FitTls(full.size() >= 4 ? full : inliers);
  fitted.inlier_fraction = static_cast<double>(inliers.size()) / samples;
  return fitted;
}

std::optional<Eigen::Vector2d> Intersect(const Line2d& a, const Line2d& b) {
  const double det = a.direction.x() * b.direction.y() - a.direction.y() * b.direction.x();
  if (std::abs(det) < 0.1) return std::nullopt;  // sides closer than ~6 degrees to parallel
  const Eigen::Vector2d d = b.point - a.point;
  const double t = (d.x() * b.direction.y() - d.y() * b.direction.x()) / det;
  return a.point + t * a.direction;
}

// One round: edge points along each side within +-half_window, lines, intersections.
std::optional<RefinedQuad> RefineOnce(const cv::Mat& gray, const Quad2d& corners, double half_window,
                                      const RefineOptions& options) {
  std::array<Line2d, 4> lines;
  double worst = 1.0;
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector2d a = corners[i];
    const Eigen::Vector2d b = corners[(i + 1) % 4];
    const double length = (b - a).norm();
    const Eigen::Vector2d along = (b - a) / length;
    const Eigen::Vector2d outward(along.y(), -along.x());  // clockwise quad, y down
    const int samples = std::clamp(static_cast<int>(length / 1.5), 8, 96);
    std::vector<Eigen::Vector2d> points;
    std::vector<double> strengths;
    for (int k = 0; k < samples; ++k) {
      const Eigen::Vector2d p = a + (0.1 + 0.8 * k / (samples - 1.0)) * (b - a);
      double strength = 0.0;
      const double s = EdgeOffset(gray, p, outward, half_window, options.min_step, &strength);
      if (!std::isnan(s)) points.push_back(p + s * outward), strengths.push_back(strength);
    }
    const std::optional<Line2d> line = FitEdgeLine(points, strengths, samples);
    if (!line || line->inlier_fraction < options.min_inlier_fraction) return std::nullopt;
    lines[i] = *line;
    worst = std::min(worst, line->inlier_fraction);
  }
  RefinedQuad out;
  out.inlier_fraction = worst;
  for (int i = 0; i < 4; ++i) {
    // Corner i joins side i-1 (ending at i) and side i (starting at i).
    const std::optional<Eigen::Vector2d> c = Intersect(lines[(i + 3) % 4], lines[i]);
    if (!c || (*c - corners[i]).norm() > options.max_shift_px) return std::nullopt;
    out.corners_px[i] = *c;
  }
  return out;
}

}  // namespace

std::optional<RefinedQuad> RefineQuadCorners(const cv::Mat& gray, const Quad2d& corners_px,
                                             const RefineOptions& options) {
  if (gray.empty() || gray.type() != CV_8UC1) return std::nullopt;
  // The first window scales with the symbol (decoders can be off by most of a module on
  // rotated symbols) and stays well inside it: a sixth of the shortest side at most.
  double shortest = std::numeric_limits<double>::infinity();
  for (int i = 0; i < 4; ++i) shortest = std::min(shortest, (corners_px[(i + 1) % 4] - corners_px[i]).norm());
  const double window = std::min(std::max(options.search_px, options.search_fraction * shortest), shortest / 6.0);
  if (!(window >= 0.75)) return std::nullopt;
  RefineOptions round = options;
  round.max_shift_px = std::max(options.max_shift_px, 1.5 * window);
  const std::optional<RefinedQuad> first = RefineOnce(gray, corners_px, window, round);
  if (!first) return std::nullopt;
  std::optional<RefinedQuad> second = RefineOnce(gray, first->corners_px, std::min(window, 1.25), round);
  if (!second) return first;
  for (int i = 0; i < 4; ++i) {
    if ((second->corners_px[i] - corners_px[i]).norm() > round.max_shift_px) return first;
  }
  return second;
}

}  // namespace waymark
