// Dead reckoning of a differential-drive (unicycle) robot from velocity commands.
//
// Each sample (t_i, v_i, w_i) holds from its own stamp t_i until the next stamp t_{i+1}; over
// dt = t_{i+1} - t_i the robot moves on the exact arc
//   theta' = theta + w dt
//   x' = x + v/w (sin theta' - sin theta),  y' = y - v/w (cos theta' - cos theta)   (|w dt| > 1e-9)
//   x' = x + v dt cos theta,                y' = y + v dt sin theta                 (otherwise)
// in the plane (robot: x forward, y left, z up; docs/design.md). The last sample's command is
// not integrated (no later stamp).
#pragma once

#include <vector>

#include "geometry/pose.h"
#include "geometry/types.h"

namespace waymark {

struct VelocitySample {
  double stamp_s = 0.0;
  double v_mps = 0.0;    // forward velocity
  double w_radps = 0.0;  // angular velocity about z
};

// The pose after moving with (v, w) for dt from T_start (the arc above).
SE2d IntegrateArc(const SE2d& T_start, double v_mps, double w_radps, double dt_s);

// T_odom_robot at every sample's stamp, starting at T_odom_start (the first sample's pose).
// Stamps must not decrease (std::invalid_argument otherwise); equal stamps give equal poses.
Trajectory IntegrateVelocities(const std::vector<VelocitySample>& samples, const SE2d& T_odom_start = SE2d());

}  // namespace waymark
