// Shared helpers of the factor tests: random transforms, two real calibrations, a viewing
// geometry with every corner in front of the camera, and a GradientChecker run under the
// manifolds the solver uses.
#pragma once

#include <ceres/cost_function.h>
#include <ceres/gradient_checker.h>
#include <ceres/manifold.h>
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <array>
#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "factors/pose_block.h"
#include "geometry/camera.h"
#include "geometry/pose.h"
#include "geometry/types.h"
#include "tests/test_cameras.h"

namespace waymark::testing {

inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

inline Eigen::Vector3d RandomVector(std::mt19937& rng, double scale) {
  std::uniform_real_distribution<double> u(-scale, scale);
  return Eigen::Vector3d(u(rng), u(rng), u(rng));
}

inline Eigen::Quaterniond RandomRotation(std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  return Eigen::Quaterniond(n(rng), n(rng), n(rng), n(rng)).normalized();
}

inline SE3d RandomSE3(std::mt19937& rng, double translation_scale_m) {
  return SE3d(RandomRotation(rng), RandomVector(rng, translation_scale_m));
}

// R_robot_camera of a camera looking along robot +x (camera z = robot x, camera x = robot -y,
// camera y = robot -z), tilted up by tilt_rad about the camera's x axis.
inline Eigen::Quaterniond ForwardCameraRotation(double tilt_rad) {
  Eigen::Matrix3d R_robot_camera;
  R_robot_camera << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  return Eigen::Quaterniond(R_robot_camera * Eigen::AngleAxisd(tilt_rad, Eigen::Vector3d::UnitX()));
}

// tagslam-test16 cam0 (radtan) and tagslam-test22 cam0 (equidistant), as typed into
// tests/test_cameras.h; mounted looking forward at 0.3 m height, tilted up 10 degrees.
inline CameraInfo TestCamera(CameraModel model) {
  CameraInfo info = model == CameraModel::kPinholeRadtan ? TagslamRadtanInfo() : TagslamFisheyeInfo();
  info.T_robot_camera = SE3d(ForwardCameraRotation(10.0 * M_PI / 180.0), Eigen::Vector3d(0.1, 0.05, 0.3));
  return info;
}

// Pixels of the four corners of a marker seen at T_camera_marker; false if one is behind.
inline bool ProjectCorners(const CameraInfo& camera, const SE3d& T_camera_marker, double size_m,
                           std::array<Eigen::Vector2d, 4>* corners_px) {
  double distortion[5] = {0, 0, 0, 0, 0};
  for (size_t i = 0; i < camera.distortion.size(); ++i) distortion[i] = camera.distortion[i];
  const std::array<Eigen::Vector3d, 4> corners_marker = MarkerCorners(size_m);
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector3d corner_camera = T_camera_marker * corners_marker[i];
    if (!ProjectPoint<double>(camera.model, camera.intrinsics.data(), distortion, corner_camera.data(),
                              (*corners_px)[i].data())) {
      return false;
    }
  }
  return true;
}

// A marker in front of the camera: 0.5-3 m away, within ~0.3 rad of the optical axis, facing the
// camera within ~0.6 rad.
inline SE3d RandomVisibleMarker(std::mt19937& rng) {
  std::uniform_real_distribution<double> depth(0.5, 3.0);
  const Eigen::Vector3d p_camera =
      Eigen::Vector3d(RandomVector(rng, 0.3).head<2>().homogeneous()) * depth(rng);
  // Facing the camera: marker z towards -camera z, then a random tilt.
  const Eigen::Quaterniond facing(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()));
  return SE3d(facing * ExpSO3(RandomVector(rng, 0.35)), p_camera);
}

// Runs ceres::GradientChecker with `manifolds` (nullptr = Euclidean) at `parameters`.
inline void ExpectGradientsMatch(const ceres::CostFunction& cost,
                                 const std::vector<const ceres::Manifold*>& manifolds,
                                 const std::vector<const double*>& parameters, double relative_precision,
                                 const std::string& what) {
  // Ridders' first step is 2^5 times the relative step (0.32 |x| by default): large enough to push
  // a corner behind the camera, where the reprojection factors return false. 1e-4 keeps it small.
  ceres::NumericDiffOptions options;
  options.ridders_relative_initial_step_size = 1e-4;
  const ceres::GradientChecker checker(&cost, &manifolds, options);
  ceres::GradientChecker::ProbeResults results;
  EXPECT_TRUE(checker.Probe(parameters.data(), relative_precision, &results))
      << what << ": max relative error " << results.maximum_relative_error << "\n"
      << results.error_log;
}

}  // namespace waymark::testing
