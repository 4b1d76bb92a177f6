#include "plan/floor_plan.h"

#include "io/dataset_io.h"
#include "io/util.h"
#include "io/yaml_util.h"
#include "util/format.h"

namespace waymark::plan {
namespace {

double OptionalNumber(const std::filesystem::path& path, const YAML::Node& map, const std::string& key,
                      double fallback) {
  return map[key] ? YamlNumber(path, map[key], key) : fallback;
}

Eigen::Vector2d Point(const std::filesystem::path& path, const YAML::Node& node, const std::string& what) {
  const std::vector<double> v = YamlNumbers(path, node, what, 2);
  return {v[0], v[1]};
}

}  // namespace

FloorPlan ReadFloorPlan(const std::filesystem::path& path) {
  const YAML::Node root = YamlLoadMap(path, ReadTextFile(path));
  if (YamlString(path, YamlRequire(path, root, "format"), "format") != "waymark-floor-plan") {
    ThrowYamlError(path, root["format"], "format: expected waymark-floor-plan");
  }
  if (YamlInteger(path, YamlRequire(path, root, "version"), "version") != 1) {
    ThrowYamlError(path, root["version"], "version: expected 1");
  }
  YamlWarnUnknownKeys(path, root,
                      {"format", "version", "ceiling_height_m", "walls", "rig", "family", "code_sizes_m",
                       "code_height_m", "margin_m", "anchors", "detect"},
                      "", nullptr);
  FloorPlan plan;
  plan.ceiling_height_m = YamlNumber(path, YamlRequire(path, root, "ceiling_height_m"), "ceiling_height_m");
  if (!(plan.ceiling_height_m > 0.0))
    ThrowYamlError(path, root["ceiling_height_m"], "ceiling_height_m: expected > 0");
  if (root["family"]) plan.family = YamlString(path, root["family"], "family");
  const YAML::Node sizes = YamlRequire(path, root, "code_sizes_m");
  plan.code_sizes_m = YamlNumbers(path, sizes, "code_sizes_m", std::nullopt);
  if (plan.code_sizes_m.empty()) ThrowYamlError(path, sizes, "code_sizes_m: expected at least one size");
  for (double size : plan.code_sizes_m) {
    if (const std::string why = CheckMarkerSize(size); !why.empty())
      ThrowYamlError(path, sizes, "code_sizes_m: " + why);
  }
  plan.code_height_m = YamlNumber(path, YamlRequire(path, root, "code_height_m"), "code_height_m");
  plan.margin_m = OptionalNumber(path, root, "margin_m", 0.0);
  if (root["anchors"]) plan.anchors = static_cast<int>(YamlInteger(path, root["anchors"], "anchors"));
  if (plan.anchors < 0) ThrowYamlError(path, root["anchors"], "anchors: expected >= 0");
  const YAML::Node walls = YamlRequire(path, root, "walls");
  if (!walls.IsSequence() || walls.size() == 0) {
    ThrowYamlError(path, walls,
                   "walls: expected a list of at least one wall {from: [x, y], to: [x, y], height_m}");
  }
  for (size_t i = 0; i < walls.size(); ++i) {
    const std::string what = "walls[" + std::to_string(i) + "]";
    if (!walls[i].IsMap())
      ThrowYamlError(path, walls[i], what + ": expected {from: [x, y], to: [x, y], height_m: h}");
    FloorWall wall;
    wall.from_world = Point(path, YamlRequire(path, walls[i], "from"), what + ".from");
    wall.to_world = Point(path, YamlRequire(path, walls[i], "to"), what + ".to");
    wall.height_m = OptionalNumber(path, walls[i], "height_m", plan.ceiling_height_m);
    if ((wall.to_world - wall.from_world).norm() < 1e-6)
      ThrowYamlError(path, walls[i], what + ": zero length");
    if (!(wall.height_m > 0.0)) ThrowYamlError(path, walls[i], what + ".height_m: expected > 0");
    plan.walls.push_back(wall);
  }
  const double largest = *std::max_element(plan.code_sizes_m.begin(), plan.code_sizes_m.end());
  if (!(plan.code_height_m - 0.5 * largest > 0.0) ||
      plan.code_height_m + 0.5 * largest > plan.ceiling_height_m) {
    ThrowYamlError(
        path, root["code_height_m"],
        "code_height_m: codes of " + FormatDouble(largest) + " m would not fit between floor and ceiling");
  }
  if (const YAML::Node detect = root["detect"]) {
    if (!detect.IsMap()) ThrowYamlError(path, detect, "detect: expected a map");
    plan.min_range_m = OptionalNumber(path, detect, "min_range_m", plan.min_range_m);
    plan.max_range_m = OptionalNumber(path, detect, "max_range_m", plan.max_range_m);
    plan.max_angle_deg = OptionalNumber(path, detect, "max_angle_deg", plan.max_angle_deg);
    plan.border_px = OptionalNumber(path, detect, "border_px", plan.border_px);
    plan.pixel_sigma_px = OptionalNumber(path, detect, "pixel_sigma_px", plan.pixel_sigma_px);
    plan.camera_hz = OptionalNumber(path, detect, "camera_hz", plan.camera_hz);
    if (!(plan.min_range_m >= 0.0 && plan.max_range_m > plan.min_range_m && plan.pixel_sigma_px > 0.0 &&
          plan.camera_hz > 0.0 && plan.max_angle_deg > 0.0 && plan.max_angle_deg < 90.0)) {
      ThrowYamlError(
          path, detect,
          "detect: expected 0 <= min_range_m < max_range_m, 0 < max_angle_deg < 90, pixel_sigma_px > 0, "
          "camera_hz > 0");
    }
  }
  const std::filesystem::path rig =
      path.parent_path() / YamlString(path, YamlRequire(path, root, "rig"), "rig");
  const Dataset dataset = LoadDataset(rig);
  for (const std::string& name : dataset.config.cameras) plan.cameras.push_back(dataset.cameras.at(name));
  if (plan.cameras.empty()) ThrowYamlError(path, root["rig"], "rig: the dataset has no camera");
  if (dataset.config.odometry_sigma) plan.odometry_sigma = *dataset.config.odometry_sigma;
  return plan;
}

}  // namespace waymark::plan
