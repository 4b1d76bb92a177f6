// Marker-corner reprojection for a planar robot: the robot pose is SE(2), lifted to 3-D at z = 0,
// and the fixed camera mount T_robot_camera keeps the camera's height and tilt.
//
//   T_world_robot   = (Rz(theta), [x, y, 0])
//   T_camera_marker = T_robot_camera^-1 * T_world_robot^-1 * T_world_marker
//   r = (1 / sigma_px) [ project(K, d, T_camera_marker * c_i) - z_i ]_{i = 0..3}      (8 residuals)
//
// Frames and symbols as in factors/marker_reprojection_factor.h.
// Parameter blocks (factors/pose_block.h):
//   T_world_robot  [x y theta]                  (Euclidean; theta enters only through cos/sin)
//   T_world_marker [qx qy qz qw tx ty tz]       (SE3Manifold)
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

class PlanarMarkerReprojectionFactor {
 public:
  // Throws std::invalid_argument on bad input (see CornerObservation).
  PlanarMarkerReprojectionFactor(const CameraInfo& camera, double size_m,
                                 const std::array<Eigen::Vector2d, 4>& corners_px, double sigma_px)
      : observation_(camera, size_m, corners_px, sigma_px),
        T_camera_robot_(camera.T_robot_camera.inverse()) {}

  template <typename T>
  bool operator()(const T* const T_world_robot, const T* const T_world_marker, T* residuals) const {
    const SE3T<T> T_camera_world =
        SE3TFromSE3<T>(T_camera_robot_) * SE3TFromSE2Block(T_world_robot).inverse();
    return observation_.Residuals(T_camera_world * SE3TFromBlock(T_world_marker), residuals);
  }

  static ceres::CostFunction* Create(const CameraInfo& camera, double size_m,
                                     const std::array<Eigen::Vector2d, 4>& corners_px, double sigma_px) {
    return new ceres::AutoDiffCostFunction<PlanarMarkerReprojectionFactor, 8, kSE2BlockSize, kSE3BlockSize>(
        new PlanarMarkerReprojectionFactor(camera, size_m, corners_px, sigma_px));
  }

 private:
  const CornerObservation observation_;
  const SE3d T_camera_robot_;
};

}  // namespace waymark
