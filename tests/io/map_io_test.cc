#include "io/map_io.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <ctime>
#include <filesystem>
#include <random>
#include <string>

#include "io/util.h"

namespace waymark {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

const char* const kGoodMap = R"({"format": "waymark-map", "version": 1,
 "markers": [
  {"family": "datamatrix", "id": "A01", "size_m": 0.08,
   "T_world_marker": {"t": [1, 2, 3], "q_xyzw": [0, 0, 0, 1]},
   "fixed": true, "component": 2},
  {"family": "apriltag-36h11", "id": "7", "size_m": 0.16,
   "T_world_marker": {"t": [0, 0, 1.5],
                      "q_xyzw": [0.0, 0.70710808, 0.0, -0.707105483]}}
 ]}
)";

// Replaces the first occurrence of `from` in kGoodMap.
std::string GoodMapWith(const std::string& from, const std::string& to) {
  std::string text = kGoodMap;
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return text.replace(at, from.size(), to);
}

std::string ParseError(const std::string& text) {
  try {
    ParseMap(text, "map.json");
  } catch (const FormatError& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected a FormatError for:\n" << text;
  return "";
}

TEST(MapIoTest, ParsesGoodMap) {
  ReadWarnings warnings;
  const MarkerMap map = ParseMap(kGoodMap, "map.json", &warnings);
  ASSERT_EQ(map.markers.size(), 2u);
  EXPECT_EQ(map.markers[0].key, (MarkerKey{"datamatrix", "A01"}));
  EXPECT_EQ(map.markers[0].size_m, 0.08);
  EXPECT_TRUE(map.markers[0].fixed);
  EXPECT_EQ(map.markers[0].component, 2);
  EXPECT_EQ(map.markers[0].T_world_marker.translation(), Eigen::Vector3d(1, 2, 3));
  EXPECT_FALSE(map.markers[1].fixed);
  EXPECT_FALSE(map.markers[1].component.has_value());
  EXPECT_FALSE(map.markers[1].covariance.has_value());
  EXPECT_NEAR(map.markers[1].T_world_marker.rotation().norm(), 1.0, 1e-15);
  EXPECT_EQ(warnings.Total(), 0);
}

TEST(MapIoTest, ErrorsNameFileLineAndField) {
  EXPECT_THAT(ParseError(GoodMapWith("[0, 0, 0, 1]", "[0, 0, 1]")),
              HasSubstr("map.json:4: markers[0].T_world_marker.q_xyzw: expected 4 numbers, got 3"));
  EXPECT_THAT(ParseError(GoodMapWith("-0.707105483", "-0.5")),
              HasSubstr("map.json:8: markers[1].T_world_marker.q_xyzw: expected unit norm within 0.001"));
  EXPECT_THAT(ParseError(GoodMapWith("\"datamatrix\"", "\"aztec\"")),
              HasSubstr("map.json:3: markers[0].family: unknown family \"aztec\""));
  EXPECT_THAT(ParseError(GoodMapWith("\"size_m\": 0.16", "\"size_m\": \"big\"")),
              HasSubstr("map.json:6: markers[1].size_m: expected a number, got a string"));
  EXPECT_THAT(ParseError(GoodMapWith("\"size_m\": 0.16", "\"size_m\": -1")),
              HasSubstr("map.json:6: markers[1].size_m: expected a positive size"));
  EXPECT_THAT(ParseError(GoodMapWith("\"t\": [1, 2, 3]", "\"t\": [1, 2, 1e999]")),
              HasSubstr("map.json:4: invalid JSON: number overflow parsing '1e999'"));
  EXPECT_THAT(ParseError(GoodMapWith("\"id\": \"7\"", "\"id\": 7")),
              HasSubstr("map.json:6: markers[1].id: expected a string, got a number"));
  EXPECT_THAT(ParseError(GoodMapWith("\"fixed\": true", "\"fixed\": 1")),
              HasSubstr("map.json:5: markers[0].fixed: expected true or false"));
  EXPECT_THAT(ParseError(GoodMapWith("\"component\": 2", "\"component\": 1.5")),
              HasSubstr("map.json:5: markers[0].component: expected an integer, got 1.5"));
  EXPECT_THAT(ParseError(GoodMapWith("\"fixed\": true,", "\"covariance\": [1, 2],")),
              HasSubstr("map.json:5: markers[0].covariance: expected 36 numbers, got 2"));
  EXPECT_THAT(ParseError(GoodMapWith("\"id\": \"7\"", "\"id\": \"A01\", \"family\": \"datamatrix\"")),
              HasSubstr("markers[1]: duplicate marker datamatrix:A01"));
  EXPECT_THAT(ParseError(GoodMapWith("\"size_m\": 0.08,", "")),
              HasSubstr("map.json:3: markers[0]: missing key \"size_m\""));
}

TEST(MapIoTest, HeaderAndSyntaxErrors) {
  EXPECT_THAT(ParseError(GoodMapWith("waymark-map", "other")),
              HasSubstr("map.json:1: format: expected \"waymark-map\""));
  EXPECT_THAT(ParseError(GoodMapWith("\"version\": 1", "\"version\": 2")),
              HasSubstr("map.json:1: version: expected 1, got 2"));
  EXPECT_THAT(ParseError(GoodMapWith("\"version\": 1", "\"version\": \"1\"")),
              HasSubstr("version: expected an integer"));
  EXPECT_THAT(ParseError(GoodMapWith("\"fixed\": true,", "\"fixed\": true")),
              HasSubstr("map.json:5: invalid JSON"));
  EXPECT_THAT(ParseError(GoodMapWith("0.08", "NaN")), HasSubstr("map.json:3: invalid JSON"));
  EXPECT_THAT(ParseError("[]"), HasSubstr("map.json:1: expected an object, got an array"));
  EXPECT_THAT(ParseError(""), HasSubstr("map.json:1: invalid JSON"));
}

// Issue 18: a 20 000-marker map did not load in 60 s (the line of every value was counted
// from the start of the file). Now 100 000 markers load in well under a second, and an error
// in the last one still names its line.
TEST(MapIoTest, LargeMapsLoadInLinearTime) {
  const int n = 100000;
  std::string text = "{\"format\": \"waymark-map\", \"version\": 1,\n \"markers\": [";
  for (int i = 0; i < n; ++i) {
    text += std::string(i ? "," : "") + "\n  {\"family\":\"qr\",\"id\":\"M" + std::to_string(i) +
            "\",\"size_m\":0.1,\"T_world_marker\":{\"t\":[" + std::to_string(i) +
            ",0,1],\"q_xyzw\":[0,0,0,1]},\"fixed\":true}";
  }
  text += "\n ]}\n";
  // Processor time, not wall time: the machine may be shared.
  const std::clock_t start = std::clock();
  const MarkerMap map = ParseMap(text, "big.json");
  const double seconds = static_cast<double>(std::clock() - start) / CLOCKS_PER_SEC;
  EXPECT_EQ(map.markers.size(), static_cast<size_t>(n));
  EXPECT_LT(seconds, 5.0);  // quadratic: hours; linear: about 0.5 s in Release
  const size_t last = text.rfind("\"size_m\":0.1");
  text.replace(last, 12, "\"size_m\":-1");
  EXPECT_THAT(ParseError(text), HasSubstr("map.json:" + std::to_string(n + 2) + ": markers[99999].size_m:"));
}

// Issue 18, finding 8: size_m 9223372036854775808 and positions of 1e308 were accepted.
TEST(MapIoTest, PhysicallyMeaninglessValuesAreErrors) {
  EXPECT_THAT(ParseError(GoodMapWith("0.08", "9223372036854775808")),
              HasSubstr("map.json:3: markers[0].size_m: expected a size between 1e-04 and 100 m, got "
                        "9223372036854775808"));
  EXPECT_THAT(
      ParseError(GoodMapWith("[1, 2, 3]", "[1, 2, 1e308]")),
      HasSubstr(
          "map.json:4: markers[0].T_world_marker.t: expected coordinates within +-1e+07 m, got 1e+308"));
  MarkerMap map = ParseMap(kGoodMap, "map.json");
  map.markers[0].size_m = 1e6;
  EXPECT_THROW(FormatMap(map), std::invalid_argument);
}

const char* const kSquareMap = R"({"format": "waymark-map", "version": 1,
 "markers": [
  {"family": "square", "id": "A", "size_m": 2.0,
   "T_world_marker": {"t": [0, 0, 2.3], "q_xyzw": [1, 0, 0, 0]},
   "square": {"tape_width_m": 0.04, "solid_side": "left", "dash_m": 0.15, "gap_m": 0.05}},
  {"family": "square", "id": "B", "size_m": 1.5,
   "T_world_marker": {"t": [4, 0, 2.3], "q_xyzw": [1, 0, 0, 0]}}
 ]}
)";

std::string SquareMapWith(const std::string& from, const std::string& to) {
  std::string text = kSquareMap;
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return text.replace(at, from.size(), to);
}

TEST(MapIoTest, SquareTapeRoundTrip) {
  const MarkerMap map = ParseMap(kSquareMap, "map.json");
  ASSERT_EQ(map.markers.size(), 2u);
  ASSERT_TRUE(map.markers[0].square_tape.has_value());
  EXPECT_EQ(map.markers[0].square_tape->tape_width_m, 0.04);
  EXPECT_EQ(map.markers[0].square_tape->solid_side, SquareSide::kLeft);
  EXPECT_EQ(map.markers[0].square_tape->dash_m, 0.15);
  EXPECT_EQ(map.markers[0].square_tape->gap_m, 0.05);
  EXPECT_FALSE(map.markers[1].square_tape.has_value());  // the defaults
  const MarkerMap again = ParseMap(FormatMap(map), "again.json");
  ASSERT_TRUE(again.markers[0].square_tape.has_value());
  EXPECT_EQ(again.markers[0].square_tape->solid_side, SquareSide::kLeft);
  EXPECT_EQ(again.markers[0].square_tape->gap_m, 0.05);
  EXPECT_FALSE(again.markers[1].square_tape.has_value());
}

TEST(MapIoTest, SquareTapeErrors) {
  EXPECT_THAT(
      ParseError(SquareMapWith("\"left\"", "\"up\"")),
      HasSubstr("map.json:5: markers[0].square.solid_side: expected top, right, bottom or left, got \"up\""));
  EXPECT_THAT(ParseError(SquareMapWith("\"tape_width_m\": 0.04", "\"tape_width_m\": 0.9")),
              HasSubstr("map.json:5: markers[0].square: tape_width_m: expected > 0 and <= side / 4"));
  EXPECT_THAT(ParseError(SquareMapWith("\"dash_m\": 0.15", "\"dash_m\": \"long\"")),
              HasSubstr("map.json:5: markers[0].square.dash_m: expected a number"));
  EXPECT_THAT(ParseError(SquareMapWith("\"square\": {", "\"square\": 3, \"x\": {")),
              HasSubstr("markers[0].square: expected an object"));
  EXPECT_THAT(
      ParseError(SquareMapWith("\"family\": \"square\", \"id\": \"A\"", "\"family\": \"qr\", \"id\": \"A\"")),
      HasSubstr("markers[0].square: only a marker of family square has a tape"));
  EXPECT_THAT(ParseError(SquareMapWith("\"size_m\": 1.5", "\"size_m\": 0.1")),
              HasSubstr("map.json:6: markers[1].size_m: too small for the default tape"));
}

TEST(MapIoTest, UnknownKeysAreCountedWarnings) {
  ReadWarnings warnings;
  const MarkerMap map = ParseMap(
      GoodMapWith("\"fixed\": true", "\"fixed\": true, \"colour\": \"red\"").replace(1, 0, "\"note\": 1, "),
      "map.json", &warnings);
  EXPECT_EQ(map.markers.size(), 2u);
  EXPECT_EQ(warnings.counts["unknown key"], 2);
  ASSERT_EQ(warnings.first_messages.size(), 2u);
  EXPECT_THAT(warnings.first_messages[0] + warnings.first_messages[1],
              HasSubstr("map.json:5: unknown key \"markers[0].colour\""));
}

TEST(MapIoTest, MissingFileIsNamed) {
  EXPECT_THROW(
      {
        try {
          ReadMap("/nonexistent/markers.json");
        } catch (const FormatError& e) {
          EXPECT_THAT(e.what(), HasSubstr("/nonexistent/markers.json: cannot open"));
          throw;
        }
      },
      FormatError);
}

TEST(MapIoTest, RoundTripIsExact) {
  std::mt19937 rng(11);
  std::normal_distribution<double> normal(0.0, 3.0);
  MarkerMap map;
  for (int i = 0; i < 50; ++i) {
    MapMarker marker;
    marker.key = {i % 2 ? "qr" : "apriltag-36h11", "id \"" + std::to_string(i) + "\"\\/é"};
    marker.size_m = 0.05 + std::abs(normal(rng));
    marker.T_world_marker = SE3d(Eigen::Quaterniond(normal(rng), normal(rng), normal(rng), normal(rng)),
                                 Eigen::Vector3d(normal(rng), normal(rng), normal(rng)));
    if (i % 3 == 0) {
      Matrix6d A = Matrix6d::Random();
      marker.covariance = A * A.transpose() * 1e-3;
    }
    marker.fixed = i % 5 == 0;
    if (i % 4 == 0) marker.component = i / 4;
    map.markers.push_back(marker);
  }
  const fs::path path =
      fs::temp_directory_path() / ("waymark_map_io_test_" + std::to_string(::getpid())) / "map.json";
  WriteMap(path, map);
  ReadWarnings warnings;
  const MarkerMap read = ReadMap(path, &warnings);
  EXPECT_EQ(warnings.Total(), 0);
  ASSERT_EQ(read.markers.size(), map.markers.size());
  for (size_t i = 0; i < read.markers.size(); ++i) {
    const MapMarker& a = map.markers[i];
    const MapMarker& b = read.markers[i];
    EXPECT_EQ(a.key, b.key);
    EXPECT_EQ(a.size_m, b.size_m);
    EXPECT_EQ(a.T_world_marker.translation(), b.T_world_marker.translation());
    EXPECT_EQ(a.T_world_marker.rotation().coeffs(), b.T_world_marker.rotation().coeffs());
    ASSERT_EQ(a.covariance.has_value(), b.covariance.has_value());
    if (a.covariance) {
      EXPECT_EQ(*a.covariance, *b.covariance);
    }
    EXPECT_EQ(a.fixed, b.fixed);
    EXPECT_EQ(a.component, b.component);
  }
  EXPECT_EQ(FormatMap(read), FormatMap(map));
  fs::remove_all(path.parent_path());

  map.markers.push_back(map.markers[0]);
  EXPECT_THROW(FormatMap(map), std::invalid_argument);  // duplicate key
}

// covariance_factor: 6 x k row-major, the same k for every marker, within the covariance.
TEST(MapIoTest, CovarianceFactorRoundTripAndErrors) {
  MarkerMap map;
  for (int i = 0; i < 3; ++i) {
    MapMarker marker;
    marker.key = {"qr", "F" + std::to_string(i)};
    marker.size_m = 0.1;
    CovarianceFactor F = CovarianceFactor::Random(6, 2) * 1e-2;
    const Matrix6d B = Matrix6d::Random() * 1e-2;
    marker.covariance = F * F.transpose() + B * B.transpose();
    if (i != 1) marker.covariance_factor = F;  // markers without one are allowed
    map.markers.push_back(marker);
  }
  const MarkerMap read = ParseMap(FormatMap(map), "map.json");
  ASSERT_EQ(read.markers.size(), 3u);
  ASSERT_TRUE(read.markers[0].covariance_factor.has_value());
  EXPECT_EQ(*read.markers[0].covariance_factor, *map.markers[0].covariance_factor);
  EXPECT_EQ(read.markers[0].covariance_factor->cols(), 2);
  EXPECT_FALSE(read.markers[1].covariance_factor.has_value());
  EXPECT_EQ(FormatMap(read), FormatMap(map));

  const std::string covariance =
      "\"covariance\": [1e-4, 0, 0, 0, 0, 0, 0, 1e-4, 0, 0, 0, 0, 0, 0, 1e-4, 0, 0, 0, 0, 0, 0, 1e-4, 0, 0, "
      "0, 0, 0, 0, 1e-4, 0, 0, 0, 0, 0, 0, 1e-4], ";
  const std::string factor_k1 = "\"covariance_factor\": [0.005, 0, 0, 0, 0, 0.001], ";
  EXPECT_NO_THROW(
      ParseMap(GoodMapWith("\"fixed\": true,", covariance + factor_k1 + "\"fixed\": false,"), "m"));
  EXPECT_THAT(ParseError(GoodMapWith("\"fixed\": true,",
                                     covariance + "\"covariance_factor\": [1, 2, 3], \"fixed\": false,")),
              HasSubstr("markers[0].covariance_factor: expected a non-empty array of 6 k numbers"));
  EXPECT_THAT(ParseError(GoodMapWith("\"fixed\": true,", factor_k1 + "\"fixed\": false,")),
              HasSubstr("markers[0].covariance_factor: expected a covariance with the covariance_factor"));
  EXPECT_THAT(
      ParseError(GoodMapWith("\"fixed\": true,",
                             covariance + "\"covariance_factor\": [0.02, 0, 0, 0, 0, 0], \"fixed\": false,")),
      HasSubstr("markers[0].covariance_factor: expected covariance - F F^T positive semi-definite"));
  std::string two = GoodMapWith("\"fixed\": true,", covariance + factor_k1 + "\"fixed\": false,");
  two.replace(
      two.find("\"size_m\": 0.16"), 14,
      "\"size_m\": 0.16, " + covariance + "\"covariance_factor\": [0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]");
  EXPECT_THAT(ParseError(two),
              HasSubstr("markers[1].covariance_factor: expected 6 x 1 like the markers before, got 6 x 2"));

  map.markers[1].covariance_factor = CovarianceFactor(6, 0);
  EXPECT_THROW(FormatMap(map), std::invalid_argument);
  map.markers[1].covariance_factor.reset();
  map.markers[0].covariance.reset();
  EXPECT_THROW(FormatMap(map), std::invalid_argument);
}

TEST(MapIoTest, ReadsTagslamMaps) {
  const fs::path root = fs::path(WAYMARK_SHARED_DATA) / "tagslam";
  if (!fs::exists(root)) GTEST_SKIP() << "shared data absent: " << root << " (tagslam maps not checked)";
  for (const char* set : {"tagslam-test16", "tagslam-test17", "tagslam-test22"}) {
    ReadWarnings warnings;
    const MarkerMap known = ReadMap(root / set / "markers.json", &warnings);
    ASSERT_EQ(known.markers.size(), 1u) << set;
    EXPECT_TRUE(known.markers[0].fixed);
    EXPECT_EQ(known.markers[0].key.family, "apriltag-36h11");
    EXPECT_FALSE(ReadMap(root / set / "reference" / "markers.json", &warnings).markers.empty());
    EXPECT_EQ(warnings.Total(), 0) << set;
  }
}

}  // namespace
}  // namespace waymark

namespace waymark {
namespace {

// A dataset's known markers may give a code's size without its pose (MapPoses::kOptional);
// every other map needs the pose, and a fixed or covariance-carrying entry always does.
TEST(MapIoTest, SizeOnlyEntriesOnlyWhereAllowed) {
  const std::string text = R"({"format": "waymark-map", "version": 1, "markers": [
  {"family": "qr", "id": "load-7", "size_m": 0.05},
  {"family": "qr", "id": "0/1/2", "size_m": 0.15, "T_world_marker": {"t": [1, 2, 0], "q_xyzw": [0, 0, 0, 1]},
   "fixed": true}]}
)";
  const MarkerMap known = ParseMap(text, "markers.json", nullptr, MapPoses::kOptional);
  ASSERT_EQ(known.markers.size(), 2u);
  EXPECT_FALSE(known.markers[0].has_pose);
  EXPECT_DOUBLE_EQ(known.markers[0].size_m, 0.05);
  EXPECT_TRUE(known.markers[1].has_pose);
  // Round trip keeps the entry size-only.
  const MarkerMap again = ParseMap(FormatMap(known), "again.json", nullptr, MapPoses::kOptional);
  EXPECT_FALSE(again.markers[0].has_pose);
  EXPECT_EQ(FormatMap(again), FormatMap(known));

  try {
    ParseMap(text, "map.json");
    FAIL() << "a size-only entry must be refused where poses are required";
  } catch (const FormatError& e) {
    EXPECT_THAT(e.what(), HasSubstr("map.json:2"));
    EXPECT_THAT(e.what(), HasSubstr("T_world_marker"));
  }
  const std::string fixed_without_pose = R"({"format": "waymark-map", "version": 1, "markers": [
  {"family": "qr", "id": "a", "size_m": 0.05, "fixed": true}]}
)";
  try {
    ParseMap(fixed_without_pose, "markers.json", nullptr, MapPoses::kOptional);
    FAIL() << "a fixed marker needs a pose";
  } catch (const FormatError& e) {
    EXPECT_THAT(e.what(), HasSubstr("markers.json:2"));
    EXPECT_THAT(e.what(), HasSubstr("expected a pose"));
  }
}

TEST(MapIoTest, RangeBearingNoiseRoundTripWithOptionalOdometryDelay) {
  const std::string noise =
      R"("range_bearing_noise": {"range_a_m": 0.02, "range_b": 0.03, "bearing_rad": 0.005, )"
      R"("odometry_q_t": 0.001, "odometry_q_r": 0.004, "odometry_c_d": 0.1)";
  const MarkerMap without = ParseMap(GoodMapWith("\"markers\"", noise + "},\n \"markers\""), "map.json");
  ASSERT_TRUE(without.range_bearing_noise);
  EXPECT_EQ(without.range_bearing_noise->odometry_delay_s, 0.0);  // absent: 0
  EXPECT_EQ(FormatMap(without).find("odometry_delay_s"), std::string::npos);
  const MarkerMap with = ParseMap(
      GoodMapWith("\"markers\"", noise + ", \"odometry_delay_s\": 0.25},\n \"markers\""), "map.json");
  ASSERT_TRUE(with.range_bearing_noise);
  EXPECT_EQ(with.range_bearing_noise->odometry_delay_s, 0.25);
  const MarkerMap again = ParseMap(FormatMap(with), "again.json");
  EXPECT_EQ(again.range_bearing_noise->odometry_delay_s, 0.25);
  EXPECT_EQ(again.range_bearing_noise->odometry_q_r, 0.004);
  EXPECT_EQ(again.range_bearing_noise->range_scale_sigma, 0.0);  // absent: 0, not written
  EXPECT_EQ(FormatMap(again).find("range_scale"), std::string::npos);
  const MarkerMap scaled = ParseMap(
      GoodMapWith("\"markers\"",
                  noise + R"(, "range_scale_sigma": 0.03, "range_scale_time_s": 1.5},)" + "\n \"markers\""),
      "map.json");
  const MarkerMap scaled_again = ParseMap(FormatMap(scaled), "again.json");
  EXPECT_EQ(scaled_again.range_bearing_noise->range_scale_sigma, 0.03);
  EXPECT_EQ(scaled_again.range_bearing_noise->range_scale_time_s, 1.5);
  EXPECT_THAT(
      ParseError(GoodMapWith("\"markers\"", noise + R"(, "range_scale_sigma": 1.5},)" + "\n \"markers\"")),
      HasSubstr("range_bearing_noise.range_scale_sigma: expected a number in [0, 1), got 1.5"));
  EXPECT_THAT(
      ParseError(GoodMapWith("\"markers\"", noise + R"(, "range_scale_time_s": 0},)" + "\n \"markers\"")),
      HasSubstr("range_bearing_noise.range_scale_time_s: expected a positive number, got 0"));
  EXPECT_THAT(
      ParseError(GoodMapWith("\"markers\"", noise + ", \"odometry_delay_s\": 11},\n \"markers\"")),
      HasSubstr(
          "range_bearing_noise.odometry_delay_s: expected a number of at most 10 s either way, got 11"));
}

// map.json range_bearing_sensor: written and read back to the last digit; a map without it (older
// builds) reads as before (no sensor model); its errors name the field.
TEST(MapIoTest, RangeBearingSensorRoundTripAndOldMapsWithout) {
  const MarkerMap old = ParseMap(kGoodMap, "map.json");
  EXPECT_FALSE(old.range_bearing_sensor);
  EXPECT_EQ(FormatMap(old).find("range_bearing_sensor"), std::string::npos);
  MarkerMap map = old;
  RangeBearingSensorModel model;
  model.depth_ranges = true;
  for (const char* name : {"robot1", "robot2"}) {
    RangeBearingSensorModel::Dataset dataset;
    dataset.name = name;
    dataset.values.range_offset_m = 0.0439;
    dataset.values.bearing_offset_rad = -0.0002;
    dataset.values.bearing_scale = -0.0203;
    dataset.values.depth_share = 0.9987;
    dataset.values.range_scale = 0.0208;
    dataset.values.odometry_calibration = Eigen::Vector3d(0.0452, 0.0341, 0.0112);
    dataset.noise.range_a_m = 0.01;
    dataset.noise.range_b = 0.0046;
    dataset.noise.odometry_delay_s = 0.173;
    model.datasets.push_back(dataset);
  }
  model.prior_mean.depth_share = 0.98;
  model.prior_sigma.depth_share = 0.017;
  model.prior_mean.range_scale = 1.0 / 3.0;
  model.prior_sigma.range_scale = 0.02;
  model.prior_sigma.odometry_calibration = Eigen::Vector3d(0.01, 0.04, 0.02);
  map.range_bearing_sensor = model;
  const MarkerMap again = ParseMap(FormatMap(map), "again.json");
  ASSERT_TRUE(again.range_bearing_sensor);
  const RangeBearingSensorModel& read = *again.range_bearing_sensor;
  EXPECT_TRUE(read.depth_ranges);
  ASSERT_EQ(read.datasets.size(), 2u);
  EXPECT_EQ(read.datasets[1].name, "robot2");
  EXPECT_EQ(read.datasets[1].values.depth_share, 0.9987);
  EXPECT_EQ(read.datasets[1].values.odometry_calibration[2], 0.0112);
  EXPECT_EQ(read.datasets[0].noise.range_b, 0.0046);
  EXPECT_EQ(read.datasets[0].noise.odometry_delay_s, 0.173);
  EXPECT_EQ(read.prior_mean.range_scale, 1.0 / 3.0);
  EXPECT_EQ(read.prior_sigma.odometry_calibration[1], 0.04);
  EXPECT_EQ(FormatMap(again), FormatMap(map));
  // Errors.
  std::string text = FormatMap(map);
  const auto with = [&](const std::string& from, const std::string& to) {
    std::string t = text;
    const size_t at = t.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    return t.replace(at, from.size(), to);
  };
  EXPECT_THAT(
      ParseError(with("\"range_model\":\"depth\"", "\"range_model\":\"size\"")),
      HasSubstr("range_bearing_sensor.range_model: expected \"depth\" or \"distance\", got \"size\""));
  EXPECT_THAT(
      ParseError(with("\"range_model\":\"depth\"", "\"range_model\":\"distance\"")),
      HasSubstr("range_bearing_sensor.prior_mean.depth_share: expected 0 with range_model \"distance\""));
  EXPECT_THAT(ParseError(with("\"name\":\"robot2\"", "\"name\":\"robot1\"")),
              HasSubstr("range_bearing_sensor.datasets[1].name: duplicate dataset robot1"));
  EXPECT_THAT(
      ParseError(with("\"prior_sigma\":{\"range_offset_m\":0.0", "\"prior_sigma\":{\"range_offset_m\":-1")),
      HasSubstr("range_bearing_sensor.prior_sigma.range_offset_m: expected a sigma >= 0, got -1"));
  EXPECT_THAT(
      ParseError(with("\"range_scale\":0.0208", "\"range_scale\":-1.5")),
      HasSubstr("range_bearing_sensor.datasets[0].range_scale: expected a scale error in (-1, 1), got -1.5"));
  EXPECT_THAT(
      ParseError(with("\"odometry_calibration\":[0.0452,0.0341,0.0112]", "\"odometry_calibration\":[1]")),
      HasSubstr("range_bearing_sensor.datasets[0].odometry_calibration: expected 3 numbers"));
  EXPECT_THAT(
      ParseError(with("\"range_a_m\":0.01,\"range_b\":0.0046", "\"range_a_m\":0,\"range_b\":0.0046")),
      HasSubstr("range_bearing_sensor.datasets[0].noise.range_a_m: expected a positive number, got 0"));
  // A sensor model without the odometry calibration's correlation time (before it was fitted by the
  // build) reads as before and is written without it.
  EXPECT_FALSE(read.calibration_time);
  EXPECT_EQ(text.find("calibration_time_s"), std::string::npos);
}

// A sensor model with one dataset ("robot1") and every value at its default.
RangeBearingSensorModel SensorModelOfOneDataset() {
  RangeBearingSensorModel model;
  RangeBearingSensorModel::Dataset dataset;
  dataset.name = "robot1";
  model.datasets.push_back(dataset);
  return model;
}

// map.json range_bearing_sensor online_variance_factor (the build's leave-one-out calibration):
// optional (absent: not written, not read), round trip exact, > 0.
TEST(MapIoTest, RangeBearingSensorOnlineVarianceFactorRoundTrip) {
  MarkerMap map = ParseMap(kGoodMap, "map.json");
  map.range_bearing_sensor = SensorModelOfOneDataset();
  EXPECT_EQ(FormatMap(map).find("online_variance_factor"), std::string::npos);
  EXPECT_FALSE(ParseMap(FormatMap(map), "a.json").range_bearing_sensor->online_variance_factor);
  map.range_bearing_sensor->online_variance_factor = 3.6412345678901;
  const std::string text = FormatMap(map);
  const MarkerMap again = ParseMap(text, "again.json");
  ASSERT_TRUE(again.range_bearing_sensor->online_variance_factor);
  EXPECT_EQ(*again.range_bearing_sensor->online_variance_factor, 3.6412345678901);
  EXPECT_EQ(FormatMap(again), text);
  std::string bad = text;
  const std::string from = "\"online_variance_factor\":3.6412345678901";
  ASSERT_NE(bad.find(from), std::string::npos);
  bad.replace(bad.find(from), from.size(), "\"online_variance_factor\":0");
  EXPECT_THAT(ParseError(bad),
              HasSubstr("range_bearing_sensor.online_variance_factor: expected a factor > 0, got 0"));
  map.range_bearing_sensor->online_variance_factor = -1.0;
  EXPECT_THROW(FormatMap(map), std::invalid_argument);
}

// map.json range_bearing_sensor calibration_time_s and calibration_turn_scale_sigma (the build's
// fit, waymark localize's default correlation time): written and read back to the last digit;
// the two go together; errors name the field.
TEST(MapIoTest, RangeBearingSensorCalibrationTimeRoundTrip) {
  MarkerMap map = ParseMap(kGoodMap, "map.json");
  RangeBearingSensorModel model = SensorModelOfOneDataset();
  model.calibration_time = RangeBearingSensorModel::CalibrationTime{2.357812345678, 0.0412345678901};
  map.range_bearing_sensor = model;
  const std::string text = FormatMap(map);
  const MarkerMap again = ParseMap(text, "again.json");
  ASSERT_TRUE(again.range_bearing_sensor);
  ASSERT_TRUE(again.range_bearing_sensor->calibration_time);
  EXPECT_EQ(again.range_bearing_sensor->calibration_time->time_s, 2.357812345678);
  EXPECT_EQ(again.range_bearing_sensor->calibration_time->turn_scale_sigma, 0.0412345678901);
  EXPECT_EQ(FormatMap(again), text);
  const auto with = [&](const std::string& from, const std::string& to) {
    std::string t = text;
    const size_t at = t.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    return t.replace(at, from.size(), to);
  };
  EXPECT_THAT(ParseError(with(",\"calibration_turn_scale_sigma\":0.0412345678901", "")),
              HasSubstr("range_bearing_sensor.calibration_turn_scale_sigma: expected calibration_time_s and "
                        "calibration_turn_scale_sigma together"));
  EXPECT_THAT(ParseError(with("\"calibration_time_s\":2.357812345678,", "")),
              HasSubstr("range_bearing_sensor.calibration_time_s: expected calibration_time_s and "
                        "calibration_turn_scale_sigma together"));
  EXPECT_THAT(ParseError(with("\"calibration_time_s\":2.357812345678", "\"calibration_time_s\":0")),
              HasSubstr("range_bearing_sensor.calibration_time_s: expected a time > 0 (s), got 0"));
  EXPECT_THAT(ParseError(with("\"calibration_turn_scale_sigma\":0.0412345678901",
                              "\"calibration_turn_scale_sigma\":-1")),
              HasSubstr("range_bearing_sensor.calibration_turn_scale_sigma: expected a sigma >= 0, got -1"));
  // The writer refuses a time that is not > 0.
  map.range_bearing_sensor->calibration_time->time_s = 0.0;
  EXPECT_THROW(FormatMap(map), std::invalid_argument);
}

}  // namespace
}  // namespace waymark
