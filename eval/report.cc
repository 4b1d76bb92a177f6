#include "eval/report.h"

#include <cstdio>
#include <sstream>

#include "util/format.h"

namespace waymark::eval {
namespace {

using json = Json;

json MatrixToJson(const Eigen::Matrix3d& R) {
  json rows = json::array();
  for (int r = 0; r < 3; ++r) rows.push_back({R(r, 0), R(r, 1), R(r, 2)});
  return rows;
}

json KeyToJson(const MarkerKey& key) { return {{"family", key.family}, {"id", key.id}}; }

json KeysToJson(const std::vector<MarkerKey>& keys) {
  json out = json::array();
  for (const MarkerKey& key : keys) out.push_back(KeyToJson(key));
  return out;
}

json AlignmentToJson(const Sim3Alignment& alignment) {
  return {{"scale", alignment.scale},
          {"R_gt_est", MatrixToJson(alignment.R_gt_est)},
          {"t_gt_est", {alignment.t_gt_est.x(), alignment.t_gt_est.y(), alignment.t_gt_est.z()}}};
}

// "| name | rmse | mean | median | std | min | max | n |" row of a Markdown table.
std::string MarkdownRow(const std::string& name, const ErrorStats& s, int digits) {
  std::ostringstream row;
  row << "| " << name << " | " << FormatFixed(s.rmse, digits) << " | " << FormatFixed(s.mean, digits) << " | "
      << FormatFixed(s.median, digits) << " | " << FormatFixed(s.std, digits) << " | "
      << FormatFixed(s.min, digits) << " | " << FormatFixed(s.max, digits) << " | " << s.count << " |\n";
  return row.str();
}

std::string TableLine(const std::string& name, const ErrorStats& s, int digits) {
  char buffer[256];
  std::snprintf(buffer, sizeof(buffer), "%-22s %10s %10s %10s %10s %10s %6zu\n", name.c_str(),
                FormatFixed(s.rmse, digits).c_str(), FormatFixed(s.mean, digits).c_str(),
                FormatFixed(s.median, digits).c_str(), FormatFixed(s.std, digits).c_str(),
                FormatFixed(s.max, digits).c_str(), s.count);
  return buffer;
}

std::string TrajectoryMarkdown(const EvalReportInput& input) {
  const TrajectoryEvaluation& e = *input.trajectory;
  std::ostringstream md;
  md << "## Trajectory\n\n"
     << "- estimate: `" << input.est_path << "` (" << e.est_poses << " poses)\n"
     << "- ground truth: `" << input.gt_path << "` (" << e.gt_poses << " poses)\n"
     << "- associated pairs: " << e.ate.translation_m.count << " (max-dt " << e.options.max_dt_s << " s)\n"
     << "- alignment: " << AlignmentModeName(e.options.align) << (e.options.scale ? " with scale" : "")
     << " (scale " << FormatFixed(e.alignment.scale, 6) << ")\n\n"
     << "| metric | rmse | mean | median | std | min | max | n |\n|---|---|---|---|---|---|---|---|\n"
     << MarkdownRow("ATE translation (m)", e.ate.translation_m, 4)
     << MarkdownRow("ATE rotation (deg)", e.ate.rotation_deg, 3)
     << MarkdownRow("abs. error x (m)", e.ate.axes.x_m, 4)
     << MarkdownRow("abs. error y (m)", e.ate.axes.y_m, 4)
     << MarkdownRow("abs. error z (m)", e.ate.axes.z_m, 4)
     << MarkdownRow("abs. error yaw (deg)", e.ate.axes.yaw_deg, 3);
  if (e.rpe) {
    const std::string delta =
        FormatFixed(e.rpe->options.delta, e.rpe->options.unit == RpeUnit::kFrames ? 0 : 3) + " " +
        RpeUnitName(e.rpe->options.unit);
    md << MarkdownRow("RPE translation (m) / " + delta, e.rpe->translation_m, 4)
       << MarkdownRow("RPE rotation (deg) / " + delta, e.rpe->rotation_deg, 3);
  }
  if (e.pe_te) {
    md << MarkdownRow("PE planar (m)", e.pe_te->position_m, 4)
       << MarkdownRow("PE 3-D (m)", e.pe_te->position_3d_m, 4)
       << MarkdownRow("TE heading (deg)", e.pe_te->heading_deg, 3);
  }
  md << "\nATE equals evo's APE (translation part) with the same association and alignment.\n";
  if (e.pe_te) {
    md << "PE/TE: predicted poses from `" << input.predicted_path << "` (" << e.predicted_poses << " poses, "
       << e.pe_te->position_m.count << " correction instants), "
       << (e.options.align_predicted ? "aligned like the estimate" : "not aligned (map frame = world frame)")
       << "; PE = " << FormatFixed(e.pe_te->position_m.mean, 4)
       << " m, TE = " << FormatFixed(e.pe_te->heading_deg.mean, 3)
       << " deg (means over the instants, [Bach] eq. 15).\n";
  }
  return md.str();
}

std::string MapMarkdown(const EvalReportInput& input) {
  const MapEvalResult& m = *input.map;
  std::ostringstream md;
  md << "## Map\n\n- estimate: `" << input.map_path << "`\n- ground truth: `" << input.gt_map_path << "`\n"
     << "- matched markers: " << m.markers << "; position RMS " << FormatFixed(m.position_rmse_m, 4)
     << " m; orientation RMS " << FormatFixed(m.orientation_rmse_deg, 3) << " deg\n\n"
     << "| component | markers | aligned by | position RMS (m) | orientation RMS (deg) "
        "|\n|---|---|---|---|---|\n";
  for (const ComponentResult& c : m.components) {
    md << "| " << c.component << " | " << c.markers << " of " << c.markers_total << " | "
       << MapAlignmentMethodName(c.method) << " | "
       << (c.markers > 0 ? FormatFixed(c.position_rmse_m, 4) : "n/a") << " | "
       << (c.markers > 0 ? FormatFixed(c.orientation_rmse_deg, 3) : "n/a") << " |\n";
  }
  md << "\n| marker | component | position error (m) | orientation error (deg) |\n|---|---|---|---|\n";
  for (const MarkerError& e : m.per_marker) {
    md << "| `" << e.key.ToString() << "` | " << e.component << " | " << FormatFixed(e.position_error_m, 4)
       << " | " << FormatFixed(e.orientation_error_deg, 3) << " |\n";
  }
  const auto list = [&md](const char* title, const std::vector<MarkerKey>& keys) {
    if (keys.empty()) return;
    md << "\n" << title << ":";
    for (const MarkerKey& key : keys) md << " `" << key.ToString() << "`";
    md << "\n";
  };
  list("Missing from the estimate", m.missing_in_estimate);
  list("Not in the ground truth", m.missing_in_groundtruth);
  return md.str();
}

}  // namespace

Json StatsToJson(const ErrorStats& s) {
  return {{"rmse", s.rmse}, {"mean", s.mean}, {"median", s.median}, {"std", s.std},
          {"min", s.min},   {"max", s.max},   {"sse", s.sse},       {"count", s.count}};
}

Json TrajectoryEvaluationToJson(const TrajectoryEvaluation& e) {
  json out;
  json ate = StatsToJson(e.ate.translation_m);
  ate.erase("count");
  ate["pairs"] = e.ate.translation_m.count;
  ate["unit"] = "m";
  ate["rotation_deg"] = StatsToJson(e.ate.rotation_deg);
  ate["axes"] = {{"x_m", StatsToJson(e.ate.axes.x_m)},
                 {"y_m", StatsToJson(e.ate.axes.y_m)},
                 {"z_m", StatsToJson(e.ate.axes.z_m)},
                 {"yaw_deg", StatsToJson(e.ate.axes.yaw_deg)}};
  out["ate"] = ate;
  json alignment = AlignmentToJson(e.alignment);
  alignment["mode"] = AlignmentModeName(e.options.align);
  alignment["scale_corrected"] = e.options.scale;
  out["alignment"] = alignment;
  out["association"] = {{"max_dt_s", e.options.max_dt_s},
                        {"gt_poses", e.gt_poses},
                        {"est_poses", e.est_poses},
                        {"pairs", e.ate.translation_m.count}};
  if (e.rpe) {
    out["rpe"] = {{"delta", e.rpe->options.delta},
                  {"unit", RpeUnitName(e.rpe->options.unit)},
                  {"pairs", e.rpe->index_pairs.size()},
                  {"translation_m", StatsToJson(e.rpe->translation_m)},
                  {"rotation_deg", StatsToJson(e.rpe->rotation_deg)}};
  }
  if (e.pe_te) {
    out["pe_te"] = {
        {"instants", e.pe_te->position_m.count},          {"predicted_poses", e.predicted_poses},
        {"aligned", e.options.align_predicted},           {"pe_m", StatsToJson(e.pe_te->position_m)},
        {"pe_3d_m", StatsToJson(e.pe_te->position_3d_m)}, {"te_deg", StatsToJson(e.pe_te->heading_deg)}};
  }
  return out;
}

Json MapEvaluationToJson(const MapEvalResult& m) {
  json components = json::array();
  for (const ComponentResult& c : m.components) {
    json component = {{"component", c.component},
                      {"markers", c.markers},
                      {"markers_total", c.markers_total},
                      {"alignment", MapAlignmentMethodName(c.method)},
                      {"position_rmse", c.markers > 0 ? json(c.position_rmse_m) : json(nullptr)},
                      {"orientation_rmse_deg", c.markers > 0 ? json(c.orientation_rmse_deg) : json(nullptr)}};
    const json transform = AlignmentToJson(c.alignment);
    component["R_gt_est"] = transform["R_gt_est"];
    component["t_gt_est"] = transform["t_gt_est"];
    components.push_back(component);
  }
  json per_marker = json::array();
  for (const MarkerError& e : m.per_marker) {
    json marker = KeyToJson(e.key);
    marker["component"] = e.component;
    marker["position_error"] = e.position_error_m;
    marker["orientation_error_deg"] = e.orientation_error_deg;
    per_marker.push_back(marker);
  }
  return {{"position_rmse", m.position_rmse_m},
          {"orientation_rmse_deg", m.orientation_rmse_deg},
          {"markers", m.markers},
          {"components", components},
          {"per_marker", per_marker},
          {"missing_in_estimate", KeysToJson(m.missing_in_estimate)},
          {"missing_in_groundtruth", KeysToJson(m.missing_in_groundtruth)}};
}

Json EvalReportToJson(const EvalReportInput& input) {
  json out = json::object();
  json inputs = json::object();
  if (input.trajectory) {
    out.update(TrajectoryEvaluationToJson(*input.trajectory));
    inputs["est"] = input.est_path;
    inputs["gt"] = input.gt_path;
    if (!input.predicted_path.empty()) inputs["predicted"] = input.predicted_path;
  }
  if (input.map) {
    out["map"] = MapEvaluationToJson(*input.map);
    inputs["map"] = input.map_path;
    inputs["gt_map"] = input.gt_map_path;
  }
  out["inputs"] = inputs;
  return out;
}

std::string EvalReportToMarkdown(const EvalReportInput& input) {
  std::string md = "# Waymark evaluation\n\n";
  if (input.trajectory) md += TrajectoryMarkdown(input);
  if (input.trajectory && input.map) md += "\n";
  if (input.map) md += MapMarkdown(input);
  return md;
}

std::string EvalSummaryTable(const EvalReportInput& input) {
  std::string out;
  char header[256];
  std::snprintf(header, sizeof(header), "%-22s %10s %10s %10s %10s %10s %6s\n", "metric", "rmse", "mean",
                "median", "std", "max", "n");
  out += header;
  if (const TrajectoryEvaluation* e = input.trajectory) {
    out += TableLine("ATE trans (m)", e->ate.translation_m, 4) +
           TableLine("ATE rot (deg)", e->ate.rotation_deg, 3);
    out += TableLine("|x| (m)", e->ate.axes.x_m, 4) + TableLine("|y| (m)", e->ate.axes.y_m, 4) +
           TableLine("|z| (m)", e->ate.axes.z_m, 4) + TableLine("|yaw| (deg)", e->ate.axes.yaw_deg, 3);
    if (e->rpe) {
      out += TableLine("RPE trans (m)", e->rpe->translation_m, 4) +
             TableLine("RPE rot (deg)", e->rpe->rotation_deg, 3);
    }
    if (e->pe_te)
      out += TableLine("PE (m)", e->pe_te->position_m, 4) + TableLine("TE (deg)", e->pe_te->heading_deg, 3);
  }
  if (const MapEvalResult* m = input.map) {
    char line[256];
    std::snprintf(line, sizeof(line), "%-22s %10s %50zu\n%-22s %10s %50zu\n", "map position (m)",
                  FormatFixed(m->position_rmse_m, 4).c_str(), m->markers, "map orient (deg)",
                  FormatFixed(m->orientation_rmse_deg, 3).c_str(), m->markers);
    out += line;
    if (!m->missing_in_estimate.empty() || !m->missing_in_groundtruth.empty()) {
      out += "markers missing from the estimate: " + std::to_string(m->missing_in_estimate.size()) +
             ", not in the ground truth: " + std::to_string(m->missing_in_groundtruth.size()) + "\n";
    }
  }
  return out;
}

}  // namespace waymark::eval
