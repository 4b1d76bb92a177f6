// A synthetic survey shared by the mapping tests: a camera carried towards a wall of three codes
// and back (free motion), detections with 0.3 px corner noise (fixed seed), and odometry whose
// clock may be offset from the images'.
#pragma once

#include <cmath>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "geometry/camera.h"
#include "geometry/types.h"

namespace waymark::testing {

inline constexpr double kMarkerSizeM = 0.2;

inline CameraInfo FrontCamera() {
  CameraInfo info;
  info.name = "cam0";
  info.model = CameraModel::kPinholeRadtan;
  info.width = 1280;
  info.height = 960;
  info.intrinsics = {700.0, 700.0, 640.0, 480.0};
  info.distortion = {0.0, 0.0, 0.0, 0.0, 0.0};
  // Robot x forward, z up; camera z along robot x, camera x along robot -y, camera y along -z.
  info.T_robot_camera = SE3d(Eigen::Quaterniond(0.5, -0.5, 0.5, -0.5), Eigen::Vector3d(0.1, 0.0, 0.0));
  return info;
}

// A forward-looking pinhole camera (x right, y down, z along the robot's x), 0.5 px noise.
inline CameraInfo ForwardCamera() {
  CameraInfo info;
  info.name = "cam0";
  info.width = 1280;
  info.height = 960;
  info.intrinsics = {1100.0, 1100.0, 640.0, 480.0};
  info.distortion = {0.0, 0.0, 0.0, 0.0, 0.0};
  Eigen::Matrix3d R_robot_camera;
  R_robot_camera << 0, 0, 1, -1, 0, 0, 0, -1, 0;  // camera z = robot x, camera x = robot -y
  info.T_robot_camera = SE3d(R_robot_camera, Eigen::Vector3d(0.05, 0.0, 0.3));
  info.pixel_sigma = 0.5;
  return info;
}

// A code on a wall facing -x (its z axis), at `position`, yawed by `yaw_rad` about the vertical.
inline SE3d WallCode(const Eigen::Vector3d& position, double yaw_rad) {
  Eigen::Matrix3d R_world_marker;  // marker x = world -y, y = world z, z = world -x
  R_world_marker << 0, 0, -1, -1, 0, 0, 0, 1, 0;
  return SE3d(Eigen::Matrix3d(Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()) * R_world_marker),
              position);
}

// Three codes on a wall at x = 3 m, facing the robot (marker z along world -x, y up).
inline std::vector<std::pair<MarkerKey, SE3d>> WallMarkers() {
  Eigen::Matrix3d R_world_marker;
  R_world_marker.col(0) = Eigen::Vector3d(0, -1, 0);
  R_world_marker.col(1) = Eigen::Vector3d(0, 0, 1);
  R_world_marker.col(2) = Eigen::Vector3d(-1, 0, 0);
  std::vector<std::pair<MarkerKey, SE3d>> markers;
  const Eigen::Vector3d centres[] = {{3.0, -0.5, 1.0}, {3.0, 0.0, 1.2}, {3.0, 0.5, 1.0}};
  for (int i = 0; i < 3; ++i) {
    markers.push_back({MarkerKey{"apriltag-36h11", std::to_string(i)}, SE3d(R_world_marker, centres[i])});
  }
  return markers;
}

// A hand-held motion towards the wall and back, swaying and turning (free, 6-DoF).
inline SE3d TrueRobotPose(double t) {
  const double x = 0.75 * (1.0 - std::cos(2.0 * M_PI * t / 10.0));
  const double y = 0.3 * std::sin(2.0 * M_PI * t / 5.0);
  const double z = 1.0 + 0.05 * std::sin(2.0 * M_PI * t / 3.0);
  const double yaw = 0.15 * std::sin(2.0 * M_PI * t / 4.0);
  const double pitch = 0.05 * std::sin(2.0 * M_PI * t / 6.0);
  const Eigen::Quaterniond q =
      Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY());
  return SE3d(q, Eigen::Vector3d(x, y, z));
}

// Images at 5 Hz for 20 s with 0.3 px corner noise (seed 7); odometry at 10 Hz whose stamps read
// the odometry's clock, `offset_s` ahead of the images' clock (stamp = true time + offset_s).
inline Dataset SyntheticSurvey(double offset_s) {
  Dataset dataset;
  dataset.config.name = "synthetic";
  dataset.config.motion = MotionModel::kFree;
  dataset.config.cameras = {"cam0"};
  dataset.config.default_marker_size_m = kMarkerSizeM;
  dataset.cameras["cam0"] = FrontCamera();
  const Camera camera(FrontCamera());
  std::mt19937 rng(7);
  std::normal_distribution<double> noise_px(0.0, 0.3);
  for (int i = 0; i <= 100; ++i) {
    const double t = 0.2 * i;
    DetectionFrame frame;
    frame.stamp_s = t;
    frame.camera = "cam0";
    const SE3d T_camera_world = (TrueRobotPose(t) * camera.info().T_robot_camera).inverse();
    for (const auto& [key, T_world_marker] : WallMarkers()) {
      MarkerObservation seen{key, {}, std::nullopt};
      bool visible = true;
      for (int k = 0; k < 4; ++k) {
        const auto px = camera.Project(T_camera_world * T_world_marker * MarkerCorners(kMarkerSizeM)[k]);
        if (!px || !camera.info().InImage(*px)) visible = false;
        if (px) seen.corners_px[k] = *px + Eigen::Vector2d(noise_px(rng), noise_px(rng));
      }
      if (visible) frame.markers.push_back(seen);
    }
    dataset.detections.push_back(frame);
  }
  for (int i = -20; i <= 220; ++i) dataset.odometry.push_back({0.1 * i + offset_s, TrueRobotPose(0.1 * i)});
  return dataset;
}

}  // namespace waymark::testing
