#include "io/camera_io.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>

#include "io/util.h"

namespace waymark {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

const char* const kGoodCamera = R"(model: pinhole-radtan
width: 1280
height: 1024
intrinsics: [1506.9, 1506.28, 641.176, 524.495]
distortion: [-0.233024, 0.217972, 0.000104351, -9.65731e-05, -0.0913426]
T_robot_camera:
  t: [0.1, 0.0, 0.0]
  q_xyzw: [0.707178787, 0.0, 0.0, -0.707034768]
pixel_sigma: 1.0
)";

std::string GoodCameraWith(const std::string& from, const std::string& to) {
  std::string text = kGoodCamera;
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return text.replace(at, from.size(), to);
}

std::string ParseError(const std::string& text) {
  try {
    ParseCameraYaml(text, "cameras/cam0.yaml", "cam0");
  } catch (const FormatError& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected a FormatError for:\n" << text;
  return "";
}

TEST(CameraIoTest, ParsesGoodCamera) {
  ReadWarnings warnings;
  const CameraInfo camera = ParseCameraYaml(kGoodCamera, "cameras/cam0.yaml", "cam0", &warnings);
  EXPECT_EQ(camera.name, "cam0");
  EXPECT_EQ(camera.model, CameraModel::kPinholeRadtan);
  EXPECT_EQ(camera.width, 1280);
  EXPECT_EQ(camera.height, 1024);
  EXPECT_EQ(camera.intrinsics[2], 641.176);
  ASSERT_EQ(camera.distortion.size(), 5u);
  EXPECT_EQ(camera.distortion[3], -9.65731e-05);
  EXPECT_EQ(camera.T_robot_camera.translation(), Eigen::Vector3d(0.1, 0, 0));
  EXPECT_NEAR(camera.T_robot_camera.rotation().norm(), 1.0, 1e-15);
  EXPECT_EQ(camera.pixel_sigma, 1.0);
  EXPECT_EQ(warnings.Total(), 0);
}

TEST(CameraIoTest, ErrorsNameFileLineAndField) {
  EXPECT_THAT(ParseError(GoodCameraWith("[1506.9, 1506.28, 641.176, 524.495]", "[1506.9, 1506.28, 641.176]")),
              HasSubstr("cameras/cam0.yaml:4: intrinsics: expected 4 numbers, got 3"));
  EXPECT_THAT(
      ParseError(GoodCameraWith("pinhole-radtan", "fisheye")),
      HasSubstr("cameras/cam0.yaml:1: model: unknown camera model 'fisheye' (expected pinhole-radtan, "
                "pinhole-equidistant or equisolid)"));
  EXPECT_THAT(ParseError(GoodCameraWith("pinhole-radtan", "equisolid")),
              HasSubstr("cameras/cam0.yaml:5: distortion (equisolid): expected 4 numbers, got 5"));
  EXPECT_THAT(ParseError(GoodCameraWith("pinhole-radtan", "pinhole-equidistant")),
              HasSubstr("cameras/cam0.yaml:5: distortion (pinhole-equidistant): expected 4 numbers, got 5"));
  EXPECT_THAT(ParseError(GoodCameraWith("641.176", ".nan")),
              HasSubstr("cameras/cam0.yaml:4: intrinsics[2]: expected a finite number, got '.nan'"));
  EXPECT_THAT(ParseError(GoodCameraWith("[0.707178787, 0.0, 0.0, -0.707034768]", "[0.7, 0.0, -0.7]")),
              HasSubstr("cameras/cam0.yaml:8: T_robot_camera.q_xyzw: expected 4 numbers, got 3"));
  EXPECT_THAT(ParseError(GoodCameraWith("-0.707034768", "-0.6")),
              HasSubstr("cameras/cam0.yaml:8: T_robot_camera.q_xyzw: expected unit norm within 0.001"));
  EXPECT_THAT(ParseError(GoodCameraWith("width: 1280", "width: 1280.5")),
              HasSubstr("cameras/cam0.yaml:2: width: expected an integer, got '1280.5'"));
  EXPECT_THAT(ParseError(GoodCameraWith("width: 1280", "width: \"1280\"")),
              HasSubstr("cameras/cam0.yaml:2: width: expected an integer, got a quoted string"));
  EXPECT_THAT(ParseError(GoodCameraWith("height: 1024", "height: -3")),
              HasSubstr("cameras/cam0.yaml:3: height: expected a positive"));
  EXPECT_THAT(ParseError(GoodCameraWith("height: 1024\n", "")),
              HasSubstr("cameras/cam0.yaml:1: missing key 'height'"));
  EXPECT_THAT(ParseError(GoodCameraWith("pixel_sigma: 1.0", "pixel_sigma: [1]")),
              HasSubstr("cameras/cam0.yaml:9: pixel_sigma: expected a number, got a list"));
  EXPECT_THAT(ParseError(GoodCameraWith("pixel_sigma: 1.0", "pixel_sigma: 0")),
              HasSubstr("pixel_sigma: expected a positive"));
  EXPECT_THAT(ParseError(GoodCameraWith("[1506.9, 1506.28", "[-1506.9, 1506.28")),
              HasSubstr("intrinsics: expected positive focal"));
  EXPECT_THAT(ParseError(GoodCameraWith("  t: [0.1, 0.0, 0.0]", "  t: [0.1, 0.0, 0.0\n")),
              HasSubstr("cameras/cam0.yaml:9: invalid YAML: end of sequence flow not found"));
  EXPECT_THAT(ParseError("- a\n- b\n"), HasSubstr("cameras/cam0.yaml:1: expected a map of keys, got a list"));
  EXPECT_THAT(ParseError(""), HasSubstr("cameras/cam0.yaml: expected a map of keys"));
}

// Issue 18, finding 8: a translation of 1e308 and k1 = 1e9 were accepted; the build then
// "succeeded" with every view rejected. Out-of-range values are one-line errors with the line.
TEST(CameraIoTest, PhysicallyMeaninglessValuesAreErrors) {
  EXPECT_EQ(ParseError(GoodCameraWith("t: [0.1, 0.0, 0.0]", "t: [1e308, 0.0, 0.0]")),
            "cameras/cam0.yaml:7: T_robot_camera.t: expected coordinates within +-1e+07 m, got 1e+308");
  EXPECT_EQ(ParseError(GoodCameraWith("t: [0.1, 0.0, 0.0]", "t: [0.1, 150, 0.0]")),
            "cameras/cam0.yaml:7: T_robot_camera.t: expected the camera within 100 m of the robot, got "
            "150.0000333333296 m");
  EXPECT_EQ(ParseError(GoodCameraWith("[-0.233024,", "[1e9,")),
            "cameras/cam0.yaml:5: distortion: expected coefficients within +-100, got 1e+09");
  EXPECT_EQ(ParseError(GoodCameraWith("[1506.9,", "[1e9,")),
            "cameras/cam0.yaml:4: intrinsics: expected focal lengths up to 1e+06 px, got 1e+09");
  EXPECT_THAT(
      ParseError(GoodCameraWith("641.176", "1e7")),
      HasSubstr("cameras/cam0.yaml:4: intrinsics: expected the principal point within one image size"));
  EXPECT_EQ(ParseError(GoodCameraWith("pixel_sigma: 1.0", "pixel_sigma: 1e300")),
            "cameras/cam0.yaml:9: pixel_sigma: expected a positive number of pixels up to 1000, got 1e+300");
  CameraInfo camera = ParseCameraYaml(kGoodCamera, "cameras/cam0.yaml", "cam0");
  camera.distortion[0] = 1e9;
  EXPECT_THROW(FormatCameraYaml(camera), std::invalid_argument);  // the writer refuses it too
}

// Extrinsic self-calibration (issue 13, item 4): the mount's prior sigmas, [rad, m].
TEST(CameraIoTest, MountSigmaIsReadCheckedAndWritten) {
  const CameraInfo plain = ParseCameraYaml(kGoodCamera, "cameras/cam0.yaml", "cam0");
  EXPECT_FALSE(plain.T_robot_camera_sigma.has_value());
  ReadWarnings warnings;
  const CameraInfo calibrating =
      ParseCameraYaml(std::string(kGoodCamera) + "T_robot_camera_sigma: [0.035, 0.03]\n", "cameras/cam0.yaml",
                      "cam0", &warnings);
  EXPECT_EQ(warnings.Total(), 0);
  ASSERT_TRUE(calibrating.T_robot_camera_sigma.has_value());
  EXPECT_EQ((*calibrating.T_robot_camera_sigma)[0], 0.035);
  EXPECT_EQ((*calibrating.T_robot_camera_sigma)[1], 0.03);
  const CameraInfo again = ParseCameraYaml(FormatCameraYaml(calibrating), "cameras/cam0.yaml", "cam0");
  EXPECT_EQ(again.T_robot_camera_sigma, calibrating.T_robot_camera_sigma);

  EXPECT_EQ(ParseError(std::string(kGoodCamera) + "T_robot_camera_sigma: [0.035]\n"),
            "cameras/cam0.yaml:10: T_robot_camera_sigma: expected 2 numbers, got 1");
  EXPECT_EQ(
      ParseError(std::string(kGoodCamera) + "T_robot_camera_sigma: [0, 0.03]\n"),
      "cameras/cam0.yaml:10: T_robot_camera_sigma: expected [rotation rad in (0, pi], translation m in (0, "
      "100]], got [0, 0.03]");
  EXPECT_THAT(ParseError(std::string(kGoodCamera) + "T_robot_camera_sigma: [0.1, 1e9]\n"),
              HasSubstr("cameras/cam0.yaml:10: T_robot_camera_sigma: expected"));
  EXPECT_THAT(ParseError(std::string(kGoodCamera) + "T_robot_camera_sigma: [4, 0.1]\n"),
              HasSubstr("cameras/cam0.yaml:10: T_robot_camera_sigma: expected"));
  const CameraInfo wiggling = ParseCameraYaml(std::string(kGoodCamera) + "frame_wiggle_sigma: [0.01, 0.02]\n",
                                              "cameras/cam0.yaml", "cam0");
  ASSERT_TRUE(wiggling.frame_wiggle_sigma.has_value());
  EXPECT_EQ((*wiggling.frame_wiggle_sigma)[1], 0.02);
  EXPECT_EQ(ParseCameraYaml(FormatCameraYaml(wiggling), "cameras/cam0.yaml", "cam0").frame_wiggle_sigma,
            wiggling.frame_wiggle_sigma);
  EXPECT_THAT(ParseError(std::string(kGoodCamera) + "frame_wiggle_sigma: [-0.01, 0.02]\n"),
              HasSubstr("cameras/cam0.yaml:10: frame_wiggle_sigma: expected"));
  CameraInfo bad = calibrating;
  (*bad.T_robot_camera_sigma)[1] = -1.0;
  EXPECT_THROW(FormatCameraYaml(bad), std::invalid_argument);  // the writer refuses it too
}

TEST(CameraIoTest, MissingFileAndUnknownKeys) {
  try {
    ReadCameraYaml("/nonexistent/cameras/cam9.yaml");
    FAIL() << "expected FormatError";
  } catch (const FormatError& e) {
    EXPECT_THAT(e.what(), HasSubstr("/nonexistent/cameras/cam9.yaml: cannot open"));
  }
  ReadWarnings warnings;
  ParseCameraYaml(std::string(kGoodCamera) + "rolling_shutter: true\n", "cameras/cam0.yaml", "cam0",
                  &warnings);
  EXPECT_EQ(warnings.counts["unknown key"], 1);
  ASSERT_EQ(warnings.first_messages.size(), 1u);
  EXPECT_EQ(warnings.first_messages[0], "cameras/cam0.yaml:10: unknown key 'rolling_shutter' ignored");
}

TEST(CameraIoTest, RoundTripIsExact) {
  CameraInfo camera;
  camera.name = "fisheye";
  camera.model = CameraModel::kPinholeEquidistant;
  camera.width = 800;
  camera.height = 848;
  camera.intrinsics = {283.943 + 1e-11, 284.986, 421.0 / 3.0, 400.527};
  camera.distortion = {0.00132, 0.1 / 3.0, -0.02875, 1e-300};
  camera.T_robot_camera =
      SE3d(Eigen::Quaterniond(0.3, -0.2, 0.9, 0.1), Eigen::Vector3d(0.1 / 7.0, -2.0, 1e-9));
  const fs::path path = fs::temp_directory_path() / ("waymark_camera_io_test_" + std::to_string(::getpid())) /
                        "cameras" / "fisheye.yaml";
  WriteCameraYaml(path, camera);
  ReadWarnings warnings;
  const CameraInfo read = ReadCameraYaml(path, &warnings);
  EXPECT_EQ(warnings.Total(), 0);
  EXPECT_EQ(read.name, "fisheye");
  EXPECT_EQ(read.model, camera.model);
  EXPECT_EQ(read.width, camera.width);
  EXPECT_EQ(read.height, camera.height);
  EXPECT_EQ(read.intrinsics, camera.intrinsics);
  EXPECT_EQ(read.distortion, camera.distortion);
  EXPECT_EQ(read.T_robot_camera.translation(), camera.T_robot_camera.translation());
  EXPECT_EQ(read.T_robot_camera.rotation().coeffs(), camera.T_robot_camera.rotation().coeffs());
  EXPECT_FALSE(read.pixel_sigma.has_value());
  fs::remove_all(path.parent_path().parent_path());

  camera.distortion.push_back(0.0);
  EXPECT_THROW(FormatCameraYaml(camera), std::invalid_argument);
}

TEST(CameraIoTest, ReadsEquisolid) {
  const std::string text = GoodCameraWith("pinhole-radtan", "equisolid");
  const std::string equisolid = text.substr(0, text.find("distortion:")) + "distortion: [0, 0, 0.001, 0]\n" +
                                text.substr(text.find("T_robot_camera:"));
  const CameraInfo camera = ParseCameraYaml(equisolid, "cameras/cam0.yaml", "cam0");
  EXPECT_EQ(camera.model, CameraModel::kEquisolid);
  EXPECT_EQ(camera.distortion, std::vector<double>({0.0, 0.0, 0.001, 0.0}));
  EXPECT_EQ(ParseCameraYaml(FormatCameraYaml(camera), "cameras/cam0.yaml", "cam0").model,
            CameraModel::kEquisolid);
}

}  // namespace
}  // namespace waymark
