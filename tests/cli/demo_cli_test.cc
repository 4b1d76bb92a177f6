// End to end through the `waymark` binary: `waymark demo` on the dataset shipped in data/demo
// (detect -> map build -> localize loose and tight -> eval) prints the accuracy table and
// writes its reports; the figures are held to bounds (ours better than the loosely coupled
// EKF and than odometry alone, a map error bound, detection working on the shipped images).
// Bad input gives one line on stderr, exit 1, and no output directory.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <string>

#include "io/map_io.h"
#include "io/tum_io.h"
#include "io/util.h"
#include "tests/cli/cli_test_util.h"

namespace waymark {
namespace {

namespace fs = std::filesystem;

class DemoCliTest : public CliTest {
 protected:
  DemoCliTest() : CliTest("demo_cli") {}

  // A one-line error on stderr that contains `text`, exit 1, nothing on stdout, no --out.
  void ExpectCleanFailure(const RunResult& result, const std::string& text) const {
    EXPECT_EQ(result.exit_code, 1) << result.err;
    EXPECT_NE(result.err.find(text), std::string::npos) << result.err;
    EXPECT_EQ(result.err.find("error"), result.err.rfind("error")) << result.err;
    EXPECT_EQ(result.err.back(), '\n');
    EXPECT_EQ(result.err.find('\n', result.err.find("error")), result.err.size() - 1) << result.err;
    EXPECT_TRUE(result.out.empty()) << result.out;
    EXPECT_FALSE(fs::exists(dir_ / "out"));
  }

  static fs::path DemoData() { return fs::path(WAYMARK_SOURCE_DIR) / "data" / "demo"; }
};

// The rows of report.json's table by method.
std::map<std::string, nlohmann::json> TableRows(const nlohmann::json& report) {
  std::map<std::string, nlohmann::json> rows;
  for (const nlohmann::json& row : report.at("table")) rows[row.at("method").get<std::string>()] = row;
  return rows;
}

// Issue 18, finding 9: scripts/demo.sh OUT_DIR began with `rm -rf "$OUT_DIR"`, so
// `scripts/demo.sh ~/robot` wiped the user's directory. The script now deletes nothing and
// hands a relative OUT_DIR to the binary as the caller meant it (a stub binary records it).
TEST_F(DemoCliTest, DemoScriptDeletesNothingOfTheUsers) {
  const fs::path user_dir = dir_ / "robot";
  fs::create_directories(user_dir / "notes");
  AtomicWriteFile(user_dir / "notes" / "calibration.txt", "precious\n");
  const fs::path stub = dir_ / "stub.sh";
  AtomicWriteFile(stub, "#!/bin/sh\nprintf '%s\\n' \"$@\" > " + (dir_ / "args.txt").string() + "\n");
  fs::permissions(stub, fs::perms::owner_all);
  const std::string script = (fs::path(WAYMARK_SOURCE_DIR) / "scripts" / "demo.sh").string();
  const std::string env = "WAYMARK_DEMO_SKIP_SETUP=1 WAYMARK_DEMO_BINARY=" + stub.string() + " ";
  ASSERT_EQ(std::system((env + script + " " + user_dir.string()).c_str()), 0);
  EXPECT_EQ(ReadTextFile(user_dir / "notes" / "calibration.txt"), "precious\n");
  EXPECT_NE(ReadTextFile(dir_ / "args.txt").find("--out\n" + user_dir.string() + "\n"), std::string::npos);
  // A relative OUT_DIR is the caller's, not the source tree's.
  ASSERT_EQ(std::system(("cd " + dir_.string() + " && " + env + script + " robot").c_str()), 0);
  EXPECT_NE(ReadTextFile(dir_ / "args.txt").find("--out\n" + user_dir.string() + "\n"), std::string::npos);
  EXPECT_EQ(ReadTextFile(user_dir / "notes" / "calibration.txt"), "precious\n");
}

TEST_F(DemoCliTest, ShippedDataGivesTheTableWithOursBest) {
  const fs::path out = dir_ / "out";
  const RunResult demo = Run("demo --data " + DemoData().string() + " --out " + out.string());
  ASSERT_EQ(demo.exit_code, 0) << demo.err;
  for (const char* text :
       {"odometry alone", "loosely coupled EKF", "ours (tight, corners)", "ATE RMSE",
        "map against the true code poses", "the map's covariances predicted", "detection ("}) {
    EXPECT_NE(demo.out.find(text), std::string::npos) << text << " missing from\n" << demo.out;
  }
  EXPECT_NE(demo.err.find("demo: done"), std::string::npos) << demo.err;

  const nlohmann::json report = nlohmann::json::parse(ReadTextFile(out / "report.json"));
  const auto rows = TableRows(report);
  ASSERT_EQ(rows.size(), 3u);
  const auto figure = [&](const char* method, const char* column) {
    return rows.at(method).at(column).get<double>();
  };
  // The map's frame error is shared by both filters: in the world frame ours is at least as
  // good; the path's shape (aligned), the predicted poses (PE, TE) tell the filters apart.
  EXPECT_LT(figure("ours", "ate_rmse_m"), 1.05 * figure("loose", "ate_rmse_m"));
  EXPECT_LT(figure("ours", "ate_rmse_m"), 0.3 * figure("odometry", "ate_rmse_m"));
  EXPECT_LT(figure("ours", "ate_rmse_m"), 0.03);
  EXPECT_LT(figure("ours", "aligned_ate_rmse_m"), 0.8 * figure("loose", "aligned_ate_rmse_m"));
  EXPECT_LT(figure("ours", "aligned_ate_rmse_m"), 0.3 * figure("odometry", "aligned_ate_rmse_m"));
  EXPECT_LT(figure("ours", "pe_mean_m"), figure("loose", "pe_mean_m"));
  EXPECT_LT(figure("ours", "pe_mean_m"), 0.3 * figure("odometry", "pe_mean_m"));
  EXPECT_LT(figure("ours", "te_mean_deg"), figure("loose", "te_mean_deg"));
  EXPECT_GT(figure("ours", "tracked_fraction"), 0.7);

  const nlohmann::json& map = report.at("map");
  EXPECT_GE(map.at("markers").get<int>(), 28);
  EXPECT_EQ(map.at("components").get<int>(), 1);
  EXPECT_LT(map.at("evaluation").at("position_rmse").get<double>(), 0.012);
  EXPECT_LT(map.at("evaluation").at("orientation_rmse_deg").get<double>(), 1.5);
  for (const char* part : {"survey", "run"}) {
    const nlohmann::json& check = report.at(part).at("detection_check");
    EXPECT_GE(check.at("read").get<double>(), 0.9 * check.at("codes_in_view").get<double>()) << part;
    EXPECT_LT(check.at("worst_corner_error_median_px").get<double>(), 0.6) << part;
    EXPECT_LE(check.at("gross").get<double>(), 0.15 * check.at("read").get<double>()) << part;
  }

  for (const char* name : {"report.md", "run_loose.svg", "run_ours.svg", "run_odometry.svg", "map.svg",
                           "survey_detections.jsonl", "run_detections.jsonl", "run_loose_predicted.tum",
                           "run_ours_predicted.tum"}) {
    EXPECT_GT(fs::file_size(out / name), 0u) << name;
  }
  EXPECT_EQ(ReadMap(out / "map.json").markers.size(), map.at("markers").get<size_t>());
  EXPECT_FALSE(ReadTum(out / "run_ours.tum").empty());
  EXPECT_NE(ReadTextFile(out / "report.md").find("| ours (tight, corners) |"), std::string::npos);
}

TEST_F(DemoCliTest, DirectoryWithoutSurveyAndRunIsAnError) {
  ExpectCleanFailure(Run("demo --data " + (dir_ / "missing").string() + " --out " + (dir_ / "out").string()),
                     "not a demo dataset (expected survey/dataset.yaml and run/dataset.yaml)");
  fs::create_directories(dir_ / "half" / "survey");
  AtomicWriteFile(dir_ / "half" / "survey" / "dataset.yaml",
                  ReadTextFile(DemoData() / "survey" / "dataset.yaml"));
  ExpectCleanFailure(Run("demo --data " + (dir_ / "half").string() + " --out " + (dir_ / "out").string()),
                     "not a demo dataset");
}

TEST_F(DemoCliTest, BrokenRunDatasetNamesItsFileBeforeAnyWork) {
  const fs::path data = dir_ / "data";
  fs::create_directories(data / "run");
  fs::create_directory_symlink(fs::absolute(DemoData() / "survey"), data / "survey");
  AtomicWriteFile(data / "run" / "dataset.yaml", "format: waymark-dataset\nversion: 1\nmotion: sideways\n");
  const RunResult result = Run("demo --data " + data.string() + " --out " + (dir_ / "out").string());
  ExpectCleanFailure(result, "dataset.yaml");
  EXPECT_EQ(result.err.find("detecting"), std::string::npos) << result.err;
}

TEST_F(DemoCliTest, UnknownOptionAndPositionalAreErrors) {
  ExpectCleanFailure(Run("demo --speed 2"), "--speed");
  ExpectCleanFailure(Run("demo extra"), "unexpected argument 'extra'");
}

TEST_F(DemoCliTest, HelpListsTheOptions) {
  const RunResult help = Run("demo --help");
  EXPECT_EQ(help.exit_code, 0);
  for (const char* option : {"--data DIR", "--out DIR", "--families LIST"}) {
    EXPECT_NE(help.out.find(option), std::string::npos) << option;
  }
}

}  // namespace
}  // namespace waymark
