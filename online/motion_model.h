// Prediction models of the localizer (state and error state: online/ekf_state.h).
//
// Planar odometry increment (body frame of robot k-1), u = [dx, dy, dtheta] taken from
//   T_odom_robot(k-1)^-1 * T_odom_robot(k) (only increments of the drifting odometry are used):
//   x' = x + c dx - s dy,  y' = y + s dx + c dy,  theta' = theta + dtheta   (c, s of theta)
//   F = [1 0 -s dx - c dy; 0 1 c dx - s dy; 0 0 1],   G = du: [c -s 0; s c 0; 0 0 1]
//
// Unicycle ([Bach], eq. 5), velocities (v, omega) held for T seconds, u = [d, a] = [v T, omega T]:
//   x' = x + d cos(theta + a/2),  y' = y + d sin(theta + a/2),  theta' = theta + a
//   F = [1 0 -d sin(.); 0 1 d cos(.); 0 0 1]            ([Bach], eq. 8)
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
// Random-walk terms of odometry_sigma (geometry/odometry_noise.h, OdometryRandomWalk) over the
// increment's duration dt and distance d, added to the variances of every axis of u:
//   translation  trans_per_sqrt_s^2 dt + trans_per_sqrt_m^2 d,   rotation  rot_per_sqrt_s^2 dt (+
//   rot_per_sqrt_m^2 d)
// (the unicycle's single translation axis takes the whole translation walk). Summed over the
// samples between two camera frames they equal the covariance the map build gives the odometry
// link between those frames (mapping/survey.h): the map and the filter state the same drift.
// rot_per_sqrt_m, when dataset.yaml states it, replaces heading_per_sqrt_m below (planar).
// Heading random walk per distance (planar increments and the unicycle): the variance
//   heading_per_sqrt_m^2 * distance
// is added to sigma_rot^2, so that the heading uncertainty grows like sqrt(distance) whatever
// the odometry rate. It covers what odometry_sigma leaves out: a wheel-radius mismatch dr/r
// turns the robot by (dr/r) / track_width rad per metre driven straight (0.1 % on a 0.3 m
// track: 3.3 mrad/m, the simulator's default), which white per-angle noise cannot represent.
#pragma once

#include <Eigen/Core>

#include "geometry/pose.h"
#include "geometry/types.h"

namespace waymark {

struct OdometryNoise {
  OdometrySigma sigma{0.02, 0.02};
  // Per increment, added to sigma_trans: keep it far below trans_per_m * distance of a moving
  // increment (1e-4 m was a third of it at 20 Hz and 0.3 m/s, +78 % variance: the filter was
  // pessimistic, mean NEES 1.9 with the true map; docs/online.md, consistency).
  double floor_trans_m = 1e-5;
  double floor_rot_rad = 1e-4;        // per increment
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
// dt_s: the increment's duration (the random-walk terms; 0 leaves them out).
MotionPrediction PredictPlanarIncrement(const Eigen::Vector3d& x, const SE2d& increment,
                                        const OdometryNoise& noise, double dt_s = 0.0);

// [Bach]'s unicycle with velocities v (m/s) and omega (rad/s) over dt_s seconds.
MotionPrediction PredictUnicycle(const Eigen::Vector3d& x, double v_mps, double omega_radps, double dt_s,
                                 const OdometryNoise& noise);

// 6-DoF increment for the free model; R_level is the state's current roll-and-pitch rotation.
MotionPrediction PredictFreeIncrement(const Eigen::Vector4d& x, const Eigen::Matrix3d& R_level,
                                      const SE3d& increment, const OdometryNoise& noise, double dt_s = 0.0);

// The tilt of the odometry frame in the map's world frame (free model, AttitudeSource::kOdometry).
// A visual odometry without gravity starts at the identity: its frame is tilted by the robot's
// roll and pitch at that instant, and its rotation noise tilts it further as it flies. Taking
// its roll and pitch as the robot's then tilts every predicted view (1 deg at 1.3 m height moves
// a floor code by 2.3 cm). Only the direction of gravity matters, so the estimate is
//   u = R_world_odom^T e_z    (the world's up axis in the odometry frame, a unit vector)
// with the error d in the tangent plane (u_true = normalize(u + B d), B = TangentBasis(u), 3x2),
// P = E[d d^T] (2x2). The robot's roll and pitch follow from u_robot = R_odom_robot^T u:
//   R_level = Ry(pitch) Rx(roll) with R_level^T e_z = u_robot:
//   pitch = atan2(-u_robot.x, hypot(u_robot.y, u_robot.z)),  roll = atan2(u_robot.y, u_robot.z).
// Propagate (each odometry increment): P += sigma_rot^2 I2, sigma_rot as in PredictFreeIncrement
//   (the increment's rotation noise, turned into the world frame, tilts the odometry frame).
// Update with a robot attitude R_world_robot_code (a single code's pose) whose world-frame
// rotation error phi (R_true = Exp(phi) R_code) has covariance Sigma_phi:
//   u_meas = R_odom_robot R_code^T e_z,   d u_meas / d phi = R_odom_robot R_code^T Hat(e_z) = J,
//   y = B^T (u_meas - u),  H = I2,  R = B^T J Sigma_phi J^T B,  S = P + R,
//   gated when y^T S^-1 y > gate (a flipped single-code pose), else
//   K = P S^-1,  u = normalize(u + B K y),  P = (I - K) P (I - K)^T + K R K^T.
// Starts from u = e_z (a gravity-aligned odometry, which the estimate then merely confirms).
class OdometryTilt {
 public:
  // prior_sigma_rad: the odometry frame's tilt before any code (per axis); gate: NIS threshold (dof 2).
  OdometryTilt(double prior_sigma_rad = 0.1, double gate = 11.62);

  void Reset();
  void Propagate(const SE3d& increment, const OdometryNoise& noise, double dt_s = 0.0);
  // True when the measurement was used (finite and inside the gate).
  bool Update(const Eigen::Matrix3d& R_odom_robot, const Eigen::Matrix3d& R_world_robot_code,
              const Eigen::Matrix3d& covariance_phi_world);
  // The robot's R_level = Ry(pitch) Rx(roll) at the odometry attitude R_odom_robot.
  Eigen::Matrix3d Level(const Eigen::Matrix3d& R_odom_robot) const;
  // P as the covariance of the robot's world-frame rotation error phi (R_true = Exp(phi) R):
  // u_robot = R^T e_z moves by R^T Hat(e_z) phi = R_odom_robot^T B d, so with M = R_world_odom B
  // (R_world_odom = R_world_robot R_odom_robot^T):  phi = [M.row(1); -M.row(0); 0] d  (J, 3x2),
  // Sigma_phi = J P J^T (no yaw part).
  Eigen::Matrix3d WorldCovariance(const Eigen::Matrix3d& R_world_robot,
                                  const Eigen::Matrix3d& R_odom_robot) const;

  const Eigen::Vector3d& up_odom() const { return up_odom_; }
  const Eigen::Matrix2d& covariance() const { return covariance_; }
  int updates() const { return updates_; }

 private:
  double prior_sigma_rad_, gate_;
  Eigen::Vector3d up_odom_ = Eigen::Vector3d::UnitZ();
  Eigen::Matrix2d covariance_;
  int updates_ = 0;
};

// Two orthonormal vectors orthogonal to the unit vector u (columns; a fixed function of u).
Eigen::Matrix<double, 3, 2> TangentBasis(const Eigen::Vector3d& u);

// R_level = Ry(pitch) Rx(roll) whose transpose maps e_z to the unit vector up_robot.
Eigen::Matrix3d LevelFromUp(const Eigen::Vector3d& up_robot);

}  // namespace waymark
