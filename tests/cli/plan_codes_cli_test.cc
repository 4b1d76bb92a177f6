// End-to-end: `waymark plan-codes` on a small corridor loop, the planned layout surveyed by
// `waymark sim --markers`, and the one-line errors.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "io/dataset_io.h"
#include "io/map_io.h"
#include "io/util.h"
#include "tests/cli/cli_test_util.h"

namespace waymark {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

// A 4 x 3 m corridor loop (centre line), 1.2 m wide: the inner block and the outer walls.
constexpr const char* kSmallLoop = "--set place.loop_length_m=4 --set place.loop_width_m=3";

std::string Walls() {
  return "walls:\n"
         "  - {from: [0.6, 0.6], to: [3.4, 0.6]}\n  - {from: [3.4, 0.6], to: [3.4, 2.4]}\n"
         "  - {from: [3.4, 2.4], to: [0.6, 2.4]}\n  - {from: [0.6, 2.4], to: [0.6, 0.6]}\n"
         "  - {from: [-0.6, -0.6], to: [4.6, -0.6]}\n  - {from: [4.6, -0.6], to: [4.6, 3.6]}\n"
         "  - {from: [4.6, 3.6], to: [-0.6, 3.6]}\n  - {from: [-0.6, 3.6], to: [-0.6, -0.6]}\n";
}

class PlanCodesCliTest : public CliTest {
 protected:
  PlanCodesCliTest() : CliTest("plan_codes_cli") {}
  void SetUp() override {
    CliTest::SetUp();
    ASSERT_EQ(Run(std::string("sim corridor ") + kSmallLoop + " --seed 5 --out " + (dir_ / "rig").string())
                  .exit_code,
              0);
  }
  void WriteWorld(const std::string& walls) {
    std::ofstream(dir_ / "world.yaml")
        << "format: waymark-floor-plan\nversion: 1\nceiling_height_m: 2.5\nrig: rig\n"
           "code_sizes_m: [0.10]\ncode_height_m: 0.30\n"
        << walls;
  }
  std::string PlanArgs(const std::string& path, const std::string& rest) const {
    return "plan-codes " + (dir_ / "world.yaml").string() + " --path " + path + " --out " +
           (dir_ / "planned.json").string() + " " + rest;
  }
};

TEST_F(PlanCodesCliTest, PlansPrintsPerMetreAndTheSimSurveysIt) {
  WriteWorld(Walls());
  const std::string path = (dir_ / "rig" / "groundtruth" / "trajectory.tum").string();
  const RunResult r = Run(PlanArgs(path, "--target-mm 1000 --spacings 2,1"));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("chosen: "));
  EXPECT_THAT(r.out, HasSubstr("every 2 m"));  // the sparser one meets 1 m
  EXPECT_THAT(r.out, HasSubstr("| 0-1 | "));
  const MarkerMap planned = ReadMap(dir_ / "planned.json");
  ASSERT_GE(planned.markers.size(), 3u);
  EXPECT_TRUE(planned.markers[0].fixed);
  EXPECT_TRUE(planned.markers[2].covariance);
  const RunResult s = Run(std::string("sim corridor ") + kSmallLoop + " --seed 6 --markers " +
                          (dir_ / "planned.json").string() + " --out " + (dir_ / "survey").string());
  ASSERT_EQ(s.exit_code, 0) << s.err;
  const Dataset survey = LoadDataset(dir_ / "survey");
  ASSERT_TRUE(survey.groundtruth_markers);
  EXPECT_EQ(survey.groundtruth_markers->markers.size(), planned.markers.size());
  EXPECT_FALSE(survey.detections.empty());
}

TEST_F(PlanCodesCliTest, BadInputIsAOneLineError) {
  const std::string path = (dir_ / "rig" / "groundtruth" / "trajectory.tum").string();
  WriteWorld("walls: []\n");
  RunResult r = Run(PlanArgs(path, "--target-mm 10"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_THAT(r.err, HasSubstr("world.yaml:7: walls: expected a list of at least one wall"));
  WriteWorld("walls:\n  - {from: [0, 0], to: [1, 0]}\n  - {from: [0, 1], to: [1, 1]}\n");
  r = Run(PlanArgs(path, "--target-mm 10"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_THAT(r.err, HasSubstr("trajectory.tum: pose "));
  EXPECT_THAT(r.err, HasSubstr("is outside the floor plan"));
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  WriteWorld(Walls());
  r = Run(PlanArgs(path, "--target-mm 0"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_THAT(r.err, HasSubstr("the target error must be > 0"));
  r = Run(PlanArgs(path, "--target-mm 0.001 --spacings 2"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("no layout meets 0.001 mm"));
  EXPECT_FALSE(fs::exists(dir_ / "planned.json"));
  std::ofstream(dir_ / "empty.json") << "{\"format\": \"waymark-map\", \"version\": 1, \"markers\": []}";
  r = Run("sim corridor --markers " + (dir_ / "empty.json").string() + " --out " + (dir_ / "s").string());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_THAT(r.err, HasSubstr("empty.json: no code to place"));
}

}  // namespace
}  // namespace waymark
