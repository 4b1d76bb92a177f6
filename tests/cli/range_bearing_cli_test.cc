// End to end through the `waymark` binary: `waymark import mrclam` on a tiny hand-written run
// (and its one-line errors), `waymark map build` of several range-bearing datasets with
// --trajectory-dir, `waymark localize` of a third robot against that map (ATE and NEES), and
// `waymark map build` of two simulated corridor surveys (different seeds) into one map.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "eval/map_metrics.h"
#include "io/dataset_io.h"
#include "io/map_io.h"
#include "io/tum_io.h"
#include "tests/cli/cli_test_util.h"
#include "tests/mapping/range_bearing_world.h"

namespace waymark {
namespace {

namespace fs = std::filesystem;

using ::testing::HasSubstr;
using ::testing::Not;

class RangeBearingCliTest : public CliTest {
 protected:
  RangeBearingCliTest() : CliTest("range_bearing_cli") {}

  fs::path TinyRun() const {
    const fs::path run = dir_ / "run";
    fs::create_directories(run);
    const auto write = [&](const std::string& name, const std::string& text) {
      std::ofstream(run / name) << text;
    };
    write("Barcodes.dat", "# Subject # Barcode #\n1 5\n2 14\n6 72\n7 27\n");
    write("Landmark_Groundtruth.dat", "6 1.0 2.0 0.0001 0.0002\n7 -1.0 0.5 0.0001 0.0001\n");
    write("Robot1_Odometry.dat", "100.0 1.0 0.0\n101.0 1.0 0.0\n102.0 0.0 0.0\n");
    write("Robot2_Odometry.dat", "100.0 0.0 0.5\n102.0 0.0 0.0\n");
    write("Robot1_Measurement.dat", "100.5 72 2.0 0.1\n100.5 99 4.0 0.0\n101.5 27 2.5 1.0\n");
    write("Robot2_Measurement.dat", "101.0 27 2.0 0.5\n");
    write("Robot1_Groundtruth.dat",
          "99.0 0.0 0.0 0.0\n100.0 1.0 0.0 0.0\n101.0 2.0 0.0 0.0\n102.0 3.0 0.0 0.0\n103.0 4.0 0.0 0.0\n");
    write("Robot2_Groundtruth.dat",
          "99.0 5.0 5.0 0.0\n100.0 5.0 5.0 0.5\n101.0 5.0 5.0 1.0\n102.0 5.0 5.0 1.5\n103.0 5.0 5.0 2.0\n");
    return run;
  }
};

TEST_F(RangeBearingCliTest, ImportMrclam) {
  const fs::path run = TinyRun();
  const RunResult import =
      Run("import mrclam " + run.string() + " --out " + (dir_ / "out").string() + " --known-start");
  ASSERT_EQ(import.exit_code, 0) << import.err;
  EXPECT_THAT(import.out,
              HasSubstr("robot1: 3 velocity samples, 2 measurement stamps, 2 landmark observations"));
  EXPECT_THAT(import.out, HasSubstr("rejected: 1 misread barcodes (99 x1)"));
  EXPECT_THAT(import.out, HasSubstr("dead reckoning ATE RMSE: "));
  const Dataset robot1 = LoadDataset(dir_ / "out" / "robot1");
  EXPECT_EQ(robot1.range_bearing.size(), 2u);
  EXPECT_TRUE(robot1.config.start_prior);
  EXPECT_TRUE(robot1.groundtruth_trajectory);
  EXPECT_EQ(robot1.warnings.Total(), 0);
  const RunResult info = Run("dataset info " + (dir_ / "out" / "robot1").string());
  EXPECT_EQ(info.exit_code, 0) << info.err;
  EXPECT_THAT(info.out, HasSubstr("range-bearing: 2 stamps, 2 landmark observations, 0 robot sightings"));
}

TEST_F(RangeBearingCliTest, ImportRefusesMalformedFilesWithOneLine) {
  const fs::path run = TinyRun();
  std::ofstream(run / "Robot2_Measurement.dat") << "101.0 27 2.0\n";
  const RunResult import = Run("import mrclam " + run.string() + " --out " + (dir_ / "out").string());
  EXPECT_EQ(import.exit_code, 1);
  EXPECT_THAT(import.err,
              HasSubstr("Robot2_Measurement.dat:1: expected 4 numbers (time barcode range bearing), got 3"));
  EXPECT_EQ(std::count(import.err.begin(), import.err.end(), '\n'), 1) << import.err;
  EXPECT_FALSE(fs::exists(dir_ / "out"));
  const RunResult missing =
      Run("import mrclam " + (dir_ / "nowhere").string() + " --out " + (dir_ / "out").string());
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_THAT(missing.err, HasSubstr("not a directory"));
}

TEST_F(RangeBearingCliTest, SeveralRobotsOneMapThenLocalizeAnother) {
  // `waymark localize` of robot2 against MAP (in the test's directory), writing OUT there.
  const auto localize_robot2 = [this](const std::string& out, const std::string& options,
                                      const std::string& map = "map.json") {
    return Run("localize " + (dir_ / "robot2").string() + " --map " + (dir_ / map).string() + " --out " +
               (dir_ / out).string() + (options.empty() ? "" : " " + options));
  };
  // A localize run of robot2 refused with `message` on one line, writing nothing.
  const auto expect_refused = [&](const std::string& options, const std::string& message) {
    const RunResult refused = localize_robot2("refused.tum", options);
    EXPECT_NE(refused.exit_code, 0) << options;
    EXPECT_THAT(refused.err, HasSubstr(message));
    EXPECT_EQ(std::count(refused.err.begin(), refused.err.end(), '\n'), 1) << refused.err;
    EXPECT_FALSE(fs::exists(dir_ / "refused.tum")) << options;
  };
  testing::RangeBearingWorldOptions world;
  world.outlier_share = 0.02;
  for (int i = 0; i < 3; ++i)
    WriteDataset(dir_ / ("robot" + std::to_string(i)), testing::RangeBearingRobot(i, 20 + i, world));
  const RunResult build = Run("map build " + (dir_ / "robot0").string() + " " + (dir_ / "robot1").string() +
                              " --out " + (dir_ / "map.json").string() + " --trajectory-dir " +
                              (dir_ / "smoothed").string() + " --range-model distance");
  ASSERT_EQ(build.exit_code, 0) << build.err;
  EXPECT_THAT(build.out, HasSubstr("landmarks: 10"));
  EXPECT_TRUE(fs::exists(dir_ / "smoothed" / "robot0.tum"));
  EXPECT_TRUE(fs::exists(dir_ / "smoothed" / "robot1.tum"));
  EXPECT_THAT(build.out, HasSubstr("depth share 0.000, range scale 0.0000"));
  const MarkerMap map = ReadMap(dir_ / "map.json");
  ASSERT_TRUE(map.range_bearing_noise);
  EXPECT_TRUE(map.markers.front().is_point);
  // With the depth model, the default (these sensors read distances: a depth share near 0 is
  // found); --depth-ranges is the same.
  const RunResult depth_build =
      Run("map build " + (dir_ / "robot0").string() + " " + (dir_ / "robot1").string() + " --out " +
          (dir_ / "map-depth.json").string());
  ASSERT_EQ(depth_build.exit_code, 0) << depth_build.err;
  EXPECT_THAT(depth_build.out, HasSubstr("landmarks: 10"));
  EXPECT_THAT(depth_build.out, Not(HasSubstr("depth share 0.000, range scale 0.0000")));
  EXPECT_THAT(depth_build.out, HasSubstr("range model depth"));
  const RunResult flag_build =
      Run("map build " + (dir_ / "robot0").string() + " " + (dir_ / "robot1").string() + " --out " +
          (dir_ / "map-flag.json").string() + " --depth-ranges");
  ASSERT_EQ(flag_build.exit_code, 0) << flag_build.err;
  // The same build (the range-bearing build differs in its last digits from run to run:
  // docs/reliability.md), hence a tolerance.
  const MarkerMap flag_map = ReadMap(dir_ / "map-flag.json"),
                  depth_map_read = ReadMap(dir_ / "map-depth.json");
  ASSERT_TRUE(flag_map.range_bearing_sensor);
  EXPECT_TRUE(flag_map.range_bearing_sensor->depth_ranges);
  ASSERT_EQ(flag_map.markers.size(), depth_map_read.markers.size());
  for (size_t i = 0; i < flag_map.markers.size(); ++i)
    EXPECT_LT((flag_map.markers[i].T_world_marker.translation() -
               depth_map_read.markers[i].T_world_marker.translation())
                  .norm(),
              1e-6);
  // A build of robot0 alone that the options make refuse: one line, no map written.
  const auto expect_build_refused = [&](const std::string& options, const std::string& message) {
    const fs::path out = dir_ / "m-refused.json";
    const RunResult refused =
        Run("map build " + (dir_ / "robot0").string() + " --out " + out.string() + " " + options);
    EXPECT_EQ(refused.exit_code, 1) << options;
    EXPECT_THAT(refused.err, HasSubstr(message));
    EXPECT_EQ(std::count(refused.err.begin(), refused.err.end(), '\n'), 1) << refused.err;
    EXPECT_FALSE(fs::exists(out));
  };
  expect_build_refused("--range-model size", "--range-model: expected depth or distance, got 'size'");
  expect_build_refused("--range-model distance --depth-ranges",
                       "--depth-ranges means --range-model depth: not with --range-model distance");
  const RunResult localize = localize_robot2("robot2.tum", "");
  ASSERT_EQ(localize.exit_code, 0) << localize.err;
  EXPECT_THAT(localize.out, HasSubstr("ATE RMSE: "));
  EXPECT_THAT(localize.out, HasSubstr("NEES: mean "));
  // The truth's yaw to the odometry (the simulated truth is the odometry's frame: about 0).
  EXPECT_THAT(localize.out, HasSubstr("truth frame: the odometry's direction of travel is "));
  EXPECT_THAT(localize.out, HasSubstr("NEES against the heading as recorded: mean "));
  EXPECT_GT(ReadTum(dir_ / "robot2.tum").size(), 1000u);
  // The variance factor by leaving each robot out: the geometric mean of their factors, in
  // map.json, and localize scales by it; one dataset cannot be left out.
  const RunResult calibrated =
      Run("map build " + (dir_ / "robot0").string() + " " + (dir_ / "robot1").string() + " --out " +
          (dir_ / "map-calibrated.json").string() + " --calibrate-online");
  ASSERT_EQ(calibrated.exit_code, 0) << calibrated.err;
  EXPECT_THAT(calibrated.out, HasSubstr("leave-one-out: robot0 against the map of the others: NEES mean "));
  EXPECT_THAT(calibrated.out, HasSubstr("leave-one-out: robot1 against the map of the others: NEES mean "));
  EXPECT_THAT(calibrated.out, HasSubstr("(geometric mean of the left-out datasets' mean NEES / 3"));
  const MarkerMap calibrated_map = ReadMap(dir_ / "map-calibrated.json");
  ASSERT_TRUE(calibrated_map.range_bearing_sensor);
  ASSERT_TRUE(calibrated_map.range_bearing_sensor->online_variance_factor);
  EXPECT_GT(*calibrated_map.range_bearing_sensor->online_variance_factor, 0.0);
  const RunResult scaled = localize_robot2("robot2-scaled.tum", "", "map-calibrated.json");
  ASSERT_EQ(scaled.exit_code, 0) << scaled.err;
  EXPECT_THAT(scaled.out, HasSubstr("(the map's leave-one-out calibration; the reported covariance scaled)"));
  expect_build_refused("--calibrate-online", "--calibrate-online needs at least two range-bearing datasets");
  // The map's sensor model: one entry per robot, the prior for another robot; the EKF reads it.
  ASSERT_TRUE(map.range_bearing_sensor);
  EXPECT_EQ(map.range_bearing_sensor->datasets.size(), 2u);
  EXPECT_EQ(map.range_bearing_sensor->datasets[0].name, "robot0");
  EXPECT_THAT(localize.out, HasSubstr("sensor prior: the map's (2 robots, range model distance)"));
  const RunResult no_prior = localize_robot2("robot2-no-prior.tum", "--sensor-prior none");
  ASSERT_EQ(no_prior.exit_code, 0) << no_prior.err;
  EXPECT_THAT(no_prior.out, HasSubstr("sensor prior: none"));
  const RunResult depth_map = localize_robot2("robot2-depth-map.tum", "", "map-depth.json");
  ASSERT_EQ(depth_map.exit_code, 0) << depth_map.err;
  EXPECT_THAT(depth_map.out, HasSubstr("range model depth"));
  EXPECT_THAT(depth_map.out, HasSubstr("NEES: mean "));
  expect_refused("--sensor-prior truth", "--sensor-prior: expected map or none, got 'truth'");
  // The map carries each landmark's covariance and its rows of the joint factor.
  ASSERT_TRUE(map.markers.front().position_covariance);
  ASSERT_TRUE(map.markers.front().covariance_factor);
  EXPECT_EQ(map.markers.front().covariance_factor->cols(), 20);
  const RunResult consider = localize_robot2("robot2-consider.tum", "--map-uncertainty consider");
  ASSERT_EQ(consider.exit_code, 0) << consider.err;
  EXPECT_THAT(consider.out, HasSubstr("NEES: mean "));
  expect_refused("--map-uncertainty schmidt",
                 "--map-uncertainty: expected estimate, consider, in-noise or ignore, got 'schmidt'");
  const RunResult live = Run("localize " + (dir_ / "robot2").string() + " --map " +
                             (dir_ / "map.json").string() + " --live --map-uncertainty consider");
  EXPECT_NE(live.exit_code, 0);
  EXPECT_THAT(live.err,
              HasSubstr("--map-uncertainty, --sensor-prior, --depth-share-sigma, "
                        "--calibration-time, --turn-fluctuation, --variance-factor, --update-iterations and "
                        "--relocalization-iterations are for "
                        "range-bearing datasets, not --live"));
  // The reported covariance's variance factor: > 0 only.
  expect_refused("--variance-factor 0", "--variance-factor: expected a number > 0, got 0");
  // The update's Gauss-Newton iterations: 3 while tracking and 1 while lost (the plain EKF) run;
  // 0 is refused.
  const RunResult plain =
      localize_robot2("robot2-plain.tum", "--update-iterations 3 --relocalization-iterations 1");
  ASSERT_EQ(plain.exit_code, 0) << plain.err;
  EXPECT_THAT(plain.out, HasSubstr("NEES: mean "));
  expect_refused("--update-iterations 0", "--update-iterations: expected an integer in 1..100, got 0");
  expect_refused("--relocalization-iterations 101",
                 "--relocalization-iterations: expected an integer in 1..100, got 101");
  // The sensor's depth share estimated by the EKF; a negative sigma refused.
  const RunResult depth = localize_robot2("robot2-depth.tum", "--depth-share-sigma 1");
  ASSERT_EQ(depth.exit_code, 0) << depth.err;
  EXPECT_THAT(depth.out, HasSubstr("NEES: mean "));
  expect_refused("--depth-share-sigma -1", "--depth-share-sigma: expected a number >= 0, got -1");
  // The odometry calibration as a Gauss-Markov state; a negative correlation time refused.
  const RunResult gauss_markov = localize_robot2("robot2-gm.tum", "--calibration-time 5");
  ASSERT_EQ(gauss_markov.exit_code, 0) << gauss_markov.err;
  EXPECT_THAT(gauss_markov.out, HasSubstr("NEES: mean "));
  expect_refused("--calibration-time -1", "--calibration-time: expected a number of seconds >= 0, got -1");
  const RunResult fluctuation = localize_robot2("robot2-f.tum", "--turn-fluctuation 0.08,2.5");
  ASSERT_EQ(fluctuation.exit_code, 0) << fluctuation.err;
  expect_refused("--turn-fluctuation 0.08",
                 "--turn-fluctuation: expected SIGMA,SECONDS (two numbers >= 0), got 0.08");
  // The correlation time by default from the map (range_bearing_sensor calibration_time_s): the
  // same poses, to the byte, as --calibration-time with it on the map without the key;
  // --calibration-time 0 and --sensor-prior none keep the calibration constant, as a map without it.
  MarkerMap timed = ReadMap(dir_ / "map.json");
  ASSERT_TRUE(timed.range_bearing_sensor);
  timed.range_bearing_sensor->calibration_time = RangeBearingSensorModel::CalibrationTime{3.5, 0.05};
  WriteMap(dir_ / "map-timed.json", timed);
  timed.range_bearing_sensor->calibration_time.reset();
  WriteMap(dir_ / "map-untimed.json", timed);
  const auto localize_with = [&](const std::string& map, const std::string& out, const std::string& extra) {
    const RunResult r = Run("localize " + (dir_ / "robot2").string() + " --map " + (dir_ / map).string() +
                            " --out " + (dir_ / out).string() + extra);
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return r.out;
  };
  const auto file = [&](const std::string& name) {
    std::ifstream in(dir_ / name);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  };
  EXPECT_THAT(localize_with("map-timed.json", "t-default.tum", ""),
              HasSubstr("odometry calibration: Gauss-Markov, correlation time 3.5 s (the map's)"));
  EXPECT_THAT(localize_with("map-untimed.json", "u-3.5.tum", " --calibration-time 3.5"),
              HasSubstr("odometry calibration: Gauss-Markov, correlation time 3.5 s (--calibration-time)"));
  EXPECT_EQ(file("t-default.tum"), file("u-3.5.tum"));
  EXPECT_THAT(localize_with("map-untimed.json", "u-default.tum", ""),
              HasSubstr("odometry calibration: constant"));
  EXPECT_THAT(localize_with("map-timed.json", "t-0.tum", " --calibration-time 0"),
              HasSubstr("odometry calibration: constant"));
  EXPECT_EQ(file("t-0.tum"), file("u-default.tum"));
  EXPECT_NE(file("t-default.tum"), file("u-default.tum"));
  EXPECT_THAT(localize_with("map-timed.json", "t-5.tum", " --calibration-time 5"),
              HasSubstr("odometry calibration: Gauss-Markov, correlation time 5 s (--calibration-time)"));
  EXPECT_EQ(file("t-5.tum"), file("robot2-gm.tum"));
  EXPECT_THAT(localize_with("map-timed.json", "t-none.tum", " --sensor-prior none"),
              HasSubstr("odometry calibration: constant"));
  EXPECT_THAT(localize_with("map-timed.json", "t-f.tum", " --turn-fluctuation 0.08,2.5"),
              HasSubstr("odometry calibration: constant"));
  EXPECT_EQ(file("t-f.tum"), file("robot2-f.tum"));
}

TEST_F(RangeBearingCliTest, TwoCorridorSurveysOneMap) {
  for (const int seed : {5, 6}) {
    const RunResult sim =
        Run("sim corridor --out " + (dir_ / ("survey" + std::to_string(seed))).string() + " --seed " +
            std::to_string(seed) +
            " --set place.loop_length_m=4 --set place.loop_width_m=3 --set place.spacing_m=0.5");
    ASSERT_EQ(sim.exit_code, 0) << sim.err;
  }
  const RunResult build =
      Run("map build " + (dir_ / "survey5").string() + " " + (dir_ / "survey6").string() + " --out " +
          (dir_ / "map.json").string() + " --trajectory-dir " + (dir_ / "smoothed").string());
  ASSERT_EQ(build.exit_code, 0) << build.err;
  EXPECT_THAT(build.out, HasSubstr("datasets: 2 built as one survey"));
  EXPECT_TRUE(fs::exists(dir_ / "smoothed" / "survey5.tum")) << build.out;
  EXPECT_TRUE(fs::exists(dir_ / "smoothed" / "survey6.tum")) << build.out;
  const MarkerMap map = ReadMap(dir_ / "map.json");
  const eval::MapEvalResult error =
      eval::EvaluateMap(map, ReadMap(dir_ / "survey5" / "groundtruth/markers.json"));
  EXPECT_EQ(error.components.size(), 1u);
  EXPECT_LE(error.position_rmse_m, 0.01);
  // The smoothed trajectories are back at each survey's own stamps.
  const Trajectory own = ReadTum(dir_ / "survey6" / "groundtruth" / "trajectory.tum");
  const Trajectory smoothed = ReadTum(dir_ / "smoothed" / "survey6.tum");
  EXPECT_GE(smoothed.front().stamp_s, own.front().stamp_s - 1.0);
  EXPECT_LE(smoothed.back().stamp_s, own.back().stamp_s + 1.0);
  const RunResult one_file =
      Run("map build " + (dir_ / "survey5").string() + " " + (dir_ / "survey6").string() + " --out " +
          (dir_ / "m2.json").string() + " --trajectory " + (dir_ / "t.tum").string());
  EXPECT_EQ(one_file.exit_code, 1);
  EXPECT_THAT(one_file.err, HasSubstr("--trajectory is for one dataset"));
  const RunResult depth =
      Run("map build " + (dir_ / "survey5").string() + " " + (dir_ / "survey6").string() + " --out " +
          (dir_ / "m3.json").string() + " --trajectory-dir " + (dir_ / "s3").string() + " --depth-ranges");
  EXPECT_EQ(depth.exit_code, 1);
  EXPECT_THAT(depth.err, HasSubstr("--range-model and --depth-ranges are for range-bearing datasets"));
  EXPECT_FALSE(fs::exists(dir_ / "m3.json"));
  const RunResult camera =
      Run("localize " + (dir_ / "survey5").string() + " --map " + (dir_ / "map.json").string() + " --out " +
          (dir_ / "run.tum").string() + " --map-uncertainty consider");
  EXPECT_NE(camera.exit_code, 0);
  EXPECT_THAT(camera.err,
              HasSubstr("--map-uncertainty, --sensor-prior, --depth-share-sigma, "
                        "--calibration-time, --turn-fluctuation, --variance-factor, --update-iterations and "
                        "--relocalization-iterations are for "
                        "range-bearing datasets (range_bearing.jsonl)"));
}

}  // namespace
}  // namespace waymark
