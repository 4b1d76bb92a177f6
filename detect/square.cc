#include "detect/square.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <numeric>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <stdexcept>

#include "geometry/square_marker.h"
#include "util/format.h"

namespace waymark {
namespace {

constexpr int kMaxFirstLines = 16;     // strongest lines tried as the solid side
constexpr double kSampleStepM = 0.02;  // refinement samples along a side

bool Fail(std::string* why, const std::string& reason) {
  if (why != nullptr) *why = reason;
  return false;
}

// Difference of two line angles modulo pi, in [-pi/2, pi/2].
double AngleDiff(double a, double b) { return std::remainder(a - b, M_PI); }

// Bilinear sample of an 8-bit image; -1 outside.
double Sample(const cv::Mat& image, double x, double y) {
  const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  if (x0 < 0 || y0 < 0 || x0 + 1 >= image.cols || y0 + 1 >= image.rows) return -1.0;
  const double fx = x - x0, fy = y - y0;
  const std::uint8_t* r0 = image.ptr<std::uint8_t>(y0);
  const std::uint8_t* r1 = image.ptr<std::uint8_t>(y0 + 1);
  return (1 - fy) * ((1 - fx) * r0[x0] + fx * r0[x0 + 1]) + fy * ((1 - fx) * r1[x0] + fx * r1[x0 + 1]);
}

double Shoelace(const std::array<Eigen::Vector2d, 4>& q) {
  double sum = 0.0;
  for (int i = 0; i < 4; ++i) sum += q[i].x() * q[(i + 1) % 4].y() - q[(i + 1) % 4].x() * q[i].y();
  return sum;
}

}  // namespace

bool SquareDetectorOptions::Check(std::string* why) const {
  std::string tape_why;
  if (!CheckSquareTape(tape, side_m, &tape_why)) return Fail(why, "square detector: " + tape_why);
  if (!(ceiling_height_m > 0.0 && std::isfinite(ceiling_height_m))) {
    return Fail(why,
                "square detector: ceiling height: expected > 0 m, got " + FormatDouble(ceiling_height_m));
  }
  if (!(rectified_mm_per_px > 0.0) || !(rectified_half_extent_m > 0.0) ||
      rectified_half_extent_m * 1000.0 / rectified_mm_per_px > 2000.0) {
    return Fail(why, "square detector: the rectified image must be 1 to 4001 px wide");
  }
  if (diff_threshold < 1 || diff_threshold > 254)
    return Fail(why, "square detector: diff_threshold: expected 1..254");
  if (hough_votes < 1) return Fail(why, "square detector: hough_votes: expected >= 1");
  if (!(distance_gate > 0.0 && distance_gate < 0.5) || !(angle_gate_deg > 0.0 && angle_gate_deg < 45.0)) {
    return Fail(why, "square detector: gates: expected 0 < distance_gate < 0.5, 0 < angle_gate_deg < 45");
  }
  return true;
}

SquareDetector::SquareDetector(const Camera& camera, const SquareDetectorOptions& options)
    : camera_(camera), options_(options) {
  std::string why;
  if (!options_.Check(&why)) throw std::invalid_argument(why);
  const double s = options_.rectified_mm_per_px * 1e-3, z = options_.ceiling_height_m;
  const int half = static_cast<int>(std::lround(options_.rectified_half_extent_m / s));
  rect_size_ = 2 * half + 1;
  map_x_.create(rect_size_, rect_size_, CV_32F);
  map_y_.create(rect_size_, rect_size_, CV_32F);
  for (int i = 0; i < rect_size_; ++i) {
    for (int j = 0; j < rect_size_; ++j) {
      const std::optional<Eigen::Vector2d> px =
          camera_.Project(Eigen::Vector3d((j - half) * s, (i - half) * s, z));
      map_x_.at<float>(i, j) = px ? static_cast<float>(px->x()) : -10.0f;
      map_y_.at<float>(i, j) = px ? static_cast<float>(px->y()) : -10.0f;
    }
  }
}

cv::Mat SquareDetector::Diff(const cv::Mat& on, const cv::Mat& off) const {
  if (on.empty() || off.empty()) throw std::invalid_argument("LED pair: empty image");
  if (on.size() != off.size()) {
    throw std::invalid_argument("LED pair: the on image is " + std::to_string(on.cols) + "x" +
                                std::to_string(on.rows) + " but the off image is " +
                                std::to_string(off.cols) + "x" + std::to_string(off.rows));
  }
  if (on.type() != CV_8UC1 || off.type() != CV_8UC1)
    throw std::invalid_argument("LED pair: expected 8-bit gray images");
  if (on.cols != camera_.width() || on.rows != camera_.height()) {
    throw std::invalid_argument("LED pair: images are " + std::to_string(on.cols) + "x" +
                                std::to_string(on.rows) + " but camera " + camera_.name() + " is " +
                                std::to_string(camera_.width()) + "x" + std::to_string(camera_.height()));
  }
  cv::Mat diff;
  cv::subtract(on, off, diff);  // saturates at 0
  return diff;
}

cv::Mat SquareDetector::TopHat(const cv::Mat& diff) const {
  cv::Mat rectified, binary, opened, tophat;
  cv::remap(diff, rectified, map_x_, map_y_, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0));
  // A light blur first: a large bright region near the threshold (a person near the LEDs) would
  // binarize into speckle that the opening cannot remove.
  cv::GaussianBlur(rectified, rectified, cv::Size(5, 5), 1.0);
  cv::threshold(rectified, binary, options_.diff_threshold, 255, cv::THRESH_BINARY);
  const double tape_px = options_.tape.tape_width_m * 1000.0 / options_.rectified_mm_per_px;
  const int k = 2 * static_cast<int>(std::ceil(1.5 * tape_px)) + 1;
  cv::morphologyEx(binary, opened, cv::MORPH_OPEN, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(k, k)));
  cv::subtract(binary, opened, tophat);
  // Pieces smaller than half a dash are not tape (the rectified image is metric: a dash has the
  // same size in pixels anywhere).
  cv::Mat labels, stats, centroids;
  const int n = cv::connectedComponentsWithStats(tophat, labels, stats, centroids, 8, CV_32S);
  const double min_area = 0.5 * tape_px * options_.tape.dash_m * 1000.0 / options_.rectified_mm_per_px;
  std::vector<std::uint8_t> keep(static_cast<size_t>(n), 1);
  for (int i = 1; i < n; ++i) keep[i] = stats.at<int>(i, cv::CC_STAT_AREA) >= min_area;
  for (int r = 0; r < tophat.rows; ++r) {
    const int* label = labels.ptr<int>(r);
    std::uint8_t* out = tophat.ptr<std::uint8_t>(r);
    for (int c = 0; c < tophat.cols; ++c) {
      if (out[c] != 0 && !keep[label[c]]) out[c] = 0;
    }
  }
  return tophat;
}

cv::Mat SquareDetector::RectifiedTopHat(const cv::Mat& on, const cv::Mat& off) const {
  return TopHat(Diff(on, off));
}

Eigen::Vector2d SquareDetector::ToImage(const Eigen::Vector2d& plane) const {
  const std::optional<Eigen::Vector2d> px =
      camera_.Project(Eigen::Vector3d(plane.x(), plane.y(), options_.ceiling_height_m));
  return px ? *px : Eigen::Vector2d(std::nan(""), std::nan(""));
}

double SquareDetector::LongestRun(const cv::Mat& tophat, const Eigen::Vector2d& a,
                                  const Eigen::Vector2d& b) const {
  const double s = options_.rectified_mm_per_px * 1e-3, w = options_.tape.tape_width_m;
  const double half = (rect_size_ - 1) / 2;
  const double length = (b - a).norm(), end = 1.5 * w;
  if (length <= 2.0 * end) return 0.0;
  const Eigen::Vector2d u = (b - a) / length, n(-u.y(), u.x());
  const double step = 0.5 * s;
  const int across = static_cast<int>(std::ceil((0.5 * w + s) / s));
  double longest = 0.0, run = 0.0;
  for (double t = end; t <= length - end; t += step) {
    const Eigen::Vector2d q = a + t * u;
    bool on = false;
    for (int k = -across; k <= across && !on; ++k) {
      const Eigen::Vector2d p = q + (k * s) * n;
      const int j = static_cast<int>(std::lround(p.x() / s + half)),
                i = static_cast<int>(std::lround(p.y() / s + half));
      on = i >= 0 && j >= 0 && i < tophat.rows && j < tophat.cols && tophat.at<std::uint8_t>(i, j) != 0;
    }
    run = on ? run + step : 0.0;
    longest = std::max(longest, run);
  }
  return longest;
}

int SquareDetector::RefineLine(const cv::Mat& diff, const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                               Line* line) const {
  const double w = options_.tape.tape_width_m, z = options_.ceiling_height_m;
  const double length = (b - a).norm(), end = 1.5 * w;
  if (length <= 2.0 * end) return 0;
  const Eigen::Vector2d u = (b - a) / length, n(-u.y(), u.x());
  std::vector<Eigen::Vector2d> points;
  for (double t = end; t <= length - end; t += kSampleStepM) {
    const Eigen::Vector2d q = a + t * u;
    const Eigen::Vector2d p = ToImage(q), p_side = ToImage(q + 0.5 * w * n);
    if (!p.allFinite() || !p_side.allFinite()) continue;
    const double half_px = (p_side - p).norm();
    if (!(half_px > 0.2)) continue;
    const Eigen::Vector2d n_img = (p_side - p) / half_px;
    const double h = half_px + 3.0;
    double centre = 0.0;
    bool ok = true;
    for (int iteration = 0; iteration < 2 && ok; ++iteration) {
      std::vector<double> ts, vs;
      for (double t_px = -h; t_px <= h + 1e-9; t_px += 0.5) {
        const Eigen::Vector2d x = p + (centre + t_px) * n_img;
        const double v = Sample(diff, x.x(), x.y());
        if (v < 0.0) {
          ok = false;
          break;
        }
        ts.push_back(centre + t_px);
        vs.push_back(v);
      }
      if (!ok || vs.size() < 8) {
        ok = false;
        break;
      }
      std::vector<double> border = {vs[0],
                                    vs[1],
                                    vs[2],
                                    vs[3],
                                    vs[vs.size() - 1],
                                    vs[vs.size() - 2],
                                    vs[vs.size() - 3],
                                    vs[vs.size() - 4]};
      std::nth_element(border.begin(), border.begin() + 4, border.end());
      const double background = border[4];
      const double peak = *std::max_element(vs.begin(), vs.end()) - background;
      if (peak < options_.diff_threshold) {
        ok = false;
        break;
      }
      double sum_w = 0.0, sum_tw = 0.0;
      for (size_t k = 0; k < vs.size(); ++k) {
        const double weight = std::max(0.0, vs[k] - background);
        sum_w += weight;
        sum_tw += weight * ts[k];
      }
      centre = sum_tw / sum_w;
      if (std::abs(centre) > h) ok = false;
    }
    if (!ok) continue;
    const std::optional<Eigen::Vector3d> ray = camera_.Unproject(p + centre * n_img);
    if (ray) points.emplace_back(ray->x() * z, ray->y() * z);
  }
  for (int pass = 0; pass < 2; ++pass) {
    if (points.size() < 5) return 0;
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    for (const Eigen::Vector2d& p : points) mean += p;
    mean /= static_cast<double>(points.size());
    Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
    for (const Eigen::Vector2d& p : points) cov += (p - mean) * (p - mean).transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eigen(cov);
    const Eigen::Vector2d normal = eigen.eigenvectors().col(0);  // smallest eigenvalue
    line->theta = std::atan2(normal.y(), normal.x());
    line->rho = normal.dot(mean);
    if (pass == 1) break;
    std::vector<double> residuals;
    for (const Eigen::Vector2d& p : points) residuals.push_back(std::abs(normal.dot(p) - line->rho));
    std::vector<double> sorted = residuals;
    std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
    const double limit = 3.0 * std::max(sorted[sorted.size() / 2], 1e-4);
    std::vector<Eigen::Vector2d> kept;
    for (size_t k = 0; k < points.size(); ++k) {
      if (residuals[k] <= limit) kept.push_back(points[k]);
    }
    points = std::move(kept);
  }
  return static_cast<int>(points.size());
}

namespace {

std::optional<Eigen::Vector2d> IntersectLines(double theta_a, double rho_a, double theta_b, double rho_b) {
  Eigen::Matrix2d A;
  A << std::cos(theta_a), std::sin(theta_a), std::cos(theta_b), std::sin(theta_b);
  if (std::abs(A.determinant()) < 0.1) return std::nullopt;  // closer than ~6 deg to parallel
  return Eigen::Vector2d(A.inverse() * Eigen::Vector2d(rho_a, rho_b));
}

}  // namespace

std::vector<SquareDetection> SquareDetector::Detect(const cv::Mat& on, const cv::Mat& off) const {
  const cv::Mat diff = Diff(on, off);
  const cv::Mat tophat = TopHat(diff);
  std::vector<cv::Vec3f> found;
  cv::HoughLines(tophat, found, 1.0, M_PI / 180.0, options_.hough_votes);
  std::stable_sort(found.begin(), found.end(),
                   [](const cv::Vec3f& a, const cv::Vec3f& b) { return a[2] > b[2]; });
  const double s = options_.rectified_mm_per_px * 1e-3, c = (rect_size_ - 1) / 2;
  std::vector<Line> lines;
  for (const cv::Vec3f& l : found) {
    const double theta = l[1];
    lines.push_back({theta, s * (l[0] - c * std::cos(theta) - c * std::sin(theta))});
  }
  const double d = options_.side_m, gate_d = options_.distance_gate * d;
  const double gate_a = options_.angle_gate_deg * M_PI / 180.0;
  // The first line (in vote order) parallel to `ref` at distance d from it.
  const auto parallel_at_d = [&](const Line& ref) -> std::optional<Line> {
    for (const Line& l : lines) {
      const double da = AngleDiff(l.theta, ref.theta);
      if (std::abs(da) > gate_a) continue;
      const double rho = std::cos(l.theta - ref.theta) >= 0.0 ? l.rho : -l.rho;  // in ref's orientation
      if (std::abs(std::abs(rho - ref.rho) - d) <= gate_d) return l;
    }
    return std::nullopt;
  };
  const int tries = std::min<int>(kMaxFirstLines, static_cast<int>(lines.size()));
  for (int first = 0; first < tries; ++first) {
    const Line& l1 = lines[first];
    const std::optional<Line> l2 = parallel_at_d(l1);
    if (!l2) continue;
    for (const Line& l3 : lines) {
      if (std::abs(AngleDiff(l3.theta, l1.theta + 0.5 * M_PI)) > gate_a) continue;
      const std::optional<Line> l4 = parallel_at_d(l3);
      if (!l4) continue;
      // Corners: A = l1 x l3, B = l1 x l4, C = l4 x l2, D = l3 x l2 (a closed loop of sides).
      std::array<Line, 4> sides = {l1, *l4, *l2, l3};  // A-B on l1, B-C on l4, C-D on l2, D-A on l3
      std::array<Eigen::Vector2d, 4> q;
      bool ok = true;
      for (int k = 0; k < 4 && ok; ++k) {
        const Line& prev = sides[(k + 3) % 4];
        const Line& next = sides[k];
        const std::optional<Eigen::Vector2d> p = IntersectLines(prev.theta, prev.rho, next.theta, next.rho);
        ok = p.has_value();
        if (ok) q[k] = *p;
      }
      if (!ok) continue;
      // Clockwise in the image (the rectified plane has the image's axes): reverse otherwise.
      if (Shoelace(q) < 0.0) {
        std::reverse(q.begin(), q.end());
        std::reverse(sides.begin(), sides.end());
        std::rotate(sides.begin(), sides.begin() + 3, sides.end());  // side k again runs q[k] -> q[k+1]
      }
      // Which side is solid: exactly one with a run longer than any dash can be.
      SquareDetection detection;
      const double solid_run = 2.0 * options_.tape.dash_m + options_.tape.gap_m;
      int solid = -1, count = 0;
      std::array<double, 4> runs{};
      for (int k = 0; k < 4; ++k) {
        runs[k] = LongestRun(tophat, q[k], q[(k + 1) % 4]);
        if (runs[k] > solid_run) {
          solid = k;
          ++count;
        }
      }
      if (count != 1) return {};  // the solid side hidden or not telling: no fix rather than a flip
      std::rotate(q.begin(), q.begin() + solid, q.end());
      std::rotate(sides.begin(), sides.begin() + solid, sides.end());
      std::rotate(runs.begin(), runs.begin() + solid, runs.end());
      detection.longest_run_m = runs;
      // Twice: the second pass samples along the first pass's lines (the Hough line can be off
      // by a few pixels and a degree, which shifts the profile windows along a side).
      for (int pass = 0; pass < (options_.refine ? 2 : 0); ++pass) {
        const std::array<Eigen::Vector2d, 4> before = q;
        for (int k = 0; k < 4; ++k) {
          detection.refined_samples[k] = RefineLine(diff, before[k], before[(k + 1) % 4], &sides[k]);
        }
        for (int k = 0; k < 4 && ok; ++k) {
          const Line& prev = sides[(k + 3) % 4];
          const std::optional<Eigen::Vector2d> p =
              IntersectLines(prev.theta, prev.rho, sides[k].theta, sides[k].rho);
          ok = p.has_value() && (*p - before[k]).norm() < 0.25 * d;
          if (ok) q[k] = *p;
        }
        if (!ok) return {};
      }
      for (int k = 0; k < 4; ++k) {
        detection.corners_px[k] = ToImage(q[k]);
        if (!detection.corners_px[k].allFinite() || !camera_.info().InImage(detection.corners_px[k])) {
          return {};
        }
      }
      return {detection};
    }
  }
  return {};
}

std::optional<double> SquareCeilingHeight(const MarkerMap& map, const CameraInfo& camera) {
  std::optional<double> height;
  for (const MapMarker& m : map.markers) {
    if (m.key.family != kFamilySquare || !m.has_pose) continue;
    const double h = m.T_world_marker.translation().z() - camera.T_robot_camera.translation().z();
    if (h > 0.0 && (!height || h > *height)) height = h;
  }
  return height;
}

}  // namespace waymark
