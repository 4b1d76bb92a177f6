// Marker-corner reprojection for a free (6-DoF) robot with a fixed, calibrated camera mount.
//
//   T_camera_marker = T_robot_camera^-1 * T_world_robot^-1 * T_world_marker
//   r = (1 / sigma_px) [ project(K, d, T_camera_marker * c_i) - z_i ]_{i = 0..3}      (8 residuals)
//
// Frames: world (z up), robot (x forward, z up), camera (OpenCV: x right, y down, z forward),
// marker (origin at the symbol centre, z out of the face). c_i are the corners in the marker frame,
// z_i the detected corners in pixels, both in docs/design.md order; residual layout [u0 v0 ... u3 v3].
// T_robot_camera comes from the camera's yaml and is held constant here.
//
// Parameter blocks (factors/pose_block.h, manifold SE3Manifold for both):
//   T_world_robot  [qx qy qz qw tx ty tz]
//   T_world_marker [qx qy qz qw tx ty tz]
// Near and behind the camera (depth < 10 cm): a finite penalty that grows as the corner moves
// behind, continuous with the pinhole residual; false only for a non-finite depth (see
// factors/corner_observation.h for why).
#pragma once

#include <ceres/autodiff_cost_function.h>

#include <Eigen/Core>
#include <array>

#include "factors/corner_observation.h"
#include "factors/pose_block.h"
#include "geometry/types.h"

namespace waymark {

class MarkerReprojectionFactor {
 public:
  // Throws std::invalid_argument on bad input (see CornerObservation).
  MarkerReprojectionFactor(const CameraInfo& camera, double size_m,
                           const std::array<Eigen::Vector2d, 4>& corners_px, double sigma_px)
      : observation_(camera, size_m, corners_px, sigma_px),
        T_camera_robot_(camera.T_robot_camera.inverse()) {}

  template <typename T>
  bool operator()(const T* const T_world_robot, const T* const T_world_marker, T* residuals) const {
    const SE3T<T> T_camera_world = SE3TFromSE3<T>(T_camera_robot_) * SE3TFromBlock(T_world_robot).inverse();
    return observation_.Residuals(T_camera_world * SE3TFromBlock(T_world_marker), residuals);
  }

  static ceres::CostFunction* Create(const CameraInfo& camera, double size_m,
                                     const std::array<Eigen::Vector2d, 4>& corners_px, double sigma_px) {
    return new ceres::AutoDiffCostFunction<MarkerReprojectionFactor, 8, kSE3BlockSize, kSE3BlockSize>(
        new MarkerReprojectionFactor(camera, size_m, corners_px, sigma_px));
  }

 private:
  const CornerObservation observation_;
  const SE3d T_camera_robot_;
};

}  // namespace waymark
