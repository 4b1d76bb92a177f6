#include "plan/route_io.h"

#include <cmath>
#include <sstream>

#include "io/json_util.h"
#include "util/format.h"

namespace waymark::plan {
namespace {

std::string Number(double value) { return std::isfinite(value) ? FormatDouble(value) : "null"; }

std::string Quoted(const std::string& text) { return nlohmann::json(text).dump(); }

std::string Codes(const std::vector<MarkerKey>& codes) {
  std::string out = "[";
  for (size_t i = 0; i < codes.size(); ++i) {
    out += (i ? ", " : "") + std::string("{\"family\": ") + Quoted(codes[i].family) +
           ", \"id\": " + Quoted(codes[i].id) + "}";
  }
  return out + "]";
}

std::string Matrix(const Eigen::Matrix3d& m) {
  std::string out = "[";
  for (int i = 0; i < 9; ++i) out += (i ? ", " : "") + Number(m(i / 3, i % 3));
  return out + "]";
}

}  // namespace

std::string FormatRoute(const Route& route) {
  std::ostringstream out;
  out << "{\"format\": \"waymark-route\", \"version\": 1,\n"
      << " \"length_m\": " << Number(route.length_m) << ", \"cost\": " << Number(route.cost)
      << ", \"turn_rad\": " << Number(route.turn_rad) << ", \"blind_m\": " << Number(route.blind_m)
      << ", \"max_position_sigma_m\": " << Number(route.max_position_sigma_m)
      << ",\n \"goal_yaw_given\": " << (route.goal_yaw_given ? "true" : "false");
  if (route.goal_code) {
    out << ", \"goal_code\": {\"family\": " << Quoted(route.goal_code->family)
        << ", \"id\": " << Quoted(route.goal_code->id) << "}";
  }
  out << ",\n \"waypoints\": [";
  for (size_t i = 0; i < route.waypoints.size(); ++i) {
    const RouteWaypoint& w = route.waypoints[i];
    const double sigma = std::sqrt(std::max(0.0, w.covariance(0, 0) + w.covariance(1, 1)));
    out << (i ? ",\n  " : "\n  ") << "{\"x\": " << Number(w.x_y_yaw.x())
        << ", \"y\": " << Number(w.x_y_yaw.y()) << ", \"yaw\": " << Number(w.x_y_yaw.z())
        << ", \"node\": " << w.node << ", \"position_sigma_m\": " << Number(sigma)
        << ", \"covariance\": " << Matrix(w.covariance) << "}";
  }
  out << "],\n \"segments\": [";
  for (size_t i = 0; i < route.segments.size(); ++i) {
    const RouteSegment& s = route.segments[i];
    out << (i ? ",\n  " : "\n  ") << "{\"from\": " << i << ", \"to\": " << i + 1
        << ", \"length_m\": " << Number(s.length_m) << ", \"blind_m\": " << Number(s.blind_m)
        << ", \"max_position_sigma_m\": " << Number(s.max_position_sigma_m)
        << ", \"codes\": " << Codes(s.codes) << "}";
  }
  out << "]}\n";
  return out.str();
}

Route ParseRoute(const std::string& text, const std::filesystem::path& path) {
  const nlohmann::json root = ParseJsonDocument(text, path, nullptr);
  const JsonSource source = JsonSourceForText(path, text);
  if (!root.is_object()) ThrowJsonError(source, "", "expected a JSON object");
  const nlohmann::json* format = JsonMember(source, root, "", "format", true);
  if (JsonString(source, *format, "format") != "waymark-route") {
    ThrowJsonError(source, "format", "expected \"waymark-route\"");
  }
  if (JsonInteger(source, *JsonMember(source, root, "", "version", true), "version") != 1) {
    ThrowJsonError(source, "version", "expected 1");
  }
  Route route;
  if (const nlohmann::json* v = JsonMember(source, root, "", "goal_yaw_given", false)) {
    route.goal_yaw_given = JsonBool(source, *v, "goal_yaw_given");
  }
  for (const char* key : {"length_m", "cost"}) {
    if (const nlohmann::json* v = JsonMember(source, root, "", key, false)) {
      (std::string(key) == "cost" ? route.cost : route.length_m) = JsonNumber(source, *v, key);
    }
  }
  const nlohmann::json& waypoints = *JsonMember(source, root, "", "waypoints", true);
  if (!waypoints.is_array() || waypoints.empty()) {
    ThrowJsonError(source, "waypoints", "expected a non-empty array of waypoints");
  }
  for (size_t i = 0; i < waypoints.size(); ++i) {
    const std::string field = JsonField("waypoints", i);
    RouteWaypoint w;
    int axis = 0;
    for (const char* key : {"x", "y", "yaw"}) {
      w.x_y_yaw[axis++] =
          JsonNumber(source, *JsonMember(source, waypoints[i], field, key, true), JsonField(field, key));
    }
    if (const nlohmann::json* v = JsonMember(source, waypoints[i], field, "covariance", false)) {
      const std::vector<double> c = JsonNumbers(source, *v, JsonField(field, "covariance"), 9);
      for (int k = 0; k < 9; ++k) w.covariance(k / 3, k % 3) = c[k];
    }
    route.waypoints.push_back(w);
  }
  for (size_t i = 1; i < route.waypoints.size(); ++i) {
    route.segments.push_back(
        RouteSegment{(route.waypoints[i].x_y_yaw.head<2>() - route.waypoints[i - 1].x_y_yaw.head<2>()).norm(),
                     {},
                     0.0,
                     0.0});
  }
  return route;
}

Route ReadRoute(const std::filesystem::path& path) { return ParseRoute(ReadTextFile(path), path); }

}  // namespace waymark::plan
