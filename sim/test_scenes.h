// The camera and pose that the renderer's accuracy test (tests/sim/render_test.cc) and the
// corner-accuracy benchmark (bench/render_corner_bench.cc) render their codes with.
// Frames as in docs/design.md: world z up; camera x right, y down, z along the optical axis.
#pragma once

#include <Eigen/Core>

#include "geometry/camera.h"
#include "geometry/pose.h"
#include "sim/world.h"

namespace waymark::sim {

inline constexpr double kTestCameraHeightM = 1.2;

// 1280x960, fx = fy = 1000 px, principal point at the centre, mild barrel distortion.
inline Camera TestCamera() {
  CameraInfo info;
  info.name = "cam";
  info.width = 1280;
  info.height = 960;
  info.intrinsics = {1000.0, 1000.0, 640.0, 480.0};
  info.distortion = {-0.05, 0.01, 0.0005, -0.0003, 0.0};
  return Camera(info);
}

// T_world_camera: kTestCameraHeightM above the floor, looking along world +x, upright.
inline SE3d TestCameraPose() {
  return SE3d(RotationFromZY(Eigen::Vector3d::UnitX(), -Eigen::Vector3d::UnitZ()),
              Eigen::Vector3d(0.0, 0.0, kTestCameraHeightM));
}

}  // namespace waymark::sim
