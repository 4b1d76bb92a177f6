#include "geometry/camera.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>

namespace waymark {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
// The equidistant model is used up to theta = pi/2 - kThetaMargin (tan = 1e6).
constexpr double kThetaMargin = 1e-6;

// d(r radial(r))/dr for the radtan model, tangential terms left out.
double RadtanRadialSlope(const std::vector<double>& d, double r) {
  const double u = r * r;
  return 1.0 + u * (3.0 * d[0] + u * (5.0 * d[1] + u * 7.0 * d[4]));
}

// theta_d(theta) and its derivative for the equidistant model.
double EquidistantThetaD(const std::vector<double>& d, double theta, double* slope = nullptr) {
  const double t2 = theta * theta;
  if (slope != nullptr) {
    *slope = 1.0 + t2 * (3.0 * d[0] + t2 * (5.0 * d[1] + t2 * (7.0 * d[2] + t2 * 9.0 * d[3])));
  }
  return theta * (1.0 + t2 * (d[0] + t2 * (d[1] + t2 * (d[2] + t2 * d[3]))));
}

// rho(theta) = 2 sin(theta/2) P(theta) and its derivative for the equisolid model,
// P = 1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8.
double EquisolidRho(const std::vector<double>& d, double theta, double* slope = nullptr) {
  const double t2 = theta * theta;
  const double poly = 1.0 + t2 * (d[0] + t2 * (d[1] + t2 * (d[2] + t2 * d[3])));
  const double base = 2.0 * std::sin(0.5 * theta);
  if (slope != nullptr) {
    const double dpoly = theta * (2.0 * d[0] + t2 * (4.0 * d[1] + t2 * (6.0 * d[2] + t2 * 8.0 * d[3])));
    *slope = std::cos(0.5 * theta) * poly + base * dpoly;
  }
  return base * poly;
}

// The radial map of either fisheye model: image radius (normalized) of a ray theta off-axis.
double FisheyeRho(CameraModel model, const std::vector<double>& d, double theta, double* slope = nullptr) {
  return model == CameraModel::kEquisolid ? EquisolidRho(d, theta, slope)
                                          : EquidistantThetaD(d, theta, slope);
}

// First root of a function that is positive at `lo`, searched on the given grid of points
// and refined by bisection; `hi_default` if it stays positive on the whole grid.
template <typename F>
double FirstRoot(F f, const std::vector<double>& grid, double hi_default) {
  double lo = 0.0;
  for (double x : grid) {
    if (f(x) > 0.0) {
      lo = x;
      continue;
    }
    double hi = x;
    for (int i = 0; i < 200 && hi - lo > 1e-15 * hi; ++i) {
      const double mid = 0.5 * (lo + hi);
      (f(mid) > 0.0 ? lo : hi) = mid;
    }
    return lo;
  }
  return hi_default;
}

// Solves f(x) = target for x in [lo, hi], f increasing there, by Newton steps kept inside
// a shrinking bracket (bisection when a step leaves it). `f(x, &slope)` returns the value.
template <typename F>
std::optional<double> SolveIncreasing(F f, double target, double lo, double hi) {
  double x = 0.5 * (lo + hi);
  for (int i = 0; i < 200; ++i) {
    double slope = 0.0;
    const double e = f(x, &slope) - target;
    if (std::abs(e) <= 1e-16 * std::max(1.0, std::abs(target))) return x;
    (e < 0.0 ? lo : hi) = x;
    double next = slope > 0.0 ? x - e / slope : 0.5 * (lo + hi);
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    if (next == x || hi - lo <= 1e-16 * hi) return x;
    x = next;
  }
  return std::nullopt;
}

void CheckCameraInfo(const CameraInfo& info) {
  const std::string where = "camera `" + info.name + "` (" + CameraModelName(info.model) + "): ";
  const size_t expected = CameraInfo::DistortionSize(info.model);
  if (info.distortion.size() != expected) {
    throw std::runtime_error(where + "distortion: expected " + std::to_string(expected) +
                             " coefficients, got " + std::to_string(info.distortion.size()));
  }
  for (double v : info.intrinsics) {
    if (!std::isfinite(v)) throw std::runtime_error(where + "intrinsics: expected finite numbers");
  }
  for (double v : info.distortion) {
    if (!std::isfinite(v)) throw std::runtime_error(where + "distortion: expected finite numbers");
  }
  if (info.intrinsics[0] <= 0.0 || info.intrinsics[1] <= 0.0) {
    throw std::runtime_error(where + "intrinsics: expected fx > 0 and fy > 0");
  }
  if (info.width <= 0 || info.height <= 0) {
    throw std::runtime_error(where + "expected width > 0 and height > 0");
  }
}

}  // namespace

Camera::Camera(CameraInfo info) : info_(std::move(info)) {
  CheckCameraInfo(info_);
  const std::vector<double>& d = info_.distortion;
  std::vector<double> grid;
  if (info_.model == CameraModel::kPinholeRadtan) {
    for (double r = 1e-3; r < 1e3; r *= 1.01) grid.push_back(r);
    max_radius_ = FirstRoot([&d](double r) { return RadtanRadialSlope(d, r); }, grid, kInf);
  } else {
    const double theta_end = 0.5 * M_PI - kThetaMargin;
    for (int i = 1; i <= 2000; ++i) grid.push_back(theta_end * i / 2000.0);
    double slope = 0.0;
    const CameraModel model = info_.model;
    const auto f = [&d, &slope, model](double theta) {
      FisheyeRho(model, d, theta, &slope);
      return slope;
    };
    max_radius_ = std::tan(FirstRoot(f, grid, theta_end));
  }
}

Eigen::Vector2d Camera::Distort(const Eigen::Vector2d& xy, Eigen::Matrix2d* J) const {
  const double* d = info_.distortion.data();
  const double x = xy.x(), y = xy.y(), u = x * x + y * y;
  Eigen::Vector2d xy_d;
  if (info_.model == CameraModel::kPinholeRadtan) {
    DistortRadtan(d, x, y, &xy_d.x(), &xy_d.y());
    if (J != nullptr) {
      const double radial = 1.0 + u * (d[0] + u * (d[1] + u * d[4]));
      const double dradial_du = d[0] + u * (2.0 * d[1] + u * 3.0 * d[4]);
      (*J)(0, 0) = radial + 2.0 * x * x * dradial_du + 2.0 * d[2] * y + 6.0 * d[3] * x;
      (*J)(0, 1) = 2.0 * x * y * dradial_du + 2.0 * d[2] * x + 2.0 * d[3] * y;
      (*J)(1, 0) = 2.0 * x * y * dradial_du + 2.0 * d[2] * x + 2.0 * d[3] * y;
      (*J)(1, 1) = radial + 2.0 * y * y * dradial_du + 6.0 * d[2] * y + 2.0 * d[3] * x;
    }
    return xy_d;
  }
  // Fisheye: (xd, yd) = s(u) (x, y), J = s I + 2 s'(u) (x, y)^T (x, y).
  const bool equisolid = info_.model == CameraModel::kEquisolid;
  const double s = equisolid ? EquisolidScale(d, u) : EquidistantScale(d, u);
  if (J == nullptr) return s * xy;
  double ds_du = 0.0;
  if (u < kEquidistantSeriesR2) {
    ds_du = equisolid ? (d[0] - 3.0 / 8.0) + 2.0 * u * (d[1] - 25.0 / 24.0 * d[0] + 31.0 / 128.0)
                      : (d[0] - 1.0 / 3.0) + 2.0 * u * (d[1] - d[0] + 0.2);
  } else {
    double rho_slope = 0.0;
    FisheyeRho(info_.model, info_.distortion, std::atan(std::sqrt(u)), &rho_slope);
    // ds/dr = (rho'(theta) / (1 + u) - s) / r,  ds/du = ds/dr / (2 r).
    ds_du = (rho_slope / (1.0 + u) - s) / (2.0 * u);
  }
  *J = s * Eigen::Matrix2d::Identity() + 2.0 * ds_du * xy * xy.transpose();
  return s * xy;
}

std::optional<Eigen::Vector2d> Camera::Project(const Eigen::Vector3d& p_camera,
                                               Eigen::Matrix<double, 2, 3>* J_px_p) const {
  if (!p_camera.allFinite() || !(p_camera.z() > kMinDepth)) return std::nullopt;
  const double inv_z = 1.0 / p_camera.z();
  const Eigen::Vector2d xy = p_camera.head<2>() * inv_z;
  if (!(xy.norm() <= max_radius_)) return std::nullopt;
  Eigen::Matrix2d J_d;
  const Eigen::Vector2d xy_d = Distort(xy, J_px_p != nullptr ? &J_d : nullptr);
  const auto& k = info_.intrinsics;
  if (J_px_p != nullptr) {
    Eigen::Matrix<double, 2, 3> J_xy_p;
    J_xy_p << inv_z, 0.0, -xy.x() * inv_z, 0.0, inv_z, -xy.y() * inv_z;
    *J_px_p = Eigen::Vector2d(k[0], k[1]).asDiagonal() * J_d * J_xy_p;
  }
  return Eigen::Vector2d(k[0] * xy_d.x() + k[2], k[1] * xy_d.y() + k[3]);
}

std::optional<Eigen::Vector3d> Camera::Unproject(const Eigen::Vector2d& px) const {
  if (!px.allFinite()) return std::nullopt;
  const auto& k = info_.intrinsics;
  const Eigen::Vector2d xy_d((px.x() - k[2]) / k[0], (px.y() - k[3]) / k[1]);
  const std::optional<Eigen::Vector2d> xy =
      info_.model == CameraModel::kPinholeRadtan ? UndistortRadtan(xy_d) : UndistortFisheye(xy_d);
  if (!xy) return std::nullopt;
  return Eigen::Vector3d(xy->x(), xy->y(), 1.0);
}

std::optional<Eigen::Vector2d> Camera::UndistortRadtan(const Eigen::Vector2d& xy_d) const {
  const std::vector<double>& d = info_.distortion;
  const auto radial_map = [&d](double r, double* slope) {
    *slope = RadtanRadialSlope(d, r);
    const double u = r * r;
    return r * (1.0 + u * (d[0] + u * (d[1] + u * d[4])));
  };
  // Start from the radial-only solution, bracketed inside the valid field of view.
  const double r_d = xy_d.norm();
  double hi = max_radius_, slope = 0.0;
  if (std::isinf(hi)) {
    for (hi = 1.0; radial_map(hi, &slope) < r_d && hi < 1e6; hi *= 2.0) {
    }
  }
  // Past the radial peak no radius fits without tangential terms; start at the peak and let
  // the full model below decide (tangential terms move the fold slightly).
  std::optional<double> r = hi;
  if (radial_map(hi, &slope) > r_d) r = SolveIncreasing(radial_map, r_d, 0.0, hi);
  if (!r) return std::nullopt;
  Eigen::Vector2d xy = r_d > 0.0 ? Eigen::Vector2d(xy_d * (*r / r_d)) : Eigen::Vector2d::Zero();
  // Newton on the full model, tangential terms included.
  Eigen::Matrix2d J;
  Eigen::Vector2d e = Distort(xy, &J) - xy_d;
  for (int i = 0; i < 30 && e.norm() > 1e-16 * std::max(1.0, r_d); ++i) {
    if (!(J.determinant() > 0.0)) return std::nullopt;
    xy -= J.inverse() * e;  // 2x2: the closed-form inverse is exact enough
    e = Distort(xy, &J) - xy_d;
  }
  if (!(e.norm() <= 1e-12 * std::max(1.0, r_d)) || !(xy.norm() <= max_radius_)) return std::nullopt;
  return xy;
}

std::optional<Eigen::Vector2d> Camera::UndistortFisheye(const Eigen::Vector2d& xy_d) const {
  const std::vector<double>& d = info_.distortion;
  const CameraModel model = info_.model;
  const double theta_d = xy_d.norm();
  if (theta_d == 0.0) return Eigen::Vector2d::Zero();
  const double theta_max = std::atan(max_radius_);
  const auto theta_map = [&d, model](double theta, double* slope) {
    return FisheyeRho(model, d, theta, slope);
  };
  if (FisheyeRho(model, d, theta_max) < theta_d) return std::nullopt;
  const std::optional<double> theta = SolveIncreasing(theta_map, theta_d, 0.0, theta_max);
  if (!theta) return std::nullopt;
  const Eigen::Vector2d xy = xy_d * (std::tan(*theta) / theta_d);
  if (!((Distort(xy) - xy_d).norm() <= 1e-12 * std::max(1.0, theta_d))) return std::nullopt;
  return xy;
}

}  // namespace waymark
