// Odometry between-factor in SE(3), for free (6-DoF) datasets.
//
//   T_a_b   = T_world_robot_a^-1 * T_world_robot_b            (the estimated increment)
//   delta   = BoxMinus(M, T_a_b) = [Log(q_M^-1 q_a_b), R_M^T (t_a_b - t_M)]   (geometry/pose.h)
//   r       = S delta,   S = C^-1 with Sigma = C C^T           (6 residuals, order [r, t])
//
// M = T_odom_robot_a^-1 * T_odom_robot_b is the measured increment (only increments of the
// drifting odometry are trusted). Noise model: T_a_b = M * Exp(delta), delta ~ N(0, Sigma), i.e. the
// right perturbation of geometry.h in the frame of robot b as odometry predicted it; Sigma is
// usually OdometryCovarianceSE3 (factors/odometry_covariance.h).
// Parameter blocks (factors/pose_block.h, manifold SE3Manifold for both):
//   T_world_robot_a [qx qy qz qw tx ty tz]
//   T_world_robot_b [qx qy qz qw tx ty tz]
// Always returns true.
#pragma once

#include <ceres/autodiff_cost_function.h>

#include <Eigen/Core>

#include "factors/pose_block.h"
#include "factors/sqrt_information.h"
#include "geometry/pose.h"

namespace waymark {

class OdometrySE3Factor {
 public:
  // Throws std::invalid_argument if `covariance` is not finite, symmetric and positive definite.
  OdometrySE3Factor(const SE3d& T_a_b_measured, const Matrix6d& covariance)
      : T_a_b_measured_(T_a_b_measured),
        sqrt_information_(SqrtInformation<6>(covariance, "odometry SE(3) factor")) {}

  template <typename T>
  bool operator()(const T* const T_world_robot_a, const T* const T_world_robot_b, T* residuals) const {
    const SE3T<T> T_a_b = SE3TFromBlock(T_world_robot_a).inverse() * SE3TFromBlock(T_world_robot_b);
    const Eigen::Matrix<T, 6, 1> delta = BoxMinusT(SE3TFromSE3<T>(T_a_b_measured_), T_a_b);
    Eigen::Map<Eigen::Matrix<T, 6, 1>> whitened(residuals);
    whitened = sqrt_information_.template cast<T>() * delta;
    return true;
  }

  static ceres::CostFunction* Create(const SE3d& T_a_b_measured, const Matrix6d& covariance) {
    return new ceres::AutoDiffCostFunction<OdometrySE3Factor, 6, kSE3BlockSize, kSE3BlockSize>(
        new OdometrySE3Factor(T_a_b_measured, covariance));
  }

 private:
  const SE3d T_a_b_measured_;
  const Matrix6d sqrt_information_;
};

}  // namespace waymark
