// `waymark demo`: the whole pipeline on the small dataset shipped in data/demo/ (a rendered
// survey and a separate run through the same place; scripts/make-demo-data.sh makes it):
//   detect the survey's images (detect/detector.h) -> learn the map (mapping/map_builder.h)
//   -> detect the run's images -> localize the run twice on the same detections (runner/run.h):
//      [Bach]'s loosely coupled EKF and ours (the tight corner update)
//   -> evaluate against the ground truth (eval/): the run's ATE for odometry alone, loose and
//      ours; PE / TE of the poses predicted before each correction; the map's marker errors.
// The table goes to stdout, a few progress lines to stderr; --out receives report.json,
// report.md, the map, the run's trajectories, the detections and SVG plots, written atomically
// once everything has been computed. No math here: every step is a library call.
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <map>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "cli/args.h"
#include "cli/command.h"
#include "cli/dataset_detect.h"
#include "detect/detector.h"
#include "eval/association.h"
#include "eval/detection_check.h"
#include "eval/map_metrics.h"
#include "eval/report.h"
#include "eval/svg_plot.h"
#include "eval/trajectory_eval.h"
#include "io/dataset_io.h"
#include "io/detections_io.h"
#include "io/map_io.h"
#include "io/tum_io.h"
#include "io/util.h"
#include "mapping/build_report.h"
#include "mapping/map_builder.h"
#include "runner/run.h"
#include "util/format.h"

namespace waymark::cli {
namespace {

namespace fs = std::filesystem;
using eval::Json;

constexpr const char* kUsage = R"(Usage: waymark demo [--data DIR] [--out DIR] [--families LIST] [--threads N]

The whole pipeline on the small dataset shipped with Waymark (data/demo: a rendered survey of a
corridor loop and a separate run through the same place, both with ground truth):
  1. detect the codes in the survey's images
  2. learn the map of the codes (one Ceres optimization, as `waymark map build`)
  3. detect the codes in the run's images
  4. localize the run against the map twice: [Bach]'s loosely coupled EKF, and ours (the
     tightly coupled corner update), as `waymark localize --mode loose|tight`
  5. evaluate against the ground truth: the run's ATE (no alignment: the map's frame is the
     world's, through its anchor codes; odometry alone starts at the true pose), PE / TE of the
     poses predicted just before each correction ([Bach]), and the map's marker errors.
Prints the accuracy table on stdout and progress on stderr.

Options:
  --data DIR       the demo dataset: a directory with survey/ and run/ (default: data/demo of
                   the source tree: $WAYMARK_SOURCE_DIR/data/demo, ./data/demo, or data/demo
                   next to the directory of the waymark binary)
  --out DIR        where the reports go (default out/demo): report.json, report.md, map.json,
                   survey_detections.jsonl, run_detections.jsonl, run_loose.tum, run_ours.tum,
                   run_*_predicted.tum, map.svg, run_odometry.svg, run_loose.svg, run_ours.svg
  --families LIST  code families to detect (default: the families of the survey's markers.json)
  --threads N      detection threads per image: the families at the same time (default: the
                   machine's cores; the results do not depend on N)
)";

// ---------------------------------------------------------------- finding the data

bool IsDemoData(const fs::path& dir) {
  std::error_code ec;
  return fs::is_regular_file(dir / "survey" / "dataset.yaml", ec) &&
         fs::is_regular_file(dir / "run" / "dataset.yaml", ec);
}

// --data, else data/demo under $WAYMARK_SOURCE_DIR, the working directory, or the source tree
// the binary was built in (build*/waymark -> data/demo).
fs::path FindDemoData(const Args& args) {
  if (const auto given = args.Get("data")) {
    if (!IsDemoData(*given)) {
      throw std::runtime_error(*given +
                               ": not a demo dataset (expected survey/dataset.yaml and run/dataset.yaml)");
    }
    return *given;
  }
  std::vector<fs::path> candidates;
  if (const char* source = std::getenv("WAYMARK_SOURCE_DIR"))
    candidates.push_back(fs::path(source) / "data/demo");
  candidates.push_back("data/demo");
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    candidates.push_back(exe.parent_path().parent_path() / "data/demo");
    candidates.push_back(exe.parent_path().parent_path().parent_path() / "data/demo");
  }
  std::string looked;
  for (const fs::path& dir : candidates) {
    if (IsDemoData(dir)) return dir;
    looked += (looked.empty() ? "" : ", ") + dir.string();
  }
  throw std::runtime_error("no demo dataset found (looked in " + looked + "); give --data DIR");
}

// A dataset with images and the ground truth the demo evaluates against.
Dataset LoadDemoDataset(const fs::path& dir) {
  Dataset dataset = LoadDataset(dir);
  if (dataset.images.empty())
    throw std::runtime_error(dir.string() + ": no images (images.csv) to detect on");
  if (!dataset.groundtruth_trajectory || dataset.groundtruth_trajectory->empty()) {
    throw std::runtime_error(dir.string() + ": no groundtruth/trajectory.tum to evaluate against");
  }
  if (!dataset.groundtruth_markers) {
    throw std::runtime_error(dir.string() + ": no groundtruth/markers.json to evaluate against");
  }
  if (dataset.odometry.empty()) throw std::runtime_error(dir.string() + ": no odometry.tum");
  return dataset;
}

// ---------------------------------------------------------------- steps

void Log(const std::string& line) { std::cerr << "demo: " << line << "\n"; }

// Progress of long steps on a terminal: one line rewritten in place; nothing in pipes.
std::function<void(const std::string&)> TerminalProgress() {
  if (!StderrIsTerminal()) return nullptr;
  return [](const std::string& line) { std::cerr << "\r\033[K" << line << std::flush; };
}

void EndProgress() {
  if (StderrIsTerminal()) std::cerr << "\r\033[K" << std::flush;
}

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// Detects the codes of every image of `dataset` and makes them its detections.
long DetectImages(Dataset* dataset, const std::vector<std::string>& families, int threads) {
  DetectorOptions options;
  options.threads = threads;
  const std::unique_ptr<MarkerDetector> detector = CreateMultiDetector(families, options);
  const auto progress = TerminalProgress();
  std::vector<DetectionFrame> frames;
  long codes = 0;
  for (const ImageEntry& entry : dataset->images) {
    std::string why;
    std::optional<DetectionFrame> frame =
        DetectImageFile(*detector, dataset->dir / entry.path, entry.stamp_s, entry.camera, &why);
    if (!frame) throw std::runtime_error(why);
    frame->image = entry.path;
    codes += static_cast<long>(frame->markers.size());
    frames.push_back(std::move(*frame));
    if (progress)
      progress("detecting " + std::to_string(frames.size()) + "/" + std::to_string(dataset->images.size()));
  }
  EndProgress();
  std::stable_sort(frames.begin(), frames.end(),
                   [](const DetectionFrame& a, const DetectionFrame& b) { return a.stamp_s < b.stamp_s; });
  dataset->detections = std::move(frames);
  dataset->has_detections_file = true;
  return codes;
}

// The detections of a rendered dataset against its exact corners (groundtruth/corners.jsonl);
// nullopt when the dataset has none.
std::optional<eval::DetectionCheck> CheckDetections(const Dataset& dataset) {
  const fs::path path = dataset.dir / "groundtruth" / "corners.jsonl";
  if (!fs::exists(path)) return std::nullopt;
  return eval::CheckDetections(dataset.detections, ReadDetections(path, nullptr, &dataset.cameras));
}

LocalizeRun Localize(const Dataset& run, const MarkerMap& map, CorrectionMode mode) {
  LocalizeRunOptions options;
  options.localizer = DefaultLocalizerOptions(run);
  options.localizer.mode = mode;
  options.progress = TerminalProgress();
  LocalizeRun result = RunLocalizer(run, map, options);
  EndProgress();
  return result;
}

double TrackedFraction(const LocalizeRun& run) {
  long tracked = 0;
  for (const PoseOutput& output : run.outputs)
    tracked += output.tracking == TrackingStatus::kTracking ? 1 : 0;
  return run.outputs.empty() ? 0.0 : static_cast<double>(tracked) / run.outputs.size();
}

// ---------------------------------------------------------------- evaluation

// One row of the table.
struct Method {
  std::string key;    // report.json member and file names: odometry, loose, ours
  std::string label;  // table text
  eval::TrajectoryEvaluation evaluation;
  // The same poses fitted to the truth by a rotation about z and a translation (se2): the
  // path's shape alone, without the map frame's (or the start pose's) error.
  std::optional<eval::TrajectoryEvaluation> aligned;
  double tracked_fraction = 1.0;
  const LocalizeRun* run = nullptr;  // null for odometry alone
};

eval::TrajectoryEvalOptions EvalOptions(eval::AlignmentMode align) {
  eval::TrajectoryEvalOptions options;
  options.align = align;
  return options;
}

// Localizer output in the map's frame, which is the world's: no alignment.
Method EvaluateLocalizer(const std::string& key, const std::string& label, const Trajectory& gt,
                         const LocalizeRun& run) {
  if (run.trajectory.empty()) throw std::runtime_error(label + ": the localizer never tracked the run");
  Method method{key, label, {}, std::nullopt, TrackedFraction(run), &run};
  method.evaluation =
      eval::EvaluateTrajectory(gt, run.trajectory, run.predicted, EvalOptions(eval::AlignmentMode::kNone));
  method.evaluation.predicted_poses = run.predicted.size();
  method.aligned =
      eval::EvaluateTrajectory(gt, run.trajectory, std::nullopt, EvalOptions(eval::AlignmentMode::kSE2));
  return method;
}

// Dead reckoning from the true start pose (evo's --align_origin); its PE / TE are taken at the
// instants `ours` corrected, so that the three rows compare the same moments.
Method EvaluateOdometry(const Trajectory& gt, const Trajectory& odometry, const Trajectory& instants) {
  Method method{"odometry", "odometry alone", {}, std::nullopt, 1.0, nullptr};
  method.evaluation =
      eval::EvaluateTrajectory(gt, odometry, std::nullopt, EvalOptions(eval::AlignmentMode::kOrigin));
  method.aligned =
      eval::EvaluateTrajectory(gt, odometry, std::nullopt, EvalOptions(eval::AlignmentMode::kSE2));
  const Trajectory odometry_world = method.evaluation.alignment.Apply(odometry);
  Trajectory at_instants;
  for (const eval::StampPair& pair : eval::AssociateByStamp(instants, odometry_world, eval::kDefaultMaxDtS)) {
    at_instants.push_back(odometry_world[pair.est_index]);
  }
  if (!at_instants.empty()) {
    method.evaluation.predicted_poses = at_instants.size();
    method.evaluation.pe_te = eval::EvaluatePredicted(
        gt, at_instants, EvalOptions(eval::AlignmentMode::kNone), eval::Sim3Alignment());
  }
  return method;
}

// ---------------------------------------------------------------- results and reports

struct DemoResult {
  fs::path data_dir;
  std::vector<std::string> families;
  int detect_threads = 1;  // --threads
  Dataset survey, run;
  long survey_codes = 0, run_codes = 0;
  std::optional<eval::DetectionCheck> survey_check, run_check;
  MapBuildResult map;
  eval::MapEvalResult map_eval;
  LocalizeRun loose, ours;
  std::vector<Method> methods;  // odometry, loose, ours
  double seconds = 0.0;
};

std::string Mm(double metres) { return FormatFixed(1e3 * metres, 1) + " mm"; }

// Text of the table cells of one method: ATE RMSE, ATE max, aligned ATE RMSE, PE mean, TE mean,
// tracked.
std::vector<std::string> Cells(const Method& m) {
  const eval::TrajectoryEvaluation& e = m.evaluation;
  std::vector<std::string> cells = {Mm(e.ate.translation_m.rmse), Mm(e.ate.translation_m.max),
                                    m.aligned ? Mm(m.aligned->ate.translation_m.rmse) : "-"};
  cells.push_back(e.pe_te ? Mm(e.pe_te->position_m.mean) : "-");
  cells.push_back(e.pe_te ? FormatFixed(e.pe_te->heading_deg.mean, 2) + " deg" : "-");
  cells.push_back(FormatFixed(100.0 * m.tracked_fraction, 1) + " %");
  return cells;
}

std::string Pad(const std::string& text, size_t width, bool left = false) {
  if (text.size() >= width) return text;
  const std::string fill(width - text.size(), ' ');
  return left ? text + fill : fill + text;
}

std::string DetectionLine(const DemoResult& r) {
  eval::DetectionCheck all;
  for (const auto& check : {r.survey_check, r.run_check}) {
    if (check) all.Add(*check);
  }
  if (all.codes_in_view == 0) return "";
  return "detection (survey and run images): " + std::to_string(all.read) + " of " +
         std::to_string(all.codes_in_view) + " codes wider than " + FormatFixed(all.options.min_side_px, 0) +
         " px read; worst corner error median " + FormatFixed(all.MedianWorstCornerPx(), 2) + " px, " +
         std::to_string(all.Gross()) + " codes off by > " + FormatFixed(all.options.gross_px, 0) + " px\n";
}

// The map's error against the truth, and what its covariances predicted for it without the truth
// (eval::PredictMapError; pooled over the components by their code counts).
std::string MapLine(const DemoResult& r) {
  const std::optional<double> predicted_m = eval::PooledAlignedRms(eval::PredictMapError(r.map.map));
  const std::string predicted =
      predicted_m ? " (the map's covariances predicted " + Mm(*predicted_m) + ")" : "";
  return "map against the true code poses: " + std::to_string(r.map_eval.markers) + " codes, position RMSE " +
         Mm(r.map_eval.position_rmse_m) + predicted + ", orientation RMSE " +
         FormatFixed(r.map_eval.orientation_rmse_deg, 2) + " deg\n";
}

std::string FormatTable(const DemoResult& r, const std::string& out_dir) {
  std::ostringstream out;
  const Trajectory& gt = *r.run.groundtruth_trajectory;
  out << "waymark demo: survey " << r.survey.images.size() << " images, " << r.map.map.markers.size()
      << " codes mapped; run " << r.run.images.size() << " images, "
      << FormatFixed(gt.back().stamp_s - gt.front().stamp_s, 1) << " s\n\n";
  const std::vector<std::string> header = {"ATE RMSE", "ATE max", "aligned", "PE mean", "TE mean", "tracked"};
  out << Pad("run against the true path", 30, true);
  for (const std::string& h : header) out << Pad(h, 11);
  out << "\n";
  for (const Method& m : r.methods) {
    out << Pad("  " + m.label, 30, true);
    for (const std::string& cell : Cells(m)) out << Pad(cell, 11);
    out << "\n";
  }
  out << MapLine(r) << DetectionLine(r) << "\n"
      << "ATE without alignment (the map's frame is the world's, through its anchor codes); odometry\n"
         "alone starts at the true pose. aligned: ATE RMSE after the best rotation about z and\n"
         "translation (se2), the path's shape alone. PE / TE: the pose predicted just before each\n"
         "correction of ours ([Bach]). Reports and plots: "
      << out_dir << "\n";
  return out.str();
}

std::string FormatMarkdownTable(const DemoResult& r) {
  std::ostringstream out;
  out << "| run against the true path | ATE RMSE | ATE max | aligned ATE RMSE (se2) | PE mean | TE mean | "
         "tracked |\n"
      << "|---|---|---|---|---|---|---|\n";
  for (const Method& m : r.methods) {
    out << "| " << m.label;
    for (const std::string& cell : Cells(m)) out << " | " << cell;
    out << " |\n";
  }
  return out.str();
}

Json CheckToJson(const std::optional<eval::DetectionCheck>& check) {
  if (!check) return nullptr;
  return Json{{"min_side_px", check->options.min_side_px},
              {"codes_in_view", check->codes_in_view},
              {"read", check->read},
              {"worst_corner_error_median_px", check->MedianWorstCornerPx()},
              {"gross_px", check->options.gross_px},
              {"gross", check->Gross()}};
}

Json DatasetToJson(const Dataset& dataset, long codes, const std::optional<eval::DetectionCheck>& check) {
  const Trajectory& gt = *dataset.groundtruth_trajectory;
  return Json{{"dir", dataset.dir.string()},
              {"images", dataset.images.size()},
              {"codes_detected", codes},
              {"duration_s", gt.back().stamp_s - gt.front().stamp_s},
              {"detection_check", CheckToJson(check)}};
}

Json MethodToJson(const Method& m) {
  Json json{{"method", m.label}, {"tracked_fraction", m.tracked_fraction}};
  json["evaluation"] = eval::TrajectoryEvaluationToJson(m.evaluation);
  if (m.aligned) json["evaluation_aligned_se2"] = eval::TrajectoryEvaluationToJson(*m.aligned);
  if (m.run) {
    const LocalizerCounters& c = m.run->counters;
    json["counters"] = Json{{"frames", c.frames},         {"accepted", c.accepted},
                            {"gated", c.gated},           {"unknown_markers", c.unknown_markers},
                            {"not_usable", c.not_usable}, {"initializations", c.initializations},
                            {"times_lost", c.times_lost}, {"rejected_inputs", c.rejected_inputs}};
    json["warnings"] = m.run->warnings;
  }
  return json;
}

Json TableToJson(const DemoResult& r) {
  Json rows = Json::array();
  for (const Method& m : r.methods) {
    const eval::TrajectoryEvaluation& e = m.evaluation;
    rows.push_back(
        Json{{"method", m.key},
             {"ate_rmse_m", e.ate.translation_m.rmse},
             {"ate_max_m", e.ate.translation_m.max},
             {"aligned_ate_rmse_m", m.aligned ? Json(m.aligned->ate.translation_m.rmse) : Json(nullptr)},
             {"pe_mean_m", e.pe_te ? Json(e.pe_te->position_m.mean) : Json(nullptr)},
             {"te_mean_deg", e.pe_te ? Json(e.pe_te->heading_deg.mean) : Json(nullptr)},
             {"tracked_fraction", m.tracked_fraction}});
  }
  return rows;
}

Json ReportJson(const DemoResult& r) {
  Json json{{"format", "waymark-demo-report"}, {"version", 1}, {"data", r.data_dir.string()}};
  json["families"] = r.families;
  json["table"] = TableToJson(r);
  json["map"] =
      Json{{"markers", r.map.map.markers.size()},  {"components", r.map.components.size()},
           {"outliers", r.map.outliers.size()},    {"unmapped", r.map.unmapped.size()},
           {"solver_time_s", r.map.solver_time_s}, {"evaluation", eval::MapEvaluationToJson(r.map_eval)}};
  json["survey"] = DatasetToJson(r.survey, r.survey_codes, r.survey_check);
  json["run"] = DatasetToJson(r.run, r.run_codes, r.run_check);
  for (const Method& m : r.methods) json[m.key] = MethodToJson(m);
  json["seconds"] = r.seconds;
  return json;
}

std::string ReportMarkdown(const DemoResult& r) {
  std::ostringstream out;
  out << "# waymark demo\n\nData: `" << r.data_dir.string() << "` (survey " << r.survey.images.size()
      << " images, run " << r.run.images.size() << " images; families " << r.families.front()
      << (r.families.size() > 1 ? ", ..." : "") << ").\n\n"
      << FormatMarkdownTable(r) << "\n"
      << MapLine(r) << "\n"
      << DetectionLine(r) << "\n"
      << "ATE without alignment (the map's frame is the world's, through its anchor codes); odometry alone "
         "starts at the true pose. Aligned: ATE RMSE after the best rotation about z and translation (se2), "
         "the path's shape alone. PE / TE: the pose predicted just before each correction of ours (seed "
         "000).\n\n"
      << "## Map build\n\n```\n"
      << FormatBuildSummary(r.map) << "```\n\n";
  eval::EvalReportInput map_input;
  map_input.map_path = "map.json";
  map_input.gt_map_path = (r.survey.dir / "groundtruth/markers.json").string();
  map_input.map = &r.map_eval;
  out << "## Map against the true code poses\n\n" << eval::EvalReportToMarkdown(map_input) << "\n";
  for (const Method& m : r.methods) {
    eval::EvalReportInput input;
    input.est_path = m.key == "odometry" ? (r.run.dir / "odometry.tum").string() : "run_" + m.key + ".tum";
    input.gt_path = (r.run.dir / "groundtruth/trajectory.tum").string();
    input.trajectory = &m.evaluation;
    out << "## Run: " << m.label << "\n\n" << eval::EvalReportToMarkdown(input) << "\n";
  }
  return out.str();
}

// Every output as (file name, contents); rendered before anything is written.
std::vector<std::pair<std::string, std::string>> RenderOutputs(const DemoResult& r,
                                                               const std::string& table) {
  std::vector<std::pair<std::string, std::string>> files = {
      {"report.json", ReportJson(r).dump(2) + "\n"},
      {"report.md", ReportMarkdown(r) + "\n## Table as printed\n\n```\n" + table + "```\n"},
      {"map.json", FormatMap(r.map.map)},
      {"survey_detections.jsonl", FormatDetections(r.survey.detections)},
      {"run_detections.jsonl", FormatDetections(r.run.detections)},
      {"run_loose.tum", FormatTum(r.loose.trajectory, "waymark demo: loosely coupled EKF, T_world_robot")},
      {"run_ours.tum", FormatTum(r.ours.trajectory, "waymark demo: ours (tight corner EKF), T_world_robot")},
      {"run_loose_predicted.tum",
       FormatTum(r.loose.predicted, "waymark demo: loose, predicted before correction")},
      {"run_ours_predicted.tum",
       FormatTum(r.ours.predicted, "waymark demo: ours, predicted before correction")}};
  const MarkerMap& truth = *r.survey.groundtruth_markers;
  eval::PlotInput map_plot;
  map_plot.markers = eval::PlotMarkersFromMapEval(r.map.map, truth, r.map_eval);
  map_plot.title = "waymark demo: learned map vs true code poses";
  files.emplace_back("map.svg", eval::RenderSvg(map_plot));
  for (const Method& m : r.methods) {
    eval::PlotInput plot;
    plot.trajectory = &m.evaluation;
    plot.markers = eval::PlotMarkersFromMaps(&r.map.map, eval::Sim3Alignment(), &truth);
    plot.title = "waymark demo: run, " + m.label;
    files.emplace_back("run_" + m.key + ".svg", eval::RenderSvg(plot));
  }
  return files;
}

// ---------------------------------------------------------------- the pipeline

void DetectAndMap(DemoResult* r) {
  auto start = std::chrono::steady_clock::now();
  Log("detecting the codes in " + std::to_string(r->survey.images.size()) + " survey images");
  r->survey_codes = DetectImages(&r->survey, r->families, r->detect_threads);
  r->survey_check = CheckDetections(r->survey);
  Log(std::to_string(r->survey_codes) + " codes detected in " + FormatFixed(SecondsSince(start), 1) + " s");
  start = std::chrono::steady_clock::now();
  Log("learning the map (Ceres)");
  MapBuildOptions options;
  options.progress = TerminalProgress();
  r->map = BuildMap(r->survey, options);
  EndProgress();
  r->map_eval = eval::EvaluateMap(r->map.map, *r->survey.groundtruth_markers);
  Log(std::to_string(r->map.map.markers.size()) + " codes mapped in " + FormatFixed(SecondsSince(start), 1) +
      " s");
}

void DetectAndLocalize(DemoResult* r) {
  auto start = std::chrono::steady_clock::now();
  Log("detecting the codes in " + std::to_string(r->run.images.size()) + " run images");
  r->run_codes = DetectImages(&r->run, r->families, r->detect_threads);
  r->run_check = CheckDetections(r->run);
  Log(std::to_string(r->run_codes) + " codes detected in " + FormatFixed(SecondsSince(start), 1) + " s");
  start = std::chrono::steady_clock::now();
  Log("localizing the run against the map: loosely coupled EKF, then ours (tight)");
  r->loose = Localize(r->run, r->map.map, CorrectionMode::kLoosePose);
  r->ours = Localize(r->run, r->map.map, CorrectionMode::kTightCorners);
  Log("localized twice in " + FormatFixed(SecondsSince(start), 1) + " s");
  const Trajectory& gt = *r->run.groundtruth_trajectory;
  r->methods.push_back(EvaluateOdometry(gt, r->run.odometry, r->ours.predicted));
  r->methods.push_back(EvaluateLocalizer("loose", "loosely coupled EKF", gt, r->loose));
  r->methods.push_back(EvaluateLocalizer("ours", "ours (tight, corners)", gt, r->ours));
}

int RunDemo(const std::vector<std::string>& argv) {
  const Args args(argv, {"data", "out", "families", "threads"}, {});
  if (args.Help()) {
    std::cout << kUsage;
    return 0;
  }
  args.ExpectPositionals(0, 0, "arguments");
  const auto start = std::chrono::steady_clock::now();
  DemoResult r;
  r.data_dir = FindDemoData(args);
  const std::string out_dir = args.GetOr("out", "out/demo");
  r.survey = LoadDemoDataset(r.data_dir / "survey");
  r.run = LoadDemoDataset(r.data_dir / "run");
  Log("data " + r.data_dir.string());
  const MarkerMap known = r.survey.known_markers.value_or(MarkerMap());
  r.families = DetectionFamilies(
      known, args.Has("families") ? ParseFamilyList(*args.Get("families")) : std::vector<std::string>());
  r.detect_threads = DetectionThreads(args);
  DetectAndMap(&r);
  DetectAndLocalize(&r);
  r.seconds = SecondsSince(start);
  const std::string table = FormatTable(r, out_dir);
  const auto files = RenderOutputs(r, table);
  std::vector<std::pair<fs::path, std::string>> outputs;
  for (const auto& [name, contents] : files) outputs.emplace_back(fs::path(out_dir) / name, contents);
  AtomicWriteFiles(outputs);  // all or nothing
  std::cout << table;
  Log("done in " + FormatFixed(r.seconds, 1) + " s; " + std::to_string(files.size()) + " files in " +
      out_dir);
  return 0;
}

const CommandRegistrar kRegistrar({"demo",
                                   "the whole pipeline on the shipped demo data: detect, map, localize, "
                                   "evaluate; prints the accuracy table",
                                   kUsage, RunDemo});

}  // namespace
}  // namespace waymark::cli
