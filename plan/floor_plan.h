// The floor plan `waymark plan-codes` places codes on (docs/formats.md, "Floor plan"): vertical
// wall segments with their heights, the ceiling height, the survey robot's camera rig (a dataset
// directory's cameras and odometry noise), the allowed code sizes and the detection limits.
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <vector>

#include "geometry/types.h"

namespace waymark::plan {

struct FloorWall {
  Eigen::Vector2d from_world = Eigen::Vector2d::Zero();
  Eigen::Vector2d to_world = Eigen::Vector2d::Zero();
  double height_m = 0.0;
};

struct FloorPlan {
  std::vector<FloorWall> walls;
  double ceiling_height_m = 0.0;
  std::string family = "qr";
  std::vector<double> code_sizes_m;
  double code_height_m = 0.0;  // centre height of the codes on the walls
  double margin_m = 0.0;       // no code centre closer than this (plus half its size) to a wall's end
  int anchors = 2;             // the first codes' poses are given (the map's gauge), as the simulator's
  // Detection limits and noise of the prediction (sim/world.h's VisibilityLimits).
  double min_range_m = 0.2, max_range_m = 0.8, max_angle_deg = 60.0, border_px = 2.0;
  double pixel_sigma_px = 0.5;
  double camera_hz = 10.0;
  // The rig: cameras (T_robot_camera, lens) and odometry noise of this dataset.
  std::vector<CameraInfo> cameras;
  OdometrySigma odometry_sigma{0.02, 0.02};
};

// Reads WORLD.yaml; `rig` is resolved relative to the file. Errors: FormatError "path:line: what".
FloorPlan ReadFloorPlan(const std::filesystem::path& path);

}  // namespace waymark::plan
