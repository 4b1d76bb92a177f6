// `waymark localize`: the online localizer on a dataset (runner/run.h's RunLocalizer) or, with
// --live, on JSON lines read from stdin (runner/run.h's LocalizeStream). This file parses
// arguments and input lines, writes the outputs and prints the summary; no math.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "cli/args.h"
#include "cli/command.h"
#include "eval/trajectory_eval.h"
#include "io/dataset_io.h"
#include "io/detections_io.h"
#include "io/json_util.h"
#include "io/map_io.h"
#include "io/tum_io.h"
#include "io/util.h"
#include "runner/live_input.h"
#include "runner/range_bearing_run.h"
#include "runner/run.h"
#include "util/format.h"
#include "util/stats.h"

namespace waymark::cli {
namespace {

constexpr const char* kUsage = R"(Usage:
  waymark localize DATASET --map MAP.json --out RUN.tum [options]
  waymark localize DATASET --map MAP.json --live [options] < input.jsonl > poses.jsonl

A dataset with range-bearing observations (range_bearing.jsonl) is localized against the
point landmarks of MAP.json by the range-bearing EKF (online/range_bearing_localizer.h) with
the map's range_bearing_noise (with its odometry_delay_s: the odometry's lag behind the
measurements, estimated by the map build), starting at dataset.yaml's start_prior; it writes --out (the
poses while not lost) and, when the dataset has a ground truth, prints the ATE and the NEES.
The filter's heading is the odometry's direction of travel: the NEES compares it with the
truth's heading turned by the truth's yaw to the odometry, measured on the straight stretches
(a motion-capture frame sits on the robot as its markers were put); the NEES against the
heading as recorded is printed beside it.
The map's landmark errors (its position_covariance and position_covariance_factor) are handled as
--map-uncertainty says:
  --map-uncertainty M estimate (default: the landmarks' errors are states of the EKF, refined by
                      the sightings), consider (Schmidt: kept correlated with the state, not
                      estimated), in-noise (added to each sighting's noise as if independent) or
                      ignore (the map taken as exact); range-bearing datasets only
  --sensor-prior P    map (default) or none. map: when MAP.json has a range_bearing_sensor (written
                      by `waymark map build`), the EKF reads ranges with the map's range model
                      (depth or distance) and starts the robot's odometry calibration, sensor
                      offsets, bearing scale, depth share and range scale at the mapped robots'
                      mean with their spread as sigma (docs/online.md); none: as with a map
                      without it (ranges as distances, the calibration and offsets from 0 with
                      fixed weak sigmas); range-bearing datasets only
  --depth-share-sigma S  the sigma of the sensor's depth share c_depth in the EKF (ranges read
                      (1 - c) distance + c depth along the sensor's axis: a camera that ranges a
                      code by its apparent size reads its depth), from the map's mean (or 0) with
                      this sigma (default: the map's spread, or 0 without a sensor prior: ranges
                      taken as distances; 1: weak); range-bearing datasets only
  --calibration-time T  the odometry calibration (heading drift, turn and distance scale) as a
                      first-order Gauss-Markov process of correlation time T seconds about the
                      prior's mean, with the prior's sigma as its stationary sigma (docs/online.md);
                      0: constant; default: the map's range_bearing_sensor calibration_time_s (fitted
                      by `waymark map build` from the mapped robots' smoothed trajectories against
                      their odometry) with --sensor-prior map and without --turn-fluctuation, else
                      0; range-bearing datasets only
  --turn-fluctuation S,T  the turn scale's fast variation as its own Gauss-Markov state beside the
                      robot's constant turn scale: stationary sigma S, correlation time T seconds
                      (the map's calibration_turn_scale_sigma and calibration_time_s are both, as
                      fitted by the map build; default: none); range-bearing datasets only
  --variance-factor K  report the EKF's pose covariance scaled by K > 0 (the estimate and the
                      gates unchanged); default: the map's range_bearing_sensor
                      online_variance_factor (`waymark map build --calibrate-online`: leave one
                      out on the mapped robots, docs/online.md) with --sensor-prior map, else 1;
                      1 disables; range-bearing datasets only
  --update-iterations N  Gauss-Newton iterations of each EKF update while tracking (the
                      iterated EKF: h relinearized at the updated state, stopping once converged;
                      1..100, default 1: the plain EKF); range-bearing datasets only
  --relocalization-iterations N  the same while the filter is lost (its prior widened to
                      reacquire: one linearization can settle on a wrong pose); 1..100, default 1;
                      range-bearing datasets only

Localizes the robot against MAP.json (from `waymark map build`) with an EKF (docs/online.md):
the odometry predicts, every code seen corrects. Odometry and camera frames are merged in
time order and the odometry is interpolated to each frame's instant. Codes absent from the
map, frames outside the odometry's time span and inputs whose time goes backwards are
counted warnings; a map with none of the detected codes (a map of another place) is an error.

Dataset mode reads DATASET's odometry.tum and detections.jsonl (or, with --detect-images, its
images.csv) and writes:
  --out FILE          tracked poses T_world_robot, one per camera instant while tracking (TUM)
  --predicted FILE    the pose predicted just before each correcting frame (TUM), for
                      `waymark eval --predicted` ([Bach]'s PE and TE)
  --poses FILE        one JSON line per camera frame: stamp, camera, status (tracking, suspect,
                      lost, uninitialized), pose and covariance while tracking, the frame's
                      accepted, gated and unknown codes and its latency (docs/formats.md)
It prints frames, tracking %, correction counts, relocalizations, how often the track became
suspect or lost because codes the map puts in view were not seen, and the per-frame latency
(detection, if any, plus odometry and update): mean, median, p99 and max in ms.

--live reads JSON lines on stdin, in time order (docs/formats.md, "Localization input/output"):
  {"t": 1.25, "T_odom_robot": {"t": [x, y, z], "q_xyzw": [qx, qy, qz, qw]}}      odometry
  {"t": 1.25, "v": 0.5, "omega": 0.1}     velocities (planar: m/s, rad/s since the previous one)
  {"t": 1.30, "camera": "cam0", "markers": [...]}            detections (detections.jsonl)
  {"t": 1.30, "camera": "cam0", "image": "frames/0001.png"}   an image to detect on
and writes one JSON line per camera frame on stdout (the --poses format), flushed at once.
A frame is answered when the odometry has passed its stamp (interpolated), or 0.5 s of input
later. Odometry is held --late-frame-window seconds behind the newest input, so a frame that
arrives after newer odometry, up to that late, is still used at its own stamp. DATASET gives only dataset.yaml and the cameras. A malformed line is reported on
stderr with its line number, counted and skipped; the counts go to stderr at the end.

Options:
  --map FILE          the map (map.json format), required
  --mode MODE         tight (the four corners, default), loose ([Bach]'s single-code pose) or
                      single-frame (no filter: each frame's robust PnP over all its codes; the
                      baseline a filter must match, docs/online.md)
  --without-odometry V,W     a dataset or stream without odometry: between frames the pose is a
                      random walk of V m/s per axis and W rad/s in heading (default 1,2; a
                      hand-held camera or a walking robot); used until odometry comes
  --detect-images     detect the codes on DATASET's images (images.csv) instead of reading
                      detections.jsonl; the detection time counts in the latency
  --families LIST     families to detect (default: those of the map's codes), e.g.
                      qr,datamatrix,apriltag-36h11
  --realtime          pace the input by its timestamps (replay at the recorded speed; a gap
                      between two stamps waits at most 1 s, and the shortened gaps are counted)
  --live              read the input from stdin (above) instead of DATASET's files
  --odometry-time-offset S   odometry clock minus image clock, s (as `waymark map build` reports
                      it for the survey): odometry stamped t is used at t - S (default 0)
  --late-frame-window S      live: how late (s) a frame may arrive after newer odometry and still
                      be used at its stamp (default 0.2)
  --start-pose X,Y,YAW_DEG   the robot's pose in the map at its first odometry sample, roughly
                      (within about 0.5 m and 15 deg): tells apart the map's squares (family
                      square: no ids, all alike) until the first start. Required when the map
                      has several squares and no code of another family (docs/online.md)
  --detect-budget-ms MS      live, image lines: wall-clock time per image after which the second
                      passes (QR, DataMatrix, AprilTag) stop (default 25; 0: no limit); the
                      attempts skipped are counted in the summary. Offline (dataset mode) detection
                      never reads a clock: its results depend on the images alone.
  --full-frame-every N       live, image lines: while tracking, detect only where the map
                      predicts its codes (each predicted code's box grown by half its side, at
                      least 24 px; no code predicted in view: nothing to detect), and on the
                      whole frame every N-th frame per camera and whenever the track is not
                      tracking (default 10; 1: always the whole frame). The summary gives the
                      CPU time per image of both kinds.
)";

const std::set<std::string> kValues = {"map",
                                       "out",
                                       "mode",
                                       "without-odometry",
                                       "predicted",
                                       "poses",
                                       "families",
                                       "odometry-time-offset",
                                       "late-frame-window",
                                       "detect-budget-ms",
                                       "full-frame-every",
                                       "start-pose",
                                       "map-uncertainty",
                                       "sensor-prior",
                                       "depth-share-sigma",
                                       "calibration-time",
                                       "turn-fluctuation",
                                       "variance-factor",
                                       "update-iterations",
                                       "relocalization-iterations"};
const std::set<std::string> kFlags = {"detect-images", "realtime", "live"};
// The options only a range-bearing dataset (range_bearing.jsonl) takes, in the order the
// refusal names them.
const std::vector<std::string> kRangeBearingOnly = {
    "map-uncertainty",  "sensor-prior",    "depth-share-sigma", "calibration-time",
    "turn-fluctuation", "variance-factor", "update-iterations", "relocalization-iterations"};

bool HasRangeBearingOnlyOption(const Args& args) {
  return std::any_of(kRangeBearingOnly.begin(), kRangeBearingOnly.end(),
                     [&args](const std::string& name) { return args.Has(name); });
}

// "--map-uncertainty, --sensor-prior, ... and --relocalization-iterations".
std::string RangeBearingOnlyOptions() {
  std::string names;
  for (size_t i = 0; i < kRangeBearingOnly.size(); ++i) {
    if (i > 0) names += i + 1 == kRangeBearingOnly.size() ? " and " : ", ";
    names += "--" + kRangeBearingOnly[i];
  }
  return names;
}
// Live image detection: wall-clock ms per image for the second passes (a 30 fps camera
// leaves 33 ms per frame for detection and the update).
constexpr double kDefaultLiveDetectBudgetMs = 25.0;

LocalizeRunOptions ParseOptions(const Args& args, const Dataset& dataset) {
  LocalizeRunOptions options;
  options.localizer = DefaultLocalizerOptions(dataset);
  const std::string mode = args.GetOr("mode", "tight");
  if (mode == "tight") {
    options.localizer.mode = CorrectionMode::kTightCorners;
  } else if (mode == "loose") {
    options.localizer.mode = CorrectionMode::kLoosePose;
  } else if (mode == "single-frame") {
    options.localizer.mode = CorrectionMode::kSingleFrame;
  } else {
    throw std::invalid_argument("--mode: expected tight, loose or single-frame, got '" + mode + "'");
  }
  if (args.Has("without-odometry")) {
    const std::vector<double> values = *args.GetDoubleList("without-odometry");
    if (values.size() != 2 || !(values[0] >= 0.0) || !(values[1] >= 0.0) || !std::isfinite(values[0]) ||
        !std::isfinite(values[1])) {
      throw std::invalid_argument("--without-odometry: expected V,W: two finite numbers >= 0 (m/s, rad/s)");
    }
    options.localizer.without_odometry = {values[0], values[1]};
  }
  options.detect_images = args.Flag("detect-images");
  if (args.Has("families")) options.families = ParseFamilyList(*args.Get("families"));
  options.realtime = args.Flag("realtime");
  if (args.Has("odometry-time-offset"))
    options.odometry_time_offset_s = *args.GetDouble("odometry-time-offset");
  if (args.Has("late-frame-window")) options.late_frame_window_s = *args.GetDouble("late-frame-window");
  if (const auto pose = args.GetDoubleList("start-pose")) {
    if (pose->size() != 3) {
      throw std::invalid_argument("option --start-pose: expected X,Y,YAW_DEG (3 numbers), got " +
                                  std::to_string(pose->size()));
    }
    options.localizer.start_pose = SE2d((*pose)[0], (*pose)[1], (*pose)[2] * M_PI / 180.0).ToSE3();
  }
  if (StderrIsTerminal()) {
    options.progress = [](const std::string& line) { std::cerr << "\r\033[K" << line << std::flush; };
  }
  std::string why;
  if (!options.Check(&why)) throw std::invalid_argument(why);
  return options;
}

// Squares carry no id and the detector needs them alike: with several and no code of another
// family, the first square seen could be any of them; only --start-pose tells which.
void CheckSquaresCanStart(const Args& args, const MarkerMap& map) {
  if (args.Has("start-pose")) return;
  int squares = 0;
  for (const MapMarker& m : map.markers) {
    if (!m.has_pose) continue;
    if (m.key.family != kFamilySquare) return;
    ++squares;
  }
  if (squares < 2) return;
  throw std::invalid_argument(*args.Get("map") + ": " + std::to_string(squares) +
                              " squares without ids and no other code: which square the robot first sees "
                              "is ambiguous; give --start-pose X,Y,YAW_DEG (the robot's pose at its first "
                              "odometry sample, within about 0.5 m and 15 deg)");
}

// Mean, median, p99 and max of the per-frame latencies.
std::string LatencyLine(std::vector<double> latency_ms) {
  if (latency_ms.empty()) return "latency per frame: no frame";
  std::sort(latency_ms.begin(), latency_ms.end());
  double sum = 0.0;
  for (double ms : latency_ms) sum += ms;
  return "latency per frame (ms): mean " + FormatFixed(sum / latency_ms.size(), 3) + ", median " +
         FormatFixed(QuantileOfSorted(latency_ms, 0.5), 3) + ", p99 " +
         FormatFixed(QuantileOfSorted(latency_ms, 0.99), 3) + ", max " + FormatFixed(latency_ms.back(), 3);
}

void PrintSummary(const LocalizeRun& run, std::ostream& out) {
  long tracking = 0;
  for (const PoseOutput& pose : run.outputs) tracking += pose.T_world_robot.has_value();
  const LocalizerCounters& c = run.counters;
  const double percent = run.outputs.empty() ? 0.0 : 100.0 * tracking / run.outputs.size();
  out << "frames: " << run.outputs.size() << " (" << run.frames_with_codes << " with codes, "
      << run.frames_with_map_codes << " with codes of the map), tracking " << FormatFixed(percent, 1)
      << " % (" << run.trajectory.size() << " poses)\n"
      << "corrections: accepted " << c.accepted << ", gated " << c.gated << ", unknown codes "
      << c.unknown_markers << ", not usable " << c.not_usable << "\n"
      << "initializations: " << c.initializations << " (relocalizations "
      << std::max(0L, c.initializations - 1) << "), times lost " << c.times_lost << ", rejected inputs "
      << c.rejected_inputs << "\n"
      << "suspect: " << c.times_suspect << " times (" << c.suspect_by_missed_codes
      << " by codes expected in view but "
      << "not seen, " << c.suspect_cleared << " cleared), lost by missed codes " << c.lost_by_missed_codes
      << "; codes expected in view " << c.expected_codes << ", not detected " << c.expected_missed << "\n"
      << "lost: " << c.times_lost << " times (" << c.lost_by_gated_frames
      << " by frames whose codes were all gated, " << c.lost_by_uncertainty << " by no code for too long, "
      << c.lost_by_missed_codes << " by codes expected in view but not seen, " << c.lost_by_numerical_failure
      << " by numerical failure)\n"
      << LatencyLine(run.latency_ms) << "\n";
  for (const std::string& warning : run.warnings) out << "warning: " << warning << "\n";
}

// Formats every output first, then writes them: a failure leaves no partial output.
void WriteOutputs(const Args& args, const LocalizeRun& run) {
  const std::string tum = FormatTum(run.trajectory, "waymark localize: tracked T_world_robot");
  std::string predicted, poses;
  if (args.Has("predicted")) {
    predicted = FormatTum(run.predicted, "waymark localize: T_world_robot predicted before each correction");
  }
  if (args.Has("poses")) {
    for (size_t i = 0; i < run.outputs.size(); ++i)
      poses += FormatPoseLine(run.outputs[i], run.cameras[i], run.frame_counts[i], run.latency_ms[i]) + "\n";
  }
  std::vector<std::pair<std::filesystem::path, std::string>> files = {{args.Require("out"), tum}};
  if (args.Has("predicted")) files.emplace_back(*args.Get("predicted"), predicted);
  if (args.Has("poses")) files.emplace_back(*args.Get("poses"), poses);
  AtomicWriteFiles(files);  // all or nothing
}

// A dataset with range_bearing.jsonl: the range-bearing EKF (runner/range_bearing_run.h); with a
// ground truth, its ATE and NEES.
int RunRangeBearingDataset(const Args& args, const Dataset& dataset, const MarkerMap& map) {
  for (const char* option : {"predicted", "poses", "mode", "families", "odometry-time-offset"}) {
    if (args.Has(option))
      throw std::invalid_argument(std::string("--") + option + " is not for range-bearing datasets");
  }
  if (args.Flag("detect-images") || args.Flag("realtime"))
    throw std::invalid_argument("--detect-images and --realtime are not for range-bearing datasets");
  const std::string sensor_prior = args.GetOr("sensor-prior", "map");
  if (sensor_prior != "map" && sensor_prior != "none")
    throw std::invalid_argument("--sensor-prior: expected map or none, got '" + sensor_prior + "'");
  // The map's defaults (the same as the map build's leave-one-out runs), then the options.
  RangeBearingLocalizerOptions options = LocalizerOptionsFromMap(map, sensor_prior == "map");
  if (args.Has("map-uncertainty")) {
    const std::string name = *args.Get("map-uncertainty");
    const auto mode = ParseRangeBearingMapUncertainty(name);
    if (!mode)
      throw std::invalid_argument(
          "--map-uncertainty: expected estimate, consider, in-noise or ignore, got '" + name + "'");
    options.map_uncertainty = *mode;
  }
  if (sensor_prior == "map" && map.range_bearing_sensor) {
    std::cout << "sensor prior: the map's (" << map.range_bearing_sensor->datasets.size()
              << " robots, range model " << (map.range_bearing_sensor->depth_ranges ? "depth" : "distance")
              << ")\n";
  } else {
    std::cout << "sensor prior: none (ranges as distances, fixed weak sigmas)\n";
  }
  if (args.Has("depth-share-sigma")) {
    options.depth_share_sigma = *args.GetDouble("depth-share-sigma");
    if (!(options.depth_share_sigma >= 0.0) || !std::isfinite(options.depth_share_sigma))
      throw std::invalid_argument("--depth-share-sigma: expected a number >= 0, got " +
                                  *args.Get("depth-share-sigma"));
  }
  if (args.Has("calibration-time")) {
    const double tau = *args.GetDouble("calibration-time");
    if (!(tau >= 0.0) || !std::isfinite(tau))
      throw std::invalid_argument("--calibration-time: expected a number of seconds >= 0, got " +
                                  *args.Get("calibration-time"));
    options.calibration_time_s = Eigen::Vector3d::Constant(tau);
  } else if (args.Has("turn-fluctuation")) {
    // Its own fast state beside a constant calibration, not the map's Gauss-Markov time.
    options.calibration_time_s = RangeBearingLocalizerOptions().calibration_time_s;
  }
  if (options.calibration_time_s[0] > 0.0) {
    std::cout << "odometry calibration: Gauss-Markov, correlation time "
              << FormatSignificant(options.calibration_time_s[0], 4) << " s ("
              << (args.Has("calibration-time") ? "--calibration-time" : "the map's") << ")\n";
  } else {
    std::cout << "odometry calibration: constant\n";
  }
  if (args.Has("turn-fluctuation")) {
    const std::optional<std::vector<double>> v = args.GetDoubleList("turn-fluctuation");
    if (!v || v->size() != 2 || !((*v)[0] >= 0.0) || !((*v)[1] >= 0.0) || !std::isfinite((*v)[0]) ||
        !std::isfinite((*v)[1]))
      throw std::invalid_argument("--turn-fluctuation: expected SIGMA,SECONDS (two numbers >= 0), got " +
                                  *args.Get("turn-fluctuation"));
    options.turn_fluctuation_sigma = (*v)[0];
    options.turn_fluctuation_time_s = (*v)[1];
  }
  if (args.Has("variance-factor")) {
    const std::optional<double> k = args.GetDouble("variance-factor");
    if (!k || !(*k > 0.0) || !std::isfinite(*k))
      throw std::invalid_argument("--variance-factor: expected a number > 0, got " +
                                  *args.Get("variance-factor"));
    options.variance_factor = *k;
  } else if (sensor_prior == "map" && map.range_bearing_sensor &&
             map.range_bearing_sensor->online_variance_factor) {
    options.variance_factor = *map.range_bearing_sensor->online_variance_factor;
  }
  if (options.variance_factor != 1.0) {
    std::cout << "variance factor: " << FormatSignificant(options.variance_factor, 4) << " ("
              << (args.Has("variance-factor") ? "--variance-factor" : "the map's leave-one-out calibration")
              << "; the reported covariance scaled)\n";
  }
  for (const auto& [name, field] :
       {std::pair<const char*, int*>{"update-iterations", &options.update_iterations},
        {"relocalization-iterations", &options.relocalization_iterations}}) {
    if (!args.Has(name)) continue;
    const std::optional<long> n = args.GetInt(name);
    if (!n || *n < 1 || *n > 100)
      throw std::invalid_argument(std::string("--") + name + ": expected an integer in 1..100, got " +
                                  *args.Get(name));
    *field = static_cast<int>(*n);
  }
  if (!map.range_bearing_noise)
    std::cerr << "warning: the map has no range_bearing_noise: the default noise model is used\n";
  const RangeBearingRun run = RunRangeBearingLocalizer(dataset, map, options);
  AtomicWriteFile(
      args.Require("out"),
      FormatTum(run.poses, "waymark localize: T_world_robot of the range-bearing EKF while not lost"));
  std::cout << "odometry delay: " << FormatFixed(options.noise.odometry_delay_s, 3) << " s (the map's)\n";
  const RangeBearingSensorValues& found = run.final_sensor;
  std::cout << "at the end: odometry calibration [" << FormatSignificant(found.odometry_calibration[0], 3)
            << ", " << FormatSignificant(found.odometry_calibration[1], 3) << ", "
            << FormatSignificant(found.odometry_calibration[2], 3) << "], range offset "
            << FormatSignificant(found.range_offset_m, 3) << " m, bearing offset "
            << FormatSignificant(found.bearing_offset_rad, 3) << " rad, bearing scale "
            << FormatSignificant(found.bearing_scale, 3) << ", depth share "
            << FormatSignificant(found.depth_share, 3) << ", range scale "
            << FormatSignificant(found.range_scale, 3) << "\n";
  std::cout << "poses: " << run.poses.size() << " written, " << run.outputs_withheld
            << " withheld while lost, " << run.outputs_while_lost << " written while lost\n";
  std::cout << "observations:";
  for (const auto& [reason, count] : run.counts) std::cout << " " << reason << " " << count << ",";
  std::cout << "\n";
  if (dataset.groundtruth_trajectory && !run.poses.empty()) {
    eval::TrajectoryEvalOptions eval_options;
    eval_options.max_dt_s = 0.02;
    eval_options.align = eval::AlignmentMode::kNone;
    const eval::TrajectoryEvaluation ate =
        eval::EvaluateTrajectory(*dataset.groundtruth_trajectory, run.poses, std::nullopt, eval_options);
    eval_options.align = eval::AlignmentMode::kSE2;
    const eval::TrajectoryEvaluation aligned =
        eval::EvaluateTrajectory(*dataset.groundtruth_trajectory, run.poses, std::nullopt, eval_options);
    std::cout << "ATE RMSE: " << FormatFixed(ate.ate.translation_m.rmse, 3) << " m in the map's frame, "
              << FormatFixed(aligned.ate.translation_m.rmse, 3) << " m after SE(2) alignment ("
              << ate.ate.stamps_s.size() << " poses; rotation " << FormatFixed(ate.ate.rotation_deg.rmse, 2)
              << " deg)\n";
    // The filter's heading is the odometry's; the truth's body frame may be turned on the robot.
    const std::optional<TruthYawEstimate> yaw =
        EstimateTruthYaw(*dataset.groundtruth_trajectory, dataset.odometry);
    if (yaw) {
      const NeesResult recorded =
          ComputeNees(*dataset.groundtruth_trajectory, run.poses, run.covariances, 0.02);
      std::cout << "truth frame: the odometry's direction of travel is " << FormatSignificant(yaw->yaw_rad, 3)
                << " rad from the truth's heading (median over " << yaw->windows
                << " straight stretches, spread " << FormatSignificant(yaw->spread_rad, 3)
                << " rad); NEES against the heading as recorded: mean " << FormatFixed(recorded.mean, 2)
                << " [" << FormatFixed(recorded.mean_lower_correlated, 3) << ", "
                << FormatFixed(recorded.mean_upper_correlated, 3) << "], heading mean "
                << FormatFixed(recorded.mean_heading, 2) << "; below, against the truth turned by it\n";
    } else {
      std::cout
          << "truth frame: too few straight stretches to compare the truth's heading with the odometry's "
             "direction of travel; NEES against the heading as recorded\n";
    }
    const NeesResult nees = ComputeNees(*dataset.groundtruth_trajectory, run.poses, run.covariances, 0.02,
                                        yaw ? yaw->yaw_rad : 0.0);
    std::cout << "NEES: mean " << FormatFixed(nees.mean, 2) << " over " << nees.samples
              << " poses (95 % bounds of the mean of independent draws [" << FormatFixed(nees.mean_lower, 3)
              << ", " << FormatFixed(nees.mean_upper, 3) << "]; of " << FormatFixed(nees.effective_samples, 1)
              << " effective samples, the series' integrated autocorrelation time "
              << FormatFixed(nees.autocorrelation_time, 1) << " poses: ["
              << FormatFixed(nees.mean_lower_correlated, 3) << ", "
              << FormatFixed(nees.mean_upper_correlated, 3) << "]); "
              << FormatFixed(100.0 * nees.share_inside, 1)
              << " % of poses inside the per-pose 95 % interval [" << FormatFixed(nees.sample_lower, 3)
              << ", " << FormatFixed(nees.sample_upper, 3) << "]\n";
    std::cout << "NEES by part: position mean " << FormatFixed(nees.mean_position, 2) << " (2 dof), "
              << FormatFixed(100.0 * nees.share_inside_position, 1)
              << " % inside its 95 % interval; heading mean " << FormatFixed(nees.mean_heading, 2)
              << " (1 dof), " << FormatFixed(100.0 * nees.share_inside_heading, 1)
              << " % inside; innovations: mean NIS " << FormatFixed(run.mean_nis, 2)
              << " over the accepted updates (2 dof)\n";
  }
  return 0;
}

int RunDataset(const Args& args) {
  args.Require("out");
  if (args.Has("detect-budget-ms")) throw std::invalid_argument("--detect-budget-ms applies to --live only");
  if (args.Has("full-frame-every")) throw std::invalid_argument("--full-frame-every applies to --live only");
  args.ExpectDistinctOutputs({"out", "predicted", "poses"});
  const MarkerMap map = ReadMap(args.Require("map"));
  const Dataset dataset = LoadDataset(args.positionals()[0]);
  if (dataset.has_range_bearing_file) return RunRangeBearingDataset(args, dataset, map);
  if (HasRangeBearingOnlyOption(args))
    throw std::invalid_argument(RangeBearingOnlyOptions() +
                                " are for range-bearing datasets (range_bearing.jsonl)");
  const LocalizeRunOptions options = ParseOptions(args, dataset);
  CheckSquaresCanStart(args, map);
  const LocalizeRun run = RunLocalizer(dataset, map, options);
  if (StderrIsTerminal()) std::cerr << "\r\033[K";
  WriteOutputs(args, run);
  PrintSummary(run, std::cout);
  return 0;
}

// ---- Live mode ----

int RunLive(const Args& args) {
  if (HasRangeBearingOnlyOption(args))
    throw std::invalid_argument(RangeBearingOnlyOptions() + " are for range-bearing datasets, not --live");
  if (args.Has("out") || args.Has("predicted") || args.Has("poses") || args.Flag("detect-images")) {
    throw std::invalid_argument(
        "--live writes to stdout: --out, --predicted, --poses and --detect-images do not apply");
  }
  const MarkerMap map = ReadMap(args.Require("map"));
  const Dataset dataset = LoadDataset(args.positionals()[0]);
  LocalizeRunOptions options = ParseOptions(args, dataset);
  CheckSquaresCanStart(args, map);
  options.progress = nullptr;
  options.detector.live_budget_ms = kDefaultLiveDetectBudgetMs;
  if (const auto budget = args.GetDouble("detect-budget-ms")) {
    if (!(*budget >= 0.0)) throw std::invalid_argument("--detect-budget-ms: expected a value >= 0");
    options.detector.live_budget_ms = *budget;
  }
  if (const auto n = args.GetInt("full-frame-every")) {
    if (*n < 1 || *n > 1000000)
      throw std::invalid_argument("--full-frame-every: expected 1..1000000, got " + std::to_string(*n));
    options.predicted_regions.full_frame_every = static_cast<int>(*n);
  }
  LiveInput live(dataset, map, options, std::cout, std::cerr);
  live.Run(std::cin);
  live.PrintSummary(std::cerr);
  return 0;
}

int RunLocalize(const std::vector<std::string>& argv) {
  const Args args(argv, kValues, kFlags);
  if (args.Help()) {
    std::cout << kUsage;
    return 0;
  }
  args.ExpectPositionals(1, 1, "dataset directory DATASET");
  args.Require("map");
  return args.Flag("live") ? RunLive(args) : RunDataset(args);
}

const CommandRegistrar kRegistrar(Command{
    "localize", "localize a robot against a map: a dataset's odometry and codes, or live JSON lines on stdin",
    kUsage, RunLocalize});

}  // namespace
}  // namespace waymark::cli
