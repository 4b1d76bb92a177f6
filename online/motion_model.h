// Prediction models of the localizer (state and error state: online/ekf_state.h).
//
// Planar odometry increment (body frame of robot k-1), u = [dx, dy, dtheta] taken from
//   T_odom_robot(k-1)^-1 * T_odom_robot(k) (only increments of the drifting odometry are used):
//   x' = x + c dx - s dy,  y' = y + s dx + c dy,  theta' = theta + dtheta   (c, s of theta)
//   F = [1 0 -s dx - c dy; 0 1 c dx - s dy; 0 0 1],   G = du: [c -s 0; s c 0; 0 0 1]
//
// Unicycle (seed 000, eq. 5), velocities (v, omega) held for T seconds, u = [d, a] = [v T, omega T]:
//   x' = x + d cos(theta + a/2),  y' = y + d sin(theta + a/2),  theta' = theta + a
//   F = [1 0 -d sin(.); 0 1 d cos(.); 0 0 1]            (seed 000, eq. 8)
//   G = [cos(.) -d/2 sin(.); sin(.) d/2 cos(.); 0 1]
//
// Free odometry increment (6-DoF, state [x y z yaw], R = Rz(yaw) R_level), u = [dt (3), dphi (3)]
// with T_robot(k-1)_robot(k) = (dR Exp(dphi), dt):
//   t' = t + R dt,   R' = R dR,   yaw' = yaw(R')
//   F = [I3, Hat(e_z) R dt; 0, 1],   G = [R, 0; 0, YawJacobianWorld(R') R']
// (roll and pitch of R' are replaced by the attitude source afterwards, see ekf_state.h).
//
// Noise, from OdometrySigma scaled by what the increment travelled, as factors/ does it:
//   sigma_trans = trans_per_m * distance + floor_trans_m,  sigma_rot = rot_per_rad * |angle| + floor_rot_rad
//   planar: Qu = diag(sigma_trans^2, sigma_trans^2, sigma_rot^2); unicycle: diag(sigma_trans^2, sigma_rot^2);
//   free: diag(sigma_trans^2 I3, sigma_rot^2 I3).
// The floors keep a robot at a standstill from becoming infinitely certain (wheel slip, vibration).
// Heading random walk per distance (planar increments and the unicycle): the variance
//   heading_per_sqrt_m^2 * distance
// is added to sigma_rot^2, so that the heading uncertainty grows like sqrt(distance) whatever
// the odometry rate. It covers what odometry_sigma leaves out: a wheel-radius mismatch dr/r
// turns the robot by (dr/r) / track_width rad per metre driven straight (0.1 % on a 0.3 m
// track: 3.3 mrad/m, the simulator's default), which white per-angle noise cannot represent.
#pragma once

#include <Eigen/Core>

#include "core/geometry.h"
#include "core/types.h"

namespace waymark {

struct OdometryNoise {
  OdometrySigma sigma{0.02, 0.02};
  double floor_trans_m = 1e-4;  // per increment
  double floor_rot_rad = 1e-4;  // per increment
  double heading_per_sqrt_m = 0.005;  // rad / sqrt(m), see above

  bool Check(std::string* why) const;
};

// Everything EkfState::Propagate needs.
struct MotionPrediction {
  Eigen::VectorXd mean;           // f(x, u)
  Eigen::MatrixXd F;              // df/dx  (dim x dim)
  Eigen::MatrixXd G;              // df/du  (dim x |u|)
  Eigen::MatrixXd Qu;             // covariance of u
  Eigen::Matrix3d R_world_robot;  // free only: the full predicted rotation R' (for the attitude source)
};

// Planar increment (x, y, theta of T_odom_robot(k-1)^-1 T_odom_robot(k)).
MotionPrediction PredictPlanarIncrement(const Eigen::Vector3d& x, const SE2d& increment,
                                        const OdometryNoise& noise);

// Seed 000's unicycle with velocities v (m/s) and omega (rad/s) over dt_s seconds.
MotionPrediction PredictUnicycle(const Eigen::Vector3d& x, double v_mps, double omega_radps, double dt_s,
                                 const OdometryNoise& noise);

// 6-DoF increment for the free model; R_level is the state's current roll-and-pitch rotation.
MotionPrediction PredictFreeIncrement(const Eigen::Vector4d& x, const Eigen::Matrix3d& R_level,
                                      const SE3d& increment, const OdometryNoise& noise);

}  // namespace waymark
