#include "io/tum_io.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <random>
#include <string>

#include "io/util.h"

namespace waymark {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

// The FormatError message of parsing `text` as "traj.tum" (fails the test if it parses).
std::string ParseError(const std::string& text) {
  try {
    ParseTum(text, "traj.tum");
  } catch (const FormatError& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected a FormatError for:\n" << text;
  return "";
}

TEST(TumIoTest, ParsesCommentsBlankLinesTabsAndNormalizes) {
  const Trajectory trajectory = ParseTum(
      "# header\n\n  # indented comment\n1.5 1 2 3 0 0 0 1\n2.5\t-1 0.5 0 0 0 0.7072 0.7072\r\n", "traj.tum");
  ASSERT_EQ(trajectory.size(), 2u);
  EXPECT_EQ(trajectory[0].stamp_s, 1.5);
  EXPECT_EQ(trajectory[0].T.translation(), Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(trajectory[1].stamp_s, 2.5);
  EXPECT_NEAR(trajectory[1].T.rotation().norm(), 1.0, 1e-15);
  EXPECT_NEAR(trajectory[1].T.yaw(), M_PI / 2, 1e-12);
}

TEST(TumIoTest, MalformedInputNamesFileAndLine) {
  EXPECT_THAT(ParseError("# c\n1 0 0 0 0 0 0 1\n2 0 0 0 0 0 1\n"),
              HasSubstr("traj.tum:3: expected 8 numbers 't tx ty tz qx qy qz qw', got 7 fields"));
  EXPECT_THAT(ParseError("1 0 0 0 0 0 0 1 9\n"), HasSubstr("traj.tum:1: expected 8 numbers"));
  EXPECT_THAT(ParseError("1 0 0 nan 0 0 0 1\n"),
              HasSubstr("traj.tum:1: tz: expected a finite number, got 'nan'"));
  EXPECT_THAT(ParseError("1 0 0 0 0 0 0 inf\n"), HasSubstr("traj.tum:1: qw: expected a finite number"));
  EXPECT_THAT(ParseError("1 0 0 0x 0 0 0 1\n"),
              HasSubstr("traj.tum:1: tz: expected a finite number, got '0x'"));
  EXPECT_THAT(ParseError("1 0 0 0 0 0 0 1.01\n"),
              HasSubstr("traj.tum:1: q_xyzw: expected unit norm within 0.001, got 1.01"));
  EXPECT_THAT(ParseError("1 0 0 0 0 0 0 0\n"), HasSubstr("traj.tum:1: q_xyzw: expected unit norm"));
  EXPECT_THAT(ParseError("2 0 0 0 0 0 0 1\n\n2 0 0 0 0 0 0 1\n"),
              HasSubstr("traj.tum:3: t: expected stamps strictly increasing, got 2 after 2"));
  EXPECT_THAT(ParseError("2 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n"),
              HasSubstr("traj.tum:2: t: expected stamps strictly"));
}

TEST(TumIoTest, MissingFileIsNamed) {
  try {
    ReadTum("/nonexistent/dir/odometry.tum");
    FAIL() << "expected FormatError";
  } catch (const FormatError& e) {
    EXPECT_THAT(e.what(), HasSubstr("/nonexistent/dir/odometry.tum: cannot open"));
  }
}

TEST(TumIoTest, RoundTripIsExact) {
  std::mt19937 rng(7);
  std::normal_distribution<double> normal(0.0, 10.0);
  Trajectory trajectory;
  double stamp_s = 1560889276.31902;
  for (int i = 0; i < 200; ++i) {
    stamp_s += 0.001 + std::abs(normal(rng)) * 0.01;
    const Eigen::Quaterniond q(normal(rng), normal(rng), normal(rng), normal(rng));
    trajectory.push_back({stamp_s, SE3d(q, Eigen::Vector3d(normal(rng), normal(rng), normal(rng)))});
  }
  const fs::path path =
      fs::temp_directory_path() / ("waymark_tum_io_test_" + std::to_string(::getpid())) / "t.tum";
  WriteTum(path, trajectory, "written by tum_io_test\nsecond line");
  const Trajectory read = ReadTum(path);
  ASSERT_EQ(read.size(), trajectory.size());
  for (size_t i = 0; i < read.size(); ++i) {
    EXPECT_EQ(read[i].stamp_s, trajectory[i].stamp_s);
    EXPECT_EQ(read[i].T.translation(), trajectory[i].T.translation());
    EXPECT_EQ(read[i].T.rotation().coeffs(), trajectory[i].T.rotation().coeffs()) << i;
  }
  EXPECT_EQ(FormatTum(read), FormatTum(trajectory));
  EXPECT_THAT(ReadTextFile(path), HasSubstr("# written by tum_io_test\n# second line\n"));
  fs::remove_all(path.parent_path());
}

TEST(TumIoTest, WriterRejectsWhatTheReaderWould) {
  Trajectory trajectory = {{1.0, SE3d()}, {1.0, SE3d()}};
  EXPECT_THROW(FormatTum(trajectory), std::invalid_argument);
  trajectory[1].stamp_s = std::nan("");
  EXPECT_THROW(FormatTum(trajectory), std::invalid_argument);
}

}  // namespace
}  // namespace waymark
