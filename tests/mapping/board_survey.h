// A synthetic survey of a rigid board, shared by the board tests (mapping and cli): a hand-held
// camera without odometry (30 frames) sweeps along a wall holding a board of six small codes (3 x 2 grid) and
// four loose codes, with 1 px corner noise (fixed seed). `split` makes two sweeps with no code
// in common (the left half of the board and two loose codes, then the right half and the two
// others): without the board they are two maps.
#pragma once

#include <cmath>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "geometry/camera.h"
#include "geometry/types.h"

namespace waymark::testing {

inline constexpr double kBoardCodeSizeM = 0.08;

// A wall code facing -x (z along world -x, x along world -y, y up) at `position`, yawed about z.
inline SE3d BoardWallPose(const Eigen::Vector3d& position, double yaw_rad) {
  Eigen::Matrix3d R_world_marker;
  R_world_marker << 0, 0, -1, -1, 0, 0, 0, 1, 0;
  return SE3d(Eigen::Matrix3d(Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()) * R_world_marker),
              position);
}

inline SE3d TrueBoardPose() { return BoardWallPose(Eigen::Vector3d(2.0, 0.0, 1.3), 0.05); }

// The board's layout: ids B0..B5, a 3 x 2 grid with 0.12 m pitch, the codes tilted slightly.
inline std::vector<BoardMember> BoardLayout() {
  std::vector<BoardMember> members;
  for (int i = 0; i < 6; ++i) {
    const double x = 0.12 * (i % 3 - 1), y = 0.12 * (i / 3 == 0 ? 0.5 : -0.5);
    const Eigen::Quaterniond q(Eigen::AngleAxisd(0.02 * (i - 2.5), Eigen::Vector3d::UnitZ()));
    members.push_back(
        {MarkerKey{"apriltag-36h11", "B" + std::to_string(i)}, SE3d(q, Eigen::Vector3d(x, y, 0.0))});
  }
  return members;
}

// Every code with its true pose: the board's six, then L0..L3 on the wall around it.
inline std::vector<std::pair<MarkerKey, SE3d>> BoardSurveyTruth() {
  std::vector<std::pair<MarkerKey, SE3d>> codes;
  for (const BoardMember& m : BoardLayout()) codes.push_back({m.key, TrueBoardPose() * m.T_board_marker});
  const Eigen::Vector3d loose[] = {{2.05, 0.9, 1.1}, {2.0, 0.55, 1.5}, {2.0, -0.55, 1.1}, {2.05, -0.9, 1.45}};
  for (int i = 0; i < 4; ++i)
    codes.push_back(
        {MarkerKey{"apriltag-36h11", "L" + std::to_string(i)}, BoardWallPose(loose[i], -0.1 + 0.07 * i)});
  return codes;
}

inline CameraInfo BoardSurveyCamera() {
  CameraInfo info;
  info.name = "cam0";
  info.width = 1280;
  info.height = 960;
  info.intrinsics = {900.0, 900.0, 640.0, 480.0};
  info.distortion = {0.0, 0.0, 0.0, 0.0, 0.0};
  Eigen::Matrix3d R_robot_camera;
  R_robot_camera << 0, 0, 1, -1, 0, 0, 0, -1, 0;  // camera z = robot x, camera x = robot -y
  info.T_robot_camera = SE3d(R_robot_camera, Eigen::Vector3d(0.0, 0.0, 0.3));
  info.pixel_sigma = 1.0;
  return info;
}

// The dataset (no odometry, free motion, default size kBoardCodeSizeM); known markers: a
// size-only entry per code, and the board (unknown pose) when with_board.
// `far`: the camera sweeps 1.6-1.8 m from the wall (else 0.85-1.35 m), where a single 8 cm code's
// depth and tilt are poorly seen.
inline Dataset BoardSurvey(bool with_board, bool split = false, bool far = false, unsigned seed = 11) {
  Dataset dataset;
  dataset.config.name = "board-survey";
  dataset.config.motion = MotionModel::kFree;
  dataset.config.cameras = {"cam0"};
  dataset.config.default_marker_size_m = kBoardCodeSizeM;
  dataset.cameras["cam0"] = BoardSurveyCamera();
  const Camera camera(BoardSurveyCamera());
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise_px(0.0, 1.0);
  const auto truth = BoardSurveyTruth();
  const int frames = 30;
  for (int i = 0; i < frames; ++i) {
    const double s = static_cast<double>(i) / (frames - 1);  // 0 .. 1 along the sweep
    const double y = split ? (i < frames / 2 ? -0.1 - 0.9 * 2 * s : 0.1 + 0.9 * (2 * s - 1)) : 1.0 - 2.0 * s;
    const double x = far ? 0.3 + 0.1 * std::sin(7.0 * s) : 0.9 + 0.25 * std::sin(7.0 * s);
    const double yaw = -0.35 * y + 0.1 * std::sin(11.0 * s);
    const Eigen::Quaterniond q = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                                 Eigen::AngleAxisd(0.05 * std::sin(5.0 * s), Eigen::Vector3d::UnitY());
    const SE3d T_world_robot(q, Eigen::Vector3d(x, y, 1.0));
    DetectionFrame frame;
    frame.stamp_s = 0.2 * i;
    frame.camera = "cam0";
    const SE3d T_camera_world = (T_world_robot * camera.info().T_robot_camera).inverse();
    for (const auto& [key, T_world_marker] : truth) {
      if (split) {
        // First sweep: codes at y < 0 (B0, B3 and the right-hand loose codes); then y > 0.
        const bool first = T_world_marker.translation().y() < -0.01;
        const bool second = T_world_marker.translation().y() > 0.01;
        if ((i < frames / 2 && !first) || (i >= frames / 2 && !second)) continue;
      }
      MarkerObservation seen{key, {}, std::nullopt};
      bool visible = true;
      for (int k = 0; k < 4; ++k) {
        const auto px = camera.Project(T_camera_world * T_world_marker * MarkerCorners(kBoardCodeSizeM)[k]);
        if (!px || !camera.info().InImage(*px)) visible = false;
        if (px) seen.corners_px[k] = *px + Eigen::Vector2d(noise_px(rng), noise_px(rng));
      }
      if (visible) frame.markers.push_back(seen);
    }
    dataset.detections.push_back(frame);
  }
  MarkerMap known;
  for (const auto& [key, T] : truth) {
    MapMarker m;
    m.key = key;
    m.size_m = kBoardCodeSizeM;
    m.has_pose = false;
    known.markers.push_back(m);
  }
  if (with_board)
    known.boards.push_back(
        MapBoard{"shelf", BoardLayout(), false, SE3d(), std::nullopt, false, std::nullopt});
  dataset.known_markers = known;
  return dataset;
}

}  // namespace waymark::testing
