// Covariance of an odometry increment from dataset.yaml's odometry_sigma, for the odometry
// between-factors (factors/odometry_se2_factor.h, factors/odometry_se3_factor.h).
//
// The noise grows with the motion of the increment T_a_b = T_odom_robot_a^-1 T_odom_robot_b:
//   d     = |t_a_b|            (metres; the chord, close to the path length for short increments)
//   angle = |Log(q_a_b)|       (radians; |theta| in SE(2))
//   sigma_t = sqrt((trans_per_m * d)^2 + floor_m^2)          on every translation axis
//   sigma_r = sqrt((rot_per_rad * angle)^2 + floor_rad^2)    on every rotation axis
//   SE(3): Sigma = diag(sigma_r^2 I3, sigma_t^2 I3)   (tangent order [rx ry rz tx ty tz])
//   SE(2): Sigma = diag(sigma_t^2, sigma_t^2, sigma_r^2) (order [x y theta])
// The floor keeps a standstill (d = 0, angle = 0) from being infinitely certain, which would make
// the information matrix singular and pin the two poses together. It is added in quadrature, so it
// only matters when the motion term is below it. The defaults, 0.1 mm and 0.1 mrad per increment,
// are below the motion term of any moving increment of the datasets (e.g. 2 % of 2.5 cm at 20 Hz
// is 0.5 mm) and still bound a long standstill (100 increments accumulate 1 mm).
// Note: independent increments with sigma proportional to distance make the accumulated drift
// depend on the odometry rate (N steps over D metres give trans_per_m * D / sqrt(N)); the datasets
// state odometry_sigma per increment of their own odometry stream.
//
// Random-walk terms (OdometryRandomWalk, geometry/odometry_noise.h): the relative motion between two instants
// a, b that are T = t_b - t_a seconds and L metres of path apart (L summed over the samples, not the chord)
// gets, on every axis,
//   translation variance  trans_per_sqrt_s^2 T + trans_per_sqrt_m^2 L
//   rotation variance     rot_per_sqrt_s^2 T + rot_per_sqrt_m^2 L
// These add over any split of [a, b] (variance linear in T and L), so the map's frame-to-frame
// links (mapping/survey.h) and the localizer's per-sample predictions (online/motion_model.h)
// state the same drift whatever the odometry rate or the frame rate.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <stdexcept>
#include <string>

#include "factors/sqrt_information.h"
#include "geometry/odometry_noise.h"
#include "geometry/pose.h"
#include "geometry/types.h"

namespace waymark {

struct OdometryNoiseFloor {
  double sigma_m = 1e-4;    // translation sigma of a standstill increment
  double sigma_rad = 1e-4;  // rotation sigma of an increment without rotation
};

namespace odometry_covariance_internal {

inline void Check(const OdometrySigma& sigma, const OdometryNoiseFloor& floor) {
  const auto non_negative = [](double v) { return std::isfinite(v) && v >= 0.0; };
  const auto positive = [](double v) { return std::isfinite(v) && v > 0.0; };
  if (!non_negative(sigma.trans_per_m) || !non_negative(sigma.rot_per_rad)) {
    throw std::invalid_argument("odometry_sigma: trans_per_m and rot_per_rad must be finite and >= 0, got " +
                                FormatDouble(sigma.trans_per_m) + " and " + FormatDouble(sigma.rot_per_rad));
  }
  CheckRandomWalkTerms(sigma);
  if (!positive(floor.sigma_m) || !positive(floor.sigma_rad)) {
    throw std::invalid_argument("odometry noise floor: sigma_m and sigma_rad must be finite and > 0");
  }
}

}  // namespace odometry_covariance_internal

// Covariance of an SE(3) increment, right perturbation, order [rx ry rz tx ty tz].
// Throws std::invalid_argument on a negative or non-finite sigma or a non-positive floor.
inline Matrix6d OdometryCovarianceSE3(const OdometrySigma& sigma, const SE3d& T_a_b,
                                      const OdometryNoiseFloor& floor = {}) {
  odometry_covariance_internal::Check(sigma, floor);
  const double sigma_t = std::hypot(sigma.trans_per_m * T_a_b.translation().norm(), floor.sigma_m);
  const double sigma_r = std::hypot(sigma.rot_per_rad * LogSO3(T_a_b.rotation()).norm(), floor.sigma_rad);
  Vector6d variances;
  variances << Eigen::Vector3d::Constant(sigma_r * sigma_r), Eigen::Vector3d::Constant(sigma_t * sigma_t);
  return variances.asDiagonal();
}

// Covariance of an SE(2) increment, order [x y theta].
// Throws std::invalid_argument on a negative or non-finite sigma or a non-positive floor.
inline Eigen::Matrix3d OdometryCovarianceSE2(const OdometrySigma& sigma, const SE2d& T_a_b,
                                             const OdometryNoiseFloor& floor = {}) {
  odometry_covariance_internal::Check(sigma, floor);
  const double sigma_t = std::hypot(sigma.trans_per_m * T_a_b.translation().norm(), floor.sigma_m);
  const double sigma_r = std::hypot(sigma.rot_per_rad * std::abs(T_a_b.theta()), floor.sigma_rad);
  return Eigen::Vector3d(sigma_t * sigma_t, sigma_t * sigma_t, sigma_r * sigma_r).asDiagonal();
}

}  // namespace waymark
