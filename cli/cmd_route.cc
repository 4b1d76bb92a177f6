// `waymark route`: a route over a survey's poses (plan/route.h), written as route.json.
#include <cmath>
#include <iostream>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "cli/args.h"
#include "cli/command.h"
#include "io/dataset_io.h"
#include "io/map_io.h"
#include "io/util.h"
#include "plan/route.h"
#include "plan/route_io.h"
#include "plan/survey.h"
#include "util/format.h"

namespace waymark::cli {
namespace {

constexpr const char* kUsage = R"(Usage:
  waymark route MAP.json --survey DATASET --from X,Y[,YAW] --to X,Y[,YAW] --out ROUTE.json [options]
  waymark route MAP.json --survey DATASET --from X,Y[,YAW] --to-code FAMILY:ID --out ROUTE.json [options]

Plans a route on MAP.json over the poses of the survey DATASET ([George]'s observation points;
docs/planning.md). The survey is localized against the map; its poses, thinned to about 0.5 m,
are the nodes; two nodes are joined where the survey drove between them or where a code was seen
from both (at most 2 m apart). The cost of a route is its length, plus the position uncertainty
that odometry accumulates where no code is in view, plus its turning; Dijkstra finds the cheapest.
ROUTE.json (docs/formats.md, "Route") holds the waypoints, the codes expected along each segment,
the predicted pose covariance at each waypoint, the length and the cost. X, Y in metres in the
map's frame, YAW in radians (optional: free). A start or goal farther than --max-snap from every
survey pose, or a goal that no surveyed path reaches, is an error.

Options:
  --survey DATASET         the survey the map was built from (odometry + detections), required
  --from X,Y[,YAW]         start pose, required
  --to X,Y[,YAW]           goal pose, or
  --to-code FAMILY:ID      goal: the survey pose from which the code was seen that is cheapest to
                           reach, facing as the survey did there
  --via X,Y[;X,Y...]       pass these points in order (one Dijkstra leg per point)
  --component N            the map component (docs/formats.md: each has its own world frame) whose
                           survey poses make the graph (default 0)
  --out FILE               route.json, required
  --node-spacing M         thinning of the survey poses (default 0.5)
  --max-snap M             start, goal and via points at most this far from a node (default 1.0)
  --turn-cost C            cost per radian turned, in metres (default 0.2)
  --uncertainty-cost C     cost per metre of position sigma accumulated without a code in view
                           (default 100: 1 cm of sigma costs as much as 1 m of path)
)";

Eigen::Vector3d ParsePose(const Args& args, const std::string& name) {
  args.Require(name);
  const std::vector<double> v = *args.GetDoubleList(name);
  if (v.size() != 2 && v.size() != 3) {
    throw std::invalid_argument("option --" + name + ": expected X,Y or X,Y,YAW, got " +
                                std::to_string(v.size()) + " numbers");
  }
  return {v[0], v[1], v.size() == 3 ? v[2] : std::nan("")};
}

std::vector<Eigen::Vector3d> ParseVia(const std::string& text) {
  std::vector<Eigen::Vector3d> points;
  size_t begin = 0;
  while (begin <= text.size()) {
    const size_t end = std::min(text.find(';', begin), text.size());
    const std::string item = text.substr(begin, end - begin);
    const size_t comma = item.find(',');
    const std::optional<double> x =
        comma == std::string::npos ? std::nullopt : ParseFiniteDouble(item.substr(0, comma));
    const std::optional<double> y =
        comma == std::string::npos ? std::nullopt : ParseFiniteDouble(item.substr(comma + 1));
    if (!x || !y) throw std::invalid_argument("option --via: expected X,Y[;X,Y...], got '" + item + "'");
    points.emplace_back(*x, *y, std::nan(""));
    begin = end + 1;
  }
  return points;
}

int RunRoute(const std::vector<std::string>& argv) {
  const Args args(argv,
                  {"survey", "from", "to", "to-code", "via", "out", "node-spacing", "max-snap", "turn-cost",
                   "uncertainty-cost", "component"},
                  {});
  if (args.Help()) {
    std::cout << kUsage;
    return 0;
  }
  args.ExpectPositionals(1, 1, "MAP.json");
  const std::string out = args.Require("out");
  const std::string survey_dir = args.Require("survey");
  const Eigen::Vector3d start = ParsePose(args, "from");
  if (!args.Has("to") && !args.Has("to-code")) {
    throw std::invalid_argument("option --to or --to-code is required");
  }
  if (args.Has("to") && args.Has("to-code"))
    throw std::invalid_argument("give either --to or --to-code, not both");
  plan::RouteGoal goal;
  if (args.Has("to")) goal.pose = ParsePose(args, "to");
  if (const auto code = args.Get("to-code")) {
    const size_t colon = code->find(':');
    if (colon == std::string::npos || colon == 0 || colon + 1 == code->size()) {
      throw std::invalid_argument("option --to-code: expected FAMILY:ID, got '" + *code + "'");
    }
    goal.code = MarkerKey{code->substr(0, colon), code->substr(colon + 1)};
  }
  const std::vector<Eigen::Vector3d> via =
      args.Has("via") ? ParseVia(*args.Get("via")) : std::vector<Eigen::Vector3d>{};
  const MarkerMap map = ReadMap(args.positionals()[0]);
  const long component = args.GetInt("component").value_or(0);
  if (goal.code && !map.Find(*goal.code)) {
    throw std::invalid_argument("option --to-code: " + goal.code->ToString() + " is not in " +
                                args.positionals()[0]);
  }
  if (goal.code && map.Find(*goal.code)->component.value_or(0) != component) {
    throw std::invalid_argument("option --to-code: " + goal.code->ToString() + " is in map component " +
                                std::to_string(map.Find(*goal.code)->component.value_or(0)) + ", not in " +
                                std::to_string(component) + " (--component): no surveyed path leads there");
  }
  const Dataset survey = LoadDataset(survey_dir);
  plan::RouteOptions options;
  options.odometry = plan::SurveyOdometryNoise(survey);
  options.node_spacing_m = args.GetDouble("node-spacing").value_or(options.node_spacing_m);
  options.max_snap_m = args.GetDouble("max-snap").value_or(options.max_snap_m);
  options.turn_cost_per_rad = args.GetDouble("turn-cost").value_or(options.turn_cost_per_rad);
  options.uncertainty_cost_per_m =
      args.GetDouble("uncertainty-cost").value_or(options.uncertainty_cost_per_m);
  std::string why;
  if (!options.Check(&why)) throw std::invalid_argument("route options: " + why);
  std::vector<plan::SurveyPose> poses;
  for (const plan::SurveyPose& pose : plan::LocalizeSurvey(survey, map)) {
    if (pose.component == component) poses.push_back(pose);
  }
  const plan::SurveyGraph graph = plan::BuildSurveyGraph(poses, options);
  std::vector<plan::Route> legs;
  Eigen::Vector3d from = start;
  for (const Eigen::Vector3d& point : via) {
    plan::RouteGoal leg_goal;
    leg_goal.pose = point;
    legs.push_back(plan::PlanRoute(graph, from, leg_goal, options));
    from = legs.back().waypoints.back().x_y_yaw;
  }
  legs.push_back(plan::PlanRoute(graph, from, goal, options));
  const plan::Route route = plan::JoinRoutes(legs);
  AtomicWriteFile(out, plan::FormatRoute(route));
  std::cerr << "route: " << route.waypoints.size() << " waypoints, " << FormatFixed(route.length_m, 2)
            << " m, cost " << FormatFixed(route.cost, 2) << ", " << FormatFixed(route.blind_m, 2)
            << " m without a code in view, predicted position sigma at most "
            << FormatFixed(1000.0 * route.max_position_sigma_m, 1) << " mm (graph: " << graph.nodes.size()
            << " nodes, " << graph.edges.size() << " edges, " << graph.components << " parts) -> " << out
            << "\n";
  return 0;
}

const CommandRegistrar kRegistrar({"route", "plan a route over a survey's poses (Dijkstra; docs/planning.md)",
                                   kUsage, RunRoute});

}  // namespace
}  // namespace waymark::cli
