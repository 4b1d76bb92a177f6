// True robot motion and the odometry a robot would measure along it.
//
// Trajectories are sampled at a fixed rate (the odometry rate). A trajectory may be cut into
// segments: the robot is carried (picked up and set down elsewhere) between segments, so no
// sample is taken during the carry and odometry restarts from identity in each segment.
//
// Wheel odometry (differential drive, planar). Per step k the true body-frame increment
// (dx, dy, dtheta) of T_world_robot is an arc of length s; the wheels roll
//   s_l = s - dtheta L / 2,   s_r = s + dtheta L / 2            (L: true track width)
// and the encoders, read with the nominal radius while the true radius is (1 + e) times it,
// report s_l / (1 + e_l) and s_r / (1 + e_r). Odometry integrates with the nominal track width
// L (1 + e_L):   s' = (s_l' + s_r') / 2,   dtheta' = (s_r' - s_l') / (L (1 + e_L)),
// turns (s', dtheta') back into an arc (dx', dy', dtheta') and adds white noise
//   dx', dy' += N(0, (trans_per_m |s|)^2),   dtheta' += N(0, (rot_per_rad |dtheta|)^2),
// which is the noise model dataset.yaml's odometry_sigma states (per step, proportional to the
// distance and the angle travelled). The e_* are the systematic error; they are not in
// odometry_sigma.
//
// Visual odometry (6-DoF, drones). Per step the true increment dT = (dR, dt) becomes
//   dt' = (1 + scale_error) dt + N(0, (trans_per_m |dt|)^2 I)
//   dR' = dR Exp(N(0, (rot_per_rad |Log dR|)^2 I)) Rz(yaw_drift_rad_per_m |dt|)
// (the yaw drift is about the body z axis, which stays near vertical in level flight).
#pragma once

#include <Eigen/Core>
#include <random>
#include <vector>

#include "geometry/pose.h"
#include "geometry/types.h"

namespace waymark::sim {

struct SimTrajectory {
  Trajectory T_world_robot;  // true poses, stamps in seconds
  std::vector<int> segment;  // per sample; increases by one at each carry
  double LengthM() const;    // path length, carries excluded
};

// Builds a differential-drive path: turns in place and straight runs at constant rates,
// sampled every 1 / rate_hz seconds. Every step is an exact SE(2) motion.
class PlanarPathBuilder {
 public:
  PlanarPathBuilder(const SE2d& T_world_start, double rate_hz, double speed_mps, double turn_rate_rad_s);

  void TurnBy(double angle_rad);                      // in place, positive = counter-clockwise
  void TurnTo(double yaw_rad);                        // shortest turn to a heading
  void DriveTo(const Eigen::Vector2d& target_world);  // turn to face the target, then straight
  void Wait(double duration_s);                       // stand still
  // Carried to `T_world_new` during `duration_s` (no samples; a new segment begins).
  void CarryTo(const SE2d& T_world_new, double duration_s);

  const SE2d& current() const { return current_; }
  SimTrajectory Build(double height_m = 0.0) const;

 private:
  void Step(const SE2d& T_step);

  double dt_s_, speed_mps_, turn_rate_rad_s_;
  SE2d current_;
  double stamp_s_ = 0.0;
  int segment_ = 0;
  std::vector<std::pair<double, SE2d>> samples_;
  std::vector<int> segments_;
};

// Builds a 6-DoF flight: yaw turns in place and straight flights between waypoints, with a
// deterministic roll/pitch wobble of amplitude `wobble_rad` (two incommensurate sines) on top,
// as a multirotor tilts while it holds a course.
class FlightPathBuilder {
 public:
  FlightPathBuilder(const Eigen::Vector3d& start_world, double yaw_rad, double rate_hz, double speed_mps,
                    double yaw_rate_rad_s, double wobble_rad);

  void YawTo(double yaw_rad);
  void FlyTo(const Eigen::Vector3d& target_world);  // keeps the current yaw (holonomic)
  SimTrajectory Build() const;

 private:
  void Sample();

  double dt_s_, speed_mps_, yaw_rate_rad_s_, wobble_rad_;
  Eigen::Vector3d position_;
  double yaw_rad_;
  double stamp_s_ = 0.0;
  Trajectory samples_;
};

struct WheelOdometryModel {
  double track_width_m = 0.3;
  double wheel_radius_error_left = 0.0;  // true radius / nominal - 1
  double wheel_radius_error_right = 0.0;
  double track_width_error = 0.0;  // nominal track width / true - 1
  OdometrySigma sigma;
};

struct VisualOdometryModel {
  double scale_error = 0.0;
  double yaw_drift_rad_per_m = 0.0;
  OdometrySigma sigma;
};

// One step of wheel odometry: the measured increment for the true increment `step` (the model
// above), drawing from `normal` (N(0, 1), kept by the caller: it caches every other draw) and rng.
SE2d WheelOdometryStep(const SE2d& step, const WheelOdometryModel& model, std::mt19937_64* rng,
                       std::normal_distribution<double>* normal);

// T_odom_robot at the stamps of `truth`, identity at the first sample of every segment.
Trajectory SimulateWheelOdometry(const SimTrajectory& truth, const WheelOdometryModel& model,
                                 std::mt19937_64* rng);
Trajectory SimulateVisualOdometry(const SimTrajectory& truth, const VisualOdometryModel& model,
                                  std::mt19937_64* rng);

}  // namespace waymark::sim
