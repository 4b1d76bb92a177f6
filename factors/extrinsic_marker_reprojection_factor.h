// Marker-corner reprojection with the camera mount as a parameter block too, for calibrating
// T_robot_camera from a survey (the map build's extrinsic self-calibration, camera YAML
// `T_robot_camera_sigma`): ExtrinsicMarkerReprojectionFactor for a free robot (SE(3) robot
// pose), PlanarExtrinsicMarkerReprojectionFactor for a planar one (SE(2) robot pose lifted to
// z = 0, as in factors/planar_marker_reprojection_factor.h; the mount then carries the camera's
// height and tilt, all six of its degrees of freedom estimated).
//
//   T_camera_marker = T_robot_camera^-1 * T_world_robot^-1 * T_world_marker
//   r = (1 / sigma_px) [ project(K, d, T_camera_marker * c_i) - z_i ]_{i = 0..3}      (8 residuals)
//
// Frames and symbols as in factors/marker_reprojection_factor.h. The camera's own yaml
// T_robot_camera is ignored here: the block holds it (initialize the block from the yaml).
// Gauge: with the extrinsic free, robot poses and mount are only observable when the robot's
// poses are tied to something else (odometry factors, or several cameras); a single camera
// without odometry leaves T_world_robot * T_robot_camera as the only observable product, so the
// caller must hold one of them constant (SetParameterBlockConstant) or add odometry.
// Parameter blocks (factors/pose_block.h, manifold SE3Manifold for all three):
//   T_world_robot  [qx qy qz qw tx ty tz]   (planar: [x y theta], Euclidean)
//   T_robot_camera [qx qy qz qw tx ty tz]
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

// The robot's pose from its block: SE(3), or [x y theta] lifted to z = 0 when Planar.
template <bool Planar, typename T>
SE3T<T> SE3TFromRobotBlock(const T* block) {
  if constexpr (Planar) {
    return SE3TFromSE2Block(block);
  } else {
    return SE3TFromBlock(block);
  }
}

template <bool Planar>
class MountMarkerReprojectionFactor {
 public:
  // Throws std::invalid_argument on bad input (see CornerObservation).
  MountMarkerReprojectionFactor(const CameraInfo& camera, double size_m,
                                const std::array<Eigen::Vector2d, 4>& corners_px, double sigma_px)
      : observation_(camera, size_m, corners_px, sigma_px) {}

  template <typename T>
  bool operator()(const T* const T_world_robot, const T* const T_robot_camera, const T* const T_world_marker,
                  T* residuals) const {
    const SE3T<T> T_world_camera = SE3TFromRobotBlock<Planar>(T_world_robot) * SE3TFromBlock(T_robot_camera);
    return observation_.Residuals(T_world_camera.inverse() * SE3TFromBlock(T_world_marker), residuals);
  }

  static ceres::CostFunction* Create(const CameraInfo& camera, double size_m,
                                     const std::array<Eigen::Vector2d, 4>& corners_px, double sigma_px) {
    return new ceres::AutoDiffCostFunction < MountMarkerReprojectionFactor, 8,
           Planar ? kSE2BlockSize : kSE3BlockSize, kSE3BlockSize,
           kSE3BlockSize > (new MountMarkerReprojectionFactor(camera, size_m, corners_px, sigma_px));
  }

 private:
  const CornerObservation observation_;
};

using ExtrinsicMarkerReprojectionFactor = MountMarkerReprojectionFactor<false>;
using PlanarExtrinsicMarkerReprojectionFactor = MountMarkerReprojectionFactor<true>;

// The same with a per-frame deviation W of the camera off its mount (camera YAML
// `frame_wiggle_sigma`: cameras not synchronized with the rig's frame stamp, or a rig that
// flexes), one SE(3) block per frame and camera, held near identity by a prior:
//
//   T_world_camera = T_world_robot * T_robot_camera * W
//
// Blocks: T_world_robot (SE(3), or [x y theta] when Planar), T_robot_camera, W, T_world_marker.
template <bool Planar>
class WiggleMarkerReprojectionFactor {
 public:
  // Throws std::invalid_argument on bad input (see CornerObservation).
  WiggleMarkerReprojectionFactor(const CameraInfo& camera, double size_m,
                                 const std::array<Eigen::Vector2d, 4>& corners_px, double sigma_px)
      : observation_(camera, size_m, corners_px, sigma_px) {}

  template <typename T>
  bool operator()(const T* const T_world_robot, const T* const T_robot_camera, const T* const wiggle,
                  const T* const T_world_marker, T* residuals) const {
    const SE3T<T> T_world_camera =
        SE3TFromRobotBlock<Planar>(T_world_robot) * SE3TFromBlock(T_robot_camera) * SE3TFromBlock(wiggle);
    return observation_.Residuals(T_world_camera.inverse() * SE3TFromBlock(T_world_marker), residuals);
  }

  static ceres::CostFunction* Create(const CameraInfo& camera, double size_m,
                                     const std::array<Eigen::Vector2d, 4>& corners_px, double sigma_px) {
    return new ceres::AutoDiffCostFunction < WiggleMarkerReprojectionFactor, 8,
           Planar ? kSE2BlockSize : kSE3BlockSize, kSE3BlockSize, kSE3BlockSize,
           kSE3BlockSize > (new WiggleMarkerReprojectionFactor(camera, size_m, corners_px, sigma_px));
  }

 private:
  const CornerObservation observation_;
};

}  // namespace waymark
