// Measurement models of the localizer: one code seen by one camera corrects the robot pose.
// State conventions: online/ekf_state.h. Map marker covariance: right perturbation of
// T_world_marker, tangent [rx ry rz tx ty tz] (docs/design.md, geometry/pose.h).
//
// (a) Loosely coupled, [Bach]'s baseline (eqs. 9-13). The code's single-image pose
//     T_camera_marker gives a robot pose through the map,
//       T_world_robot_code = T_world_marker * T_camera_marker^-1 * T_robot_camera^-1,
//     z = PoseToStateVector(T_world_robot_code),  h(x) = x,  H = I,  y = z [-] x,
//     R = fixed ([Bach]: G = diag(0.001)).
//
// (b) Tightly coupled on the four corners (ours). For corner j (object point c_m, docs/design.md order):
//       c_w = T_world_marker * c_m
//       c_r = R_world_robot^T (c_w - t_world_robot)          (robot frame)
//       c_c = T_camera_robot * c_r                            (camera frame, T_camera_robot =
//       T_robot_camera^-1) h_j = project(c_c)                                    (geometry/camera.h, 2x3
//       Jacobian J_p)
//     with R_world_robot = Rz(yaw) R_level and t_world_robot = [x, y, 0] (planar) or [x, y, z]:
//       d c_r / d t_world_robot = -R_world_robot^T
//       d c_r / d yaw           = -R_world_robot^T Hat(e_z) (c_w - t_world_robot)
//       H_j = J_p R_camera_robot [d c_r / d position, d c_r / d yaw]            (2 x dim)
//     and for the map marker's right perturbation eps = [er, et]:
//       d c_w / d eps = [-R_world_marker Hat(c_m), R_world_marker]
//       J_marker_j = J_p R_camera_robot R_world_robot^T d c_w / d eps          (2 x 6)
//     z = the 8 detected pixel coordinates, y = z - h(x),
//     R = sigma_px^2 I8 + J_marker Sigma_marker J_marker^T,
//     so a marker the map is unsure about is trusted less (its four corners move together).
#pragma once

#include <Eigen/Core>
#include <optional>

#include "geometry/camera.h"
#include "geometry/pose.h"
#include "geometry/types.h"
#include "online/ekf_state.h"

namespace waymark {

using Vector8d = Eigen::Matrix<double, 8, 1>;
using Matrix8d = Eigen::Matrix<double, 8, 8>;

// The robot pose a single code implies, with its covariance in state coordinates.
struct CodeRobotPose {
  SE3d T_world_robot;
  Eigen::MatrixXd covariance;    // dim x dim, error state of online/ekf_state.h
  CrossCovariance cross_marker;  // J_map Sigma_map (dim x 6): C_m of ekf_state.h; zero without
                                 // a map covariance
};

// T_world_robot = T_world_marker * T_camera_marker^-1 * T_robot_camera^-1 and its covariance
//   J_code Sigma_code J_code^T + J_map Sigma_map J_map^T,
// Sigma_code the 6x6 covariance of T_camera_marker (right perturbation, geometry/marker_pose.h),
// Sigma_map the marker's map covariance (zero when absent). With T_marker_robot = T_mc T_cr:
//   d t_wr / d dr = R_wm Hat(t_mr),   d t_wr / d dt = -R_wm,   d phi_wr / d dr = -R_wm
//   d t_wr / d er = -R_wm Hat(t_mr),  d t_wr / d et = R_wm,    d phi_wr / d er = R_wm
// (phi a world-frame rotation error; yaw rows through YawJacobianWorld). The state error then
// correlates with the marker's map error eps as C_m = E[delta eps^T] = J_map Sigma_map.
CodeRobotPose RobotPoseFromCode(const MapMarker& marker, const SE3d& T_camera_marker,
                                const Matrix6d& covariance_camera_marker, const SE3d& T_robot_camera,
                                MotionModel motion);

// Covariance of the world-frame rotation error phi (R_true = Exp(phi) R) of the robot attitude a
// single code implies (RobotPoseFromCode): d phi / d dr = -R_wm, d phi / d er = R_wm, so
//   Sigma_phi = R_wm (Sigma_code_rr + Sigma_map_rr) R_wm^T     (rotation blocks; map part when known)
// (the code and map errors independent). Feeds OdometryTilt::Update (online/motion_model.h).
Eigen::Matrix3d CodeAttitudeCovariance(const MapMarker& marker, const Matrix6d& covariance_camera_marker);

// Loosely coupled innovation y = z [-] x for a measured pose (H = I).
Eigen::VectorXd LooseInnovation(const EkfState& state, const SE3d& T_world_robot_measured);

// Tightly coupled prediction of the four corners.
struct CornerPrediction {
  Vector8d px;                           // h(x): [u0 v0 u1 v1 u2 v2 u3 v3]
  Eigen::MatrixXd H;                     // 8 x dim
  Eigen::Matrix<double, 8, 6> J_marker;  // d h / d eps (map marker's right perturbation)
  // d h / d phi for a world-frame rotation error of the robot (R_true = Exp(phi) R_world_robot):
  //   d c_r / d phi = R_world_robot^T Hat(c_w - t_world_robot),  J_attitude_j = J_p R_camera_robot (that)
  Eigen::Matrix<double, 8, 3> J_attitude;
};

// nullopt when a corner is behind the camera (Camera::Project undefined).
std::optional<CornerPrediction> PredictCorners(const EkfState& state, const Camera& camera,
                                               const MapMarker& marker);

// R = sigma_px^2 I8 + J_marker Sigma_marker J_marker^T + J_attitude Sigma_phi J_attitude^T
// (second term only with a marker covariance, third only with an attitude covariance: the free
// model's roll and pitch are not in the state, OdometryTilt::WorldCovariance gives theirs).
Matrix8d CornerNoise(double sigma_px, const CornerPrediction& prediction,
                     const std::optional<Matrix6d>& covariance,
                     const std::optional<Eigen::Matrix3d>& attitude_covariance = std::nullopt);

// The 8-vector of detected corners, docs/design.md order.
Vector8d StackCorners(const std::array<Eigen::Vector2d, 4>& corners_px);

}  // namespace waymark
