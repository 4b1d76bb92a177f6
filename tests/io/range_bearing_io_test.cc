// io/range_bearing_io.h, the point landmarks of io/map_io.h, dataset.yaml's range_bearing and
// start_prior (io/dataset_io.h): round trips and one expected one-line error per rule.
#include "io/range_bearing_io.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>

#include "io/dataset_io.h"
#include "io/map_io.h"
#include "io/util.h"

namespace waymark {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

std::string ParseError(const std::string& text) {
  ReadWarnings warnings;
  try {
    ParseRangeBearing(text, "range_bearing.jsonl", &warnings);
  } catch (const FormatError& e) {
    return e.what();
  }
  return "no error";
}

TEST(RangeBearingIo, RoundTrip) {
  RangeBearingFrame frame;
  frame.stamp_s = 1248444189.599;
  RangeBearingObservation obs;
  obs.key = {kFamilyBarcode, "23"};
  obs.range_m = 3.787;
  obs.bearing_rad = -0.257;
  obs.elevation_rad = 0.01;
  obs.sigma_range_m = 0.05;
  frame.landmarks.push_back(obs);
  frame.robots.push_back({"robot2", "14", 2.5, 0.3});
  RangeBearingFrame empty;
  empty.stamp_s = 1248444190.0;
  const std::string text = FormatRangeBearing({frame, empty});
  ReadWarnings warnings;
  const std::vector<RangeBearingFrame> back = ParseRangeBearing(text, "rb.jsonl", &warnings);
  ASSERT_EQ(back.size(), 2u);
  EXPECT_EQ(warnings.Total(), 0);
  EXPECT_EQ(back[0].stamp_s, frame.stamp_s);
  ASSERT_EQ(back[0].landmarks.size(), 1u);
  EXPECT_EQ(back[0].landmarks[0].key, obs.key);
  EXPECT_EQ(back[0].landmarks[0].range_m, 3.787);
  EXPECT_EQ(back[0].landmarks[0].bearing_rad, -0.257);
  EXPECT_EQ(*back[0].landmarks[0].elevation_rad, 0.01);
  EXPECT_EQ(*back[0].landmarks[0].sigma_range_m, 0.05);
  EXPECT_FALSE(back[0].landmarks[0].sigma_bearing_rad);
  ASSERT_EQ(back[0].robots.size(), 1u);
  EXPECT_EQ(back[0].robots[0].robot, "robot2");
  EXPECT_EQ(back[0].robots[0].barcode, "14");
  EXPECT_TRUE(back[1].landmarks.empty());
}

TEST(RangeBearingIo, OneLineErrors) {
  const std::string lm = R"("family": "barcode", "id": "7")";
  EXPECT_EQ(ParseError("{\"t\": 1, \"landmarks\": [}\n").substr(0, 22), "range_bearing.jsonl:1:");
  EXPECT_THAT(ParseError("{\"landmarks\": []}\n"), HasSubstr("range_bearing.jsonl:1: missing key \"t\""));
  EXPECT_THAT(ParseError("{\"t\": 1}\n"), HasSubstr("landmarks"));
  EXPECT_THAT(ParseError("{\"t\": 1, \"landmarks\": [{" + lm + ", \"range_m\": 0, \"bearing_rad\": 0}]}\n"),
              HasSubstr("landmarks[0].range_m: expected a range > 0 m, got 0"));
  EXPECT_THAT(ParseError("{\"t\": 1, \"landmarks\": [{" + lm + ", \"range_m\": 1, \"bearing_rad\": 4}]}\n"),
              HasSubstr("landmarks[0].bearing_rad: expected an angle within"));
  EXPECT_THAT(ParseError("{\"t\": 1, \"landmarks\": [{" + lm + ", \"range_m\": 1}]}\n"),
              HasSubstr("bearing_rad"));
  EXPECT_THAT(ParseError("{\"t\": 1, \"landmarks\": [{\"family\": \"morse\", \"id\": \"7\", \"range_m\": 1, "
                         "\"bearing_rad\": 0}]}\n"),
              HasSubstr("unknown family \"morse\""));
  EXPECT_THAT(ParseError("{\"t\": 1, \"landmarks\": [{" + lm +
                         ", \"range_m\": 1, \"bearing_rad\": 0, \"sigma_range_m\": -1}]}\n"),
              HasSubstr("sigma_range_m: expected a positive sigma"));
  EXPECT_THAT(ParseError("{\"t\": 2, \"landmarks\": []}\n{\"t\": 1, \"landmarks\": []}\n"),
              HasSubstr("range_bearing.jsonl:2: t: expected non-decreasing stamps"));
  EXPECT_THAT(ParseError("{\"t\": 1, \"landmarks\": [], \"robots\": [{\"robot\": \"\", \"barcode\": \"5\", "
                         "\"range_m\": 1, \"bearing_rad\": 0}]}\n"),
              HasSubstr("robots[0].robot: expected a non-empty string"));
}

TEST(RangeBearingIo, DuplicateLandmarkInFrameIsDroppedAndCounted) {
  const std::string obs = R"({"family": "barcode", "id": "7", "range_m": 1, "bearing_rad": 0})";
  ReadWarnings warnings;
  const auto frames =
      ParseRangeBearing("{\"t\": 1, \"landmarks\": [" + obs + ", " + obs + "]}\n", "f", &warnings);
  ASSERT_EQ(frames.size(), 1u);
  EXPECT_TRUE(frames[0].landmarks.empty());
  EXPECT_EQ(warnings.counts["duplicate landmark in frame"], 1);
}

TEST(RangeBearingIo, PointLandmarkInTheMapFormat) {
  MarkerMap map;
  MapMarker point;
  point.is_point = true;
  point.key = {kFamilyBarcode, "23"};
  point.T_world_marker = SE3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.5, -4.25, 0.0));
  point.position_covariance = Eigen::Vector3d(1e-4, 2e-4, 0.0).asDiagonal();
  point.component = 0;
  map.markers.push_back(point);
  MapMarker square;
  square.key = {"qr", "A"};
  square.size_m = 0.1;
  map.markers.push_back(square);
  const std::string text = FormatMap(map);
  EXPECT_THAT(text, HasSubstr("\"p_world_marker\":[0.5,-4.25,0.0]"));
  const MarkerMap back = ParseMap(text, "map.json");
  ASSERT_EQ(back.markers.size(), 2u);
  EXPECT_TRUE(back.markers[0].is_point);
  EXPECT_FALSE(back.markers[1].is_point);
  EXPECT_EQ(back.markers[0].T_world_marker.translation(), point.T_world_marker.translation());
  EXPECT_EQ(*back.markers[0].position_covariance, *point.position_covariance);
  const auto error = [](const std::string& marker) -> std::string {
    try {
      ParseMap("{\"format\": \"waymark-map\", \"version\": 1, \"markers\": [" + marker + "]}", "map.json");
    } catch (const FormatError& e) {
      return e.what();
    }
    return "no error";
  };
  EXPECT_THAT(error(R"({"family": "barcode", "id": "1", "p_world_marker": [1, 2]})"),
              HasSubstr("markers[0].p_world_marker: expected 3 numbers"));
  EXPECT_THAT(error(R"({"family": "barcode", "id": "1", "p_world_marker": [1, 2, 0], "size_m": 0.1})"),
              HasSubstr("markers[0].size_m: a point landmark (p_world_marker) has no size_m"));
  EXPECT_THAT(
      error(R"({"family": "barcode", "id": "1", "p_world_marker": [1, 2, 0], "position_covariance": [1]})"),
      HasSubstr("position_covariance: expected 9 numbers"));
  // A barcode is a point family only: as a square code it is still unknown.
  EXPECT_THAT(
      error(
          R"({"family": "barcode", "id": "1", "size_m": 0.1, "T_world_marker": {"t": [0, 0, 0], "q_xyzw": [0, 0, 0, 1]}})"),
      HasSubstr("unknown family \"barcode\""));
}

TEST(RangeBearingIo, PointLandmarkCovarianceFactor) {
  MarkerMap map;
  for (const char* id : {"1", "2"}) {
    MapMarker point;
    point.is_point = true;
    point.key = {kFamilyBarcode, id};
    point.position_covariance = Eigen::Vector3d(4e-4, 5e-4, 0.0).asDiagonal();
    // map.json position_covariance_factor; in memory the translation rows of covariance_factor.
    point.covariance_factor = CovarianceFactor::Zero(6, 2);
    point.covariance_factor->bottomRows<3>() << 0.01, -0.005, 0.003, 0.012, 0.0, 0.0;
    map.markers.push_back(point);
  }
  const MarkerMap back = ParseMap(FormatMap(map), "map.json");
  ASSERT_EQ(back.markers.size(), 2u);
  ASSERT_TRUE(back.markers[1].covariance_factor);
  EXPECT_EQ(*back.markers[1].covariance_factor, *map.markers[1].covariance_factor);
  EXPECT_THAT(FormatMap(map), HasSubstr("\"position_covariance_factor\":[0.01,-0.005,0.003,0.012,0.0,0.0]"));
  const auto error = [](const std::string& markers) -> std::string {
    try {
      ParseMap("{\"format\": \"waymark-map\", \"version\": 1, \"markers\": [" + markers + "]}", "map.json");
    } catch (const FormatError& e) {
      return e.what();
    }
    return "no error";
  };
  const std::string head = R"({"family": "barcode", "id": "1", "p_world_marker": [1, 2, 0], )";
  const std::string cov = R"("position_covariance": [1e-4, 0, 0, 0, 1e-4, 0, 0, 0, 0], )";
  EXPECT_THAT(error(head + R"("position_covariance_factor": [0.001, 0.001, 0.0]})"),
              HasSubstr("map.json:1: markers[0].position_covariance_factor: expected a position_covariance "
                        "with the factor"));
  EXPECT_THAT(error(head + cov + R"("position_covariance_factor": [0.001, 0.001]})"),
              HasSubstr("markers[0].position_covariance_factor: expected a non-empty array of 3 k numbers"));
  EXPECT_THAT(
      error(head + cov + R"("position_covariance_factor": [0.1, 0.0, 0.0]})"),
      HasSubstr("markers[0].position_covariance_factor: expected position_covariance - F F^T positive "
                "semi-definite"));
  EXPECT_THAT(
      error(head + cov + R"("position_covariance_factor": [0.001, 0.001, 0.0]}, )" +
            R"({"family": "barcode", "id": "2", "p_world_marker": [1, 2, 0], )" + cov +
            R"("position_covariance_factor": [0.001, 0.0, 0.001, 0.0, 0.0, 0.0]})"),
      HasSubstr("markers[1].position_covariance_factor: expected 3 x 1 like the point landmarks before, "
                "got 3 x 2"));
  // The writer refuses a factor with rotation rows, or without a covariance.
  (*map.markers[0].covariance_factor)(0, 0) = 0.001;
  EXPECT_THROW(FormatMap(map), std::invalid_argument);
  (*map.markers[0].covariance_factor)(0, 0) = 0.0;
  map.markers[0].position_covariance.reset();
  EXPECT_THROW(FormatMap(map), std::invalid_argument);
}

TEST(RangeBearingIo, DatasetWithRangeBearingAndStartPrior) {
  const fs::path dir = fs::temp_directory_path() / ("waymark_rb_dataset_" + std::to_string(getpid()));
  fs::remove_all(dir);
  Dataset dataset;
  dataset.config.name = "robot1";
  dataset.config.start_prior = StartPrior{SE2d(1.0, -2.0, 0.5).ToSE3(), 0.01, 0.02};
  dataset.odometry = {{0.0, SE3d()}, {1.0, SE2d(0.1, 0.0, 0.01).ToSE3()}};
  RangeBearingFrame frame;
  frame.stamp_s = 0.5;
  frame.landmarks.push_back(
      {{kFamilyBarcode, "7"}, 2.0, 0.1, std::nullopt, std::nullopt, std::nullopt, std::nullopt});
  dataset.range_bearing.push_back(frame);
  WriteDataset(dir, dataset);
  const Dataset back = LoadDataset(dir);
  EXPECT_TRUE(back.config.cameras.empty());
  EXPECT_TRUE(back.has_range_bearing_file);
  ASSERT_EQ(back.range_bearing.size(), 1u);
  ASSERT_TRUE(back.config.start_prior);
  EXPECT_NEAR(back.config.start_prior->T_world_robot.yaw(), 0.5, 1e-12);
  EXPECT_EQ(back.config.start_prior->sigma_rad, 0.02);
  EXPECT_EQ(back.warnings.Total(), 0);
  const auto yaml_error = [](const std::string& extra) -> std::string {
    try {
      ParseDatasetYaml("format: waymark-dataset\nversion: 1\nmotion: planar\ncameras: []\n" + extra,
                       "dataset.yaml");
    } catch (const FormatError& e) {
      return e.what();
    }
    return "no error";
  };
  EXPECT_EQ(yaml_error(""), "no error");
  EXPECT_THAT(yaml_error("start_prior: {sigma_m: 0.01, sigma_rad: 0.01}\n"), HasSubstr("T_world_robot"));
  EXPECT_THAT(yaml_error("start_prior: {T_world_robot: {t: [0, 0, 0], q_xyzw: [0, 0, 0, 1]}, sigma_m: 0, "
                         "sigma_rad: 0.01}\n"),
              HasSubstr("dataset.yaml:5"));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace waymark
