// io/mrclam_io.h on a tiny hand-written run (two robots, two landmarks): the integrated
// odometry, grouped measurements, misreads and the robot's own barcode counted, robot
// sightings kept, the start prior; one expected one-line error per malformed file; and the
// real run 6 when the shared data is present.
#include "io/mrclam_io.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include "io/util.h"

namespace waymark {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

class MrclamTinyRun : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("waymark_mrclam_" + std::to_string(getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    Write("Barcodes.dat", "# Subject # Barcode #\r\n  1 \t 5 \r\n  2 \t 14 \r\n  6 \t 72\r\n  7 \t 27\r\n");
    Write("Landmark_Groundtruth.dat", "# header\n6 1.0 2.0 0.0001 0.0002\n7 -1.0 0.5 0.0001 0.0001\n");
    // Robot 1 drives 1 m/s along x for 2 s, robot 2 turns in place.
    Write("Robot1_Odometry.dat", "# t v w\n100.0 1.0 0.0\n101.0 1.0 0.0\n102.0 0.0 0.0\n");
    Write("Robot2_Odometry.dat", "100.0 0.0 0.5\n102.0 0.0 0.0\n");
    Write(
        "Robot1_Measurement.dat",
        "# t barcode range bearing\n99.0 72 1.0 0.0\n100.5 72 2.0 0.1\n100.5 14 3.0 -0.2\n100.5 99 4.0 0.0\n"
        "101.0 5 1.0 0.0\n101.5 27 2.5 1.0\n");
    Write("Robot2_Measurement.dat", "101.0 27 2.0 0.5\n");
    Write("Robot1_Groundtruth.dat",
          "99.0 0.0 0.0 0.1\n100.0 1.0 0.0 0.1\n101.0 2.0 0.0 0.1\n102.0 3.0 0.0 0.1\n103.0 4.0 0.0 0.1\n");
    Write("Robot2_Groundtruth.dat",
          "99.0 5.0 5.0 0.0\n100.0 5.0 5.0 0.5\n101.0 5.0 5.0 1.0\n102.0 5.0 5.0 1.5\n103.0 5.0 5.0 2.0\n");
  }
  void TearDown() override { fs::remove_all(dir_); }
  void Write(const std::string& name, const std::string& text) { std::ofstream(dir_ / name) << text; }
  std::string Error() {
    try {
      ImportMrclam(dir_, MrclamImportOptions{});
    } catch (const FormatError& e) {
      return e.what();
    }
    return "no error";
  }
  fs::path dir_;
};

TEST_F(MrclamTinyRun, ImportsEveryPart) {
  MrclamImportOptions options;
  options.known_start = true;
  const MrclamImport run = ImportMrclam(dir_, options);
  ASSERT_EQ(run.robots.size(), 2u);
  const Dataset& robot1 = run.robots[0];
  EXPECT_EQ(robot1.config.name, "robot1");
  ASSERT_EQ(robot1.odometry.size(), 3u);
  EXPECT_NEAR(robot1.odometry[2].T.translation().x(), 2.0, 1e-12);
  ASSERT_EQ(robot1.range_bearing.size(), 2u);  // 100.5 and 101.5; 99.0 is before the odometry
  EXPECT_EQ(robot1.range_bearing[0].landmarks.size(), 1u);
  EXPECT_EQ(robot1.range_bearing[0].landmarks[0].key, (MarkerKey{kFamilyBarcode, "72"}));
  ASSERT_EQ(robot1.range_bearing[0].robots.size(), 1u);
  EXPECT_EQ(robot1.range_bearing[0].robots[0].robot, "robot2");
  const MrclamRobotReport& report = run.reports[0];
  EXPECT_EQ(report.misreads, 1u);
  EXPECT_EQ(report.misread_barcodes.at("99"), 1u);
  EXPECT_EQ(report.own_barcode, 1u);
  EXPECT_EQ(report.outside_odometry, 1u);
  EXPECT_EQ(report.landmark_observations, 2u);
  ASSERT_TRUE(robot1.config.start_prior);
  EXPECT_NEAR(robot1.config.start_prior->T_world_robot.translation().x(), 1.0,
              1e-12);  // interpolated at t=100
  ASSERT_TRUE(robot1.groundtruth_markers);
  EXPECT_EQ(robot1.groundtruth_markers->markers.size(), 2u);
  EXPECT_TRUE(robot1.groundtruth_markers->markers[0].is_point);
  EXPECT_NEAR(SE2d::FromSE3(run.robots[1].odometry.back().T).theta(), 1.0, 1e-12);
  EXPECT_FALSE(ImportMrclam(dir_, MrclamImportOptions{}).robots[0].config.start_prior);
}

TEST_F(MrclamTinyRun, MalformedFilesAreOneLineErrors) {
  Write("Robot2_Odometry.dat", "100.0 0.0 0.5\n101.0 0.0\n");
  EXPECT_EQ(Error(), (dir_ / "Robot2_Odometry.dat").string() + ":2: expected 3 numbers (time v w), got 2");
  Write("Robot2_Odometry.dat", "100.0 0.0 0.5\n99.0 0.0 0.0\n");
  EXPECT_THAT(Error(), HasSubstr("Robot2_Odometry.dat:2: time: expected non-decreasing stamps"));
  Write("Robot2_Odometry.dat", "100.0 0.0 nan\n");
  EXPECT_THAT(Error(), HasSubstr("Robot2_Odometry.dat:1: expected 3 numbers (time v w), got 'nan'"));
  Write("Robot2_Odometry.dat", "100.0 0.0 0.5\n102.0 0.0 0.0\n");
  Write("Robot2_Measurement.dat", "101.0 27.5 2.0 0.5\n");
  EXPECT_THAT(Error(), HasSubstr("Robot2_Measurement.dat:1: barcode: expected an integer, got 27.5"));
  Write("Robot2_Measurement.dat", "101.0 27 -2.0 0.5\n");
  EXPECT_THAT(Error(), HasSubstr("Robot2_Measurement.dat:1: range: expected a positive range"));
  Write("Robot2_Measurement.dat", "101.0 27 2.0 0.5\n");
  Write("Barcodes.dat", "1 5\n2 5\n");
  EXPECT_THAT(Error(), HasSubstr("Barcodes.dat:2: barcode 5 listed twice"));
  Write("Barcodes.dat", "1 5\n2 14\n6 72\n7 27\n");
  fs::remove(dir_ / "Robot2_Groundtruth.dat");
  EXPECT_THAT(Error(), HasSubstr("Robot2_Groundtruth.dat: missing file"));
  Write("Robot2_Groundtruth.dat", "99.0 5.0 5.0 0.0\n");
  Write("Landmark_Groundtruth.dat", "1 1.0 2.0 0.1 0.1\n");
  EXPECT_THAT(Error(), HasSubstr("Landmark_Groundtruth.dat:1: subject 1 is not a landmark of Barcodes.dat"));
}

TEST(MrclamRun6, ImportsTheSharedRun) {
  const fs::path run = fs::path(WAYMARK_SHARED_DATA) / "mrclam" / "MRCLAM_Dataset6";
  if (!fs::is_directory(run)) GTEST_SKIP() << "shared data mrclam/MRCLAM_Dataset6 absent: " << run;
  const MrclamImport import = ImportMrclam(run, MrclamImportOptions{});
  ASSERT_EQ(import.robots.size(), 5u);
  size_t misreads = 0;
  for (size_t i = 0; i < 5; ++i) {
    EXPECT_GT(import.reports[i].landmark_observations, 1000u) << import.reports[i].name;
    EXPECT_GT(import.robots[i].odometry.size(), 50000u);
    misreads += import.reports[i].misreads;
  }
  EXPECT_GT(misreads, 0u);  // the README: a few barcodes exist in no list
  EXPECT_EQ(import.robots[0].groundtruth_markers->markers.size(), 15u);
}

}  // namespace
}  // namespace waymark
