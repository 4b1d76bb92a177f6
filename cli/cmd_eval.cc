// `waymark eval`: trajectory and map accuracy against ground truth. Parses arguments, reads
// the files (io/tum_io.h, io/map_io.h), calls eval/ and writes the reports atomically.
// The math and its definitions are in eval/ and docs/evaluation.md.
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <optional>
#include <stdexcept>
#include <string>

#include "cli/args.h"
#include "cli/command.h"
#include "eval/map_metrics.h"
#include "eval/report.h"
#include "eval/svg_plot.h"
#include "eval/trajectory_eval.h"
#include "io/map_io.h"
#include "io/tum_io.h"
#include "io/util.h"

namespace waymark::cli {
namespace {

constexpr const char* kUsage = R"(Usage:
  waymark eval --est EST.tum --gt GT.tum [--align se3|se2|origin|none] [--scale] [--max-dt S]
               [--rpe-delta N --rpe-unit frames|m] [--predicted PRED.tum [--align-predicted]]
               [--json OUT.json] [--report OUT.md] [--plot OUT.svg] [--markers MAP.json [--gt-map GT.json]]
  waymark eval --map MAP.json --gt-map GT.json [--json OUT.json] [--report OUT.md] [--plot OUT.svg]

Trajectory accuracy of EST against GT (both TUM, T_world_robot), and/or map accuracy of MAP
against GT (both waymark-map JSON). Both forms may be combined in one call.

Trajectory options:
  --est FILE         estimated trajectory (TUM)
  --gt FILE          ground-truth trajectory (TUM)
  --align MODE       se3 (default; Umeyama, = evo_ape -a), se2 (yaw + x, y; planar robots),
                     origin (first poses made equal, = evo --align_origin: dead reckoning), none
  --scale            also fit a scale (Sim(3); with --align none: scale only, = evo -s)
  --max-dt S         association: nearest stamp within S seconds (default 0.01, as evo)
  --rpe-delta N      also compute the RPE over N frames or N metres (evo's consecutive pairs)
  --rpe-unit U       frames (default) or m
  --predicted FILE   poses predicted just before each marker correction (TUM): PE / TE of
                     [Bach], not aligned (map frame = world frame) unless --align-predicted
  --align-predicted  move the predicted poses by the estimate's alignment first
  --markers FILE     estimated markers to draw in the plot (moved by the trajectory alignment)
Map options:
  --map FILE         estimated map; each component is aligned to the truth separately
  --gt-map FILE      true marker poses (also drawn in a trajectory plot)
  --group REGEX      also print the marker RMS of the codes whose id matches REGEX and of the
                     others, each code aligned with its whole component (e.g. --group '^1/':
                     warehouse-drone's load codes apart from its floor codes)
Outputs (written atomically; a short table always goes to stdout):
  --json FILE        all figures (docs/evaluation.md lists the fields)
  --report FILE      Markdown summary
  --plot FILE        SVG: top view of trajectories and markers, error over time
)";

// Re-throws a library error with the files it concerns in front: one line, exit 1.
template <typename F>
auto WithContext(const std::string& context, F&& f) -> decltype(f()) {
  try {
    return f();
  } catch (const FormatError&) {
    throw;  // already names its file and line
  } catch (const std::exception& e) {
    throw std::runtime_error(context + ": " + e.what());
  }
}

Trajectory ReadNonEmptyTum(const std::string& path) {
  Trajectory trajectory = ReadTum(path);
  if (trajectory.empty()) throw FormatError(path, "no poses (expected lines 't tx ty tz qx qy qz qw')");
  return trajectory;
}

eval::TrajectoryEvalOptions TrajectoryOptions(const Args& args) {
  eval::TrajectoryEvalOptions options;
  options.align = eval::ParseAlignmentMode(args.GetOr("align", "se3"));
  options.scale = args.Flag("scale");
  options.max_dt_s = args.GetDouble("max-dt").value_or(eval::kDefaultMaxDtS);
  options.align_predicted = args.Flag("align-predicted");
  if (args.Has("rpe-delta")) {
    options.rpe =
        eval::RpeOptions{*args.GetDouble("rpe-delta"), eval::ParseRpeUnit(args.GetOr("rpe-unit", "frames"))};
  } else if (args.Has("rpe-unit")) {
    throw std::invalid_argument("option --rpe-unit needs --rpe-delta");
  }
  std::string why;
  if (!options.Check(&why)) throw std::invalid_argument(why);
  return options;
}

void CheckModes(const Args& args) {
  args.ExpectPositionals(0, 0, "arguments");
  const bool trajectory = args.Has("est") || args.Has("gt");
  const bool map = args.Has("map");
  if (!trajectory && !map)
    throw std::invalid_argument("give --est and --gt, or --map and --gt-map (see --help)");
  if (trajectory && !(args.Has("est") && args.Has("gt"))) {
    throw std::invalid_argument(std::string("missing required option --") + (args.Has("est") ? "gt" : "est"));
  }
  if (map && !args.Has("gt-map"))
    throw std::invalid_argument("missing required option --gt-map (with --map)");
  if (args.Has("group") && !map) throw std::invalid_argument("option --group needs --map and --gt-map");
  if (args.Has("gt-map") && !map && !args.Has("markers")) {
    throw std::invalid_argument("option --gt-map needs --map or --markers");
  }
  for (const char* name : {"predicted", "rpe-delta", "rpe-unit", "markers", "align", "max-dt"}) {
    if (args.Has(name) && !trajectory)
      throw std::invalid_argument(std::string("option --") + name + " needs --est and --gt");
  }
  for (const char* name : {"scale", "align-predicted"}) {
    if (args.Flag(name) && !trajectory)
      throw std::invalid_argument(std::string("option --") + name + " needs --est and --gt");
  }
  if (args.Has("markers") && !args.Has("plot")) throw std::invalid_argument("option --markers needs --plot");
  if (args.Flag("align-predicted") && !args.Has("predicted")) {
    throw std::invalid_argument("option --align-predicted needs --predicted");
  }
}

eval::TrajectoryEvaluation RunTrajectory(const Args& args) {
  const eval::TrajectoryEvalOptions options = TrajectoryOptions(args);
  const std::string est_path = args.Require("est"), gt_path = args.Require("gt");
  const Trajectory est = ReadNonEmptyTum(est_path);
  const Trajectory gt = ReadNonEmptyTum(gt_path);
  eval::TrajectoryEvaluation evaluation = WithContext(
      est_path + " vs " + gt_path, [&] { return eval::EvaluateTrajectory(gt, est, std::nullopt, options); });
  if (const auto predicted_path = args.Get("predicted")) {
    const Trajectory predicted = ReadNonEmptyTum(*predicted_path);
    evaluation.predicted_poses = predicted.size();
    evaluation.pe_te = WithContext(*predicted_path + " vs " + gt_path, [&] {
      return eval::EvaluatePredicted(gt, predicted, options, evaluation.alignment);
    });
  }
  return evaluation;
}

std::vector<eval::PlotMarker> MarkersToPlot(const Args& args, const eval::TrajectoryEvaluation* trajectory,
                                            const eval::MapEvalResult* map_result,
                                            const std::optional<MarkerMap>& est_map,
                                            const std::optional<MarkerMap>& gt_map) {
  if (const auto markers_path = args.Get("markers"); markers_path && trajectory) {
    const MarkerMap markers = ReadMap(*markers_path);
    return eval::PlotMarkersFromMaps(&markers, trajectory->alignment, gt_map ? &*gt_map : nullptr);
  }
  // The map evaluation's per-component alignments put the estimated markers in the truth's frame.
  if (map_result) return eval::PlotMarkersFromMapEval(*est_map, *gt_map, *map_result);
  if (gt_map) return eval::PlotMarkersFromMaps(nullptr, eval::Sim3Alignment(), &*gt_map);
  return {};
}

// Everything is computed before anything is written: an error leaves no partial output.
void WriteOutputs(const Args& args, const eval::EvalReportInput& input,
                  const std::optional<MarkerMap>& est_map, const std::optional<MarkerMap>& gt_map) {
  std::optional<std::string> svg;
  if (args.Has("plot")) {
    eval::PlotInput plot;
    plot.trajectory = input.trajectory;
    plot.markers = MarkersToPlot(args, input.trajectory, input.map, est_map, gt_map);
    const auto name = [](const std::string& path) { return std::filesystem::path(path).filename().string(); };
    plot.title = input.trajectory
                     ? "waymark eval: " + name(input.est_path) + " vs " + name(input.gt_path)
                     : "waymark eval: " + name(input.map_path) + " vs " + name(input.gt_map_path);
    svg = eval::RenderSvg(plot);
  }
  const std::string json = eval::EvalReportToJson(input).dump(2) + "\n";
  const std::string markdown = eval::EvalReportToMarkdown(input);
  std::vector<std::pair<std::filesystem::path, std::string>> files;
  if (const auto path = args.Get("json")) files.emplace_back(*path, json);
  if (const auto path = args.Get("report")) files.emplace_back(*path, markdown);
  if (svg) files.emplace_back(*args.Get("plot"), *svg);
  AtomicWriteFiles(files);  // all or nothing
}

void PrintGroup(const eval::GroupResult& group) {
  std::printf("group /%s/: %zu markers, position RMS %.4f m, orientation RMS %.3f deg\n",
              group.pattern.c_str(), group.markers, group.position_rmse_m, group.orientation_rmse_deg);
  std::printf("others: %zu markers, position RMS %.4f m, orientation RMS %.3f deg\n", group.markers_other,
              group.other_position_rmse_m, group.other_orientation_rmse_deg);
}

int RunEval(const std::vector<std::string>& argv) {
  const Args args(argv,
                  {"est", "gt", "align", "max-dt", "rpe-delta", "rpe-unit", "predicted", "json", "report",
                   "plot", "markers", "map", "gt-map", "group"},
                  {"scale", "align-predicted"});
  if (args.Help()) {
    std::cout << kUsage;
    return 0;
  }
  CheckModes(args);
  args.ExpectDistinctOutputs({"json", "report", "plot"});
  std::optional<eval::TrajectoryEvaluation> trajectory;
  if (args.Has("est")) trajectory = RunTrajectory(args);
  std::optional<MarkerMap> est_map, gt_map;
  if (args.Has("gt-map")) gt_map = ReadMap(args.Require("gt-map"));
  std::optional<eval::MapEvalResult> map_result;
  if (const auto map_path = args.Get("map")) {
    est_map = ReadMap(*map_path);
    map_result = WithContext(*map_path + " vs " + args.Require("gt-map"),
                             [&] { return eval::EvaluateMap(*est_map, *gt_map); });
  }

  eval::EvalReportInput input;
  input.est_path = args.GetOr("est", "");
  input.gt_path = args.GetOr("gt", "");
  input.predicted_path = args.GetOr("predicted", "");
  input.map_path = args.GetOr("map", "");
  input.gt_map_path = args.GetOr("gt-map", "");
  input.trajectory = trajectory ? &*trajectory : nullptr;
  input.map = map_result ? &*map_result : nullptr;

  std::optional<eval::GroupResult> group;
  if (const auto pattern = args.Get("group")) group = eval::EvaluateGroup(*map_result, *pattern);
  WriteOutputs(args, input, est_map, gt_map);
  std::cout << eval::EvalSummaryTable(input);
  if (group) PrintGroup(*group);
  return 0;
}

const CommandRegistrar kRegistrar({"eval",
                                   "trajectory and map accuracy against ground truth (ATE, RPE, PE/TE)",
                                   kUsage, RunEval});

}  // namespace
}  // namespace waymark::cli
