#include "detect/qr_grid.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "detect/refine.h"

namespace waymark {
namespace {

constexpr double kMinTimingContrast = 0.4;
constexpr double kMinRingDifference = 20.0;  // gray levels
constexpr double kMinModulePx = 1.0;
constexpr int kMaxModules = 97;    // version 20
constexpr double kMinStep = 12.0;  // gray levels per px, as RefineOptions::min_step
constexpr int kMinSidePoints = 6;
constexpr double kMinPointSpacingPx = 1.25;  // along a side
constexpr double kMinSideInliers = 0.6;

Eigen::Vector2d Apply(const cv::Matx33d& H, double u, double v) {
  const cv::Vec3d p = H * cv::Vec3d(u, v, 1.0);
  return {p[0] / p[2], p[1] / p[2]};
}

// Bilinear gray level at `p`; NaN outside the image.
double Sample(const cv::Mat& gray, const Eigen::Vector2d& p) {
  if (!(p.x() >= 0.0 && p.y() >= 0.0 && p.x() <= gray.cols - 1.0 && p.y() <= gray.rows - 1.0)) return NAN;
  const int x0 = std::min(static_cast<int>(p.x()), gray.cols - 2);
  const int y0 = std::min(static_cast<int>(p.y()), gray.rows - 2);
  const double fx = p.x() - x0, fy = p.y() - y0;
  const uint8_t* r0 = gray.ptr<uint8_t>(y0);
  const uint8_t* r1 = gray.ptr<uint8_t>(y0 + 1);
  return (1 - fy) * ((1 - fx) * r0[x0] + fx * r0[x0 + 1]) + fy * ((1 - fx) * r1[x0] + fx * r1[x0 + 1]);
}

// Mean gray level at the centres of modules (c, r) given as pairs; NaN if one is outside.
double MeanAt(const cv::Mat& gray, const cv::Matx33d& H, const std::vector<cv::Point>& modules) {
  double sum = 0.0;
  for (const cv::Point& m : modules) sum += Sample(gray, Apply(H, m.x + 0.5, m.y + 0.5));
  return sum / static_cast<double>(modules.size());
}

// Module centres of the three finders' dark ring (outer ring) and light ring, by offsets
// of the finders' top-left modules.
void FinderRings(int n, std::vector<cv::Point>* dark, std::vector<cv::Point>* light) {
  for (const cv::Point origin : {cv::Point(0, 0), cv::Point(n - 7, 0), cv::Point(0, n - 7)}) {
    for (int k = 0; k < 7; ++k) {
      for (const cv::Point m : {cv::Point(k, 0), cv::Point(k, 6), cv::Point(0, k), cv::Point(6, k)}) {
        dark->push_back(origin + m);
      }
    }
    for (int k = 1; k < 6; ++k) {
      for (const cv::Point m : {cv::Point(k, 1), cv::Point(k, 5), cv::Point(1, k), cv::Point(5, k)}) {
        light->push_back(origin + m);
      }
    }
  }
}

// The grid of n modules, or nullopt if a sample leaves the image.
std::optional<QrGridEstimate> GridFor(const cv::Mat& gray, const Quad2d& corners_px, int n) {
  const cv::Matx33d H = ImageFromModules(corners_px, n);
  std::vector<cv::Point> dark_ring, light_ring, timing_dark, timing_light;
  FinderRings(n, &dark_ring, &light_ring);
  for (int k = 8; k <= n - 9; ++k) {
    std::vector<cv::Point>& list = k % 2 == 0 ? timing_dark : timing_light;
    list.emplace_back(k, 6);
    list.emplace_back(6, k);
  }
  QrGridEstimate grid;
  grid.modules = n;
  grid.dark_level = MeanAt(gray, H, dark_ring);
  grid.light_level = MeanAt(gray, H, light_ring);
  const double timing = MeanAt(gray, H, timing_light) - MeanAt(gray, H, timing_dark);
  grid.timing_contrast = timing / (grid.light_level - grid.dark_level);
  if (!std::isfinite(grid.timing_contrast)) return std::nullopt;
  return grid;
}

// Edge points of side `side` (0 top, 1 right, 2 bottom, 3 left; from corner side to corner
// side + 1) at its dark outer modules, in image pixels.
std::vector<Eigen::Vector2d> DarkModulePoints(const cv::Mat& gray, const cv::Matx33d& H, int n, int side,
                                              double threshold, double module_px) {
  // Module k along the side, and the point at fraction s of it (0 .. n) on the side's edge.
  const auto module = [&](int k) -> cv::Point {
    switch (side) {
      case 0:
        return {k, 0};
      case 1:
        return {n - 1, k};
      case 2:
        return {n - 1 - k, n - 1};
      default:
        return {0, n - 1 - k};
    }
  };
  const auto on_edge = [&](double s) -> Eigen::Vector2d {
    switch (side) {
      case 0:
        return Apply(H, s, 0.0);
      case 1:
        return Apply(H, n, s);
      case 2:
        return Apply(H, n - s, n);
      default:
        return Apply(H, 0.0, n - s);
    }
  };
  std::vector<bool> dark(n + 1, false);
  for (int k = 0; k < n; ++k) {
    const cv::Point m = module(k);
    dark[k] = Sample(gray, Apply(H, m.x + 0.5, m.y + 0.5)) < threshold;
  }
  // Every half module along dark runs (every quarter when that is still kMinPointSpacingPx
  // apart: on sharp, nearly axis-aligned edges the pixel staircase needs the denser
  // sampling), but never within a quarter module of a dark module's light neighbour (the
  // step fades there, and slants under perspective).
  const bool quarters = 0.25 * module_px >= kMinPointSpacingPx;
  std::vector<Eigen::Vector2d> points;
  for (int k = 0; k < n; ++k) {
    if (!dark[k]) continue;
    const bool before = k > 0 && dark[k - 1];
    if (before) points.push_back(on_edge(k));
    if (before && quarters) points.push_back(on_edge(k + 0.25));
    points.push_back(on_edge(k + 0.5));
    if (dark[k + 1] && quarters) points.push_back(on_edge(k + 0.75));
  }
  return points;
}

// The line halfway between two nearly parallel lines: mean direction, through the mean of
// a's point and its foot on b.
Line2d MeanLine(const Line2d& a, const Line2d& b) {
  const Eigen::Vector2d b_direction =
      b.direction.dot(a.direction) < 0.0 ? Eigen::Vector2d(-b.direction) : b.direction;
  const Eigen::Vector2d foot = b.point + (a.point - b.point).dot(b_direction) * b_direction;
  Line2d mean;
  mean.point = 0.5 * (a.point + foot);
  mean.direction = (a.direction + b_direction).normalized();
  mean.inlier_fraction = std::min(a.inlier_fraction, b.inlier_fraction);
  return mean;
}

// A wrong module count samples both rings and timing modules at random places: small
// differences, whose ratio can still be large. The score is the smaller of the two in gray
// levels.
double Score(const QrGridEstimate& grid) {
  const double rings = grid.light_level - grid.dark_level;
  return std::min(rings, grid.timing_contrast * rings);
}

}  // namespace

cv::Matx33d ImageFromModules(const Quad2d& corners_px, int n) {
  const float f = static_cast<float>(n);
  const std::vector<cv::Point2f> modules = {{0.f, 0.f}, {f, 0.f}, {f, f}, {0.f, f}};
  std::vector<cv::Point2f> image;
  for (const Eigen::Vector2d& c : corners_px) image.emplace_back(c.x(), c.y());
  return cv::Matx33d(cv::getPerspectiveTransform(modules, image));
}

std::optional<QrGridEstimate> EstimateQrGrid(const cv::Mat& gray, const Quad2d& corners_px) {
  if (gray.empty() || gray.type() != CV_8UC1) return std::nullopt;
  const double side_px = QuadMeanSide(corners_px);
  std::optional<QrGridEstimate> best;
  for (int n = 21; n <= kMaxModules && side_px / n >= kMinModulePx; n += 4) {
    const std::optional<QrGridEstimate> grid = GridFor(gray, corners_px, n);
    if (grid && (!best || Score(*grid) > Score(*best))) best = grid;
  }
  if (!best || best->timing_contrast < kMinTimingContrast ||
      best->light_level - best->dark_level < kMinRingDifference) {
    return std::nullopt;
  }
  return best;
}

std::optional<Quad2d> FitQrSidesOnDarkModules(const cv::Mat& gray, const Quad2d& corners_px,
                                              const QrGridEstimate& grid) {
  if (gray.empty() || gray.type() != CV_8UC1 || grid.modules < 21) return std::nullopt;
  const int n = grid.modules;
  const cv::Matx33d H = ImageFromModules(corners_px, n);
  const double module_px = QuadMeanSide(corners_px) / n;
  const double half_window = std::clamp(0.75 * module_px, 1.0, 3.0);
  const double threshold = 0.5 * (grid.dark_level + grid.light_level);
  std::array<Line2d, 4> lines;
  for (int side = 0; side < 4; ++side) {
    const Eigen::Vector2d along = (corners_px[(side + 1) % 4] - corners_px[side]).normalized();
    const std::vector<Eigen::Vector2d> points = DarkModulePoints(gray, H, n, side, threshold, module_px);
    if (static_cast<int>(points.size()) < kMinSidePoints) return std::nullopt;
    const Eigen::Vector2d outward(along.y(), -along.x());  // clockwise quad, y down
    const auto [modelled, centroid] = FitEdgeThroughBoth(gray, points, outward, half_window, kMinStep);
    if (!modelled || !centroid || modelled->inlier_fraction < kMinSideInliers ||
        centroid->inlier_fraction < kMinSideInliers) {
      return std::nullopt;
    }
    lines[side] = MeanLine(*modelled, *centroid);
  }
  Quad2d out;
  const double max_move_px = std::max(1.0, 0.5 * module_px);
  for (int i = 0; i < 4; ++i) {
    const std::optional<Eigen::Vector2d> c = IntersectLines(lines[(i + 3) % 4], lines[i]);
    if (!c || (*c - corners_px[i]).norm() > max_move_px) return std::nullopt;
    out[i] = *c;
  }
  return out;
}

std::vector<uint8_t> SampleQrModules(const cv::Mat& gray, const Quad2d& corners_px,
                                     const QrGridEstimate& grid) {
  const int n = grid.modules;
  if (gray.empty() || gray.type() != CV_8UC1 || n < 1) return {};
  const cv::Matx33d H = ImageFromModules(corners_px, n);
  const double threshold = 0.5 * (grid.dark_level + grid.light_level);
  std::vector<uint8_t> dark(static_cast<size_t>(n) * n, 0);
  for (int v = 0; v < n; ++v) {
    for (int u = 0; u < n; ++u) {
      const double level = Sample(gray, Apply(H, u + 0.5, v + 0.5));
      if (std::isnan(level)) return {};
      dark[static_cast<size_t>(v) * n + u] = level < threshold ? 1 : 0;
    }
  }
  return dark;
}

}  // namespace waymark
