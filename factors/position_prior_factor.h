// Position-only prior on an SE(3) pose block: a code whose payload prints its world
// coordinates (dataset.yaml `payload`, groups x, y and optionally z).
//
//   r = S (t_world_x[0 .. kDim-1] - p_world),   S = C^-1 with Sigma = C C^T    (kDim residuals)
//
// kDim = 2 constrains x and y only (payload without z: the height stays free), kDim = 3 adds z.
// t_world_x is the translation of the block's T_world_x (x: the marker frame, whose origin is the
// symbol centre); the rotation part of the block is untouched, so its Jacobian there is zero.
// Parameter block (factors/pose_block.h, manifold SE3Manifold):
//   T_world_x [qx qy qz qw tx ty tz]
// Always returns true.
#pragma once

#include <ceres/autodiff_cost_function.h>

#include <Eigen/Core>
#include <stdexcept>

#include "factors/pose_block.h"
#include "factors/sqrt_information.h"

namespace waymark {

template <int kDim>
class PositionPriorFactor {
  static_assert(kDim == 2 || kDim == 3, "a position prior constrains x, y or x, y, z");

 public:
  using VectorD = Eigen::Matrix<double, kDim, 1>;
  using MatrixD = Eigen::Matrix<double, kDim, kDim>;

  // Throws std::invalid_argument if p_world is not finite or `covariance` is not finite,
  // symmetric and positive definite.
  PositionPriorFactor(const VectorD& p_world, const MatrixD& covariance)
      : p_world_(CheckedPosition(p_world)),
        sqrt_information_(SqrtInformation<kDim>(covariance, "position prior")) {}

  template <typename T>
  bool operator()(const T* const T_world_x, T* residuals) const {
    const Eigen::Map<const Eigen::Matrix<T, kDim, 1>> t_world_x(T_world_x + 4);
    Eigen::Map<Eigen::Matrix<T, kDim, 1>> whitened(residuals);
    whitened = sqrt_information_.template cast<T>() * (t_world_x - p_world_.template cast<T>());
    return true;
  }

  static ceres::CostFunction* Create(const VectorD& p_world, const MatrixD& covariance) {
    return new ceres::AutoDiffCostFunction<PositionPriorFactor, kDim, kSE3BlockSize>(
        new PositionPriorFactor(p_world, covariance));
  }
  // Isotropic convenience: Sigma = sigma_m^2 I.
  static ceres::CostFunction* Create(const VectorD& p_world, double sigma_m) {
    InverseSigma(sigma_m, "position prior");  // validates sigma_m
    return Create(p_world, MatrixD(MatrixD::Identity() * (sigma_m * sigma_m)));
  }

 private:
  static VectorD CheckedPosition(const VectorD& p_world) {
    if (!p_world.allFinite()) throw std::invalid_argument("position prior: non-finite position");
    return p_world;
  }

  const VectorD p_world_;
  const MatrixD sqrt_information_;
};

using PositionPriorXYFactor = PositionPriorFactor<2>;
using PositionPriorXYZFactor = PositionPriorFactor<3>;

}  // namespace waymark
