// Calibrations shared by the test suites: the two real cameras of ../shared/data/tagslam,
// typed in so the tests need no data folder. Mount (T_robot_camera) is identity; suites that
// need a mount set their own.
#pragma once

#include <string>

#include "geometry/types.h"

namespace waymark::testing {

// tagslam-test16 cam0: pinhole-radtan, strong barrel distortion.
inline CameraInfo TagslamRadtanInfo() {
  CameraInfo info;
  info.name = "test16-cam0";
  info.model = CameraModel::kPinholeRadtan;
  info.width = 1280;
  info.height = 1024;
  info.intrinsics = {1506.9, 1506.28, 641.176, 524.495};
  info.distortion = {-0.233024, 0.217972, 0.000104351, -9.65731e-05, -0.0913426};
  return info;
}

// tagslam-test22 cam0: pinhole-equidistant (RealSense T265). Its yaml says width 800, height
// 848, but the principal point (421, 401) and the sensor (848 x 800) say 848 wide; this is the
// sensor's reading.
inline CameraInfo TagslamFisheyeInfo() {
  CameraInfo info;
  info.name = "test22-cam0";
  info.model = CameraModel::kPinholeEquidistant;
  info.width = 848;
  info.height = 800;
  info.intrinsics = {283.943, 284.986, 421.079, 400.527};
  info.distortion = {0.00132, 0.03049, -0.02875, 0.0034};
  return info;
}

// [Seki]'s camera: 1280x1024 NIR (Marlin F-131B, 6.7 um pixels) behind an equisolid-angle
// fisheye (FIT FI-23, f = 2.3 mm, 160 degrees): fx = 2.3 mm / 6.7 um = 343.28 px, so the 160 degree
// circle is 2 fx sin(40 deg) = 441 px in radius and fits the 1024 px height.
inline CameraInfo Seed002EquisolidInfo() {
  CameraInfo info;
  info.name = "seed002-cam0";
  info.model = CameraModel::kEquisolid;
  info.width = 1280;
  info.height = 1024;
  info.intrinsics = {2.3e-3 / 6.7e-6, 2.3e-3 / 6.7e-6, 640.0, 512.0};
  info.distortion = {0.0, 0.0, 0.0, 0.0};
  return info;
}

// An ideal pinhole camera (no distortion), principal point at the image centre.
inline CameraInfo IdealPinholeInfo(const std::string& name, int width, int height, double focal_px) {
  CameraInfo info;
  info.name = name;
  info.model = CameraModel::kPinholeRadtan;
  info.width = width;
  info.height = height;
  info.intrinsics = {focal_px, focal_px, 0.5 * width, 0.5 * height};
  info.distortion = {0.0, 0.0, 0.0, 0.0, 0.0};
  return info;
}

}  // namespace waymark::testing
