#include "online/motion_model.h"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <string>

#include "geometry/odometry_noise.h"
#include "online/ekf_state.h"
#include "util/check.h"

namespace waymark {
namespace {

double HeadingWalkVariance(const OdometryNoise& noise, double distance_m) {
  // A heading walk stated in dataset.yaml (rot_per_sqrt_m) replaces the default allowance.
  const double q = noise.sigma.rot_per_sqrt_m > 0.0 ? noise.sigma.rot_per_sqrt_m : noise.heading_per_sqrt_m;
  return q * q * distance_m;
}

// The random-walk terms of odometry_sigma over dt_s and distance_m, without the per-metre
// heading walk (HeadingWalkVariance, planar models; the free model takes it from here).
OdometryWalkVariance WalkVariance(const OdometryNoise& noise, double dt_s, double distance_m,
                                  bool with_rot_per_m) {
  OdometrySigma sigma = noise.sigma;
  if (!with_rot_per_m) sigma.rot_per_sqrt_m = 0.0;
  return OdometryRandomWalk(sigma, std::max(0.0, dt_s), distance_m);
}

}  // namespace

bool OdometryNoise::Check(std::string* why) const {
  WAYMARK_CHECK_OPTION(IsFiniteAtLeast(sigma.trans_per_m, 0.0),
                       "odometry noise: trans_per_m must be a finite number >= 0");
  WAYMARK_CHECK_OPTION(IsFiniteAtLeast(sigma.rot_per_rad, 0.0),
                       "odometry noise: rot_per_rad must be a finite number >= 0");
  WAYMARK_CHECK_OPTION(
      IsFiniteAtLeast(sigma.trans_per_sqrt_s, 0.0) && IsFiniteAtLeast(sigma.rot_per_sqrt_s, 0.0) &&
          IsFiniteAtLeast(sigma.trans_per_sqrt_m, 0.0) && IsFiniteAtLeast(sigma.rot_per_sqrt_m, 0.0),
      "odometry noise: the random-walk terms must be finite numbers >= 0");
  WAYMARK_CHECK_OPTION(IsFiniteAtLeast(heading_per_sqrt_m, 0.0),
                       "odometry noise: heading_per_sqrt_m must be a finite number >= 0");
  WAYMARK_CHECK_OPTION(IsFinitePositive(floor_trans_m) && IsFinitePositive(floor_rot_rad),
                       "odometry noise: floor_trans_m and floor_rot_rad must be finite and > 0");
  return true;
}

MotionPrediction PredictPlanarIncrement(const Eigen::Vector3d& x, const SE2d& increment,
                                        const OdometryNoise& noise, double dt_s) {
  const double c = std::cos(x(2)), s = std::sin(x(2));
  const double dx = increment.x(), dy = increment.y(), dtheta = increment.theta();
  MotionPrediction p;
  p.mean = Eigen::Vector3d(x(0) + c * dx - s * dy, x(1) + s * dx + c * dy, WrapAngle(x(2) + dtheta));
  p.F = Eigen::Matrix3d::Identity();
  p.F(0, 2) = -s * dx - c * dy;
  p.F(1, 2) = c * dx - s * dy;
  p.G = (Eigen::Matrix3d() << c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0).finished();
  const double sigma_trans = noise.sigma.trans_per_m * std::hypot(dx, dy) + noise.floor_trans_m;
  const double sigma_rot = noise.sigma.rot_per_rad * std::abs(dtheta) + noise.floor_rot_rad;
  const OdometryWalkVariance walk = WalkVariance(noise, dt_s, std::hypot(dx, dy), false);
  const double variance_rot =
      sigma_rot * sigma_rot + HeadingWalkVariance(noise, std::hypot(dx, dy)) + walk.rotation;
  const double variance_trans = sigma_trans * sigma_trans + walk.translation;
  p.Qu = Eigen::Vector3d(variance_trans, variance_trans, variance_rot).asDiagonal();
  p.R_world_robot = Eigen::AngleAxisd(p.mean(2), Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return p;
}

MotionPrediction PredictUnicycle(const Eigen::Vector3d& x, double v_mps, double omega_radps, double dt_s,
                                 const OdometryNoise& noise) {
  const double d = v_mps * dt_s, a = omega_radps * dt_s;
  const double heading = x(2) + 0.5 * a;
  const double c = std::cos(heading), s = std::sin(heading);
  MotionPrediction p;
  p.mean = Eigen::Vector3d(x(0) + d * c, x(1) + d * s, WrapAngle(x(2) + a));
  p.F = Eigen::Matrix3d::Identity();
  p.F(0, 2) = -d * s;
  p.F(1, 2) = d * c;
  p.G = (Eigen::Matrix<double, 3, 2>() << c, -0.5 * d * s, s, 0.5 * d * c, 0.0, 1.0).finished();
  const double sigma_trans = noise.sigma.trans_per_m * std::abs(d) + noise.floor_trans_m;
  const double sigma_rot = noise.sigma.rot_per_rad * std::abs(a) + noise.floor_rot_rad;
  const OdometryWalkVariance walk = WalkVariance(noise, dt_s, std::abs(d), false);
  // The unicycle's u = [d, a] has one translation axis: the lateral share of the walk is folded
  // into it (an upper bound of the along-track one, isotropic in the plane otherwise).
  p.Qu = Eigen::Vector2d(sigma_trans * sigma_trans + walk.translation,
                         sigma_rot * sigma_rot + HeadingWalkVariance(noise, std::abs(d)) + walk.rotation)
             .asDiagonal();
  p.R_world_robot = Eigen::AngleAxisd(p.mean(2), Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return p;
}

MotionPrediction PredictFreeIncrement(const Eigen::Vector4d& x, const Eigen::Matrix3d& R_level,
                                      const SE3d& increment, const OdometryNoise& noise, double dt_s) {
  const Eigen::Matrix3d R = Eigen::AngleAxisd(x(3), Eigen::Vector3d::UnitZ()).toRotationMatrix() * R_level;
  const Eigen::Vector3d& dt = increment.translation();
  const Eigen::Matrix3d R_new = R * increment.rotation_matrix();
  const Eigen::Vector3d R_dt = R * dt;
  MotionPrediction p;
  p.mean = Eigen::Vector4d(x(0) + R_dt.x(), x(1) + R_dt.y(), x(2) + R_dt.z(),
                           std::atan2(R_new(1, 0), R_new(0, 0)));
  p.F = Eigen::Matrix4d::Identity();
  p.F.block<3, 1>(0, 3) = Hat(Eigen::Vector3d::UnitZ().eval()) * R_dt;
  p.G = Eigen::MatrixXd::Zero(4, 6);
  p.G.block<3, 3>(0, 0) = R;
  p.G.block<1, 3>(3, 3) = YawJacobianWorld(R_new) * R_new;
  const double sigma_trans = noise.sigma.trans_per_m * dt.norm() + noise.floor_trans_m;
  const double sigma_rot =
      noise.sigma.rot_per_rad * RotationAngleBetween(SE3d(), increment) + noise.floor_rot_rad;
  const OdometryWalkVariance walk = WalkVariance(noise, dt_s, dt.norm(), true);
  Eigen::Matrix<double, 6, 1> variances;
  variances << Eigen::Vector3d::Constant(sigma_trans * sigma_trans + walk.translation),
      Eigen::Vector3d::Constant(sigma_rot * sigma_rot + walk.rotation);
  p.Qu = variances.asDiagonal();
  p.R_world_robot = R_new;
  return p;
}

Eigen::Matrix<double, 3, 2> TangentBasis(const Eigen::Vector3d& u) {
  // Start from the axis least aligned with u, so the cross products are well conditioned.
  Eigen::Index axis = 0;
  u.cwiseAbs().minCoeff(&axis);
  const Eigen::Vector3d a = u.cross(Eigen::Vector3d::Unit(axis)).normalized();
  Eigen::Matrix<double, 3, 2> B;
  B << a, u.cross(a);
  return B;
}

Eigen::Matrix3d LevelFromUp(const Eigen::Vector3d& up_robot) {
  const double pitch = std::atan2(-up_robot.x(), std::hypot(up_robot.y(), up_robot.z()));
  const double roll = std::atan2(up_robot.y(), up_robot.z());
  return (Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

OdometryTilt::OdometryTilt(double prior_sigma_rad, double gate)
    : prior_sigma_rad_(prior_sigma_rad), gate_(gate) {
  Reset();
}

void OdometryTilt::Reset() {
  up_odom_ = Eigen::Vector3d::UnitZ();
  covariance_ = Eigen::Matrix2d::Identity() * (prior_sigma_rad_ * prior_sigma_rad_);
  updates_ = 0;
}

void OdometryTilt::Propagate(const SE3d& increment, const OdometryNoise& noise, double dt_s) {
  const double sigma_rot =
      noise.sigma.rot_per_rad * RotationAngleBetween(SE3d(), increment) + noise.floor_rot_rad;
  const double walk = WalkVariance(noise, dt_s, increment.translation().norm(), true).rotation;
  covariance_ += Eigen::Matrix2d::Identity() * (sigma_rot * sigma_rot + walk);
}

bool OdometryTilt::Update(const Eigen::Matrix3d& R_odom_robot, const Eigen::Matrix3d& R_world_robot_code,
                          const Eigen::Matrix3d& covariance_phi_world) {
  const Eigen::Matrix3d R_odom_world = R_odom_robot * R_world_robot_code.transpose();
  const Eigen::Vector3d up_measured = R_odom_world.col(2);
  const Eigen::Matrix<double, 3, 2> B = TangentBasis(up_odom_);
  const Eigen::Matrix<double, 2, 3> BJ = B.transpose() * R_odom_world * Hat(Eigen::Vector3d::UnitZ().eval());
  const Eigen::Vector2d y = B.transpose() * (up_measured - up_odom_);
  const Eigen::Matrix2d R = BJ * covariance_phi_world * BJ.transpose();
  const Eigen::Matrix2d S = covariance_ + R;
  const Eigen::LLT<Eigen::Matrix2d> llt(S);
  if (!y.allFinite() || !R.allFinite() || llt.info() != Eigen::Success) return false;
  if (y.dot(llt.solve(y)) > gate_) return false;
  const Eigen::Matrix2d K = llt.solve(covariance_).transpose();  // P S^-1 (P, S symmetric)
  const Eigen::Matrix2d I_K = Eigen::Matrix2d::Identity() - K;
  Eigen::Matrix2d P = I_K * covariance_ * I_K.transpose() + K * R * K.transpose();
  up_odom_ = (up_odom_ + B * (K * y)).normalized();
  covariance_ = 0.5 * (P + P.transpose());
  ++updates_;
  return true;
}

Eigen::Matrix3d OdometryTilt::Level(const Eigen::Matrix3d& R_odom_robot) const {
  return LevelFromUp(R_odom_robot.transpose() * up_odom_);
}

Eigen::Matrix3d OdometryTilt::WorldCovariance(const Eigen::Matrix3d& R_world_robot,
                                              const Eigen::Matrix3d& R_odom_robot) const {
  const Eigen::Matrix<double, 3, 2> M = R_world_robot * R_odom_robot.transpose() * TangentBasis(up_odom_);
  Eigen::Matrix<double, 3, 2> J = Eigen::Matrix<double, 3, 2>::Zero();
  J.row(0) = M.row(1);
  J.row(1) = -M.row(0);
  return J * covariance_ * J.transpose();
}

}  // namespace waymark
