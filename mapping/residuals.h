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

// Which parameter blocks a code's corner residuals act on, in this order.
enum class CornerBlocks {
  kRobotMarker,             // [robot, marker]
  kRobotMountMarker,        // [robot, mount, marker]: the camera mount estimated (T_robot_camera_sigma)
  kRobotMountWiggleMarker,  // [robot, mount, wiggle, marker]: and the frame's deviation off it
};

// The 8 reprojection residuals of one code in one image, at the camera's corner sigma.
inline ceres::CostFunction* CornerCost(MotionModel motion, const CameraInfo& camera, double size_m,
                                       const std::array<Eigen::Vector2d, 4>& corners_px,
                                       CornerBlocks blocks) {
  const double sigma_px = CornerSigmaPx(camera);
  const bool planar = motion == MotionModel::kPlanar;
  switch (blocks) {
    case CornerBlocks::kRobotMarker:
      return planar ? PlanarMarkerReprojectionFactor::Create(camera, size_m, corners_px, sigma_px)
                    : MarkerReprojectionFactor::Create(camera, size_m, corners_px, sigma_px);
    case CornerBlocks::kRobotMountMarker:
      return planar ? PlanarExtrinsicMarkerReprojectionFactor::Create(camera, size_m, corners_px, sigma_px)
                    : ExtrinsicMarkerReprojectionFactor::Create(camera, size_m, corners_px, sigma_px);
    case CornerBlocks::kRobotMountWiggleMarker:
      return planar ? WiggleMarkerReprojectionFactor<true>::Create(camera, size_m, corners_px, sigma_px)
                    : WiggleMarkerReprojectionFactor<false>::Create(camera, size_m, corners_px, sigma_px);
  }
  return nullptr;
}

}  // namespace waymark
