// Routes over a survey ([George] §III-D): where a robot can drive on a map, and which way.
//
// Graph. The nodes are the survey's traversed poses (the online filter's poses while tracking,
// localized against the map), thinned: a pose becomes a node when no node lies within
// `node_spacing_m` of it, and is otherwise merged into its nearest node. A node keeps its
// position, a heading (its first pose's), the codes of the map detected from any of its poses
// and the filter's planar covariance there (the smallest, by trace, among its poses with a code
// in view; without one, its first pose's). Edges join
//   traversed     consecutive tracking poses of the survey merged into two different nodes
//                 (the survey drove between them; a jump above `max_step_m` between consecutive
//                 poses, a carry or a relocalization, joins nothing);
//   co-visible    two nodes from which at least one common code was detected ([George]: "two
//                 observation points are connectible if one bar code is visible from both"),
//                 at most `max_covisible_m` apart: the space between them is assumed free.
//
// Cost of an edge u -> v entered from w (Dijkstra over directed edges, so the turn counts):
//   length_m(u, v) + turn_cost_per_rad |angle(w -> u, u -> v)|
//                  + uncertainty_cost_per_m * sigma_blind(u, v)
// where sigma_blind is the position sigma (sqrt of the trace of the x-y block) that odometry
// alone accumulates from zero over the edge's blind length: the whole edge when neither end has
// a code in view, half of it when one end has, none otherwise (PredictPlanarIncrement of
// online/motion_model.h with the survey's odometry noise, in `step_m` steps). The route joins
// the start point to its nearest node and the goal's nearest node to the goal point with straight
// legs (each no longer than `max_snap_m`), which count as edges (the goal leg is blind when its
// node has no code in view). In the route written, a first (last) node nearer than half the node
// spacing to the start (goal) is passed by, and so is a first node that would turn the robot
// back ([George]'s rule, route.cc); `cost` stays the graph path's.
//
// Predicted pose covariance along the route (planar x, y, yaw): from the start node's
// covariance, propagated with the same motion model along each leg (turns in place at the
// waypoints, `step_m` / `step_rad` per increment); at a node with a code in view it becomes the
// node's covariance when that is smaller (by trace): what the filter had there in the survey.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "geometry/types.h"
#include "online/motion_model.h"

namespace waymark::plan {

// One pose of the survey, localized against the map.
struct SurveyPose {
  double stamp_s = 0.0;
  Eigen::Vector3d x_y_yaw = Eigen::Vector3d::Zero();
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();  // x, y, yaw
  std::set<MarkerKey> codes;                             // codes of the map detected at this instant
  int component = 0;  // the map component (own world frame) the pose is in: of the last code seen
};

struct RouteOptions {
  double node_spacing_m = 0.5;
  double max_step_m = 0.5;       // consecutive survey poses farther apart are not joined
  double max_covisible_m = 2.0;  // co-visible nodes farther apart are not joined
  double max_snap_m = 1.0;       // start and goal at most this far from a node
  double turn_cost_per_rad = 0.2;
  double uncertainty_cost_per_m = 100.0;  // cost of 1 m of blind position sigma (1 cm: 1 m of path)
  double step_m = 0.02;                   // motion-model increment for the predictions
  double step_rad = 0.05;
  OdometryNoise odometry;  // the survey's (DefaultLocalizerOptions)

  bool Check(std::string* why) const;
};

struct RouteNode {
  Eigen::Vector2d position_world = Eigen::Vector2d::Zero();
  double yaw_rad = 0.0;
  std::set<MarkerKey> codes;
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  int component = 0;
  // For --to-code: the heading of a survey pose that saw each code from this node.
  std::vector<std::pair<MarkerKey, double>> code_yaw_rad;
};

struct RouteEdge {
  int a = 0, b = 0;
  bool traversed = false;
  bool covisible = false;
};

struct SurveyGraph {
  std::vector<RouteNode> nodes;
  std::vector<RouteEdge> edges;
  int components = 0;
};

SurveyGraph BuildSurveyGraph(const std::vector<SurveyPose>& poses, const RouteOptions& options);

struct RouteGoal {
  std::optional<Eigen::Vector3d> pose;  // x, y and yaw (yaw may be NaN: free)
  std::optional<MarkerKey> code;        // or: drive to where this code was seen from
};

struct RouteWaypoint {
  Eigen::Vector3d x_y_yaw = Eigen::Vector3d::Zero();     // yaw: heading of the next leg (last: goal yaw)
  int node = -1;                                         // -1: the start or goal point
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();  // predicted on arrival (after the turn)
};

struct RouteSegment {
  double length_m = 0.0;
  std::vector<MarkerKey> codes;       // codes expected in view (seen from either end in the survey)
  double blind_m = 0.0;               // part of the segment with no code in view
  double max_position_sigma_m = 0.0;  // predicted along the segment
};

struct Route {
  std::vector<RouteWaypoint> waypoints;
  std::vector<RouteSegment> segments;  // waypoints[i] -> waypoints[i + 1]
  double length_m = 0.0;
  double cost = 0.0;
  double turn_rad = 0.0;  // total turning
  double blind_m = 0.0;
  double max_position_sigma_m = 0.0;
  bool goal_yaw_given = false;
  std::optional<MarkerKey> goal_code;
};

// Plans from `start` (x, y, yaw; yaw NaN: free) to `goal`. Throws std::invalid_argument with one
// line for a start or goal off the graph, a goal in another component, an unknown code or one
// never seen in the survey. `map` is only used for --to-code.
Route PlanRoute(const SurveyGraph& graph, const Eigen::Vector3d& start, const RouteGoal& goal,
                const RouteOptions& options);

// Concatenates legs planned one after the other (start of each = end of the previous).
Route JoinRoutes(const std::vector<Route>& legs);

}  // namespace waymark::plan
