// End to end through the `waymark` binary: `waymark map score` of a simulated survey's true map
// and trajectory, restricted to the frames of another trajectory (--frames-of), and its errors:
// one line on stderr naming the file, a non-zero exit and no output file.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "io/tum_io.h"
#include "io/util.h"
#include "tests/cli/cli_test_util.h"

namespace waymark {
namespace {

namespace fs = std::filesystem;

class MapScoreCliTest : public CliTest {
 protected:
  MapScoreCliTest() : CliTest("map_score_cli") {}

  void SetUp() override {
    CliTest::SetUp();
    survey_ = dir_ / "survey";
    const RunResult sim = Run("sim corridor --out " + survey_.string() +
                              " --seed 5 --set place.loop_length_m=4 --set place.loop_width_m=3 "
                              "--set place.spacing_m=0.5");
    ASSERT_EQ(sim.exit_code, 0) << sim.err;
  }

  std::string TruthArgs() const {
    return "map score " + survey_.string() + " --map " + (survey_ / "groundtruth/markers.json").string() +
           " --trajectory " + (survey_ / "groundtruth/trajectory.tum").string();
  }

  static size_t LineCount(const std::string& text) { return std::count(text.begin(), text.end(), '\n'); }

  fs::path survey_;
};

TEST_F(MapScoreCliTest, FramesOfLeavesOutTheFramesTheOtherTrajectoryLacks) {
  const RunResult all = Run(TruthArgs() + " --json " + (dir_ / "all.json").string());
  ASSERT_EQ(all.exit_code, 0) << all.err;
  EXPECT_NE(all.out.find("reprojection:"), std::string::npos) << all.out;
  EXPECT_EQ(all.out.find("--frames-of"), std::string::npos) << all.out;

  // The other solution has a pose for the first half of the run only.
  Trajectory truth = ReadTum(survey_ / "groundtruth/trajectory.tum");
  ASSERT_GT(truth.size(), 100u);
  truth.resize(truth.size() / 2);
  WriteTum(dir_ / "half.tum", truth);
  const RunResult half = Run(TruthArgs() + " --frames-of " + (dir_ / "half.tum").string() + " --json " +
                             (dir_ / "half.json").string());
  ASSERT_EQ(half.exit_code, 0) << half.err;
  EXPECT_NE(half.out.find("in frames --frames-of has no pose for"), std::string::npos) << half.out;

  const nlohmann::json a = nlohmann::json::parse(ReadTextFile(dir_ / "all.json"));
  const nlohmann::json h = nlohmann::json::parse(ReadTextFile(dir_ / "half.json"));
  EXPECT_EQ(a["outside_frames_of"].get<size_t>(), 0u);
  const size_t left_out = h["outside_frames_of"].get<size_t>();
  EXPECT_GT(left_out, 0u);
  EXPECT_EQ(h["all"]["observations"].get<size_t>() + left_out, a["all"]["observations"].get<size_t>());
  EXPECT_EQ(h["without_pose"].get<size_t>(), a["without_pose"].get<size_t>());
}

TEST_F(MapScoreCliTest, BadFramesOfIsAOneLineErrorAndWritesNothing) {
  const fs::path json = dir_ / "score.json";
  const RunResult missing =
      Run(TruthArgs() + " --frames-of " + (dir_ / "absent.tum").string() + " --json " + json.string());
  EXPECT_NE(missing.exit_code, 0);
  EXPECT_EQ(LineCount(missing.err), 1u) << missing.err;
  EXPECT_NE(missing.err.find("absent.tum"), std::string::npos) << missing.err;
  EXPECT_FALSE(fs::exists(json));

  AtomicWriteFile(dir_ / "bad.tum", "0 0 0 0 0 0 0 1\nnot a pose\n");
  const RunResult bad =
      Run(TruthArgs() + " --frames-of " + (dir_ / "bad.tum").string() + " --json " + json.string());
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_EQ(LineCount(bad.err), 1u) << bad.err;
  EXPECT_NE(bad.err.find("bad.tum:2"), std::string::npos) << bad.err;
  EXPECT_FALSE(fs::exists(json));
}

TEST_F(MapScoreCliTest, MissingMapAndCollidingOutputsAreErrors) {
  const RunResult no_map = Run("map score " + survey_.string());
  EXPECT_NE(no_map.exit_code, 0);
  EXPECT_EQ(LineCount(no_map.err), 1u) << no_map.err;
  EXPECT_NE(no_map.err.find("--map"), std::string::npos) << no_map.err;

  const fs::path same = dir_ / "same.json";
  const RunResult twice = Run(TruthArgs() + " --json " + same.string() + " --out-map " + same.string());
  EXPECT_NE(twice.exit_code, 0);
  EXPECT_EQ(LineCount(twice.err), 1u) << twice.err;
  EXPECT_FALSE(fs::exists(same));
}

}  // namespace
}  // namespace waymark
