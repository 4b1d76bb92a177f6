#include "plan/route.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <queue>
#include <stdexcept>

#include "geometry/pose.h"
#include "util/check.h"
#include "util/format.h"

namespace waymark::plan {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

double Trace2(const Eigen::Matrix3d& P) { return P(0, 0) + P(1, 1); }

std::string Point(const Eigen::Vector2d& p) {
  return "(" + FormatFixed(p.x(), 2) + ", " + FormatFixed(p.y(), 2) + ")";
}

// Heading of a -> b; NaN when they (nearly) coincide.
double Heading(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const Eigen::Vector2d d = b - a;
  return d.norm() < 1e-6 ? std::nan("") : std::atan2(d.y(), d.x());
}

double TurnRad(double from_rad, double to_rad) {
  if (std::isnan(from_rad) || std::isnan(to_rad)) return 0.0;
  return std::abs(WrapAngle(to_rad - from_rad));
}

// Propagates the planar covariance P at x through one increment.
void Propagate(const SE2d& increment, const OdometryNoise& noise, Eigen::Vector3d* x, Eigen::Matrix3d* P) {
  const MotionPrediction m = PredictPlanarIncrement(*x, increment, noise);
  *P = m.F * *P * m.F.transpose() + m.G * m.Qu * m.G.transpose();
  *P = 0.5 * (*P + P->transpose()).eval();
  *x = m.mean;
}

// Turns in place to `yaw_rad`, then drives `length_m` straight; returns the largest position sigma.
double PropagateLeg(double yaw_rad, double length_m, const RouteOptions& options, Eigen::Vector3d* x,
                    Eigen::Matrix3d* P) {
  double max_sigma = std::sqrt(std::max(0.0, Trace2(*P)));
  if (!std::isnan(yaw_rad)) {
    const double turn = WrapAngle(yaw_rad - x->z());
    const int n = static_cast<int>(std::ceil(std::abs(turn) / options.step_rad));
    for (int i = 0; i < n; ++i) Propagate(SE2d(0, 0, turn / n), options.odometry, x, P);
  }
  const int n = static_cast<int>(std::ceil(length_m / options.step_m));
  for (int i = 0; i < n; ++i) {
    Propagate(SE2d(length_m / n, 0, 0), options.odometry, x, P);
    max_sigma = std::max(max_sigma, std::sqrt(std::max(0.0, Trace2(*P))));
  }
  return max_sigma;
}

// Position sigma that odometry alone accumulates from zero over `length_m` straight.
double BlindSigma(double length_m, const RouteOptions& options) {
  if (length_m <= 0.0) return 0.0;
  Eigen::Vector3d x = Eigen::Vector3d::Zero();
  Eigen::Matrix3d P = Eigen::Matrix3d::Zero();
  PropagateLeg(std::nan(""), length_m, options, &x, &P);
  return std::sqrt(Trace2(P));
}

double BlindFraction(const RouteNode* a, const RouteNode* b) {
  // A start or goal point (nullptr) counts as its node's visibility.
  const bool va = a ? !a->codes.empty() : (b && !b->codes.empty());
  const bool vb = b ? !b->codes.empty() : va;
  return va && vb ? 0.0 : (va || vb ? 0.5 : 1.0);
}

int Nearest(const SurveyGraph& graph, const Eigen::Vector2d& p, double* distance) {
  int best = -1;
  *distance = kInf;
  for (size_t i = 0; i < graph.nodes.size(); ++i) {
    const double d = (graph.nodes[i].position_world - p).norm();
    if (d < *distance) {
      *distance = d;
      best = static_cast<int>(i);
    }
  }
  return best;
}

void NumberComponents(SurveyGraph* graph) {
  const int n = static_cast<int>(graph->nodes.size());
  std::vector<std::vector<int>> adjacent(n);
  for (const RouteEdge& e : graph->edges) {
    adjacent[e.a].push_back(e.b);
    adjacent[e.b].push_back(e.a);
  }
  std::vector<int> component(n, -1);
  int count = 0;
  for (int i = 0; i < n; ++i) {
    if (component[i] >= 0) continue;
    std::vector<int> stack = {i};
    component[i] = count;
    while (!stack.empty()) {
      const int u = stack.back();
      stack.pop_back();
      for (int v : adjacent[u]) {
        if (component[v] < 0) {
          component[v] = count;
          stack.push_back(v);
        }
      }
    }
    ++count;
  }
  for (int i = 0; i < n; ++i) graph->nodes[i].component = component[i];
  graph->components = count;
}

}  // namespace

bool RouteOptions::Check(std::string* why) const {
  WAYMARK_CHECK_OPTION(node_spacing_m > 0.0, "node_spacing_m > 0");
  WAYMARK_CHECK_OPTION(max_step_m > 0.0, "max_step_m > 0");
  WAYMARK_CHECK_OPTION(max_covisible_m >= 0.0, "max_covisible_m >= 0");
  WAYMARK_CHECK_OPTION(max_snap_m > 0.0, "max_snap_m > 0");
  WAYMARK_CHECK_OPTION(turn_cost_per_rad >= 0.0, "turn_cost_per_rad >= 0");
  WAYMARK_CHECK_OPTION(uncertainty_cost_per_m >= 0.0, "uncertainty_cost_per_m >= 0");
  WAYMARK_CHECK_OPTION(step_m > 0.0, "step_m > 0");
  WAYMARK_CHECK_OPTION(step_rad > 0.0, "step_rad > 0");
  return odometry.Check(why);
}

SurveyGraph BuildSurveyGraph(const std::vector<SurveyPose>& poses, const RouteOptions& options) {
  SurveyGraph graph;
  std::vector<double> best_trace;  // per node: trace of the kept covariance (with a code in view)
  std::set<std::pair<int, int>> traversed;
  int previous_node = -1;
  const SurveyPose* previous = nullptr;
  for (const SurveyPose& pose : poses) {
    const Eigen::Vector2d p = pose.x_y_yaw.head<2>();
    double distance = kInf;
    int node = Nearest(graph, p, &distance);
    if (node < 0 || distance >= options.node_spacing_m) {
      RouteNode n;
      n.position_world = p;
      n.yaw_rad = pose.x_y_yaw.z();
      n.covariance = pose.covariance;
      graph.nodes.push_back(n);
      best_trace.push_back(kInf);
      node = static_cast<int>(graph.nodes.size()) - 1;
    }
    RouteNode& n = graph.nodes[node];
    for (const MarkerKey& key : pose.codes) {
      if (n.codes.insert(key).second) n.code_yaw_rad.emplace_back(key, pose.x_y_yaw.z());
    }
    if (!pose.codes.empty() && Trace2(pose.covariance) < best_trace[node]) {
      best_trace[node] = Trace2(pose.covariance);
      n.covariance = pose.covariance;
    }
    const bool joined = previous && (p - previous->x_y_yaw.head<2>()).norm() <= options.max_step_m;
    if (joined && previous_node != node) {
      traversed.insert({std::min(node, previous_node), std::max(node, previous_node)});
    }
    previous = &pose;
    previous_node = node;
  }
  std::map<std::pair<int, int>, RouteEdge> edges;
  for (const auto& [a, b] : traversed) edges[{a, b}] = RouteEdge{a, b, true, false};
  for (size_t a = 0; a < graph.nodes.size(); ++a) {
    for (size_t b = a + 1; b < graph.nodes.size(); ++b) {
      const RouteNode &na = graph.nodes[a], &nb = graph.nodes[b];
      if ((na.position_world - nb.position_world).norm() > options.max_covisible_m) continue;
      const bool shared = std::any_of(na.codes.begin(), na.codes.end(),
                                      [&](const MarkerKey& k) { return nb.codes.count(k) > 0; });
      if (!shared) continue;
      RouteEdge& e = edges[{static_cast<int>(a), static_cast<int>(b)}];
      e.a = static_cast<int>(a);
      e.b = static_cast<int>(b);
      e.covisible = true;
    }
  }
  for (const auto& entry : edges) graph.edges.push_back(entry.second);
  NumberComponents(&graph);
  return graph;
}

namespace {

struct Target {
  int node;
  Eigen::Vector2d point;
  double yaw_rad;  // NaN: free
};

// Dijkstra over (node, predecessor) states; returns the node sequence and its cost.
struct Search {
  const SurveyGraph& graph;
  const RouteOptions& options;
  std::vector<std::vector<std::pair<int, double>>> adjacent;  // neighbour, edge cost without turn

  Search(const SurveyGraph& g, const RouteOptions& o) : graph(g), options(o), adjacent(g.nodes.size()) {
    for (const RouteEdge& e : g.edges) {
      const RouteNode &a = g.nodes[e.a], &b = g.nodes[e.b];
      const double length = (a.position_world - b.position_world).norm();
      const double cost = length + o.uncertainty_cost_per_m * BlindSigma(BlindFraction(&a, &b) * length, o);
      adjacent[e.a].emplace_back(e.b, cost);
      adjacent[e.b].emplace_back(e.a, cost);
    }
  }

  double LegCost(const RouteNode& node, double length) const {
    return length + options.uncertainty_cost_per_m * BlindSigma(node.codes.empty() ? length : 0.0, options);
  }

  // Best node path from the start point (with yaw) to any target; cost via *cost.
  std::pair<std::vector<int>, const Target*> Run(const Eigen::Vector3d& start, int start_node,
                                                 const std::vector<Target>& targets, double* cost) const {
    const Eigen::Vector2d start_point = start.head<2>();
    const RouteNode& s = graph.nodes[start_node];
    const double start_leg_heading = Heading(start_point, s.position_world);
    const double start_leg = (s.position_world - start_point).norm();
    // State key: (node, predecessor), predecessor -1 at the start node.
    using State = std::pair<int, int>;
    std::map<State, double> dist;
    std::map<State, State> parent;
    using Entry = std::pair<double, State>;
    std::priority_queue<Entry, std::vector<Entry>, std::greater<Entry>> queue;
    const double start_cost =
        LegCost(s, start_leg) + options.turn_cost_per_rad * TurnRad(start.z(), start_leg_heading);
    dist[{start_node, -1}] = start_cost;
    queue.push({start_cost, {start_node, -1}});
    std::map<int, std::vector<const Target*>> target_of;
    for (const Target& t : targets) target_of[t.node].push_back(&t);
    double best = kInf;
    State best_state{-1, -1};
    const Target* best_target = nullptr;
    auto incoming = [&](const State& st) {
      if (st.second >= 0)
        return Heading(graph.nodes[st.second].position_world, graph.nodes[st.first].position_world);
      return std::isnan(start_leg_heading) ? start.z() : start_leg_heading;
    };
    while (!queue.empty()) {
      const auto [d, st] = queue.top();
      queue.pop();
      if (d > dist[st] || d >= best) continue;
      const RouteNode& u = graph.nodes[st.first];
      const double heading_in = incoming(st);
      if (const auto it = target_of.find(st.first); it != target_of.end()) {
        for (const Target* t : it->second) {
          const double leg_heading = Heading(u.position_world, t->point);
          const double leg = (t->point - u.position_world).norm();
          const double end_heading = std::isnan(leg_heading) ? heading_in : leg_heading;
          const double total = d + LegCost(u, leg) +
                               options.turn_cost_per_rad *
                                   (TurnRad(heading_in, leg_heading) + TurnRad(end_heading, t->yaw_rad));
          if (total < best) {
            best = total;
            best_state = st;
            best_target = t;
          }
        }
      }
      for (const auto& [v, edge_cost] : adjacent[st.first]) {
        if (v == st.second) continue;
        const double h = Heading(u.position_world, graph.nodes[v].position_world);
        const double nd = d + edge_cost + options.turn_cost_per_rad * TurnRad(heading_in, h);
        const State next{v, st.first};
        const auto it = dist.find(next);
        if (it == dist.end() || nd < it->second) {
          dist[next] = nd;
          parent[next] = st;
          queue.push({nd, next});
        }
      }
    }
    std::vector<int> path;
    if (!best_target) return {path, nullptr};
    for (State st = best_state;;) {
      path.push_back(st.first);
      const auto it = parent.find(st);
      if (it == parent.end()) break;
      st = it->second;
    }
    std::reverse(path.begin(), path.end());
    *cost = best;
    return {path, best_target};
  }
};

}  // namespace

Route PlanRoute(const SurveyGraph& graph, const Eigen::Vector3d& start, const RouteGoal& goal,
                const RouteOptions& options) {
  std::string why;
  if (!options.Check(&why)) throw std::invalid_argument("route options: " + why);
  if (graph.nodes.empty()) throw std::invalid_argument("the survey has no pose tracked against the map");
  double start_distance = 0.0;
  const int start_node = Nearest(graph, start.head<2>(), &start_distance);
  if (start_distance > options.max_snap_m) {
    throw std::invalid_argument(
        "start " + Point(start.head<2>()) + " is off the survey graph: the nearest survey pose is " +
        FormatFixed(start_distance, 2) + " m away (at most " + FormatDouble(options.max_snap_m) + " m)");
  }
  const int component = graph.nodes[start_node].component;
  std::vector<Target> targets;
  if (goal.pose) {
    double goal_distance = 0.0;
    const int goal_node = Nearest(graph, goal.pose->head<2>(), &goal_distance);
    if (goal_distance > options.max_snap_m) {
      throw std::invalid_argument(
          "goal " + Point(goal.pose->head<2>()) + " is off the survey graph: the nearest survey pose is " +
          FormatFixed(goal_distance, 2) + " m away (at most " + FormatDouble(options.max_snap_m) + " m)");
    }
    if (graph.nodes[goal_node].component != component) {
      throw std::invalid_argument(
          "goal " + Point(goal.pose->head<2>()) +
          " is in another part of the survey than the start: no surveyed path joins them");
    }
    targets.push_back({goal_node, goal.pose->head<2>(), goal.pose->z()});
  } else if (goal.code) {
    bool seen = false;
    for (size_t i = 0; i < graph.nodes.size(); ++i) {
      const RouteNode& n = graph.nodes[i];
      for (const auto& [key, yaw] : n.code_yaw_rad) {
        if (key != *goal.code) continue;
        seen = true;
        if (n.component == component) targets.push_back({static_cast<int>(i), n.position_world, yaw});
      }
    }
    if (!seen) throw std::invalid_argument("code " + goal.code->ToString() + " was never seen in the survey");
    if (targets.empty()) {
      throw std::invalid_argument(
          "code " + goal.code->ToString() +
          " was seen only from another part of the survey than the start: no surveyed "
          "path leads there");
    }
  } else {
    throw std::invalid_argument("no goal given");
  }
  const Search search(graph, options);
  double cost = 0.0;
  const auto [path, target] = search.Run(start, start_node, targets, &cost);
  if (!target) throw std::invalid_argument("no route to the goal in the survey graph");

  Route route;
  route.cost = cost;
  route.goal_yaw_given = !std::isnan(target->yaw_rad);
  route.goal_code = goal.code;
  std::vector<Eigen::Vector2d> points = {start.head<2>()};
  std::vector<int> nodes = {-1};
  for (int n : path) {
    points.push_back(graph.nodes[n].position_world);
    nodes.push_back(n);
  }
  points.push_back(target->point);
  nodes.push_back(-1);
  // Drop legs of (nearly) zero length: the start or goal on its node.
  std::vector<Eigen::Vector2d> kept_points;
  std::vector<int> kept_nodes;
  for (size_t i = 0; i < points.size(); ++i) {
    if (!kept_points.empty() && (points[i] - kept_points.back()).norm() < 1e-6) {
      if (kept_nodes.back() < 0) kept_nodes.back() = nodes[i];
      continue;
    }
    kept_points.push_back(points[i]);
    kept_nodes.push_back(nodes[i]);
  }
  // A node nearer than half the node spacing to the start (goal) is passed by: a leg of a few
  // centimetres would only add a turn there and back.
  // The first node is also passed by when going there would turn the robot back: [George]'s rule
  // (robot at r heading v, next points p1, p2): skip p1 when |a1| + |a2| > |b3| + pi/2, with
  // a1 = angle(v, p1 - r), a2 = angle(p1 - r, p2 - p1), b3 = angle(v, p2 - r).
  const double near = 0.5 * options.node_spacing_m;
  auto turns_back = [&] {
    if (std::isnan(start.z()) || kept_points.size() < 3) return false;
    const double h1 = Heading(kept_points[0], kept_points[1]), h2 = Heading(kept_points[1], kept_points[2]),
                 h3 = Heading(kept_points[0], kept_points[2]);
    return TurnRad(start.z(), h1) + TurnRad(h1, h2) > TurnRad(start.z(), h3) + 0.5 * M_PI;
  };
  if (kept_points.size() > 2 && kept_nodes[0] < 0 && kept_nodes[1] >= 0 &&
      ((kept_points[1] - kept_points[0]).norm() < near || turns_back())) {
    kept_points.erase(kept_points.begin() + 1);
    kept_nodes.erase(kept_nodes.begin() + 1);
  }
  const size_t n = kept_points.size();
  if (n > 2 && kept_nodes[n - 1] < 0 && kept_nodes[n - 2] >= 0 &&
      (kept_points[n - 1] - kept_points[n - 2]).norm() < near) {
    kept_points.erase(kept_points.end() - 2);
    kept_nodes.erase(kept_nodes.end() - 2);
  }
  Eigen::Vector3d x(start.x(), start.y(), std::isnan(start.z()) ? 0.0 : start.z());
  Eigen::Matrix3d P = graph.nodes[start_node].covariance;
  double heading = start.z();
  for (size_t i = 0; i < kept_points.size(); ++i) {
    RouteWaypoint w;
    w.node = kept_nodes[i];
    const bool last = i + 1 == kept_points.size();
    const double leg_heading = last ? std::nan("") : Heading(kept_points[i], kept_points[i + 1]);
    const double yaw = last ? (route.goal_yaw_given ? target->yaw_rad : heading) : leg_heading;
    route.turn_rad += TurnRad(heading, yaw);
    if (!std::isnan(yaw)) {
      if (i == 0 && std::isnan(start.z())) x.z() = yaw;
      PropagateLeg(yaw, 0.0, options, &x, &P);  // the turn in place
      heading = yaw;
    }
    const RouteNode* node = w.node >= 0 ? &graph.nodes[w.node] : nullptr;
    if (node && !node->codes.empty() && Trace2(node->covariance) < Trace2(P)) P = node->covariance;
    w.x_y_yaw = Eigen::Vector3d(kept_points[i].x(), kept_points[i].y(), std::isnan(yaw) ? x.z() : yaw);
    w.covariance = P;
    route.waypoints.push_back(w);
    route.max_position_sigma_m = std::max(route.max_position_sigma_m, std::sqrt(Trace2(P)));
    if (last) break;
    RouteSegment segment;
    segment.length_m = (kept_points[i + 1] - kept_points[i]).norm();
    const RouteNode* next = kept_nodes[i + 1] >= 0 ? &graph.nodes[kept_nodes[i + 1]] : nullptr;
    std::set<MarkerKey> codes;
    if (node) codes.insert(node->codes.begin(), node->codes.end());
    if (next) codes.insert(next->codes.begin(), next->codes.end());
    segment.codes.assign(codes.begin(), codes.end());
    segment.blind_m = BlindFraction(node, next) * segment.length_m;
    x.head<2>() = kept_points[i];
    segment.max_position_sigma_m = PropagateLeg(std::nan(""), segment.length_m, options, &x, &P);
    route.max_position_sigma_m = std::max(route.max_position_sigma_m, segment.max_position_sigma_m);
    route.length_m += segment.length_m;
    route.blind_m += segment.blind_m;
    route.segments.push_back(segment);
  }
  return route;
}

Route JoinRoutes(const std::vector<Route>& legs) {
  Route route;
  for (size_t k = 0; k < legs.size(); ++k) {
    const Route& leg = legs[k];
    size_t first = 0;
    if (!route.waypoints.empty() && !leg.waypoints.empty()) {
      route.waypoints.back().x_y_yaw.z() = leg.waypoints.front().x_y_yaw.z();  // heading of the next leg
      first = 1;
    }
    route.waypoints.insert(route.waypoints.end(), leg.waypoints.begin() + first, leg.waypoints.end());
    route.segments.insert(route.segments.end(), leg.segments.begin(), leg.segments.end());
    route.length_m += leg.length_m;
    route.cost += leg.cost;
    route.turn_rad += leg.turn_rad;
    route.blind_m += leg.blind_m;
    route.max_position_sigma_m = std::max(route.max_position_sigma_m, leg.max_position_sigma_m);
    route.goal_yaw_given = leg.goal_yaw_given;
    route.goal_code = leg.goal_code;
  }
  return route;
}

}  // namespace waymark::plan
