// End to end through the `waymark` binary: `waymark eval` on files written to a temporary
// directory, checking the JSON fields, the Markdown and SVG outputs, and the one-line errors.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "io/map_io.h"
#include "io/tum_io.h"
#include "io/util.h"
#include "tests/cli/cli_test_util.h"

namespace waymark {
namespace {

namespace fs = std::filesystem;
constexpr double kDeg = M_PI / 180.0;

class EvalCliTest : public CliTest {
 protected:
  EvalCliTest() : CliTest("eval_cli") {}

  std::string Path(const std::string& name) const { return (dir_ / name).string(); }

  // `waymark eval ARGUMENTS`.
  RunResult Run(const std::string& arguments) const { return RunWaymark("eval " + arguments, dir_); }
};

// The hand-computed case of tests/eval/trajectory_metrics_test.cc: after the SE(3) alignment
// the translation errors are 0.5, 0.5, 0.4, 0.4 m (rmse sqrt(0.205)) and the rotation errors
// 1, 2, 3, 4 deg (mean 2.5).
void WriteHandCase(const std::string& gt_path, const std::string& est_path) {
  const SE3d T0(Eigen::Matrix3d((Eigen::AngleAxisd(30 * kDeg, Eigen::Vector3d::UnitZ()) *
                                 Eigen::AngleAxisd(10 * kDeg, Eigen::Vector3d::UnitX()))
                                    .toRotationMatrix()),
                Eigen::Vector3d(10, 20, 0.5));
  const std::vector<Eigen::Vector3d> p = {{0, 0, 0}, {4, 0, 0}, {4, 2, 0}, {0, 2, 0}};
  const std::vector<Eigen::Vector3d> e = {{0.3, 0, 0.4}, {-0.3, 0, -0.4}, {0, 0, 0.4}, {0, 0, -0.4}};
  const std::vector<Eigen::Vector3d> axes = {Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(),
                                             Eigen::Vector3d::UnitZ(), Eigen::Vector3d(1, 1, 0).normalized()};
  Trajectory gt, est;
  for (int i = 0; i < 4; ++i) {
    const SE3d T_gt = SE3d::FromXYZYaw(p[i].x(), p[i].y(), p[i].z(), 90 * kDeg * i);
    gt.push_back({static_cast<double>(i), T_gt});
    const SE3d T_err(ExpSO3(axes[i] * (i + 1) * kDeg), Eigen::Vector3d::Zero());
    est.push_back({i + 0.004, T0 * SE3d(T_gt.rotation(), p[i] + e[i]) * T_err});
  }
  est.push_back({10.0, T0});
  WriteTum(gt_path, gt);
  WriteTum(est_path, est);
}

TEST_F(EvalCliTest, TrajectoryWritesJsonMarkdownAndSvg) {
  WriteHandCase(Path("gt.tum"), Path("est.tum"));
  // Predicted poses: the truth at t = 1 moved 0.3 m in x and turned 2 deg (PE 0.3, TE 2).
  WriteTum(Path("pred.tum"), {{1.002, SE3d::FromXYZYaw(4.3, 0, 0, 92 * kDeg)}});
  const RunResult r =
      Run("--est " + Path("est.tum") + " --gt " + Path("gt.tum") + " --rpe-delta 1 --predicted " +
          Path("pred.tum") + " --json " + Path("out/eval.json") + " --report " + Path("out/eval.md") +
          " --plot " + Path("out/eval.svg"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("ATE trans (m)"), std::string::npos) << r.out;
  const nlohmann::json j = nlohmann::json::parse(ReadTextFile(Path("out/eval.json")));
  EXPECT_NEAR(j["ate"]["rmse"].get<double>(), 0.452769256906871, 1e-9);
  EXPECT_NEAR(j["ate"]["mean"].get<double>(), 0.45, 1e-9);
  EXPECT_NEAR(j["ate"]["median"].get<double>(), 0.45, 1e-9);
  EXPECT_NEAR(j["ate"]["std"].get<double>(), 0.05, 1e-9);
  EXPECT_NEAR(j["ate"]["min"].get<double>(), 0.4, 1e-9);
  EXPECT_NEAR(j["ate"]["max"].get<double>(), 0.5, 1e-9);
  EXPECT_EQ(j["ate"]["pairs"].get<int>(), 4);
  EXPECT_NEAR(j["ate"]["rotation_deg"]["mean"].get<double>(), 2.5, 1e-9);
  EXPECT_EQ(j["association"]["est_poses"].get<int>(), 5);
  EXPECT_EQ(j["alignment"]["mode"], "se3");
  EXPECT_EQ(j["rpe"]["pairs"].get<int>(), 3);
  EXPECT_EQ(j["rpe"]["unit"], "frames");
  EXPECT_TRUE(j["rpe"]["translation_m"].contains("rmse"));
  EXPECT_EQ(j["pe_te"]["instants"].get<int>(), 1);
  EXPECT_NEAR(j["pe_te"]["pe_m"]["mean"].get<double>(), 0.3, 1e-9);
  EXPECT_NEAR(j["pe_te"]["te_deg"]["mean"].get<double>(), 2.0, 1e-9);
  EXPECT_FALSE(j["pe_te"]["aligned"].get<bool>());

  const std::string md = ReadTextFile(Path("out/eval.md"));
  EXPECT_NE(md.find("| ATE translation (m) | 0.4528 | 0.4500 |"), std::string::npos) << md;
  const std::string svg = ReadTextFile(Path("out/eval.svg"));
  EXPECT_EQ(svg.rfind("<?xml", 0), 0u);
  EXPECT_NE(svg.find("<svg"), std::string::npos);
  EXPECT_NE(svg.find("</svg>"), std::string::npos);
  EXPECT_NE(svg.find("<polyline"), std::string::npos);
  EXPECT_NE(svg.find("<circle"), std::string::npos);  // the PE instant
}

MapMarker CliMarker(const std::string& id, double x, double y, std::optional<int> component) {
  MapMarker m;
  m.key = {"qr", id};
  m.size_m = 0.1;
  m.T_world_marker = SE3d::FromXYZYaw(x, y, 1.0, 0.3 * x);
  m.component = component;
  return m;
}

// Issue 18, finding 4: `--json ok.json --plot afile/p.svg` exited 1 but left ok.json.
TEST_F(EvalCliTest, SeveralOutputsAreAllOrNothing) {
  WriteHandCase(Path("gt.tum"), Path("est.tum"));
  AtomicWriteFile(Path("afile"), "a plain file\n");
  const std::string inputs = "--est " + Path("est.tum") + " --gt " + Path("gt.tum");
  const RunResult r = Run(inputs + " --json " + Path("ok.json") + " --plot " + Path("afile/p.svg"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("afile/p.svg"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(Path("ok.json")));
  const RunResult same = Run(inputs + " --json " + Path("x") + " --report " + Path("x"));
  EXPECT_EQ(same.exit_code, 1);
  EXPECT_NE(same.err.find("--json and --report name the same file"), std::string::npos) << same.err;
  EXPECT_FALSE(fs::exists(Path("x")));
}

TEST_F(EvalCliTest, MapAgainstMap) {
  // Component 0: a, b, c moved rigidly (errors 0). Component 1: d alone, moved rigidly (0).
  // e is only in the truth, f only in the estimate.
  MarkerMap truth, estimate;
  const SE3d T = SE3d::FromXYZYaw(5, -2, 0.1, 1.0);
  for (const auto& [id, x, y, component] : std::vector<std::tuple<std::string, double, double, int>>{
           {"a", 0, 0, 0}, {"b", 3, 0, 0}, {"c", 0, 2, 0}, {"d", 6, 6, 1}}) {
    truth.markers.push_back(CliMarker(id, x, y, std::nullopt));
    MapMarker m = CliMarker(id, x, y, component);
    m.T_world_marker = (component == 0 ? T : T.inverse()) * m.T_world_marker;
    estimate.markers.push_back(m);
  }
  truth.markers.push_back(CliMarker("e", 9, 9, std::nullopt));
  estimate.markers.push_back(CliMarker("f", 1, 1, 1));
  WriteMap(Path("gt.json"), truth);
  WriteMap(Path("map.json"), estimate);
  const RunResult r = Run("--map " + Path("map.json") + " --gt-map " + Path("gt.json") + " --json " +
                          Path("map_eval.json") + " --report " + Path("map_eval.md"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(ReadTextFile(Path("map_eval.json")));
  const nlohmann::json& m = j["map"];
  EXPECT_LT(m["position_rmse"].get<double>(), 1e-9);
  EXPECT_LT(m["orientation_rmse_deg"].get<double>(), 1e-6);
  EXPECT_EQ(m["markers"].get<int>(), 4);
  ASSERT_EQ(m["components"].size(), 2u);
  EXPECT_EQ(m["components"][0]["alignment"], "positions");
  EXPECT_EQ(m["components"][1]["alignment"], "poses");
  EXPECT_EQ(m["per_marker"].size(), 4u);
  ASSERT_EQ(m["missing_in_estimate"].size(), 1u);
  EXPECT_EQ(m["missing_in_estimate"][0]["id"], "e");
  EXPECT_EQ(m["missing_in_groundtruth"][0]["id"], "f");
  EXPECT_FALSE(j.contains("ate"));
  EXPECT_NE(ReadTextFile(Path("map_eval.md")).find("`qr:e`"), std::string::npos);
}

TEST_F(EvalCliTest, TrajectoryAndMapInOneCall) {
  WriteHandCase(Path("gt.tum"), Path("est.tum"));
  MarkerMap truth, estimate;
  for (const auto& [id, x, y] :
       std::vector<std::tuple<std::string, double, double>>{{"a", 0, 0}, {"b", 3, 0}, {"c", 0, 2}}) {
    truth.markers.push_back(CliMarker(id, x, y, std::nullopt));
    estimate.markers.push_back(CliMarker(id, x + 0.5, y, 0));
  }
  WriteMap(Path("gt.json"), truth);
  WriteMap(Path("map.json"), estimate);
  const RunResult r =
      Run("--est " + Path("est.tum") + " --gt " + Path("gt.tum") + " --map " + Path("map.json") +
          " --gt-map " + Path("gt.json") + " --json " + Path("both.json") + " --plot " + Path("both.svg"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json j = nlohmann::json::parse(ReadTextFile(Path("both.json")));
  EXPECT_NEAR(j["ate"]["rmse"].get<double>(), 0.452769256906871, 1e-9);
  EXPECT_LT(j["map"]["position_rmse"].get<double>(), 1e-9);  // a pure shift, aligned away
  const std::string svg = ReadTextFile(Path("both.svg"));
  EXPECT_NE(svg.find("qr:b (estimate)"), std::string::npos);  // estimated markers drawn
  EXPECT_NE(svg.find("qr:b (true)"), std::string::npos);
}

TEST_F(EvalCliTest, MalformedTumNamesFileAndLineAndWritesNothing) {
  WriteHandCase(Path("gt.tum"), Path("est.tum"));
  AtomicWriteFile(Path("bad.tum"), "0 0 0 0 0 0 0 1\n1 0 0 zero 0 0 0 1\n");
  const RunResult r =
      Run("--est " + Path("bad.tum") + " --gt " + Path("gt.tum") + " --json " + Path("x.json"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find(Path("bad.tum") + ":2"), std::string::npos) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_FALSE(fs::exists(Path("x.json")));
}

TEST_F(EvalCliTest, NoPairsSaysSoAndSuggestsMaxDt) {
  WriteTum(Path("gt.tum"),
           {{0.0, SE3d()}, {1.0, SE3d::FromXYZYaw(1, 0, 0, 0)}, {2.0, SE3d::FromXYZYaw(1, 1, 0, 0)}});
  WriteTum(Path("late.tum"), {{50.0, SE3d()}, {51.0, SE3d::FromXYZYaw(1, 0, 0, 0)}});
  const RunResult r =
      Run("--est " + Path("late.tum") + " --gt " + Path("gt.tum") + " --json " + Path("x.json"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("no pose pairs"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("--max-dt"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(Path("late.tum")), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(Path("x.json")));
  // A larger --max-dt is not a cure for a clock 50 s off, but a 0.5 s one is.
  WriteTum(Path("offset.tum"),
           {{0.4, SE3d()}, {1.4, SE3d::FromXYZYaw(1, 0, 0, 0)}, {2.4, SE3d::FromXYZYaw(1, 1, 0, 0)}});
  EXPECT_EQ(Run("--est " + Path("offset.tum") + " --gt " + Path("gt.tum")).exit_code, 1);
  EXPECT_EQ(
      Run("--est " + Path("offset.tum") + " --gt " + Path("gt.tum") + " --max-dt 0.5 --align none").exit_code,
      0);
}

TEST_F(EvalCliTest, BadArgumentsAndFiles) {
  WriteHandCase(Path("gt.tum"), Path("est.tum"));
  const std::string both = "--est " + Path("est.tum") + " --gt " + Path("gt.tum");
  RunResult r = Run("--est " + Path("missing.tum") + " --gt " + Path("gt.tum"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find(Path("missing.tum")), std::string::npos) << r.err;
  EXPECT_EQ(Run("--est " + Path("est.tum")).exit_code, 1);
  EXPECT_EQ(Run(both + " --align sim3").exit_code, 1);
  EXPECT_EQ(Run(both + " --rpe-delta 1.5").exit_code, 1);
  EXPECT_EQ(Run(both + " --rpe-unit m").exit_code, 1);
  EXPECT_EQ(Run(both + " --max-dt -1").exit_code, 1);
  EXPECT_EQ(Run(both + " --markers " + Path("gt.tum")).exit_code, 1);  // --markers only draws: needs --plot
  EXPECT_EQ(Run(both + " --align-predicted").exit_code, 1);
  EXPECT_EQ(Run("--map " + Path("est.tum")).exit_code, 1);  // --gt-map missing
  AtomicWriteFile(Path("broken.json"),
                  "{\"format\": \"waymark-map\", \"version\": 1, \"markers\": [\n{\"family\": 3}]}\n");
  r = Run("--map " + Path("broken.json") + " --gt-map " + Path("broken.json"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find(Path("broken.json")), std::string::npos) << r.err;
  r = Run("--help");
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_NE(r.out.find("--rpe-delta"), std::string::npos);
}

}  // namespace
}  // namespace waymark
