// `waymark map`: learn a map from a survey (build), describe a map (info), and merge a new
// survey into an existing map (merge). The math is in mapping/; this file parses arguments,
// shows progress on a terminal and prints the summary.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "cli/args.h"
#include "cli/command.h"
#include "cli/dataset_detect.h"
#include "eval/map_metrics.h"
#include "factors/calibrated_odometry_factor.h"
#include "io/dataset_io.h"
#include "io/map_io.h"
#include "io/tum_io.h"
#include "io/util.h"
#include "mapping/build_report.h"
#include "mapping/map_builder.h"
#include "mapping/map_merge.h"
#include "util/format.h"
#include "util/stats.h"

namespace waymark::cli {
namespace {

constexpr const char* kUsage = R"(Usage:
  waymark map build DATASET --out MAP.json [--trajectory SMOOTHED.tum] [options]
  waymark map merge MAP.json DATASET --out MERGED.json [--trajectory SMOOTHED.tum] [options]
  waymark map info MAP.json
  waymark map score DATASET --map MAP.json [options]   (see `waymark map score --help`)

build   learns the poses of the codes seen in the dataset directory DATASET (its detections,
        odometry, cameras, known markers and payload coordinates; docs/mapping.md): codes and
        frames are initialized from single-code poses and odometry, then one optimization over
        every code and every frame pose (robust loss, outliers rejected and reported) gives the
        map, with a covariance per code, and the smoothed trajectory. Disconnected groups of
        codes become separate components, each in its own frame, except that groups holding
        anchors or priors (markers.json) are one component in the world frame.
merge   the same with the codes of MAP.json as priors (their covariance, or held fixed when
        they have none); codes of MAP.json the survey does not see are kept as they were.
info    markers, components, families, anchors and position uncertainty of a map, and the
        marker error `waymark eval` would measure, predicted per component from the covariances.

Progress goes to stderr on a terminal; the summary (markers and components, reprojection
RMS and median per camera, outliers by reason and by code, time and peak memory per phase,
solver termination) to stdout. Outputs are written
atomically, and only when the whole build succeeded.

Options (build, merge):
  --out FILE          the map (map.json format)
  --trajectory FILE   the smoothed trajectories T_world_robot (TUM), one file per component:
                      FILE holds component 0, <stem>.component<c><ext> component c >= 1
                      (e.g. smoothed.tum, smoothed.component1.tum), each in its component's frame
  --report FILE       the summary as JSON: components, reprojection per camera (RMS, median),
                      every rejected observation (code, stamp, camera, reason) and their counts
                      by reason and by code, unmapped codes, time and peak memory per phase
  --threads N         solver threads (default 2)
  --no-covariance     skip the marker covariances
  --min-frames N      codes seen in fewer frames are reported, not mapped (default 2)
  --outlier-chi2 X    gate on an observation's 8 whitened residuals (default 40)
  --no-calibration    do not estimate the odometry's systematic errors
  --odometry-calibration K,TURN,DIST[,SK,ST,SD]
                      the odometry's systematic errors known from an earlier build of this
                      robot (its summary's "odometry calibration" line prints this argument):
                      heading drift K (rad/m), turn scale and distance scale (fractions); held
                      at these values, or with the sigmas SK,ST,SD a prior that this survey
                      refines. For surveys that barely excite them (rooms joined by doors)
  --payload-sigma M   how far coordinates printed in the codes may be from the truth, per axis
                      (default 0.01 m): their position priors' sigma
  --no-id-check       keep views whose id disagrees with the code's other views along the
                      odometry (by default they are set aside and reported as misdecoded)
  --max-gap S         odometry gaps longer than S seconds split it (default 1)
  --detect-images     detect the codes on DATASET's images (images.csv) instead of reading
                      its detections.jsonl (the same detector as `waymark detect`)
  --families LIST     with --detect-images: the families to detect (default
                      qr,datamatrix,apriltag-36h11)
A dataset with images but no detections.jsonl needs --detect-images; one in which no code
is detected at all is an error (nothing is written).
)";

// Progress on a terminal: one line rewritten in place.
std::function<void(const std::string&)> TerminalProgress() {
  if (!StderrIsTerminal()) return nullptr;
  return [](const std::string& line) { std::cerr << "\r\033[K" << line << std::flush; };
}

MapBuildOptions ParseBuildOptions(const Args& args) {
  MapBuildOptions options;
  options.num_threads = 2;
  if (const auto n = args.GetInt("threads")) options.num_threads = static_cast<int>(*n);
  if (const auto n = args.GetInt("min-frames")) options.min_frames = static_cast<int>(*n);
  if (const auto x = args.GetDouble("outlier-chi2")) options.outlier_chi2 = *x;
  if (const auto x = args.GetDouble("max-gap")) options.ingest.max_odometry_gap_s = *x;
  if (const auto x = args.GetDouble("payload-sigma")) options.payload_sigma_m = *x;
  options.compute_covariance = !args.Flag("no-covariance");
  options.calibrate_odometry = !args.Flag("no-calibration");
  if (const auto c = args.GetDoubleList("odometry-calibration")) {
    if (c->size() != 3 && c->size() != 6) {
      throw std::invalid_argument(
          "option --odometry-calibration: expected K,TURN,DIST or K,TURN,DIST,SK,ST,SD (3 or 6 "
          "numbers), got " +
          std::to_string(c->size()));
    }
    if (args.Flag("no-calibration")) {
      throw std::invalid_argument("--odometry-calibration and --no-calibration exclude each other");
    }
    options.odometry_calibration = Eigen::Vector3d((*c)[0], (*c)[1], (*c)[2]);
    if (c->size() == 6) options.odometry_calibration_sigma = Eigen::Vector3d((*c)[3], (*c)[4], (*c)[5]);
  }
  options.check_ids = !args.Flag("no-id-check");
  options.progress = TerminalProgress();
  std::string why;
  if (!options.Check(&why)) throw std::invalid_argument("options: " + why);
  return options;
}

const std::set<std::string> kBuildValues = {
    "out",      "trajectory",           "report",       "threads", "min-frames", "outlier-chi2", "max-gap",
    "families", "odometry-calibration", "payload-sigma"};
const std::set<std::string> kBuildFlags = {"no-covariance", "no-calibration", "no-id-check", "detect-images"};

// DATASET with the detections the build uses (cli/dataset_detect.h).
Dataset LoadSurvey(const Args& args, const std::string& dir) {
  if (args.Has("families") && !args.Flag("detect-images")) {
    throw std::invalid_argument("--families is for --detect-images");
  }
  Dataset dataset = LoadDataset(dir);
  const std::vector<std::string> families =
      args.Has("families") ? ParseFamilyList(*args.Get("families")) : std::vector<std::string>{};
  PrepareDetectionsForMapping(args.Flag("detect-images"), families, &dataset);
  return dataset;
}

// Path of component c's trajectory: `path` itself for component 0, else
// <stem>.component<c><ext> beside it.
std::string ComponentTrajectoryPath(const std::string& path, int component) {
  if (component == 0) return path;
  const std::filesystem::path p(path);
  return (p.parent_path() /
          (p.stem().string() + ".component" + std::to_string(component) + p.extension().string()))
      .string();
}

nlohmann::json ReportJson(const MapBuildResult& result) {
  nlohmann::json report = {{"markers", result.map.markers.size()},
                           {"frames", result.frames},
                           {"observations_used", result.observations},
                           {"init_time_s", result.init_time_s},
                           {"solver_time_s", result.solver_time_s},
                           {"covariance_time_s", result.covariance_time_s},
                           {"iterations", result.iterations},
                           {"termination", result.termination},
                           {"covariance_computed", result.covariance_computed},
                           {"notes", result.notes}};
  for (const ComponentSummary& c : result.components) {
    report["components"].push_back({{"component", c.component},
                                    {"markers", c.markers},
                                    {"frames", c.frames},
                                    {"trajectory_poses", c.trajectory_poses},
                                    {"gauge", c.gauge}});
  }
  for (const CameraReprojection& r : result.reprojection) {
    report["reprojection"].push_back({{"camera", r.camera},
                                      {"observations", r.observations},
                                      {"rms_px", r.rms_px},
                                      {"median_px", r.median_px}});
  }
  report["phases"] = nlohmann::json::array();
  double peak_rss_mb = 0.0;
  for (const PhaseTime& p : result.phases) {
    report["phases"].push_back({{"phase", p.phase}, {"seconds", p.seconds}, {"peak_rss_mb", p.peak_rss_mb}});
    peak_rss_mb = std::max(peak_rss_mb, p.peak_rss_mb);
  }
  report["peak_rss_mb"] = peak_rss_mb;
  report["solves"] = nlohmann::json::array();
  for (const SolveStageSummary& solve : result.solves) {
    report["solves"].push_back({{"stage", solve.stage},
                                {"iterations", solve.iterations},
                                {"total_s", solve.total_s},
                                {"linear_solver_s", solve.linear_solver_s},
                                {"jacobian_s", solve.jacobian_s},
                                {"residual_s", solve.residual_s}});
  }
  const OutlierTally tally = TallyOutliers(result.outliers);
  report["outliers_by_reason"] = nlohmann::json::object();
  for (const auto& [reason, n] : tally.by_reason) report["outliers_by_reason"][reason] = n;
  report["outliers_by_code"] = nlohmann::json::object();
  for (const auto& [code, n] : tally.by_code) report["outliers_by_code"][code] = n;
  report["outliers"] = nlohmann::json::array();
  for (const RejectedObservation& o : result.outliers) {
    report["outliers"].push_back({{"family", o.key.family},
                                  {"id", o.key.id},
                                  {"t", o.stamp_s},
                                  {"camera", o.camera},
                                  {"rms_px", o.rms_px},
                                  {"reason", o.reason}});
  }
  if (result.odometry_calibration) {
    const Eigen::Vector3d& c = *result.odometry_calibration;
    nlohmann::json calibration = {{"k_rad_per_m", c[0]},
                                  {"turn_scale", c[1]},
                                  {"distance_scale", c[2]},
                                  {"given", result.odometry_calibration_given}};
    if (const auto& covariance = result.odometry_calibration_covariance) {
      calibration["sigma"] = {std::sqrt((*covariance)(0, 0)), std::sqrt((*covariance)(1, 1)),
                              std::sqrt((*covariance)(2, 2))};
    }
    report["odometry_calibration"] = calibration;
  }
  report["unmapped"] = nlohmann::json::array();
  for (const UnmappedMarker& u : result.unmapped) {
    report["unmapped"].push_back({{"family", u.key.family}, {"id", u.key.id}, {"reason", u.reason}});
  }
  return report;
}

// Formats every output first, then writes them: a failure leaves no partial output.
void WriteOutputs(const Args& args, const MapBuildResult& result) {
  std::vector<std::pair<std::string, std::string>> files;  // path, text
  files.emplace_back(args.Require("out"), FormatMap(result.map));
  if (const auto path = args.Get("trajectory")) {
    for (size_t c = 0; c < result.trajectories.size(); ++c) {
      files.emplace_back(
          ComponentTrajectoryPath(*path, static_cast<int>(c)),
          FormatTum(result.trajectories[c], "waymark map: smoothed T_world_robot of component " +
                                                std::to_string(c) + ", in its own frame"));
    }
  }
  if (const auto path = args.Get("report")) files.emplace_back(*path, ReportJson(result).dump(1) + "\n");
  AtomicWriteFiles({files.begin(), files.end()});  // all or nothing
}

// What `waymark eval` would measure against the truth, predicted from the map's covariances
// (eval::PredictMapError): one line per component that has a prediction.
void PrintPredictedError(const MarkerMap& map) {
  const std::vector<eval::PredictedComponentError> predictions = eval::PredictMapError(map);
  if (predictions.empty()) return;
  std::cout << "expected marker position error (from the covariance; what `waymark eval` would measure):\n";
  for (const eval::PredictedComponentError& p : predictions) {
    std::cout << "  component " << p.component << ": " << FormatFixed(1e3 * p.aligned_rms_m, 1)
              << " mm RMS after alignment, " << FormatFixed(1e3 * p.rms_m, 1) << " mm in the map's frame"
              << (p.joint ? "" : " (markers taken as independent: no covariance factor)") << "\n";
  }
}

int Finish(const Args& args, const MapBuildResult& result) {
  if (StderrIsTerminal()) std::cerr << "\r\033[K";
  WriteOutputs(args, result);
  std::cout << FormatBuildSummary(result);
  PrintPredictedError(result.map);
  if (const auto path = args.Get("trajectory")) {
    for (size_t c = 0; c < result.trajectories.size(); ++c) {
      std::cout << "trajectory of component " << c << ": "
                << ComponentTrajectoryPath(*path, static_cast<int>(c)) << " ("
                << result.trajectories[c].size() << " poses)\n";
    }
  }
  return 0;
}

int RunBuild(const std::vector<std::string>& argv) {
  const Args args(argv, kBuildValues, kBuildFlags);
  if (args.Help()) {
    std::cout << kUsage;
    return 0;
  }
  args.ExpectPositionals(1, 1, "dataset directory DATASET");
  args.Require("out");
  args.ExpectDistinctOutputs({"out", "trajectory", "report"});
  const MapBuildOptions options = ParseBuildOptions(args);
  const Dataset dataset = LoadSurvey(args, args.positionals()[0]);
  return Finish(args, BuildMap(dataset, options));
}

int RunMerge(const std::vector<std::string>& argv) {
  const Args args(argv, kBuildValues, kBuildFlags);
  if (args.Help()) {
    std::cout << kUsage;
    return 0;
  }
  args.ExpectPositionals(2, 2, "MAP.json and dataset directory DATASET");
  args.Require("out");
  args.ExpectDistinctOutputs({"out", "trajectory", "report"});
  const MapBuildOptions options = ParseBuildOptions(args);
  const MarkerMap existing = ReadMap(args.positionals()[0]);
  const Dataset dataset = LoadSurvey(args, args.positionals()[1]);
  return Finish(args, MergeSurveyIntoMap(existing, dataset, options));
}

int RunInfo(const std::vector<std::string>& argv) {
  const Args args(argv, {}, {});
  if (args.Help()) {
    std::cout << kUsage;
    return 0;
  }
  args.ExpectPositionals(1, 1, "map file MAP.json");
  const MarkerMap map = ReadMap(args.positionals()[0]);
  std::map<int, size_t> components;
  std::map<std::string, size_t> families;
  size_t fixed = 0;
  std::vector<double> sigma_mm;
  for (const MapMarker& m : map.markers) {
    ++components[m.component.value_or(0)];
    ++families[m.key.family];
    if (m.fixed) ++fixed;
    if (m.covariance)
      sigma_mm.push_back(1e3 * std::sqrt(std::max(0.0, m.covariance->bottomRightCorner<3, 3>().trace())));
  }
  std::cout << "markers: " << map.markers.size() << " (" << fixed << " fixed)\n"
            << "components: " << components.size() << "\n";
  for (const auto& [c, n] : components) std::cout << "  component " << c << ": " << n << " markers\n";
  std::cout << "families:";
  for (const auto& [family, n] : families) std::cout << " " << family << " " << n;
  std::cout << "\ncovariance: " << sigma_mm.size() << " markers";
  if (!sigma_mm.empty()) {
    std::sort(sigma_mm.begin(), sigma_mm.end());
    std::cout << ", position sigma (sqrt of the trace) median "
              << FormatFixed(QuantileOfSorted(sigma_mm, 0.5), 2) << " mm, max "
              << FormatFixed(sigma_mm.back(), 2) << " mm";
  }
  std::cout << "\n";
  PrintPredictedError(map);
  return 0;
}

int RunMap(const std::vector<std::string>& args) {
  if (args.empty()) throw std::invalid_argument("missing verb (expected build, merge or info; see --help)");
  const std::string& verb = args[0];
  const std::vector<std::string> rest(args.begin() + 1, args.end());
  if (verb == "build") return RunBuild(rest);
  if (verb == "merge") return RunMerge(rest);
  if (verb == "info") return RunInfo(rest);
  throw std::invalid_argument("unknown verb '" + verb + "' (expected build, merge or info; see --help)");
}

const CommandRegistrar kRegistrar(Command{
    "map", "learn a map from a survey (build), merge a survey, describe a map", kUsage, RunMap});

}  // namespace
}  // namespace waymark::cli
