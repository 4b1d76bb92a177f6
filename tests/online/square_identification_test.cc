// Square ceiling markers carry no id: a `square` detection with the id "*" is the map's only
// square, or the square the tracked pose predicts (geometry/square_marker.h IdentifySquare), and then
// goes through the same tight corner update as every code.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "geometry/square_marker.h"
#include "online/localizer.h"
#include "tests/test_cameras.h"

namespace waymark {
namespace {

CameraInfo UpCamera() {
  CameraInfo camera = testing::Seed002EquisolidInfo();
  camera.name = "up";
  camera.pixel_sigma = 0.5;
  camera.T_robot_camera = SE3d(Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ())),
                               Eigen::Vector3d(0.0, 0.0, 0.3));
  return camera;
}

// Squares 2 m wide, 2.3 m up, every 6 m along x, facing down.
MarkerMap Squares(int count) {
  MarkerMap map;
  Eigen::Matrix3d R_world_marker;
  R_world_marker << 1, 0, 0, 0, -1, 0, 0, 0, -1;
  for (int i = 0; i < count; ++i) {
    MapMarker square;
    square.key = {kFamilySquare, std::string(1, static_cast<char>('A' + i))};
    square.size_m = 2.0;
    square.T_world_marker = SE3d(Eigen::Quaterniond(R_world_marker), Eigen::Vector3d(6.0 * i, 0.0, 2.3));
    square.fixed = true;
    if (i == 1) square.square_tape = SquareTape{0.05, SquareSide::kLeft, 0.1, 0.1};
    map.markers.push_back(square);
  }
  return map;
}

// The detection of `square` from the robot at T_world_robot: solid side first, id "*".
std::optional<MarkerObservation> Detect(const MapMarker& square, const Camera& camera,
                                        const SE3d& T_world_robot, std::mt19937* rng) {
  std::normal_distribution<double> noise(0.0, 0.3);
  const SE3d T_camera_world = (T_world_robot * camera.info().T_robot_camera).inverse();
  std::array<Eigen::Vector2d, 4> px;
  const std::array<Eigen::Vector3d, 4> corners = MarkerCorners(square.size_m);
  for (int k = 0; k < 4; ++k) {
    const auto p = camera.Project(T_camera_world * (square.T_world_marker * corners[k]));
    if (!p || !camera.info().InImage(*p)) return std::nullopt;
    px[k] = *p + Eigen::Vector2d(noise(*rng), noise(*rng));
  }
  MarkerObservation observation;
  observation.key = {kFamilySquare, kUnidentifiedSquareId};
  const int s = static_cast<int>(TapeOf(square).solid_side);
  for (int k = 0; k < 4; ++k) observation.corners_px[k] = px[(k + s) % 4];
  return observation;
}

TEST(SquareIdentificationTest, TheOnlySquareStartsAndTracks) {
  const MarkerMap map = Squares(1);
  const CameraInfo info = UpCamera();
  const Camera camera(info);
  Localizer localizer(LocalizerOptions{}, map, {info});
  std::mt19937 rng(3);
  double worst_m = 0.0;
  for (int k = 0; k <= 40; ++k) {
    const double t = 0.1 * k;
    const SE3d T_world_robot = SE2d(-1.0 + 0.05 * k, 0.4, 0.3 + 0.02 * k).ToSE3();
    ASSERT_EQ(localizer.AddOdometry(t, T_world_robot), StepStatus::kOk);
    DetectionFrame frame;
    frame.stamp_s = t;
    frame.camera = "up";
    frame.markers.push_back(*Detect(map.markers[0], camera, T_world_robot, &rng));
    ASSERT_EQ(localizer.AddDetections(frame).status, StepStatus::kOk);
    const PoseOutput output = localizer.Output();
    ASSERT_TRUE(output.T_world_robot.has_value()) << k;
    worst_m = std::max(worst_m,
                       (output.T_world_robot->translation() - T_world_robot.translation()).head<2>().norm());
  }
  EXPECT_EQ(localizer.counters().unknown_markers, 0);
  EXPECT_EQ(localizer.counters().initializations, 1);
  EXPECT_LT(worst_m, 0.01);
}

TEST(SquareIdentificationTest, SeveralSquaresAreToldApartByThePose) {
  const MarkerMap map = Squares(2);
  const CameraInfo info = UpCamera();
  const Camera camera(info);
  Localizer localizer(LocalizerOptions{}, map, {info});
  std::mt19937 rng(4);
  // No track yet: two squares, nothing to tell them apart.
  const SE3d start = SE2d(0.2, -0.3, 0.0).ToSE3();
  ASSERT_EQ(localizer.AddOdometry(0.0, start), StepStatus::kOk);
  DetectionFrame frame;
  frame.camera = "up";
  frame.markers.push_back(*Detect(map.markers[0], camera, start, &rng));
  ASSERT_EQ(localizer.AddDetections(frame).status, StepStatus::kOk);
  EXPECT_FALSE(localizer.Output().T_world_robot.has_value());
  EXPECT_EQ(localizer.counters().unknown_markers, 1);
  // A start from square A by name (as from a prior), then "*" all the way to square B.
  frame.markers[0].key.id = "A";
  ASSERT_EQ(localizer.AddDetections(frame).status, StepStatus::kOk);
  ASSERT_TRUE(localizer.Output().T_world_robot.has_value());
  double worst_m = 0.0;
  int seen_b = 0;
  for (int k = 1; k <= 120; ++k) {
    const double t = 0.1 * k;
    const SE3d T_world_robot = SE2d(0.2 + 0.05 * k, -0.3, 0.0).ToSE3();  // to x = 6.2, under B
    ASSERT_EQ(localizer.AddOdometry(t, T_world_robot), StepStatus::kOk);
    DetectionFrame f;
    f.stamp_s = t;
    f.camera = "up";
    for (const MapMarker& square : map.markers) {
      if (const auto observation = Detect(square, camera, T_world_robot, &rng)) {
        f.markers.push_back(*observation);
        seen_b += square.key.id == "B";
      }
    }
    ASSERT_EQ(localizer.AddDetections(f).status, StepStatus::kOk);
    const PoseOutput output = localizer.Output();
    ASSERT_TRUE(output.T_world_robot.has_value()) << k;
    worst_m = std::max(worst_m,
                       (output.T_world_robot->translation() - T_world_robot.translation()).head<2>().norm());
  }
  EXPECT_GT(seen_b, 20);
  EXPECT_EQ(localizer.counters().unknown_markers, 1);  // only the first, trackless one
  EXPECT_LT(worst_m, 0.01);
}

// A start pose (moved with the odometry until the first square) tells which of two alike squares
// the first "*" is: near the truth it starts right; a start pose 6 m off (under the other square)
// starts 6 m off, i.e. it is the start pose, not the look, that decides.
TEST(SquareIdentificationTest, StartPoseTellsTheFirstSquare) {
  MarkerMap map = Squares(2);
  map.markers[1].square_tape.reset();  // alike, as the detector needs them
  const CameraInfo info = UpCamera();
  const Camera camera(info);
  for (const double offset_m : {0.0, 6.0}) {
    LocalizerOptions options;
    // The robot's pose at its first odometry sample, 0.3 m and 5 deg off the truth (+ offset_m).
    options.start_pose = SE2d(5.8 + 0.3 - offset_m, -0.3, 5.0 * M_PI / 180.0).ToSE3();
    Localizer localizer(options, map, {info});
    std::mt19937 rng(5);
    ASSERT_EQ(localizer.AddOdometry(0.0, SE2d(1.0, 2.0, 0.5).ToSE3()), StepStatus::kOk);
    // The odometry's frame is not the map's: 0.4 m forward in it before the first square.
    const SE3d T_world_robot = SE2d(6.2, -0.3, 0.0).ToSE3();
    ASSERT_EQ(localizer.AddOdometry(1.0, SE2d(1.0, 2.0, 0.5).ToSE3() * SE2d(0.4, 0.0, 0.0).ToSE3()),
              StepStatus::kOk);
    DetectionFrame frame;
    frame.stamp_s = 1.0;
    frame.camera = "up";
    frame.markers.push_back(*Detect(map.markers[1], camera, T_world_robot, &rng));
    ASSERT_EQ(localizer.AddDetections(frame).status, StepStatus::kOk);
    const PoseOutput output = localizer.Output();
    ASSERT_TRUE(output.T_world_robot.has_value()) << offset_m;
    EXPECT_EQ(localizer.counters().unknown_markers, 0);
    const double error_m =
        (output.T_world_robot->translation() - T_world_robot.translation()).head<2>().norm();
    EXPECT_NEAR(error_m, offset_m, 0.01) << offset_m;
  }
  // Without it the same detection is unknown.
  Localizer plain(LocalizerOptions{}, map, {info});
  std::mt19937 rng(5);
  DetectionFrame frame;
  frame.camera = "up";
  frame.markers.push_back(*Detect(map.markers[1], camera, SE2d(6.2, -0.3, 0.0).ToSE3(), &rng));
  ASSERT_EQ(plain.AddDetections(frame).status, StepStatus::kOk);
  EXPECT_FALSE(plain.Output().T_world_robot.has_value());
  EXPECT_EQ(plain.counters().unknown_markers, 1);
}

}  // namespace
}  // namespace waymark
