// The closed loop in simulation: a differential-drive robot follows a route (plan/route.h) with
// a pure-pursuit controller fed only by the online localizer's pose (online/localizer.h, run on
// the simulated odometry and detections against a map), never by the truth. The simulator
// (sim::SimStepper) moves the true robot with the commanded (v, omega) and draws the scenario's
// odometry and detection noise, exactly as `waymark sim` does for a scripted path.
//
// Controller, once per odometry sample, on the estimate x = (x, y, theta) after that sample:
//   not yet localized        turn in place at half the turn rate (look for a code);
//   tracking                 project x onto the route polyline, searching only from the current
//                            segment on (progress never goes back: the rule [George] states as
//                            "skip p_i when |a1| + |a2| > |b3| + pi/2"); the target is the point
//                            `lookahead_m` further along (the goal once nearer);
//                              alpha = angle(target - p) - theta,
//                            |alpha| > max_heading_error (near_goal_heading_error within
//                            near_goal_m of the goal): turn in place, omega = clamp(k_turn alpha);
//                            else pure pursuit: v = clamp(speed * remaining / slow_radius_m,
//                            min_speed, speed), omega = clamp(2 v sin(alpha) / |target - p|),
//                            backing up (alpha - pi, v < 0) when the goal is within near_goal_m
//                            and behind;
//                            at the goal (|goal - p| < goal_tolerance_m): turn in place to the
//                            route's goal yaw when it has one, then stop;
//   suspect or lost          stop; after search_after_s, turn slowly in place (look for a code).
// [Bach]'s controller (eq. 14: v ~ distance, omega ~ bearing error to the desired point) is
// the special case lookahead -> 0 with a proportional speed; pure pursuit keeps the robot on the
// segment between waypoints, which matters in doors.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "geometry/pose.h"
#include "geometry/types.h"
#include "online/localizer.h"
#include "plan/route.h"
#include "sim/params.h"
#include "sim/simulator.h"

namespace waymark::plan {

struct DriveOptions {
  double speed_mps = 0.3;
  double turn_rate_radps = 0.5;
  double lookahead_m = 0.3;
  double min_speed_mps = 0.02;
  double slow_radius_m = 0.3;
  double goal_tolerance_m = 0.005;
  double goal_yaw_tolerance_rad = 0.01;
  double max_heading_error_rad = 1.0;
  double near_goal_m = 0.1;
  double near_goal_heading_error_rad = 0.35;
  double k_turn = 2.0;  // 1/s
  double search_after_s = 2.0;
  double max_time_s = 1200.0;
  // The robot is set down at the route's start with an error drawn (from the seed) with these
  // sigmas per axis, as by hand; when start_pose_known, the filter starts from the route's start
  // with that uncertainty (Localizer::InitializeAt, as AMCL's initial pose), else from its first
  // code.
  bool start_pose_known = true;
  double placement_sigma_m = 0.05;
  double placement_sigma_rad = 0.05;
  // The map's frame in the scenario's true world; nullopt: fitted on the codes (below).
  std::optional<SE2d> T_world_map;

  bool Check(std::string* why) const;
};

struct DriveReport {
  bool reached = false;  // the controller stopped at the goal (by its estimate)
  std::string outcome;   // "reached the goal", or why not
  double duration_s = 0.0;
  double path_length_m = 0.0;                             // true distance driven
  Eigen::Vector3d goal = Eigen::Vector3d::Zero();         // map frame
  Eigen::Vector3d final_truth = Eigen::Vector3d::Zero();  // the true final pose in the map frame
  std::optional<Eigen::Vector3d> final_estimate;
  double goal_error_m = 0.0;               // |truth - goal| at the end
  double goal_yaw_error_rad = 0.0;         // when the route has a goal yaw
  std::optional<double> estimate_error_m;  // |truth - estimate| at the end
  double max_estimate_error_m = 0.0;       // over every frame with a pose
  long frames = 0, frames_tracking = 0, frames_suspect = 0, frames_lost = 0, frames_uninitialized = 0;
  long times_lost = 0, times_suspect = 0;
};

struct DriveResult {
  sim::SimResult sim;                // truth, odometry, detections (a normal dataset)
  Trajectory online;                 // the localizer's poses while tracking, one per camera frame
  std::vector<PoseOutput> outputs;   // every frame
  std::vector<std::string> cameras;  // outputs[i]'s camera
  DriveReport report;
};

// Frames. The route and the localizer are in the map's frame; the simulator in the scenario's
// true world. The robot is set down at the route's first waypoint mapped into the world by
// T_world_map, the rigid fit of the map's codes on the scenario's true codes (the largest
// component; the simulator's knowledge, never the controller's). The report's poses are in the
// map's frame (the truth mapped by T_world_map^-1), so goal_error_m includes the map's own error
// where it moves the goal.
//
// Drives `route` in `scenario` (planar, wheel odometry) from its first waypoint with noise `seed`, localizing
// against `map` with `localizer` options (nullopt: the runner's defaults for the simulated dataset). Throws
// std::invalid_argument for bad options or scenarios.
DriveResult DriveRoute(const std::string& scenario, const sim::ParamSet& params, std::uint64_t seed,
                       const Route& route, const MarkerMap& map,
                       const std::optional<LocalizerOptions>& localizer, const DriveOptions& options);

// drive.json (docs/formats.md, "Drive report").
std::string FormatDriveReport(const DriveReport& report);
// "reached the goal: 3.1 mm from it (estimate 2.0 mm off the truth), 0 lost, 0 suspect, 41.2 s"
std::string DriveSummaryLine(const DriveReport& report);

}  // namespace waymark::plan
