// Reports: the JSON contract (field names, nulls for components without common markers),
// the stdout table, and the SVG (every element closed, everything drawn inside the canvas).
#include "eval/report.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <regex>

#include "eval/svg_plot.h"

namespace waymark::eval {
namespace {

MapMarker Marker(const std::string& id, double x, double y, std::optional<int> component) {
  MapMarker m;
  m.key = {"datamatrix", id};
  m.size_m = 0.08;
  m.T_world_marker = SE3d::FromXYZYaw(x, y, 0.5, 0.1 * x);
  m.component = component;
  return m;
}

struct Maps {
  MarkerMap truth, estimate;
};

// Component 0: three markers shifted by (1, 0, 0); component 2: one marker the truth lacks.
Maps MakeMaps() {
  Maps maps;
  for (const auto& [id, x, y] :
       std::vector<std::tuple<std::string, double, double>>{{"a", 0, 0}, {"b", 4, 0}, {"c", 0, 3}}) {
    maps.truth.markers.push_back(Marker(id, x, y, std::nullopt));
    maps.estimate.markers.push_back(Marker(id, x + 1.0, y, 0));
  }
  maps.estimate.markers.push_back(Marker("lonely", 7, 7, 2));
  return maps;
}

TEST(ReportTest, MapJsonFields) {
  const Maps maps = MakeMaps();
  const MapEvalResult result = EvaluateMap(maps.estimate, maps.truth);
  EvalReportInput input;
  input.map = &result;
  input.map_path = "map.json";
  input.gt_map_path = "gt.json";
  const Json j = EvalReportToJson(input);
  ASSERT_TRUE(j.contains("map"));
  EXPECT_FALSE(j.contains("ate"));
  const Json& m = j["map"];
  for (const char* key : {"position_rmse", "orientation_rmse_deg", "markers", "components", "per_marker",
                          "missing_in_estimate", "missing_in_groundtruth"}) {
    EXPECT_TRUE(m.contains(key)) << key;
  }
  EXPECT_EQ(m["markers"].get<int>(), 3);
  ASSERT_EQ(m["components"].size(), 2u);
  EXPECT_EQ(m["components"][1]["component"].get<int>(), 2);
  EXPECT_TRUE(m["components"][1]["position_rmse"].is_null());  // nothing to compare
  EXPECT_EQ(m["components"][1]["alignment"], "none");
  EXPECT_NEAR(m["components"][0]["t_gt_est"][0].get<double>(), -1.0, 1e-9);
  EXPECT_EQ(m["missing_in_groundtruth"][0]["id"], "lonely");
  EXPECT_EQ(j["inputs"]["gt_map"], "gt.json");
  const std::string table = EvalSummaryTable(input);
  EXPECT_NE(table.find("map position (m)"), std::string::npos) << table;
  EXPECT_NE(EvalReportToMarkdown(input).find("| 2 | 0 of 1 | none | n/a | n/a |"), std::string::npos);
}

// Every numeric coordinate attribute of the SVG lies inside [0, width] x [0, height].
void ExpectInsideCanvas(const std::string& svg, double width, double height) {
  const std::regex attribute("\\b(x|y|x1|x2|y1|y2|cx|cy)=\"(-?[0-9.]+)\"");
  int checked = 0;
  for (auto it = std::sregex_iterator(svg.begin(), svg.end(), attribute); it != std::sregex_iterator();
       ++it) {
    const std::string name = (*it)[1];
    const double value = std::stod((*it)[2]);
    EXPECT_GE(value, 0.0) << name;
    EXPECT_LE(value, name.find('x') != std::string::npos ? width : height) << name;
    ++checked;
  }
  EXPECT_GT(checked, 20);
}

TEST(ReportTest, MapOnlySvg) {
  const Maps maps = MakeMaps();
  const MapEvalResult result = EvaluateMap(maps.estimate, maps.truth);
  PlotInput plot;
  plot.markers = PlotMarkersFromMapEval(maps.estimate, maps.truth, result);
  plot.title = "maps <&>";
  ASSERT_EQ(plot.markers.size(), 4u);
  for (const PlotMarker& m : plot.markers) {
    if (m.p_true && m.p_est) {
      EXPECT_LT((*m.p_true - *m.p_est).norm(), 1e-9) << m.label;  // aligned
    }
  }
  const std::string svg = RenderSvg(plot);
  EXPECT_NE(svg.find("maps &lt;&amp;&gt;"), std::string::npos);
  EXPECT_EQ(svg.find("<polyline"), std::string::npos);  // no trajectory
  EXPECT_EQ(std::count(svg.begin(), svg.end(), '<'), std::count(svg.begin(), svg.end(), '>'));
  ExpectInsideCanvas(svg, 820.0, 555.0);
  EXPECT_THROW(RenderSvg(PlotInput()), std::invalid_argument);
}

TEST(ReportTest, TrajectorySvgAndJson) {
  Trajectory gt, est;
  for (int i = 0; i < 100; ++i) {
    const double t = 0.1 * i;
    gt.push_back({t, SE3d::FromXYZYaw(std::cos(t), 2 * std::sin(t), 0, t)});
    est.push_back({t, SE3d::FromXYZYaw(std::cos(t) + 0.01 * (i % 3), 2 * std::sin(t), 0.02, t)});
  }
  TrajectoryEvalOptions options;
  options.rpe = RpeOptions{0.5, RpeUnit::kMetres};
  const TrajectoryEvaluation evaluation = EvaluateTrajectory(gt, est, Trajectory{gt[10], gt[50]}, options);
  EvalReportInput input;
  input.trajectory = &evaluation;
  const Json j = EvalReportToJson(input);
  for (const char* key : {"rmse", "mean", "median", "std", "min", "max", "pairs", "rotation_deg"}) {
    EXPECT_TRUE(j["ate"].contains(key)) << key;
  }
  EXPECT_EQ(j.begin().key(), "ate");  // written first
  EXPECT_EQ(j["rpe"]["unit"], "m");
  EXPECT_EQ(j["pe_te"]["instants"].get<int>(), 2);
  EXPECT_NEAR(j["pe_te"]["pe_m"]["max"].get<double>(), 0.0, 1e-12);
  PlotInput plot;
  plot.trajectory = &evaluation;
  const std::string svg = RenderSvg(plot);
  EXPECT_EQ(std::count(svg.begin(), svg.end(), '<'), std::count(svg.begin(), svg.end(), '>'));
  EXPECT_GT(std::count(svg.begin(), svg.end(), '\n'), 10);
  ExpectInsideCanvas(svg, 820.0, 815.0);
}

}  // namespace
}  // namespace waymark::eval
