// Odometry between-factor in SE(2), for planar datasets.
//
//   T_a_b = T_world_robot_a^-1 * T_world_robot_b = (R(th_b - th_a), R(th_a)^T (t_b - t_a))
//   delta = BoxMinus(M, T_a_b) = [R(th_M)^T (t_a_b - t_M), wrap(th_b - th_a - th_M)]  (geometry/pose.h)
//   r     = S delta,   S = C^-1 with Sigma = C C^T        (3 residuals, order [x, y, theta])
//
// M = (t_M, th_M) is the measured increment T_odom_robot_a^-1 * T_odom_robot_b projected to the
// plane (SE2d::FromSE3). Noise model: T_a_b = M * Exp(delta), delta ~ N(0, Sigma); Sigma is usually
// OdometryCovarianceSE2 (factors/odometry_covariance.h). theta is wrapped, so blocks whose angles
// differ by 2 pi give the same residual.
// Parameter blocks (factors/pose_block.h, Euclidean):
//   T_world_robot_a [x y theta]
//   T_world_robot_b [x y theta]
// Always returns true.
#pragma once

#include <ceres/autodiff_cost_function.h>

#include <Eigen/Core>
#include <cmath>

#include "factors/pose_block.h"
#include "factors/sqrt_information.h"
#include "geometry/pose.h"

namespace waymark {

class OdometrySE2Factor {
 public:
  // Throws std::invalid_argument if `covariance` is not finite, symmetric and positive definite.
  OdometrySE2Factor(const SE2d& T_a_b_measured, const Eigen::Matrix3d& covariance)
      : T_a_b_measured_(T_a_b_measured),
        sqrt_information_(SqrtInformation<3>(covariance, "odometry SE(2) factor")) {}

  template <typename T>
  bool operator()(const T* const T_world_robot_a, const T* const T_world_robot_b, T* residuals) const {
    using std::cos;
    using std::sin;
    // Translation of the increment in frame a, then in frame M.
    const T dx_world = T_world_robot_b[0] - T_world_robot_a[0];
    const T dy_world = T_world_robot_b[1] - T_world_robot_a[1];
    const T cos_a = cos(T_world_robot_a[2]), sin_a = sin(T_world_robot_a[2]);
    const T dx_a = cos_a * dx_world + sin_a * dy_world - T(T_a_b_measured_.x());
    const T dy_a = -sin_a * dx_world + cos_a * dy_world - T(T_a_b_measured_.y());
    const double cos_m = std::cos(T_a_b_measured_.theta()), sin_m = std::sin(T_a_b_measured_.theta());
    Eigen::Matrix<T, 3, 1> delta;
    delta << T(cos_m) * dx_a + T(sin_m) * dy_a, T(-sin_m) * dx_a + T(cos_m) * dy_a,
        WrapAngleT(T_world_robot_b[2] - T_world_robot_a[2] - T(T_a_b_measured_.theta()));
    Eigen::Map<Eigen::Matrix<T, 3, 1>> whitened(residuals);
    whitened = sqrt_information_.template cast<T>() * delta;
    return true;
  }

  static ceres::CostFunction* Create(const SE2d& T_a_b_measured, const Eigen::Matrix3d& covariance) {
    return new ceres::AutoDiffCostFunction<OdometrySE2Factor, 3, kSE2BlockSize, kSE2BlockSize>(
        new OdometrySE2Factor(T_a_b_measured, covariance));
  }

 private:
  const SE2d T_a_b_measured_;
  const Eigen::Matrix3d sqrt_information_;
};

}  // namespace waymark
