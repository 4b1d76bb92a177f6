// SE(2) pose prior on a planar robot (e.g. the start pose that fixes the gauge of a survey
// without anchors).
//
//   delta = BoxMinus(P, T) = [R(th_P)^T (t - t_P), wrap(th - th_P)]   (geometry/pose.h)
//   r     = S delta,   S = C^-1 with Sigma = C C^T                    (3 residuals, order [x y theta])
//
// P = T_world_robot prior, T = the block's T_world_robot. Noise model: T = P * Exp(delta),
// delta ~ N(0, Sigma).
// Parameter block (factors/pose_block.h, Euclidean):
//   T_world_robot [x y theta]
// Always returns true.
#pragma once

#include <ceres/autodiff_cost_function.h>

#include <Eigen/Core>
#include <cmath>

#include "factors/pose_block.h"
#include "factors/sqrt_information.h"
#include "geometry/pose.h"

namespace waymark {

class PosePriorSE2Factor {
 public:
  // Throws std::invalid_argument if `covariance` is not finite, symmetric and positive definite.
  PosePriorSE2Factor(const SE2d& T_world_robot_prior, const Eigen::Matrix3d& covariance)
      : T_world_robot_prior_(T_world_robot_prior),
        sqrt_information_(SqrtInformation<3>(covariance, "SE(2) pose prior")) {}

  template <typename T>
  bool operator()(const T* const T_world_robot, T* residuals) const {
    const double cos_p = std::cos(T_world_robot_prior_.theta()),
                 sin_p = std::sin(T_world_robot_prior_.theta());
    const T dx_world = T_world_robot[0] - T(T_world_robot_prior_.x());
    const T dy_world = T_world_robot[1] - T(T_world_robot_prior_.y());
    Eigen::Matrix<T, 3, 1> delta;
    delta << T(cos_p) * dx_world + T(sin_p) * dy_world, T(-sin_p) * dx_world + T(cos_p) * dy_world,
        WrapAngleT(T_world_robot[2] - T(T_world_robot_prior_.theta()));
    Eigen::Map<Eigen::Matrix<T, 3, 1>> whitened(residuals);
    whitened = sqrt_information_.template cast<T>() * delta;
    return true;
  }

  static ceres::CostFunction* Create(const SE2d& T_world_robot_prior, const Eigen::Matrix3d& covariance) {
    return new ceres::AutoDiffCostFunction<PosePriorSE2Factor, 3, kSE2BlockSize>(
        new PosePriorSE2Factor(T_world_robot_prior, covariance));
  }

 private:
  const SE2d T_world_robot_prior_;
  const Eigen::Matrix3d sqrt_information_;
};

}  // namespace waymark
