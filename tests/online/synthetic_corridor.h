// A synthetic planar robot for the online/ tests ([Bach]'s setting): a straight corridor
// with 10 cm codes on both walls every metre at camera height, a robot weaving down its
// middle with noisy wheel odometry at 20 Hz, and two side cameras (left, right) whose
// detected corners carry Gaussian pixel noise. Everything is drawn from one seeded engine.
//
// The single-image pose of each sighting comes from geometry/marker_pose (MakeCodeSighting).
#pragma once

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "geometry/camera.h"
#include "geometry/pose.h"
#include "geometry/types.h"
#include "online/code_sighting.h"
#include "online/localizer.h"
#include "online/motion_model.h"

namespace waymark::testing {

struct CorridorConfig {
  double length_m = 12.0;
  double half_width_m = 0.5;  // codes 0.5 m from the robot's centre line ([Bach]: 0.2-0.8 m)
  double code_spacing_m = 1.0;
  double code_size_m = 0.10;
  double camera_height_m = 0.3;
  double speed_mps = 0.5;
  double odometry_period_s = 0.05;  // [Bach]: T = 50 ms
  int frame_every = 2;              // a camera frame every 2nd odometry step (10 Hz)
  double pixel_sigma_px = 1.0;
  // White noise only (no systematic wheel error), so no heading random walk either.
  OdometryNoise odometry{{0.1, 0.1}, 1e-4, 2e-3, 0.0};
};

inline CameraInfo SideCamera(const std::string& name, bool left, double height_m) {
  CameraInfo info;
  info.name = name;
  info.model = CameraModel::kPinholeRadtan;
  info.width = 640;
  info.height = 480;
  info.intrinsics = {500.0, 500.0, 320.0, 240.0};
  info.distortion = {-0.1, 0.02, 0.001, -0.0005, 0.0};
  // Camera z along robot +y (left) or -y (right), camera y down (robot -z).
  Eigen::Matrix3d R_robot_camera;
  if (left) {
    R_robot_camera << 1, 0, 0, 0, 0, 1, 0, -1, 0;
  } else {
    R_robot_camera << -1, 0, 0, 0, 0, -1, 0, -1, 0;
  }
  info.T_robot_camera = SE3d(R_robot_camera, Eigen::Vector3d(0.0, left ? 0.1 : -0.1, height_m));
  return info;
}

// Codes on the left wall face -y, on the right wall +y; x right and y up as read.
inline MarkerMap CorridorMap(const CorridorConfig& config) {
  MarkerMap map;
  Eigen::Matrix3d R_left, R_right;
  R_left << 1, 0, 0, 0, 0, -1, 0, 1, 0;
  R_right << -1, 0, 0, 0, 0, 1, 0, 1, 0;
  int id = 0;
  for (double x = 0.5; x < config.length_m; x += config.code_spacing_m) {
    for (bool left : {true, false}) {
      MapMarker marker;
      marker.key = {kFamilyQr, "code-" + std::to_string(id++)};
      marker.size_m = config.code_size_m;
      const double y = left ? config.half_width_m : -config.half_width_m;
      marker.T_world_marker =
          SE3d(left ? R_left : R_right, Eigen::Vector3d(x + (left ? 0.0 : 0.5), y, config.camera_height_m));
      map.markers.push_back(marker);
    }
  }
  return map;
}

// The true path: x along the corridor, weaving +-10 cm, heading along the path tangent.
inline SE2d CorridorTruth(const CorridorConfig& config, double distance_m) {
  const double x = distance_m;
  const double y = 0.1 * std::sin(2.0 * M_PI * x / 3.0);
  const double dy_dx = 0.1 * 2.0 * M_PI / 3.0 * std::cos(2.0 * M_PI * x / 3.0);
  (void)config;
  return SE2d(x, y, std::atan2(dy_dx, 1.0));
}

// One step of the simulation: odometry at every step, frames every `frame_every` steps.
struct CorridorStep {
  double stamp_s = 0.0;
  SE3d T_world_robot_true;
  SE3d T_odom_robot;                // noisy, drifting
  std::vector<CameraFrame> frames;  // empty between frames
};

class CorridorSimulator {
 public:
  CorridorSimulator(CorridorConfig config, unsigned seed)
      : config_(config), map_(CorridorMap(config)), rng_(seed) {
    cameras_.push_back(SideCamera("left", true, config.camera_height_m));
    cameras_.push_back(SideCamera("right", false, config.camera_height_m));
    for (CameraInfo& info : cameras_) info.pixel_sigma = config.pixel_sigma_px;
  }
  const MarkerMap& map() const { return map_; }
  const std::vector<CameraInfo>& cameras() const { return cameras_; }
  const CorridorConfig& config() const { return config_; }

  // Steps until the end of the corridor. `teleport` (optional) moves the truth by that
  // transform (world frame, left-multiplied) at step `teleport_step`; odometry does not see it.
  std::vector<CorridorStep> Run(int teleport_step = -1, const SE2d& teleport = SE2d()) {
    std::vector<CorridorStep> steps;
    const double step_m = config_.speed_mps * config_.odometry_period_s;
    SE2d T_odom_robot;
    SE2d T_offset;  // teleport applied to the truth
    SE2d previous_truth = CorridorTruth(config_, 0.0);
    std::normal_distribution<double> normal(0.0, 1.0);
    for (int k = 0; k * step_m <= config_.length_m - 0.5; ++k) {
      if (k == teleport_step) T_offset = teleport;
      const SE2d truth_path = CorridorTruth(config_, k * step_m);
      const SE2d increment = previous_truth.inverse() * truth_path;
      previous_truth = truth_path;
      const MotionPrediction noise =
          PredictPlanarIncrement(Eigen::Vector3d::Zero(), increment, config_.odometry);
      const SE2d noisy(increment.x() + std::sqrt(noise.Qu(0, 0)) * normal(rng_),
                       increment.y() + std::sqrt(noise.Qu(1, 1)) * normal(rng_),
                       increment.theta() + std::sqrt(noise.Qu(2, 2)) * normal(rng_));
      if (k > 0) T_odom_robot = T_odom_robot * noisy;
      CorridorStep step;
      step.stamp_s = k * config_.odometry_period_s;
      step.T_world_robot_true = (T_offset * truth_path).ToSE3();
      step.T_odom_robot = T_odom_robot.ToSE3();
      if (k % config_.frame_every == 0) {
        for (const CameraInfo& info : cameras_) step.frames.push_back(Observe(info, step));
      }
      steps.push_back(step);
    }
    return steps;
  }

 private:
  CameraFrame Observe(const CameraInfo& info, const CorridorStep& step) {
    const Camera camera(info);
    CameraFrame frame;
    frame.stamp_s = step.stamp_s;
    frame.camera = info.name;
    const SE3d T_camera_world = (step.T_world_robot_true * info.T_robot_camera).inverse();
    std::normal_distribution<double> normal(0.0, config_.pixel_sigma_px);
    for (const MapMarker& marker : map_.markers) {
      const SE3d T_camera_marker = T_camera_world * marker.T_world_marker;
      const double depth_m = T_camera_marker.translation().z();
      const Eigen::Vector3d normal_camera = T_camera_marker.rotation_matrix().col(2);
      if (depth_m < 0.2 || depth_m > 0.8 || normal_camera.z() > -0.3) continue;  // range, facing
      MarkerObservation observation;
      observation.key = marker.key;
      bool visible = true;
      const std::array<Eigen::Vector3d, 4> corners = MarkerCorners(marker.size_m);
      for (int j = 0; j < 4 && visible; ++j) {
        const auto px = camera.Project(T_camera_marker * corners[j]);
        visible = px && info.InImage(*px);
        if (visible) observation.corners_px[j] = *px + Eigen::Vector2d(normal(rng_), normal(rng_));
      }
      if (visible) {
        MarkerPoseOptions options;
        options.sigma_px = config_.pixel_sigma_px;
        frame.sightings.push_back(MakeCodeSighting(camera, observation, marker.size_m, options));
      }
    }
    return frame;
  }

  CorridorConfig config_;
  MarkerMap map_;
  std::vector<CameraInfo> cameras_;
  std::mt19937 rng_;
};

// Planar pose error x_true [-] x_hat and NEES = e^T P^-1 e (LLT solve) over the pose block
// (x, y, yaw) of the state, whatever states follow it (odometry calibration, ...).
inline double PlanarNees(const SE3d& T_world_robot_true, const Localizer& localizer) {
  const Eigen::VectorXd truth = PoseToStateVector(T_world_robot_true, MotionModel::kPlanar);
  const int n = static_cast<int>(truth.size());
  const Eigen::VectorXd error = EkfState::BoxMinus(localizer.state().mean().head(n), truth, 2);
  return error.dot(localizer.state().covariance().topLeftCorner(n, n).llt().solve(error));
}

}  // namespace waymark::testing
