// Full SE(3) pose prior, e.g. an anchor marker from markers.json held softly instead of fixed.
//
//   delta = BoxMinus(P, T) = [Log(q_P^-1 q), R_P^T (t - t_P)]        (geometry/pose.h)
//   r     = S delta,   S = C^-1 with Sigma = C C^T                   (6 residuals, order [r, t])
//
// P = T_world_x prior (x: the marker or robot frame), T = the block's T_world_x. Noise model:
// T = P * Exp(delta), delta ~ N(0, Sigma): the right perturbation of map.json's `covariance`, so a
// map marker's covariance can be used as is.
// Parameter block (factors/pose_block.h, manifold SE3Manifold):
//   T_world_x [qx qy qz qw tx ty tz]
// Always returns true.
#pragma once

#include <ceres/autodiff_cost_function.h>

#include <Eigen/Core>

#include "factors/pose_block.h"
#include "factors/sqrt_information.h"
#include "geometry/pose.h"

namespace waymark {

class PosePriorSE3Factor {
 public:
  // Throws std::invalid_argument if `covariance` is not finite, symmetric and positive definite.
  PosePriorSE3Factor(const SE3d& T_world_x_prior, const Matrix6d& covariance)
      : T_world_x_prior_(T_world_x_prior),
        sqrt_information_(SqrtInformation<6>(covariance, "SE(3) pose prior")) {}

  template <typename T>
  bool operator()(const T* const T_world_x, T* residuals) const {
    const Eigen::Matrix<T, 6, 1> delta =
        BoxMinusT(SE3TFromSE3<T>(T_world_x_prior_), SE3TFromBlock(T_world_x));
    Eigen::Map<Eigen::Matrix<T, 6, 1>> whitened(residuals);
    whitened = sqrt_information_.template cast<T>() * delta;
    return true;
  }

  static ceres::CostFunction* Create(const SE3d& T_world_x_prior, const Matrix6d& covariance) {
    return new ceres::AutoDiffCostFunction<PosePriorSE3Factor, 6, kSE3BlockSize>(
        new PosePriorSE3Factor(T_world_x_prior, covariance));
  }

 private:
  const SE3d T_world_x_prior_;
  const Matrix6d sqrt_information_;
};

}  // namespace waymark
