// Yaw prior on an SE(3) pose block: the heading printed in a code's payload (`yaw_deg`).
//
//   yaw(T)  = atan2(R10, R00)          heading of the frame's x axis about world z (SE3d::yaw())
//   r       = wrap(yaw(T) - yaw_P) / sigma_rad
//           = atan2(R10 cos(yaw_P) - R00 sin(yaw_P), R00 cos(yaw_P) + R10 sin(yaw_P)) / sigma_rad
// (1 residual). The second form is the same angle, smooth everywhere except at +-pi.
// R = R(q) of the block's T_world_x, with R00 = 1 - 2(qy^2 + qz^2), R10 = 2(qx qy + qw qz).
// Undefined when the frame's x axis is vertical (R00 = R10 = 0): there, and within
// sqrt(R00^2 + R10^2) < 1e-6 of it, the factor returns false, so Ceres rejects a step that would
// tip the frame there (an initial value there is the caller's error).
// Parameter block (factors/pose_block.h, manifold SE3Manifold):
//   T_world_x [qx qy qz qw tx ty tz]
#pragma once

#include <ceres/autodiff_cost_function.h>

#include <cmath>
#include <stdexcept>
#include <string>

#include "factors/pose_block.h"
#include "factors/sqrt_information.h"

namespace waymark {

class YawPriorFactor {
 public:
  // Throws std::invalid_argument unless yaw_rad is finite and sigma_rad finite and > 0.
  YawPriorFactor(double yaw_rad, double sigma_rad)
      : cos_yaw_(std::cos(CheckedYaw(yaw_rad))),
        sin_yaw_(std::sin(yaw_rad)),
        inverse_sigma_rad_(InverseSigma(sigma_rad, "yaw prior")) {}

  template <typename T>
  bool operator()(const T* const T_world_x, T* residuals) const {
    using std::atan2;
    const T& qx = T_world_x[0];
    const T& qy = T_world_x[1];
    const T& qz = T_world_x[2];
    const T& qw = T_world_x[3];
    const T r00 = T(1) - T(2) * (qy * qy + qz * qz);
    const T r10 = T(2) * (qx * qy + qw * qz);
    if (r00 * r00 + r10 * r10 < T(1e-12)) return false;
    residuals[0] = atan2(r10 * T(cos_yaw_) - r00 * T(sin_yaw_), r00 * T(cos_yaw_) + r10 * T(sin_yaw_)) *
                   T(inverse_sigma_rad_);
    return true;
  }

  static ceres::CostFunction* Create(double yaw_rad, double sigma_rad) {
    return new ceres::AutoDiffCostFunction<YawPriorFactor, 1, kSE3BlockSize>(
        new YawPriorFactor(yaw_rad, sigma_rad));
  }

 private:
  static double CheckedYaw(double yaw_rad) {
    if (!std::isfinite(yaw_rad)) throw std::invalid_argument("yaw prior: non-finite yaw");
    return yaw_rad;
  }

  const double cos_yaw_;
  const double sin_yaw_;
  const double inverse_sigma_rad_;
};

}  // namespace waymark
