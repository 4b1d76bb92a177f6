// Helpers that put a survey's observations into a Ceres problem, shared by the frame
// initializer (mapping/initializer.h) and the global optimization (mapping/map_builder.h).
//
// Robot blocks hold T_world_robot: planar surveys use the SE(2) block [x y theta] (the first
// three doubles of a RobotBlock), free surveys the SE(3) block [qx qy qz qw tx ty tz]
// (factors/pose_block.h). Marker blocks hold T_world_marker as SE(3) blocks.
#pragma once

#include <ceres/loss_function.h>
#include <ceres/problem.h>

#include <array>

#include "factors/extrinsic_marker_reprojection_factor.h"
#include "factors/marker_reprojection_factor.h"
#include "factors/planar_marker_reprojection_factor.h"
#include "factors/pose_block.h"
#include "geometry/types.h"

namespace waymark {

using PoseBlock = std::array<double, kSE3BlockSize>;

// Corner noise of a camera: its pixel_sigma, else 1 px.
inline double CornerSigmaPx(const CameraInfo& camera) { return camera.pixel_sigma.value_or(1.0); }

inline void RobotToBlock(MotionModel motion, const SE3d& T_world_robot, PoseBlock* block) {
  if (motion == MotionModel::kPlanar) {
    SE2ToBlock(SE2d::FromSE3(T_world_robot), block->data());
  } else {
    SE3ToBlock(T_world_robot, block->data());
  }
}

inline SE3d RobotFromBlock(MotionModel motion, const PoseBlock& block) {
  return motion == MotionModel::kPlanar ? SE2FromBlock(block.data()).ToSE3() : SE3FromBlock(block.data());
}

// Declares a robot block (with the SE(3) manifold for free surveys).
inline void AddRobotBlock(ceres::Problem* problem, MotionModel motion, PoseBlock* block) {
  if (motion == MotionModel::kPlanar) {
    problem->AddParameterBlock(block->data(), kSE2BlockSize);
  } else {
    problem->AddParameterBlock(block->data(), kSE3BlockSize, new SE3Manifold);
  }
}

inline void AddMarkerBlock(ceres::Problem* problem, PoseBlock* block) {
  problem->AddParameterBlock(block->data(), kSE3BlockSize, new SE3Manifold);
}

// The 8 reprojection residuals of one code in one image (blocks must be declared first).
inline ceres::ResidualBlockId AddCornerResidual(ceres::Problem* problem, MotionModel motion,
                                                const CameraInfo& camera, double size_m,
                                                const std::array<Eigen::Vector2d, 4>& corners_px,
                                                PoseBlock* robot_block, PoseBlock* marker_block,
                                                ceres::LossFunction* loss) {
  const double sigma_px = CornerSigmaPx(camera);
  ceres::CostFunction* cost =
      motion == MotionModel::kPlanar
          ? PlanarMarkerReprojectionFactor::Create(camera, size_m, corners_px, sigma_px)
          : MarkerReprojectionFactor::Create(camera, size_m, corners_px, sigma_px);
  return problem->AddResidualBlock(cost, loss, robot_block->data(), marker_block->data());
}

// The same with the camera mount as a parameter block (T_robot_camera, SE(3), declared first):
// the map build's extrinsic self-calibration (camera YAML T_robot_camera_sigma).
inline ceres::ResidualBlockId AddCornerResidualWithMount(ceres::Problem* problem, MotionModel motion,
                                                         const CameraInfo& camera, double size_m,
                                                         const std::array<Eigen::Vector2d, 4>& corners_px,
                                                         PoseBlock* robot_block, PoseBlock* mount_block,
                                                         PoseBlock* marker_block, ceres::LossFunction* loss) {
  const double sigma_px = CornerSigmaPx(camera);
  ceres::CostFunction* cost =
      motion == MotionModel::kPlanar
          ? PlanarExtrinsicMarkerReprojectionFactor::Create(camera, size_m, corners_px, sigma_px)
          : ExtrinsicMarkerReprojectionFactor::Create(camera, size_m, corners_px, sigma_px);
  return problem->AddResidualBlock(cost, loss, robot_block->data(), mount_block->data(),
                                   marker_block->data());
}

}  // namespace waymark
