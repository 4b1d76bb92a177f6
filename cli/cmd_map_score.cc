// `waymark map score`: the reprojection error of a solution (a map and, optionally, a
// trajectory) on a dataset's corner observations, so that two systems are compared on the same
// observations. The math is in mapping/map_score.h; this file parses arguments and reports.
#include <iostream>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "cli/args.h"
#include "cli/command.h"
#include "io/dataset_io.h"
#include "io/map_io.h"
#include "io/tum_io.h"
#include "io/util.h"
#include "mapping/map_score.h"
#include "util/format.h"

namespace waymark::cli {
namespace {

constexpr const char* kUsage = R"(Usage:
  waymark map score DATASET --map MAP.json [--trajectory T_world_robot.tum] [options]

Scores a solution on the corner observations of the dataset directory DATASET: the RMS
reprojection error (px, over corners), overall, per camera and per marker, with the median and
the largest error of one observation. Use it to put two systems side by side on the same
observations (e.g. `waymark map build` against a dataset's reference/).

Frame poses come from --trajectory (the pose within --stamp-tolerance of each frame's stamp;
frames without one are counted, not scored); without it, each frame is solved from the map's
markers it sees, with the map held fixed.

Options:
  --map FILE                the markers (map.json format)
  --trajectory FILE         T_world_robot of the frames (TUM), in the map's world frame
  --solve-missing-markers   markers the map lacks are solved with the frame poses held fixed
                            (least squares on their corners), then scored
  --line                    also fit a 3-D line to the scored map's marker centres and print
                            the perpendicular residuals (RMS and max, mm)
  --frames-of FILE          score only the frames this trajectory (TUM) has a pose for: two
                            solutions on exactly the same observations when one of them has
                            no pose for some frames (e.g. ours scored on the frames of
                            TagSLAM's trajectory); the others are counted apart
  --stamp-tolerance S       seconds (default 0.001)
  --json FILE               also write the figures as JSON
  --out-map FILE            write the scored map (with the solved markers) in map.json format
)";

const std::set<std::string> kValues = {"map",  "trajectory", "frames-of", "stamp-tolerance",
                                       "json", "out-map"};
const std::set<std::string> kFlags = {"solve-missing-markers", "line"};

std::string Mm(double metres) { return FormatFixed(1e3 * metres, 2); }

nlohmann::json StatsJson(const ReprojectionStats& s) {
  return {{"name", s.name},
          {"observations", s.observations},
          {"rms_px", s.rms_px},
          {"median_px", s.median_px},
          {"max_px", s.max_px}};
}

std::string ScoreJson(const MapScore& score, const std::optional<LineFit>& line, size_t line_markers) {
  nlohmann::json j = {
      {"observations_total", score.observations}, {"scored", score.all.observations},
      {"without_pose", score.without_pose},       {"outside_frames_of", score.outside_frames_of},
      {"without_marker", score.without_marker},   {"not_projected", score.not_projected},
      {"frames_solved", score.frames_solved},     {"all", StatsJson(score.all)}};
  j["per_camera"] = nlohmann::json::array();
  for (const auto& s : score.per_camera) j["per_camera"].push_back(StatsJson(s));
  j["per_marker"] = nlohmann::json::array();
  for (const auto& s : score.per_marker) j["per_marker"].push_back(StatsJson(s));
  j["solved_markers"] = nlohmann::json::array();
  for (const MarkerKey& key : score.solved_markers) j["solved_markers"].push_back(key.ToString());
  if (line) {
    j["line"] = {{"markers", line_markers}, {"rms_m", line->rms_m}, {"max_m", line->max_m}};
  }
  return j.dump(1) + "\n";
}

std::vector<Eigen::Vector3d> MarkerCentres(const MarkerMap& map) {
  std::vector<Eigen::Vector3d> centres_world;
  for (const MapMarker& m : map.markers) {
    if (m.has_pose) centres_world.push_back(m.T_world_marker.translation());
  }
  return centres_world;
}

int RunScore(const std::vector<std::string>& argv) {
  const Args args(argv, kValues, kFlags);
  if (args.Help()) {
    std::cout << kUsage;
    return 0;
  }
  args.ExpectPositionals(1, 1, "dataset directory DATASET");
  args.ExpectDistinctOutputs({"json", "out-map"});
  MapScoreOptions options;
  options.solve_missing_markers = args.Flag("solve-missing-markers");
  if (const auto s = args.GetDouble("stamp-tolerance")) options.stamp_tolerance_s = *s;
  if (args.Has("frames-of")) options.frames_of = ReadTum(*args.Get("frames-of"));
  std::string why;
  if (!options.Check(&why)) throw std::invalid_argument("options: " + why);
  const MarkerMap map = ReadMap(args.Require("map"));
  std::optional<Trajectory> trajectory;
  if (args.Has("trajectory")) trajectory = ReadTum(*args.Get("trajectory"));
  const Dataset dataset = LoadDataset(args.positionals()[0]);
  const MapScore score = ScoreMap(dataset, map, trajectory, options);
  const std::vector<Eigen::Vector3d> centres_world = MarkerCentres(score.map);
  std::optional<LineFit> line;
  if (args.Flag("line") && centres_world.size() >= 2) line = FitLine(centres_world);
  // Everything is formatted before anything is written.
  const std::string json_text = args.Has("json") ? ScoreJson(score, line, centres_world.size()) : "";
  const std::string map_text = args.Has("out-map") ? FormatMap(score.map) : "";
  std::vector<std::pair<std::filesystem::path, std::string>> files;
  if (args.Has("json")) files.emplace_back(*args.Get("json"), json_text);
  if (args.Has("out-map")) files.emplace_back(*args.Get("out-map"), map_text);
  AtomicWriteFiles(files);  // all or nothing
  std::cout << FormatMapScore(score);
  if (args.Flag("line") && !line) std::cout << "line fit: needs 2 or more marker centres\n";
  if (line) {
    std::cout << "line fit of " << centres_world.size() << " marker centres: RMS " << Mm(line->rms_m)
              << " mm, max " << Mm(line->max_m) << " mm (perpendicular distances)\n";
  }
  return 0;
}

const CommandRegistrar kRegistrar(Command{
    "map score", "reprojection error of a map (and trajectory) on a dataset's observations", kUsage,
    RunScore});

}  // namespace
}  // namespace waymark::cli
