// The build report of `waymark map build`: the human summary printed on stdout (markers and
// components, reprojection per camera, outliers by reason and by code, time, solver, the odometry
// calibration). `--report`'s JSON is written by cli/cmd_map.cc from the same MapBuildResult.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "mapping/map_builder.h"

namespace waymark {

// Rejected observations counted by reason (the text before its first ':'; "id conflicts with
// X" counted as one reason) and by code (most rejected first, then by code).
struct OutlierTally {
  std::vector<std::pair<std::string, size_t>> by_reason;
  std::vector<std::pair<std::string, size_t>> by_code;
};
OutlierTally TallyOutliers(const std::vector<RejectedObservation>& outliers);

// The human summary: markers and components, reprojection RMS per camera, outliers, solver, the
// odometry calibration.
std::string FormatBuildSummary(const MapBuildResult& result);

// One line: the odometry calibration in deg/m and percent (with its sigmas when known) and, when
// estimated, the --odometry-calibration argument that reuses it; "" without one.
std::string FormatOdometryCalibration(const MapBuildResult& result);

// One line per camera mount the build estimated (extrinsic self-calibration): its
// T_robot_camera (translation in m, rotation as a rotation vector in deg), its sigmas when the
// covariances were computed, and how far it moved from the camera file; "" without any.
std::string FormatCameraMounts(const MapBuildResult& result);

}  // namespace waymark
