#include "sim/motion.h"

#include <cmath>
#include <stdexcept>

namespace waymark::sim {
namespace {

// Number of equal steps so that none exceeds max_step (at least one when amount > 0).
int StepCount(double amount, double max_step) {
  if (amount <= 0.0) return 0;
  return std::max(1, static_cast<int>(std::ceil(amount / max_step - 1e-9)));
}

// Arc (dx, dy) of a path of length s turning by dtheta, started along x.
Eigen::Vector2d ArcChord(double s, double dtheta) {
  if (std::abs(dtheta) < 1e-9) return {s * (1.0 - dtheta * dtheta / 6.0), s * dtheta / 2.0};
  return {s * std::sin(dtheta) / dtheta, s * (1.0 - std::cos(dtheta)) / dtheta};
}

// Length of the arc through the chord (dx, dy) turning by dtheta (negative when backing up).
double ArcLength(double dx, double dy, double dtheta) {
  const double chord = std::hypot(dx, dy);
  const double sign = dx < 0.0 ? -1.0 : 1.0;
  if (std::abs(dtheta) < 1e-9) return sign * chord;
  return sign * chord * (0.5 * dtheta) / std::sin(0.5 * dtheta);
}

}  // namespace

double SimTrajectory::LengthM() const {
  double length_m = 0.0;
  for (size_t k = 1; k < T_world_robot.size(); ++k) {
    if (segment[k] != segment[k - 1]) continue;
    length_m += (T_world_robot[k].T.translation() - T_world_robot[k - 1].T.translation()).norm();
  }
  return length_m;
}

PlanarPathBuilder::PlanarPathBuilder(const SE2d& T_world_start, double rate_hz, double speed_mps,
                                     double turn_rate_rad_s)
    : dt_s_(1.0 / rate_hz),
      speed_mps_(speed_mps),
      turn_rate_rad_s_(turn_rate_rad_s),
      current_(T_world_start) {
  if (!(rate_hz > 0.0 && speed_mps > 0.0 && turn_rate_rad_s > 0.0)) {
    throw std::invalid_argument("path: rate, speed and turn rate must be positive");
  }
  samples_.emplace_back(stamp_s_, current_);
  segments_.push_back(segment_);
}

void PlanarPathBuilder::Step(const SE2d& T_step) {
  current_ = current_ * T_step;
  stamp_s_ += dt_s_;
  samples_.emplace_back(stamp_s_, current_);
  segments_.push_back(segment_);
}

void PlanarPathBuilder::TurnBy(double angle_rad) {
  const int n = StepCount(std::abs(angle_rad), turn_rate_rad_s_ * dt_s_);
  for (int i = 0; i < n; ++i) Step(SE2d(0.0, 0.0, angle_rad / n));
}

void PlanarPathBuilder::TurnTo(double yaw_rad) { TurnBy(WrapAngle(yaw_rad - current_.theta())); }

void PlanarPathBuilder::DriveTo(const Eigen::Vector2d& target_world) {
  const Eigen::Vector2d delta = target_world - current_.translation();
  const double distance_m = delta.norm();
  if (distance_m < 1e-9) return;
  TurnTo(std::atan2(delta.y(), delta.x()));
  const int n = StepCount(distance_m, speed_mps_ * dt_s_);
  for (int i = 0; i < n; ++i) Step(SE2d(distance_m / n, 0.0, 0.0));
}

void PlanarPathBuilder::Wait(double duration_s) {
  const int n = StepCount(duration_s, dt_s_);
  for (int i = 0; i < n; ++i) Step(SE2d());
}

void PlanarPathBuilder::CarryTo(const SE2d& T_world_new, double duration_s) {
  current_ = T_world_new;
  stamp_s_ += std::max(duration_s, dt_s_);
  ++segment_;
  samples_.emplace_back(stamp_s_, current_);
  segments_.push_back(segment_);
}

SimTrajectory PlanarPathBuilder::Build(double height_m) const {
  SimTrajectory out;
  for (const auto& [stamp_s, T_world_robot] : samples_)
    out.T_world_robot.push_back({stamp_s, T_world_robot.ToSE3(height_m)});
  out.segment = segments_;
  return out;
}

FlightPathBuilder::FlightPathBuilder(const Eigen::Vector3d& start_world, double yaw_rad, double rate_hz,
                                     double speed_mps, double yaw_rate_rad_s, double wobble_rad)
    : dt_s_(1.0 / rate_hz),
      speed_mps_(speed_mps),
      yaw_rate_rad_s_(yaw_rate_rad_s),
      wobble_rad_(wobble_rad),
      position_(start_world),
      yaw_rad_(yaw_rad) {
  if (!(rate_hz > 0.0 && speed_mps > 0.0 && yaw_rate_rad_s > 0.0)) {
    throw std::invalid_argument("flight: rate, speed and yaw rate must be positive");
  }
  Sample();
}

void FlightPathBuilder::Sample() {
  // Roll and pitch: two sines at incommensurate frequencies (0.37 Hz, 0.23 Hz).
  const double roll_rad = wobble_rad_ * std::sin(2.0 * M_PI * 0.37 * stamp_s_);
  const double pitch_rad = wobble_rad_ * std::sin(2.0 * M_PI * 0.23 * stamp_s_ + 1.0);
  const Eigen::Quaterniond q = Eigen::AngleAxisd(yaw_rad_, Eigen::Vector3d::UnitZ()) *
                               Eigen::AngleAxisd(pitch_rad, Eigen::Vector3d::UnitY()) *
                               Eigen::AngleAxisd(roll_rad, Eigen::Vector3d::UnitX());
  samples_.push_back({stamp_s_, SE3d(q, position_)});
}

void FlightPathBuilder::YawTo(double yaw_rad) {
  const double delta_rad = WrapAngle(yaw_rad - yaw_rad_);
  const int n = StepCount(std::abs(delta_rad), yaw_rate_rad_s_ * dt_s_);
  for (int i = 0; i < n; ++i) {
    yaw_rad_ += delta_rad / n;
    stamp_s_ += dt_s_;
    Sample();
  }
}

void FlightPathBuilder::FlyTo(const Eigen::Vector3d& target_world) {
  const Eigen::Vector3d delta = target_world - position_;
  const int n = StepCount(delta.norm(), speed_mps_ * dt_s_);
  for (int i = 0; i < n; ++i) {
    position_ += delta / n;
    stamp_s_ += dt_s_;
    Sample();
  }
}

SimTrajectory FlightPathBuilder::Build() const {
  SimTrajectory out;
  out.T_world_robot = samples_;
  out.segment.assign(samples_.size(), 0);
  return out;
}

SE2d WheelOdometryStep(const SE2d& step, const WheelOdometryModel& model, std::mt19937_64* rng,
                       std::normal_distribution<double>* normal) {
  const double half_track_m = 0.5 * model.track_width_m;
  const double nominal_track_m = model.track_width_m * (1.0 + model.track_width_error);
  const double dtheta = step.theta();
  const double s = ArcLength(step.x(), step.y(), dtheta);
  const double s_left = (s - dtheta * half_track_m) / (1.0 + model.wheel_radius_error_left);
  const double s_right = (s + dtheta * half_track_m) / (1.0 + model.wheel_radius_error_right);
  const double s_meas = 0.5 * (s_left + s_right);
  const double dtheta_meas = (s_right - s_left) / nominal_track_m;
  Eigen::Vector2d d = ArcChord(s_meas, dtheta_meas);
  const double sigma_t = model.sigma.trans_per_m * std::abs(s);
  const double sigma_r = model.sigma.rot_per_rad * std::abs(dtheta);
  d.x() += sigma_t * (*normal)(*rng);
  d.y() += sigma_t * (*normal)(*rng);
  return SE2d(d.x(), d.y(), dtheta_meas + sigma_r * (*normal)(*rng));
}

Trajectory SimulateWheelOdometry(const SimTrajectory& truth, const WheelOdometryModel& model,
                                 std::mt19937_64* rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  Trajectory odometry;
  SE2d T_odom_robot;
  for (size_t k = 0; k < truth.T_world_robot.size(); ++k) {
    if (k > 0 && truth.segment[k] == truth.segment[k - 1]) {
      const SE2d step =
          SE2d::FromSE3(truth.T_world_robot[k - 1].T).inverse() * SE2d::FromSE3(truth.T_world_robot[k].T);
      T_odom_robot = T_odom_robot * WheelOdometryStep(step, model, rng, &normal);
    } else {
      T_odom_robot = SE2d();  // first sample, or set down after a carry
    }
    odometry.push_back({truth.T_world_robot[k].stamp_s, T_odom_robot.ToSE3()});
  }
  return odometry;
}

Trajectory SimulateVisualOdometry(const SimTrajectory& truth, const VisualOdometryModel& model,
                                  std::mt19937_64* rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  auto noise3 = [&](double sigma) -> Eigen::Vector3d {
    const double x = normal(*rng), y = normal(*rng), z = normal(*rng);
    return Eigen::Vector3d(x, y, z) * sigma;
  };
  Trajectory odometry;
  SE3d T_odom_robot;
  for (size_t k = 0; k < truth.T_world_robot.size(); ++k) {
    if (k > 0 && truth.segment[k] == truth.segment[k - 1]) {
      const SE3d step = truth.T_world_robot[k - 1].T.inverse() * truth.T_world_robot[k].T;
      const double distance_m = step.translation().norm();
      const double angle_rad = LogSO3(step.rotation()).norm();
      const Eigen::Vector3d t_meas =
          (1.0 + model.scale_error) * step.translation() + noise3(model.sigma.trans_per_m * distance_m);
      const Eigen::Quaterniond q_meas =
          step.rotation() * ExpSO3(noise3(model.sigma.rot_per_rad * angle_rad)) *
          Eigen::Quaterniond(
              Eigen::AngleAxisd(model.yaw_drift_rad_per_m * distance_m, Eigen::Vector3d::UnitZ()));
      T_odom_robot = T_odom_robot * SE3d(q_meas, t_meas);
    } else {
      T_odom_robot = SE3d();
    }
    odometry.push_back({truth.T_world_robot[k].stamp_s, T_odom_robot});
  }
  return odometry;
}

}  // namespace waymark::sim
