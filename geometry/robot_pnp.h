// The pose of a robot from the corners of the codes it sees in one instant, the codes' poses
// held fixed (a map's codes): robust PnP over all of a robot's cameras and codes at once.
//
// Residual of corner k of view v (whitened, 2 rows):
//   r = (pi_c(T_camera_robot * T_world_robot^-1 * T_world_marker * q_k) - z_k) / sigma_px
// over the right perturbation T_world_robot * Exp([dr, dt]) (p = the corner in the robot frame):
//   dr/d[dr, dt] = J_pi R_camera_robot [Hat(p), -I] / sigma_px
// Levenberg-Marquardt with Cauchy weights w = 1 / (1 + s / c^2), s = |r_v|^2 of the whole view
// (a misdecoded or moved code is down-weighted as one). Planar robots move in [dr_z, dt_x, dt_y]
// only and the result is planarized.
#pragma once

#include <Eigen/Core>
#include <array>
#include <optional>
#include <vector>

#include "geometry/camera.h"
#include "geometry/pose.h"

namespace waymark {

// One code seen by a robot: the code's pose is held fixed.
struct PnpView {
  const Camera* camera = nullptr;
  const std::array<Eigen::Vector2d, 4>* corners_px = nullptr;
  double sigma_px = 1.0;
  double size_m = 0.0;
  SE3d T_world_marker;
};

// Robust PnP of T_world_robot over `views` (cameras at T_world_robot * T_robot_camera) from
// `start`. Views that do not project at the start are left out; returns `start` (planarized)
// when none is left.
SE3d RefineRobotPose(const std::vector<PnpView>& views, const SE3d& start, bool planar, double cauchy_scale,
                     int max_iterations);

// The fit's quality at T: the whitened squared error of each view (nullopt for a view with a
// corner that does not project) and, when `information` is given, J^T J of the right
// perturbation [dr, dt] over the views that project (the inverse covariance of the fit; a
// caller holding some directions fixed inverts the block of the others).
std::vector<std::optional<double>> RobotPnpErrors(const std::vector<PnpView>& views,
                                                  const SE3d& T_world_robot, Matrix6d* information);

}  // namespace waymark
