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
#include "geometry/pose.h"
#include "io/camera_io.h"
#include "io/dataset_io.h"
#include "io/map_io.h"
#include "io/tum_io.h"
#include "io/util.h"
#include "mapping/build_report.h"
#include "mapping/map_builder.h"
#include "mapping/map_merge.h"
#include "mapping/multi_survey.h"
#include "mapping/range_bearing_map.h"
#include "runner/range_bearing_run.h"
#include "util/format.h"
#include "util/stats.h"

namespace waymark::cli {
namespace {

constexpr const char* kUsage = R"(Usage:
  waymark map build DATASET... --out MAP.json [--trajectory SMOOTHED.tum] [--trajectory-dir DIR] [options]
  waymark map merge MAP.json DATASET --out MERGED.json [--trajectory SMOOTHED.tum] [options]
  waymark map info MAP.json
  waymark map score DATASET --map MAP.json [options]   (see `waymark map score --help`)

build   learns the poses of the codes seen in the dataset directory DATASET (its detections,
        odometry, cameras, known markers and payload coordinates; docs/mapping.md): codes and
        frames are initialized from single-code poses and odometry, then one optimization over
        every code and every frame pose (robust loss, outliers rejected and reported) gives the
        map, with a covariance per code, and the smoothed trajectory. Disconnected groups of
        codes become separate components, each in its own frame, except that groups holding
        anchors or priors (markers.json) are one component in the world frame. Codes of a
        rigid board (markers.json `boards`: their poses on the board known) get one pose per
        board, and the map carries the board (docs/mapping.md, "Boards").
        Several datasets (robots, or survey days in one building) make one map, tied through
        the codes they share; --trajectory-dir DIR then receives each dataset's smoothed
        trajectory as DIR/<dataset name>.tum. Datasets with range-bearing observations of
        point landmarks (range_bearing.jsonl) are mapped by the range-bearing build
        (mapping/range_bearing_map.h): robot nodes at the observations' stamps, odometry with
        its systematic errors, start priors (dataset.yaml start_prior) or, without them, the
        first dataset's start as the origin; the measurement and odometry noise are estimated
        from the data; the map holds point landmarks (p_world_marker).
merge   the same with the codes of MAP.json as priors (their covariance, or held fixed when
        they have none); codes of MAP.json the survey does not see are kept as they were.
info    markers, components, families, anchors, boards and position uncertainty of a map, and the
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
  --trajectory-dir DIR  each dataset's smoothed trajectory T_world_robot as DIR/<name>.tum
                      (<name>: dataset.yaml name, or the directory's name)
  --calibrate-online  range-bearing datasets (two or more): for each, build the map of the others,
                      run the online EKF (waymark localize's defaults) on it against that map and
                      compare with its smoothed trajectory of this build (no ground truth); the
                      geometric mean of their mean NEES / 3 is written as map.json
                      range_bearing_sensor online_variance_factor, the factor waymark localize
                      scales its reported covariance by (docs/online.md); one extra build per
                      dataset
  --cameras-out DIR   every camera of DATASET as DIR/<name>.yaml, with the mounts the build
                      estimated (camera files that give T_robot_camera_sigma: extrinsic
                      self-calibration, docs/mapping.md) in place of the given ones, ready
                      to use as calibrated cameras (one dataset only)
  --report FILE       the summary as JSON: components, reprojection per camera (RMS, median),
                      every rejected observation (code, stamp, camera, reason) and their counts
                      by reason and by code, unmapped codes, time and peak memory per phase
  --threads N         solver threads (default 2); with --detect-images also the detection
                      threads per image (default: the machine's cores; same detections for any N)
  --no-covariance     skip the marker covariances
  --min-frames N      codes seen in fewer frames are reported, not mapped (default 2)
  --outlier-chi2 X    gate on an observation's 8 whitened residuals (default 40)
  --no-calibration    do not estimate the odometry's systematic errors
  --range-model M     range-bearing datasets: depth (default) reads each sensor's range as
                      (1 + s)((1 - c) distance + c depth) + b, its depth share c and range scale
                      s estimated per dataset, the odometry's error whitened in its own units
                      (docs/mapping.md; a camera that ranges codes by their apparent size reads
                      their depth); distance reads it as distance + b (the build before
                      2026-11-26). The map's range_bearing_sensor records the model and waymark
                      localize reads it
  --depth-ranges      the same as --range-model depth (kept for older scripts)
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

const std::set<std::string> kBuildValues = {"out",           "trajectory",     "report",
                                            "threads",       "min-frames",     "outlier-chi2",
                                            "max-gap",       "families",       "odometry-calibration",
                                            "payload-sigma", "trajectory-dir", "cameras-out",
                                            "range-model"};
const std::set<std::string> kBuildFlags = {"no-covariance", "no-calibration", "no-id-check",
                                           "detect-images", "depth-ranges",   "calibrate-online"};

// The detections the build uses (cli/dataset_detect.h).
void PrepareSurvey(const Args& args, Dataset* dataset) {
  if (args.Has("families") && !args.Flag("detect-images")) {
    throw std::invalid_argument("--families is for --detect-images");
  }
  const std::vector<std::string> families =
      args.Has("families") ? ParseFamilyList(*args.Get("families")) : std::vector<std::string>{};
  PrepareDetectionsForMapping(args.Flag("detect-images"), families, dataset,
                              args.Flag("detect-images") ? DetectionThreads(args) : 1);
}

// DATASET with the detections the build uses.
Dataset LoadSurvey(const Args& args, const std::string& dir) {
  Dataset dataset = LoadDataset(dir);
  PrepareSurvey(args, &dataset);
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
  report["camera_mounts"] = nlohmann::json::array();
  for (const CameraMountEstimate& mount : result.mounts) {
    const SE3d& T = mount.estimated;
    nlohmann::json entry = {
        {"camera", mount.camera},
        {"T_robot_camera",
         {{"t", {T.translation().x(), T.translation().y(), T.translation().z()}},
          {"q_xyzw", {T.rotation().x(), T.rotation().y(), T.rotation().z(), T.rotation().w()}}}},
        {"moved_rad", RotationAngleBetween(T, mount.given)},
        {"moved_m", (T.translation() - mount.given.translation()).norm()}};
    if (mount.covariance) {
      const Vector6d sd = mount.covariance->diagonal().cwiseMax(0.0).cwiseSqrt();
      entry["sigma_rot_rad"] = {sd[0], sd[1], sd[2]};
      entry["sigma_t_m"] = {sd[3], sd[4], sd[5]};
    }
    report["camera_mounts"].push_back(entry);
  }
  report["camera_wiggles"] = nlohmann::json::array();
  for (const CameraWiggleSummary& w : result.wiggles) {
    report["camera_wiggles"].push_back({{"camera", w.camera},
                                        {"frames", w.frames},
                                        {"rms_rad", w.rms_rad},
                                        {"rms_m", w.rms_m},
                                        {"max_rad", w.max_rad},
                                        {"max_m", w.max_m}});
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

// The dataset's cameras with the mounts the build estimated in place of the given ones (their
// prior sigma dropped: the files describe calibrated cameras), as DIR/<name>.yaml.
void AddCameraFiles(const std::string& dir, const std::map<std::string, CameraInfo>& cameras,
                    const MapBuildResult& result, std::vector<std::pair<std::string, std::string>>* files) {
  for (const auto& [name, given] : cameras) {
    CameraInfo camera = given;
    for (const CameraMountEstimate& mount : result.mounts) {
      if (mount.camera != name) continue;
      camera.T_robot_camera = mount.estimated;
      camera.T_robot_camera_sigma.reset();
    }
    files->emplace_back((std::filesystem::path(dir) / (name + ".yaml")).string(), FormatCameraYaml(camera));
  }
}

// Formats every output first, then writes them: a failure leaves no partial output.
void WriteOutputs(const Args& args, const MapBuildResult& result,
                  const std::map<std::string, CameraInfo>& cameras) {
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
  if (const auto dir = args.Get("cameras-out")) AddCameraFiles(*dir, cameras, result, &files);
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

int Finish(const Args& args, const MapBuildResult& result, const std::map<std::string, CameraInfo>& cameras) {
  if (StderrIsTerminal()) std::cerr << "\r\033[K";
  WriteOutputs(args, result, cameras);
  std::cout << FormatBuildSummary(result);
  PrintPredictedError(result.map);
  if (const auto dir = args.Get("cameras-out")) {
    std::cout << "cameras: " << cameras.size() << " file(s) in " << *dir << " (" << result.mounts.size()
              << " mount(s) estimated)\n";
  }
  if (const auto path = args.Get("trajectory")) {
    for (size_t c = 0; c < result.trajectories.size(); ++c) {
      std::cout << "trajectory of component " << c << ": "
                << ComponentTrajectoryPath(*path, static_cast<int>(c)) << " ("
                << result.trajectories[c].size() << " poses)\n";
    }
  }
  return 0;
}

// Datasets named alike in their dataset.yaml (e.g. two runs of one simulated place) are named
// by their directories instead; the same directory name twice is an error.
void UniqueNames(std::vector<Dataset>* datasets) {
  std::set<std::string> names;
  bool clash = false;
  for (const Dataset& d : *datasets) clash |= !names.insert(d.config.name).second;
  if (!clash) return;
  names.clear();
  for (Dataset& d : *datasets) {
    d.config.name = std::filesystem::absolute(d.dir).lexically_normal().filename().string();
    if (d.config.name.empty())
      d.config.name = std::filesystem::absolute(d.dir).lexically_normal().parent_path().filename().string();
    if (!names.insert(d.config.name).second)
      throw std::invalid_argument("two datasets are named " + d.config.name +
                                  " (dataset.yaml name and directory)");
  }
}

// Several datasets of the code families of mapping/map_builder.h as one survey
// (mapping/multi_survey.h).
int RunMultiBuild(const Args& args, std::vector<Dataset>* datasets) {
  if (args.Flag("detect-images") || args.Has("families"))
    throw std::invalid_argument(
        "--detect-images is for one dataset (detect each with `waymark detect` first)");
  if (args.Has("trajectory"))
    throw std::invalid_argument("--trajectory is for one dataset; with several, use --trajectory-dir DIR");
  MapBuildOptions options = ParseBuildOptions(args);
  std::vector<const Dataset*> pointers;
  for (Dataset& dataset : *datasets) {
    PrepareDetectionsForMapping(false, {}, &dataset);
    pointers.push_back(&dataset);
  }
  const CombinedSurvey combined =
      CombineSurveys(pointers, std::max(10.0, 10.0 * options.ingest.max_odometry_gap_s));
  MapBuildResult result = BuildMap(combined.dataset, options);
  if (StderrIsTerminal()) std::cerr << "\r\033[K";
  std::vector<std::pair<std::string, std::string>> files;
  files.emplace_back(args.Require("out"), FormatMap(result.map));
  std::vector<std::string> lines;
  if (const auto dir = args.Get("trajectory-dir")) {
    for (size_t c = 0; c < result.trajectories.size(); ++c) {
      for (const auto& [name, trajectory] : SplitTrajectory(combined, result.trajectories[c])) {
        if (trajectory.empty()) continue;
        const std::string file = c == 0 ? name + ".tum" : name + ".component" + std::to_string(c) + ".tum";
        const std::string path = (std::filesystem::path(*dir) / file).string();
        files.emplace_back(path,
                           FormatTum(trajectory, "waymark map build: smoothed T_world_robot of " + name +
                                                     " in component " + std::to_string(c) + "'s frame"));
        lines.push_back("trajectory of " + name + " (component " + std::to_string(c) + "): " + path + " (" +
                        std::to_string(trajectory.size()) + " poses)");
      }
    }
  }
  if (const auto path = args.Get("report")) files.emplace_back(*path, ReportJson(result).dump(1) + "\n");
  AtomicWriteFiles({files.begin(), files.end()});
  std::cout << "datasets: " << combined.parts.size() << " built as one survey\n"
            << FormatBuildSummary(result);
  PrintPredictedError(result.map);
  for (const std::string& line : lines) std::cout << line << "\n";
  return 0;
}

// The range-bearing build of several datasets (mapping/range_bearing_map.h).
int RunRangeBearingBuild(const Args& args, const std::vector<Dataset>& datasets) {
  for (const char* option : {"trajectory", "families", "odometry-calibration", "payload-sigma", "max-gap"}) {
    if (args.Has(option))
      throw std::invalid_argument(std::string("--") + option + " is not for range-bearing datasets");
  }
  RangeBearingBuildOptions options;
  if (const auto n = args.GetInt("threads")) options.num_threads = static_cast<int>(*n);
  if (const auto n = args.GetInt("min-frames")) options.min_observations = static_cast<int>(*n);
  if (const auto x = args.GetDouble("outlier-chi2")) options.outlier_chi2 = *x;
  const std::string range_model = args.GetOr("range-model", "depth");
  if (range_model != "depth" && range_model != "distance")
    throw std::invalid_argument("--range-model: expected depth or distance, got '" + range_model + "'");
  if (args.Flag("depth-ranges") && range_model != "depth")
    throw std::invalid_argument("--depth-ranges means --range-model depth: not with --range-model " +
                                range_model);
  if (range_model == "depth") {
    options.sensor_depth_share_sigma = 1.0;
    options.sensor_range_scale_sigma = 0.1;
    options.odometry_measurement_space = true;
  }
  const std::function<void(const std::string&)> terminal = TerminalProgress();
  options.progress = terminal;
  std::vector<const Dataset*> pointers;
  for (const Dataset& dataset : datasets) pointers.push_back(&dataset);
  RangeBearingBuildResult result = BuildRangeBearingMap(pointers, options);
  if (args.Flag("calibrate-online")) {
    // Leave one out: each dataset localized by the EKF (waymark localize's defaults) against the
    // map of the others, its NEES against its smoothed trajectory of this build (no ground truth).
    if (pointers.size() < 2 || !result.map.range_bearing_sensor)
      throw std::invalid_argument("--calibrate-online needs at least two range-bearing datasets");
    std::vector<NeesResult> runs;
    for (size_t i = 0; i < pointers.size(); ++i) {
      std::vector<const Dataset*> others;
      for (size_t j = 0; j < pointers.size(); ++j) {
        if (j != i) others.push_back(pointers[j]);
      }
      const std::string& name = pointers[i]->config.name;
      const auto reference = result.trajectories.find(name);
      if (reference == result.trajectories.end() || reference->second.empty())
        throw std::runtime_error("--calibrate-online: no smoothed trajectory of " + name);
      RangeBearingBuildOptions leave_out = options;
      leave_out.progress = nullptr;
      const RangeBearingBuildResult part = BuildRangeBearingMap(others, leave_out);
      const RangeBearingRun run =
          RunRangeBearingLocalizer(*pointers[i], part.map, LocalizerOptionsFromMap(part.map));
      NeesResult nees;
      if (!run.poses.empty()) nees = ComputeNees(reference->second, run.poses, run.covariances, 0.02);
      std::cout << "leave-one-out: " << name << " against the map of the others: NEES mean "
                << FormatFixed(nees.mean, 2) << " over " << nees.samples << " poses (position "
                << FormatFixed(nees.mean_position, 2) << ", heading " << FormatFixed(nees.mean_heading, 2)
                << "), " << run.outputs_withheld << " withheld while lost\n";
      runs.push_back(nees);
    }
    const double factor = LeaveOneOutVarianceFactor(runs);
    result.map.range_bearing_sensor->online_variance_factor = factor;
    std::cout << "online variance factor: " << FormatSignificant(factor, 4)
              << " (geometric mean of the left-out datasets' mean NEES / 3; map.json range_bearing_sensor "
                 "online_variance_factor; their pooled mean NEES / 3: "
              << FormatSignificant(PooledVarianceFactor(runs), 4) << ")\n";
  }
  if (StderrIsTerminal()) std::cerr << "\r\033[K";
  std::vector<std::pair<std::string, std::string>> files;
  files.emplace_back(args.Require("out"), FormatMap(result.map));
  if (const auto dir = args.Get("trajectory-dir")) {
    for (const auto& [name, trajectory] : result.trajectories) {
      files.emplace_back((std::filesystem::path(*dir) / (name + ".tum")).string(),
                         FormatTum(trajectory, "waymark map build: smoothed T_world_robot of " + name));
    }
  }
  if (const auto path = args.Get("report")) {
    nlohmann::json report = {{"landmarks", result.map.markers.size()},
                             {"observations_used", result.observations},
                             {"outliers", result.outliers},
                             {"range_outliers", result.range_outliers},
                             {"range_rms_m", result.range_rms_m},
                             {"bearing_rms_rad", result.bearing_rms_rad},
                             {"solver_time_s", result.solver_time_s},
                             {"noise",
                              {{"sigma_range_a_m", result.noise.range_a_m},
                               {"sigma_range_b", result.noise.range_b},
                               {"sigma_bearing_rad", result.noise.bearing_rad},
                               {"odometry_q_t", result.noise.odometry_q_t},
                               {"odometry_q_r", result.noise.odometry_q_r},
                               {"odometry_delay_s", result.noise.odometry_delay_s},
                               {"range_scale_sigma", result.noise.range_scale_sigma},
                               {"range_scale_time_s", result.noise.range_scale_time_s}}}};
    for (const RangeBearingDatasetSummary& d : result.datasets) {
      report["datasets"].push_back(
          {{"name", d.name},
           {"nodes", d.nodes},
           {"observations", d.observations},
           {"outliers", d.outliers},
           {"range_outliers", d.range_outliers},
           {"gauge", d.gauge},
           {"sensor_bias", {d.sensor_bias[0], d.sensor_bias[1]}},
           {"bearing_scale", d.bearing_scale},
           {"depth_share", d.depth_share},
           {"range_scale", d.range_scale},
           {"sigma_range", {d.noise.range_a_m, d.noise.range_b}},
           {"sigma_bearing_rad", d.noise.bearing_rad},
           {"odometry_q", {d.noise.odometry_q_t, d.noise.odometry_q_r}},
           {"odometry_delay_s", d.noise.odometry_delay_s},
           {"odometry_calibration",
            {d.odometry_calibration[0], d.odometry_calibration[1], d.odometry_calibration[2]}}});
    }
    for (const auto& [key, reason] : result.unmapped)
      report["unmapped"].push_back({{"family", key.family}, {"id", key.id}, {"reason", reason}});
    files.emplace_back(*path, report.dump(1) + "\n");
  }
  AtomicWriteFiles({files.begin(), files.end()});
  std::cout << "landmarks: " << result.map.markers.size() << " (point landmarks, one component)\n"
            << "observations: " << result.observations << " used (" << result.range_outliers
            << " of them for their bearing only: range outliers), " << result.outliers << " outliers\n"
            << "residual RMS: range " << FormatFixed(result.range_rms_m, 3) << " m, bearing "
            << FormatFixed(result.bearing_rms_rad, 4) << " rad\n"
            << "noise estimated: sigma_range " << FormatSignificant(result.noise.range_a_m, 3) << " m + "
            << FormatSignificant(result.noise.range_b, 3) << " x range, sigma_bearing "
            << FormatSignificant(result.noise.bearing_rad, 3) << " rad, odometry q_t "
            << FormatSignificant(result.noise.odometry_q_t, 3) << " m^2/m, q_r "
            << FormatSignificant(result.noise.odometry_q_r, 3) << " rad^2/rad, odometry delay "
            << FormatFixed(result.noise.odometry_delay_s, 3) << " s, range scale sigma "
            << FormatSignificant(result.noise.range_scale_sigma, 3) << " (correlation time "
            << FormatSignificant(result.noise.range_scale_time_s, 3) << " s)\n";
  for (const RangeBearingDatasetSummary& d : result.datasets) {
    std::cout << d.name << ": " << d.nodes << " nodes, " << d.observations << " observations, " << d.outliers
              << " outliers, " << d.gauge << ", odometry calibration "
              << FormatSignificant(d.odometry_calibration[0], 3) << ","
              << FormatSignificant(d.odometry_calibration[1], 3) << ","
              << FormatSignificant(d.odometry_calibration[2], 3) << ", sensor offsets "
              << FormatFixed(d.sensor_bias[0], 3) << " m, " << FormatFixed(d.sensor_bias[1], 4)
              << " rad, bearing scale " << FormatFixed(d.bearing_scale, 4) << ", depth share "
              << FormatFixed(d.depth_share, 3) << ", range scale " << FormatFixed(d.range_scale, 4)
              << ", sigma_range " << FormatSignificant(d.noise.range_a_m, 3) << " m + "
              << FormatSignificant(d.noise.range_b, 3) << " x range, sigma_bearing "
              << FormatSignificant(d.noise.bearing_rad, 3) << " rad, odometry delay "
              << FormatFixed(d.noise.odometry_delay_s, 3) << " s\n";
  }
  if (const auto& sensor = result.map.range_bearing_sensor) {
    const RangeBearingSensorValues &m = sensor->prior_mean, &sd = sensor->prior_sigma;
    const auto pm = [](double mean, double sigma) {
      return FormatSignificant(mean, 3) + " +- " + FormatSignificant(sigma, 3);
    };
    std::cout << "sensor prior for another robot (map.json range_bearing_sensor, range model "
              << (sensor->depth_ranges ? "depth" : "distance") << "): range offset "
              << pm(m.range_offset_m, sd.range_offset_m) << " m, bearing offset "
              << pm(m.bearing_offset_rad, sd.bearing_offset_rad) << " rad, bearing scale "
              << pm(m.bearing_scale, sd.bearing_scale) << ", depth share "
              << pm(m.depth_share, sd.depth_share) << ", range scale " << pm(m.range_scale, sd.range_scale)
              << ", odometry calibration " << pm(m.odometry_calibration[0], sd.odometry_calibration[0])
              << ", " << pm(m.odometry_calibration[1], sd.odometry_calibration[1]) << ", "
              << pm(m.odometry_calibration[2], sd.odometry_calibration[2]) << "\n";
  }
  {
    // Stage (5): the odometry calibration's correlation time (waymark localize's default).
    const CalibrationTimeFit& fit = result.calibration_time;
    std::cout << "odometry calibration's correlation time (map.json calibration_time_s, waymark localize's "
                 "default): ";
    if (fit.fitted) {
      std::cout << FormatFixed(fit.time_s, 2) << " s, turn scale variation sigma "
                << FormatFixed(fit.sigma, 4);
    } else {
      std::cout << "no fit (" << fit.autocovariance.size()
                << " positive lags, no decay): the EKF's calibration constant";
    }
    std::cout << "; turn scale after the constant one, autocovariance R(lag):";
    for (const auto& [lag, r] : fit.autocovariance)
      std::cout << " " << FormatSignificant(lag, 3) << ":" << FormatSignificant(r, 3);
    std::cout << "\n";
  }
  for (const auto& [key, reason] : result.unmapped)
    std::cout << "unmapped " << key.ToString() << ": " << reason << "\n";
  std::cout << "solver time: " << FormatFixed(result.solver_time_s, 2) << " s\n";
  return 0;
}

int RunBuild(const std::vector<std::string>& argv) {
  const Args args(argv, kBuildValues, kBuildFlags);
  if (args.Help()) {
    std::cout << kUsage;
    return 0;
  }
  args.ExpectPositionals(1, 1000, "dataset directory DATASET");
  args.Require("out");
  args.ExpectDistinctOutputs({"out", "trajectory", "report", "trajectory-dir", "cameras-out"});
  if (args.positionals().size() > 1 || args.Has("trajectory-dir")) {
    if (args.Has("cameras-out"))
      throw std::invalid_argument(
          "--cameras-out is for one dataset (its cameras are calibrated by its own build)");
    std::vector<Dataset> datasets;
    for (const std::string& dir : args.positionals()) datasets.push_back(LoadDataset(dir));
    UniqueNames(&datasets);
    std::vector<const Dataset*> pointers;
    for (const Dataset& dataset : datasets) pointers.push_back(&dataset);
    if (HasRangeBearing(pointers)) return RunRangeBearingBuild(args, datasets);
    if (args.Flag("depth-ranges") || args.Has("range-model"))
      throw std::invalid_argument("--range-model and --depth-ranges are for range-bearing datasets");
    return RunMultiBuild(args, &datasets);
  }
  Dataset dataset = LoadDataset(args.positionals()[0]);
  const std::vector<const Dataset*> one = {&dataset};
  if (args.Has("cameras-out") && HasRangeBearing(one))
    throw std::invalid_argument(
        "--cameras-out is for camera surveys (range-bearing datasets have no camera mount)");
  if (HasRangeBearing(one)) return RunRangeBearingBuild(args, {dataset});
  if (args.Flag("depth-ranges") || args.Has("range-model"))
    throw std::invalid_argument("--range-model and --depth-ranges are for range-bearing datasets");
  const MapBuildOptions options = ParseBuildOptions(args);
  PrepareSurvey(args, &dataset);
  return Finish(args, BuildMap(dataset, options), dataset.cameras);
}

int RunMerge(const std::vector<std::string>& argv) {
  const Args args(argv, kBuildValues, kBuildFlags);
  if (args.Help()) {
    std::cout << kUsage;
    return 0;
  }
  args.ExpectPositionals(2, 2, "MAP.json and dataset directory DATASET");
  // Options of the several-dataset and range-bearing builds, which merge does not run.
  for (const char* option : {"range-model", "depth-ranges", "trajectory-dir"}) {
    if (args.Has(option) || args.Flag(option))
      throw std::invalid_argument(std::string("--") + option + " is for map build, not map merge");
  }
  args.Require("out");
  args.ExpectDistinctOutputs({"out", "trajectory", "report", "cameras-out"});
  const MapBuildOptions options = ParseBuildOptions(args);
  const MarkerMap existing = ReadMap(args.positionals()[0]);
  const Dataset dataset = LoadSurvey(args, args.positionals()[1]);
  return Finish(args, MergeSurveyIntoMap(existing, dataset, options), dataset.cameras);
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
  for (const MapBoard& board : map.boards) {
    std::cout << "board " << board.name << ": " << board.members.size() << " codes"
              << (board.fixed ? ", fixed" : "") << "\n";
  }
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
