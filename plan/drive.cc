#include "plan/drive.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <sstream>
#include <stdexcept>

#include "eval/map_metrics.h"
#include "geometry/pose.h"
#include "runner/run.h"
#include "sim/scenarios.h"
#include "util/check.h"
#include "util/format.h"

namespace waymark::plan {
namespace {

double Clamp(double value, double limit) { return std::max(-limit, std::min(limit, value)); }

struct Command {
  double v = 0.0, omega = 0.0;
  bool done = false;
};

// The pure-pursuit follower of the header comment.
class Follower {
 public:
  Follower(const Route& route, const DriveOptions& options) : options_(options) {
    for (const RouteWaypoint& w : route.waypoints) points_.push_back(w.x_y_yaw.head<2>());
    goal_yaw_ =
        route.goal_yaw_given ? std::optional<double>(route.waypoints.back().x_y_yaw.z()) : std::nullopt;
    cumulative_.push_back(0.0);
    for (size_t i = 1; i < points_.size(); ++i) {
      cumulative_.push_back(cumulative_.back() + (points_[i] - points_[i - 1]).norm());
    }
  }

  Command Step(const Eigen::Vector3d& x) {
    Command c;
    const Eigen::Vector2d p = x.head<2>(), goal = points_.back();
    const double to_goal = (goal - p).norm();
    if (at_goal_ || to_goal < options_.goal_tolerance_m) {
      at_goal_ = true;
      if (!goal_yaw_) {
        c.done = true;
        return c;
      }
      const double error = WrapAngle(*goal_yaw_ - x.z());
      if (std::abs(error) < options_.goal_yaw_tolerance_rad) {
        c.done = true;
        return c;
      }
      c.omega = Clamp(options_.k_turn * error, options_.turn_rate_radps);
      if (std::abs(c.omega) < 0.05) c.omega = std::copysign(0.05, error);
      return c;
    }
    const double along = Project(p);
    const double remaining = cumulative_.back() - along;
    const Eigen::Vector2d target =
        remaining < options_.lookahead_m ? goal : PointAt(along + options_.lookahead_m);
    const Eigen::Vector2d d = target - p;
    double alpha = WrapAngle(std::atan2(d.y(), d.x()) - x.z());
    const bool near = to_goal < options_.near_goal_m;
    double sign = 1.0;
    if (near && std::abs(alpha) > 0.5 * M_PI) {  // the goal is behind: back up
      alpha = WrapAngle(alpha + M_PI);
      sign = -1.0;
    }
    const double max_error = near ? options_.near_goal_heading_error_rad : options_.max_heading_error_rad;
    if (std::abs(alpha) > max_error) {
      c.omega = Clamp(options_.k_turn * alpha, options_.turn_rate_radps);
      return c;
    }
    const double speed =
        std::max(options_.min_speed_mps,
                 std::min(options_.speed_mps,
                          options_.speed_mps * std::min(remaining, to_goal) / options_.slow_radius_m));
    c.v = sign * speed;
    c.omega = Clamp(2.0 * speed * std::sin(alpha) / std::max(d.norm(), 1e-3), options_.turn_rate_radps);
    return c;
  }

 private:
  // Arc length of p's projection, from the current progress on (never backwards). Where the
  // route doubles back, projections on several segments are (nearly) as close: the furthest
  // along of those within 1 cm of the closest is taken, so that a robot at the tip of a U-turn
  // moves on to the way back.
  double Project(const Eigen::Vector2d& p) {
    struct Hit {
      double distance, along;
      size_t segment;
    };
    std::vector<Hit> hits;
    for (size_t i = segment_; i + 1 < points_.size() && i < segment_ + 4; ++i) {
      const Eigen::Vector2d a = points_[i], b = points_[i + 1];
      const double length = (b - a).norm();
      double t = length < 1e-9 ? 0.0 : std::clamp((p - a).dot(b - a) / (length * length), 0.0, 1.0);
      if (cumulative_[i] + t * length < progress_)
        t = length < 1e-9 ? 0.0 : (progress_ - cumulative_[i]) / length;
      if (t > 1.0) continue;
      hits.push_back({(a + t * (b - a) - p).norm(), cumulative_[i] + t * length, i});
    }
    if (hits.empty()) return progress_;
    double closest = std::numeric_limits<double>::infinity();
    for (const Hit& h : hits) closest = std::min(closest, h.distance);
    for (const Hit& h : hits) {
      if (h.distance <= closest + 0.01 && h.along >= progress_) {
        progress_ = h.along;
        segment_ = h.segment;
      }
    }
    return progress_;
  }

  Eigen::Vector2d PointAt(double along) const {
    along = std::min(along, cumulative_.back());
    for (size_t i = 0; i + 1 < points_.size(); ++i) {
      if (along <= cumulative_[i + 1]) {
        const double length = cumulative_[i + 1] - cumulative_[i];
        const double t = length < 1e-9 ? 0.0 : (along - cumulative_[i]) / length;
        return points_[i] + t * (points_[i + 1] - points_[i]);
      }
    }
    return points_.back();
  }

  DriveOptions options_;
  std::vector<Eigen::Vector2d> points_;
  std::vector<double> cumulative_;
  std::optional<double> goal_yaw_;
  size_t segment_ = 0;
  double progress_ = 0.0;
  bool at_goal_ = false;
};

Eigen::Vector3d XYYaw(const SE3d& T) { return {T.translation().x(), T.translation().y(), T.yaw()}; }
Eigen::Vector3d XYYaw(const SE2d& T) { return {T.x(), T.y(), T.theta()}; }

// The map's frame in the scenario's true world (rigid fit of the map's codes on the true ones,
// eval/map_metrics.h; the largest component): the simulator's knowledge, used only to set the
// robot down at the route's start and to score the outcome, never by the controller.
SE2d WorldFromMap(const std::string& scenario, const sim::ParamSet& params, const MarkerMap& map) {
  MarkerMap truth;
  for (const sim::SimMarker& m : sim::BuildScene(scenario, params).world.markers) {
    MapMarker entry;
    entry.key = m.key;
    entry.size_m = m.size_m;
    entry.T_world_marker = m.T_world_marker;
    truth.markers.push_back(entry);
  }
  eval::MapEvalResult fit;
  try {
    fit = eval::EvaluateMap(map, truth);
  } catch (const std::exception& e) {
    throw std::invalid_argument("the map does not fit scenario " + scenario + ": " + e.what());
  }
  const eval::ComponentResult* best = nullptr;
  for (const eval::ComponentResult& c : fit.components) {
    if (c.method != eval::MapAlignmentMethod::kNone && (!best || c.markers > best->markers)) best = &c;
  }
  if (!best) throw std::invalid_argument("the map does not fit scenario " + scenario + ": no code in common");
  return SE2d::FromSE3(SE3d(Eigen::Quaterniond(best->alignment.R_gt_est), best->alignment.t_gt_est));
}

}  // namespace

bool DriveOptions::Check(std::string* why) const {
  WAYMARK_CHECK_OPTION(IsFinitePositive(speed_mps), "speed_mps must be > 0");
  WAYMARK_CHECK_OPTION(IsFinitePositive(turn_rate_radps), "turn_rate_radps must be > 0");
  WAYMARK_CHECK_OPTION(IsFinitePositive(lookahead_m), "lookahead_m must be > 0");
  WAYMARK_CHECK_OPTION(IsFiniteInRange(min_speed_mps, 1e-6, speed_mps),
                       "min_speed_mps must be in (0, speed_mps]");
  WAYMARK_CHECK_OPTION(IsFinitePositive(slow_radius_m), "slow_radius_m must be > 0");
  WAYMARK_CHECK_OPTION(IsFinitePositive(goal_tolerance_m), "goal_tolerance_m must be > 0");
  WAYMARK_CHECK_OPTION(IsFinitePositive(goal_yaw_tolerance_rad), "goal_yaw_tolerance_rad must be > 0");
  WAYMARK_CHECK_OPTION(IsFiniteInRange(max_heading_error_rad, 0.01, M_PI),
                       "max_heading_error_rad in [0.01, pi]");
  WAYMARK_CHECK_OPTION(IsFiniteAtLeast(near_goal_m, goal_tolerance_m),
                       "near_goal_m must be >= goal_tolerance_m");
  WAYMARK_CHECK_OPTION(IsFiniteInRange(near_goal_heading_error_rad, 0.01, M_PI),
                       "near_goal_heading_error_rad in [0.01, pi]");
  WAYMARK_CHECK_OPTION(IsFinitePositive(k_turn), "k_turn must be > 0");
  WAYMARK_CHECK_OPTION(IsFiniteAtLeast(search_after_s, 0.0), "search_after_s must be >= 0");
  WAYMARK_CHECK_OPTION(IsFinitePositive(max_time_s), "max_time_s must be > 0");
  WAYMARK_CHECK_OPTION(IsFinitePositive(placement_sigma_m), "placement_sigma_m must be > 0");
  WAYMARK_CHECK_OPTION(IsFinitePositive(placement_sigma_rad), "placement_sigma_rad must be > 0");
  return true;
}

DriveResult DriveRoute(const std::string& scenario, const sim::ParamSet& params, std::uint64_t seed,
                       const Route& route, const MarkerMap& map,
                       const std::optional<LocalizerOptions>& localizer, const DriveOptions& options) {
  std::string why;
  if (!options.Check(&why)) throw std::invalid_argument("drive options: " + why);
  if (route.waypoints.empty()) throw std::invalid_argument("the route has no waypoint");
  const Eigen::Vector3d start = route.waypoints.front().x_y_yaw;
  const SE2d T_world_map = options.T_world_map ? *options.T_world_map : WorldFromMap(scenario, params, map);
  const SE2d T_map_world = T_world_map.inverse();
  std::seed_seq placement_seed{static_cast<std::uint32_t>(seed), static_cast<std::uint32_t>(seed >> 32), 3u};
  std::mt19937_64 placement_rng(placement_seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  const double ex = normal(placement_rng), ey = normal(placement_rng), eyaw = normal(placement_rng);
  const SE2d T_map_start(start.x(), start.y(), start.z());
  const SE2d placement(options.placement_sigma_m * ex, options.placement_sigma_m * ey,
                       options.placement_sigma_rad * eyaw);
  sim::SimStepper stepper(scenario, params, seed, T_world_map * T_map_start * placement);
  auto truth_in_map = [&] { return XYYaw(T_map_world * stepper.T_world_robot()); };
  const Dataset& dataset = stepper.dataset();
  std::vector<CameraInfo> cameras;
  for (const std::string& name : dataset.config.cameras) cameras.push_back(dataset.cameras.at(name));
  Localizer filter(localizer ? *localizer : DefaultLocalizerOptions(dataset), map, cameras);
  Follower follower(route, options);

  DriveResult result;
  DriveReport& report = result.report;
  report.goal = route.waypoints.back().x_y_yaw;
  bool initialized = false;
  double not_tracking_since = 0.0;
  auto consume = [&](const sim::SimStepper::Sample& sample) {
    filter.AddOdometry(sample.stamp_s, sample.T_odom_robot);
    for (const DetectionFrame& frame : sample.frames) {
      filter.AddDetections(frame);
      const PoseOutput out = filter.Output();
      result.outputs.push_back(out);
      result.cameras.push_back(frame.camera);
      ++report.frames;
      if (out.tracking == TrackingStatus::kTracking) initialized = true;
      switch (out.tracking) {
        case TrackingStatus::kTracking:
          ++report.frames_tracking;
          break;
        case TrackingStatus::kSuspect:
          ++report.frames_suspect;
          break;
        case TrackingStatus::kLost:
          ++report.frames_lost;
          break;
        case TrackingStatus::kUninitialized:
          ++report.frames_uninitialized;
          break;
      }
      if (out.T_world_robot) {
        if (result.online.empty() || result.online.back().stamp_s < sample.stamp_s) {
          result.online.push_back({sample.stamp_s, *out.T_world_robot});
        }
        const double error = (XYYaw(*out.T_world_robot).head<2>() - truth_in_map().head<2>()).norm();
        report.max_estimate_error_m = std::max(report.max_estimate_error_m, error);
      }
    }
  };
  if (options.start_pose_known) {
    const Eigen::Vector3d variance(std::pow(options.placement_sigma_m, 2),
                                   std::pow(options.placement_sigma_m, 2),
                                   std::pow(options.placement_sigma_rad, 2));
    if (filter.InitializeAt(0.0, T_map_start.ToSE3(), Eigen::Matrix3d(variance.asDiagonal())) !=
        StepStatus::kOk) {
      throw std::invalid_argument("the localizer refused the start pose");
    }
  }
  consume(stepper.first());
  double stamp_s = 0.0;
  report.outcome = "time limit reached";
  while (stamp_s < options.max_time_s) {
    Command command;
    const PoseOutput out = filter.Output();
    if (out.tracking == TrackingStatus::kTracking && out.T_world_robot) {
      not_tracking_since = stamp_s;
      command = follower.Step(XYYaw(*out.T_world_robot));
      if (command.done) {
        report.reached = true;
        report.outcome = "reached the goal";
        break;
      }
    } else if (!initialized) {
      command.omega = 0.5 * options.turn_rate_radps;
    } else if (stamp_s - not_tracking_since > options.search_after_s) {
      command.omega = 0.25 * options.turn_rate_radps;
    }
    const sim::SimStepper::Sample sample = stepper.Advance(command.v, command.omega);
    stamp_s = sample.stamp_s;
    consume(sample);
  }
  report.times_lost = filter.counters().times_lost;
  report.times_suspect = filter.counters().times_suspect;
  report.final_truth = truth_in_map();
  const PoseOutput last = filter.Output();
  if (last.T_world_robot) {
    report.final_estimate = XYYaw(*last.T_world_robot);
    report.estimate_error_m = (report.final_estimate->head<2>() - report.final_truth.head<2>()).norm();
  }
  report.goal_error_m = (report.final_truth.head<2>() - report.goal.head<2>()).norm();
  report.goal_yaw_error_rad =
      route.goal_yaw_given ? std::abs(WrapAngle(report.final_truth.z() - report.goal.z())) : 0.0;
  result.sim = stepper.Finish();
  report.duration_s = result.sim.stats.duration_s;
  report.path_length_m = result.sim.stats.path_length_m;
  return result;
}

std::string FormatDriveReport(const DriveReport& r) {
  auto vec = [](const Eigen::Vector3d& v) {
    return "[" + FormatDouble(v.x()) + ", " + FormatDouble(v.y()) + ", " + FormatDouble(v.z()) + "]";
  };
  std::ostringstream out;
  out << "{\"format\": \"waymark-drive\", \"version\": 1,\n \"reached\": " << (r.reached ? "true" : "false")
      << ", \"outcome\": \"" << r.outcome << "\",\n \"goal\": " << vec(r.goal)
      << ", \"final_truth\": " << vec(r.final_truth);
  if (r.final_estimate) out << ", \"final_estimate\": " << vec(*r.final_estimate);
  out << ",\n \"goal_error_m\": " << FormatDouble(r.goal_error_m)
      << ", \"goal_yaw_error_rad\": " << FormatDouble(r.goal_yaw_error_rad);
  if (r.estimate_error_m) out << ", \"estimate_error_m\": " << FormatDouble(*r.estimate_error_m);
  out << ", \"max_estimate_error_m\": " << FormatDouble(r.max_estimate_error_m)
      << ",\n \"duration_s\": " << FormatDouble(r.duration_s)
      << ", \"path_length_m\": " << FormatDouble(r.path_length_m) << ",\n \"frames\": " << r.frames
      << ", \"frames_tracking\": " << r.frames_tracking << ", \"frames_suspect\": " << r.frames_suspect
      << ", \"frames_lost\": " << r.frames_lost << ", \"frames_uninitialized\": " << r.frames_uninitialized
      << ", \"times_lost\": " << r.times_lost << ", \"times_suspect\": " << r.times_suspect << "}\n";
  return out.str();
}

std::string DriveSummaryLine(const DriveReport& r) {
  std::string line = r.outcome + ": " + FormatFixed(1000.0 * r.goal_error_m, 1) + " mm from the goal";
  if (r.estimate_error_m)
    line += " (estimate " + FormatFixed(1000.0 * *r.estimate_error_m, 1) + " mm off the truth)";
  line += ", lost " + std::to_string(r.times_lost) + "x, suspect " + std::to_string(r.times_suspect) + "x, " +
          FormatFixed(r.path_length_m, 2) + " m in " + FormatFixed(r.duration_s, 1) + " s";
  return line;
}

}  // namespace waymark::plan
