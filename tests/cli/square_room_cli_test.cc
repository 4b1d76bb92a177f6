// Several ID-less squares ([Seki], docs/online.md) through the binary: `waymark sim square-ceiling
// --set place.squares=2` (its simulated detections, their ids replaced by "*" as `waymark detect
// --families square` writes them with several squares); `waymark localize` refuses without
// --start-pose (one line) and tracks through both squares with it; `waymark map build` maps the
// second square from a markers.json that knows only the first.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <string>

#include "geometry/pose.h"
#include "io/detections_io.h"
#include "io/map_io.h"
#include "io/tum_io.h"
#include "tests/cli/cli_test_util.h"

namespace waymark {
namespace {

namespace fs = std::filesystem;

std::string ReadAll(const fs::path& path) {
  std::ifstream in(path);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

class SquareRoomCli : public CliTest {
 protected:
  SquareRoomCli() : CliTest("square_room_cli") {}
  void SetUp() override {
    CliTest::SetUp();
    d_ = dir_ / "d";
    ASSERT_EQ(Run("sim square-ceiling --out " + d_.string() + " --seed 2 --set place.squares=2").exit_code,
              0);
    // The squares as the detector reports them: no id (the default tape's solid side is the top,
    // so the marker's own corner order is already "solid side first").
    const std::string text = ReadAll(d_ / "detections.jsonl");
    std::ofstream(d_ / "detections.jsonl")
        << std::regex_replace(text, std::regex("\"id\": *\"S[0-9]+\""), "\"id\": \"*\"");
    truth_ = ReadMap(d_ / "markers.json");
    ASSERT_EQ(truth_.markers.size(), 2u);
  }
  std::string Localize(const std::string& extra) const {
    return "localize " + d_.string() + " --map " + (d_ / "markers.json").string() + " --out " +
           (dir_ / "run.tum").string() + extra;
  }
  fs::path d_;
  MarkerMap truth_;
};

TEST_F(SquareRoomCli, LocalizeNeedsAStartPoseAndTracksBothSquares) {
  const RunResult refused = Run(Localize(""));
  EXPECT_EQ(refused.exit_code, 1);
  EXPECT_NE(refused.err.find("2 squares without ids and no other code"), std::string::npos) << refused.err;
  EXPECT_NE(refused.err.find("give --start-pose X,Y,YAW_DEG"), std::string::npos) << refused.err;
  EXPECT_EQ(std::count(refused.err.begin(), refused.err.end(), '\n'), 1) << refused.err;
  EXPECT_FALSE(fs::exists(dir_ / "run.tum"));
  EXPECT_EQ(Run(Localize(" --start-pose 1,2")).exit_code, 1);

  // The start pose: the truth's first pose, 0.2 m and 5 deg off.
  const Trajectory truth = ReadTum(d_ / "groundtruth" / "trajectory.tum");
  ASSERT_FALSE(truth.empty());
  const SE2d start = SE2d::FromSE3(truth.front().T);
  const std::string pose = " --start-pose " + std::to_string(start.x() + 0.2) + "," +
                           std::to_string(start.y()) + "," +
                           std::to_string(start.theta() * 180.0 / M_PI + 5.0);
  const RunResult run = Run(Localize(pose));
  ASSERT_EQ(run.exit_code, 0) << run.err;
  ASSERT_EQ(Run("eval --est " + (dir_ / "run.tum").string() + " --gt " +
                (d_ / "groundtruth" / "trajectory.tum").string() + " --align none --json " +
                (dir_ / "eval.json").string())
                .exit_code,
            0);
  const std::string eval = ReadAll(dir_ / "eval.json");
  std::smatch m;
  ASSERT_TRUE(std::regex_search(eval, m, std::regex("\"ate\"[^}]*?\"rmse\": *([-0-9.eE+]+)"))) << eval;
  EXPECT_LT(std::stod(m[1]), 0.02) << eval;
  // Under the second square (x = 6 m) too.
  const Trajectory est = ReadTum(dir_ / "run.tum");
  double max_x = -1e9;
  for (const StampedSE3& p : est) max_x = std::max(max_x, p.T.translation().x());
  EXPECT_GT(max_x, 6.0);
  EXPECT_GT(est.size(), truth.size() / 2);
}

TEST_F(SquareRoomCli, MapBuildFindsTheSecondSquare) {
  // markers.json knows the first square (the anchor) only.
  MarkerMap first;
  first.markers.push_back(truth_.markers[0]);
  WriteMap(d_ / "markers.json", first);
  const RunResult built = Run("map build " + d_.string() + " --out " + (dir_ / "map.json").string());
  ASSERT_EQ(built.exit_code, 0) << built.err;
  EXPECT_NE(built.out.find("squares: "), std::string::npos) << built.out;
  const MarkerMap map = ReadMap(dir_ / "map.json");
  ASSERT_EQ(map.markers.size(), 2u);
  const MapMarker* s1 = map.Find({kFamilySquare, "S1"});
  ASSERT_NE(s1, nullptr);
  EXPECT_TRUE(s1->square_tape.has_value());
  const double error_m =
      (s1->T_world_marker.translation() - truth_.markers[1].T_world_marker.translation()).norm();
  EXPECT_LT(error_m, 0.02) << s1->T_world_marker.translation().transpose();
}

}  // namespace
}  // namespace waymark
