// Reports of an evaluation: JSON (machine-readable, the contract other tools read), a
// Markdown summary, and the short table printed to stdout. Pure functions returning
// strings / JSON values; the CLI writes them (atomically, io/util.h).
//
// JSON layout (docs/evaluation.md has every field):
//   {"ate": {"rmse", "mean", "median", "std", "min", "max", "sse", "pairs", "unit": "m",
//            "rotation_deg": {same statistics},
//            "axes": {"x_m", "y_m", "z_m", "yaw_deg": {same statistics}}},  (per-axis |error|)
//    "alignment": {"mode", "scale_corrected", "scale", "R_gt_est", "t_gt_est"},
//    "association": {"max_dt_s", "gt_poses", "est_poses", "pairs"},
//    "rpe": {"delta", "unit", "pairs", "translation_m": {...}, "rotation_deg": {...}},
//    "pe_te": {"instants", "predicted_poses", "aligned", "pe_m": {...}, "pe_3d_m": {...},
//              "te_deg": {...}},
//    "map": {"position_rmse", "orientation_rmse_deg", "markers", "components": [...],
//            "per_marker": [...], "missing_in_estimate": [...], "missing_in_groundtruth": [...]}}
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "eval/map_metrics.h"
#include "eval/trajectory_eval.h"

namespace waymark::eval {

// Members keep the order they are written in (the reports read top-down: ate first).
using Json = nlohmann::ordered_json;

// What was evaluated, for the reports. Either or both of `trajectory` and `map` are set.
struct EvalReportInput {
  std::string est_path, gt_path, predicted_path;  // trajectory files, as given
  std::string map_path, gt_map_path;              // map files, as given
  const TrajectoryEvaluation* trajectory = nullptr;
  const MapEvalResult* map = nullptr;
};

Json StatsToJson(const ErrorStats& stats);
// The "ate", "alignment", "association", and (when present) "rpe" and "pe_te" members.
Json TrajectoryEvaluationToJson(const TrajectoryEvaluation& evaluation);
// The value of the "map" member. A component with no marker in common with the truth has
// null RMS values.
Json MapEvaluationToJson(const MapEvalResult& result);
// Everything in one object.
Json EvalReportToJson(const EvalReportInput& input);

std::string EvalReportToMarkdown(const EvalReportInput& input);

// A few aligned lines for a terminal.
std::string EvalSummaryTable(const EvalReportInput& input);

}  // namespace waymark::eval
