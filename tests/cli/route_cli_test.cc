// End-to-end: survey -> map -> `waymark route` -> `waymark sim --drive` on sim rooms, and the
// one-line errors of both commands.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "io/dataset_io.h"
#include "io/util.h"
#include "tests/cli/cli_test_util.h"

namespace waymark {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

class RouteCliTest : public CliTest {
 protected:
  RouteCliTest() : CliTest("route_cli") {}

  // A rooms survey (seed 1000) and its map, made once for the suite.
  static void SetUpTestSuite() {
    shared_ = FreshTestDir("route_cli_shared");
    ASSERT_EQ(RunWaymark("sim rooms --seed 1000 --out " + (shared_ / "survey").string(), shared_).exit_code,
              0);
    ASSERT_EQ(
        RunWaymark("map build " + (shared_ / "survey").string() + " --out " + (shared_ / "map.json").string(),
                   shared_)
            .exit_code,
        0);
  }
  static void TearDownTestSuite() { fs::remove_all(shared_); }

  std::string RouteArgs(const std::string& rest) const {
    return "route " + (shared_ / "map.json").string() + " --survey " + (shared_ / "survey").string() + " " +
           rest;
  }
  void ExpectOneLineError(const RunResult& r, const std::string& message) const {
    EXPECT_EQ(r.exit_code, 1);
    EXPECT_THAT(r.err, HasSubstr(message));
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  }

  static fs::path shared_;
};

fs::path RouteCliTest::shared_;

// rooms has no anchors: the map's frame is the survey's first pose (room 0's centre, facing +x).
TEST_F(RouteCliTest, RouteThroughTheDoorThenDriveIt) {
  const fs::path route = dir_ / "route.json";
  const RunResult r = Run(RouteArgs("--from 0,0,0 --to 4,0,1.5707963 --out " + route.string()));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.err, HasSubstr("route: "));
  const std::string text = ReadTextFile(route);
  EXPECT_THAT(text, HasSubstr("\"format\": \"waymark-route\""));
  EXPECT_THAT(text, HasSubstr("\"codes\": [{\"family\": \"datamatrix\""));
  const fs::path out = dir_ / "drive";
  const RunResult d = Run("sim rooms --drive " + route.string() + " --localize " +
                          (shared_ / "map.json").string() + " --seed 2 --out " + out.string());
  ASSERT_EQ(d.exit_code, 0) << d.err;
  EXPECT_THAT(d.err, HasSubstr("drive: reached the goal"));
  const std::string report = ReadTextFile(out / "drive.json");
  EXPECT_THAT(report, HasSubstr("\"reached\": true"));
  EXPECT_THAT(report, HasSubstr("\"times_lost\": 0"));
  const Dataset dataset = LoadDataset(out);
  EXPECT_TRUE(dataset.groundtruth_trajectory);
  EXPECT_FALSE(dataset.detections.empty());
  EXPECT_TRUE(fs::exists(out / "online" / "trajectory.tum"));
}

TEST_F(RouteCliTest, ToCodeEndsWhereTheCodeWasSeen) {
  const RunResult r =
      Run(RouteArgs("--from 0,0 --to-code datamatrix:1112 --out " + (dir_ / "r.json").string()));
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(ReadTextFile(dir_ / "r.json"),
              HasSubstr("\"goal_code\": {\"family\": \"datamatrix\", \"id\": \"1112\"}"));
}

TEST_F(RouteCliTest, BadInputIsAOneLineError) {
  const std::string out = " --out " + (dir_ / "r.json").string();
  ExpectOneLineError(Run(RouteArgs("--from 30,30 --to 4,0" + out)),
                     "start (30.00, 30.00) is off the survey graph");
  ExpectOneLineError(Run(RouteArgs("--from 0,0 --to 30,0" + out)),
                     "goal (30.00, 0.00) is off the survey graph");
  ExpectOneLineError(Run(RouteArgs("--from 0 --to 4,0" + out)),
                     "option --from: expected X,Y or X,Y,YAW, got 1 numbers");
  ExpectOneLineError(Run(RouteArgs("--from 0,0" + out)), "option --to or --to-code is required");
  ExpectOneLineError(Run(RouteArgs("--from 0,0 --to-code datamatrix:9999" + out)),
                     "datamatrix:9999 is not in");
  // The room the survey robot was carried to is a map component of its own.
  ExpectOneLineError(Run(RouteArgs("--from 0,0 --to-code datamatrix:1311" + out)), "is in map component 1");
  ExpectOneLineError(Run(RouteArgs("--from 0,0 --to 4,0 --via 1" + out)), "option --via: expected X,Y");
  EXPECT_FALSE(fs::exists(dir_ / "r.json"));
  std::ofstream(dir_ / "bad.json") << "{\"format\": \"waymark-route\", \"version\": 1,\n\"waypoints\": []}";
  ExpectOneLineError(Run("sim rooms --drive " + (dir_ / "bad.json").string() + " --localize " +
                         (shared_ / "map.json").string() + " --out " + (dir_ / "d").string()),
                     "bad.json:2: waypoints: expected a non-empty array");
  ExpectOneLineError(
      Run("sim rooms --drive " + (dir_ / "bad.json").string() + " --out " + (dir_ / "d").string()),
      "--drive and --localize go together");
  EXPECT_FALSE(fs::exists(dir_ / "d"));
}

}  // namespace
}  // namespace waymark
