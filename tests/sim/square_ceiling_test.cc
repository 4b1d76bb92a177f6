// The square-ceiling scenario ([Seki]) and its infrared LED-pair renderer: the paper's setup by
// default, the options (several squares, camera tilt, lens calibration error), the photometry
// (tape bright only with the LEDs on, falling off with the angle; lamps in both frames; a person
// near the LEDs bright with them on) and the LED-pair files of a rendered dataset.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "geometry/camera.h"
#include "geometry/square_marker.h"
#include "io/dataset_io.h"
#include "sim/ir_render.h"
#include "sim/render_io.h"
#include "sim/scenarios.h"
#include "sim/sim_io.h"
#include "sim/simulator.h"

namespace waymark::sim {
namespace {

namespace fs = std::filesystem;

ParamSet Params(const std::vector<std::string>& sets) {
  ParamSet params = ScenarioParams("square-ceiling");
  for (const std::string& s : sets) params.SetAssignment(s);
  return params;
}

TEST(SquareCeilingTest, DefaultIsThePapersSetup) {
  const Scene scene = BuildScene("square-ceiling", Params({}));
  ASSERT_EQ(scene.world.markers.size(), 1u);
  const SimMarker& square = scene.world.markers[0];
  EXPECT_EQ(square.key, (MarkerKey{kFamilySquare, "S0"}));
  EXPECT_EQ(square.size_m, 2.0);
  ASSERT_TRUE(square.square_tape.has_value());
  EXPECT_EQ(square.square_tape->tape_width_m, 0.05);
  ASSERT_EQ(scene.world.cameras.size(), 1u);
  const CameraInfo& camera = scene.world.cameras[0];
  EXPECT_EQ(camera.model, CameraModel::kEquisolid);
  EXPECT_EQ(camera.width, 1280);
  EXPECT_EQ(camera.height, 1024);
  EXPECT_NEAR(camera.intrinsics[0], 2.3e-3 / 6.7e-6, 1e-9);
  // The ceiling 2 m above the camera, the camera looking straight up.
  const SE3d T_world_camera = scene.truth.T_world_robot.front().T * camera.T_robot_camera;
  EXPECT_NEAR(square.T_world_marker.translation().z() - T_world_camera.translation().z(), 2.0, 1e-12);
  EXPECT_NEAR((T_world_camera.rotation() * Eigen::Vector3d::UnitZ()).z(), 1.0, 1e-12);
  // The square faces down (its z towards the floor).
  EXPECT_NEAR((square.T_world_marker.rotation() * Eigen::Vector3d::UnitZ()).z(), -1.0, 1e-12);
  ASSERT_TRUE(scene.ir_room.has_value());
  EXPECT_EQ(scene.ir_room->lamps.size(), 2u);
}

TEST(SquareCeilingTest, SimulatedDatasetHasTheSquareInEveryFrame) {
  const SimResult result = Simulate("square-ceiling", Params({}), 1);
  const Dataset& d = result.dataset;
  ASSERT_TRUE(d.known_markers.has_value());
  ASSERT_EQ(d.known_markers->markers.size(), 1u);
  EXPECT_TRUE(d.known_markers->markers[0].fixed);
  ASSERT_TRUE(d.known_markers->markers[0].square_tape.has_value());
  long seen = 0;
  for (const DetectionFrame& frame : d.detections) seen += static_cast<long>(frame.markers.size());
  // The loop stays within 1.2 m of the centre: the square is in view all along (2 % missed at random).
  EXPECT_GT(seen, static_cast<long>(0.95 * d.detections.size()));
}

TEST(SquareCeilingTest, TiltAndLensErrorChangeOnlyTheTruth) {
  const Scene scene =
      BuildScene("square-ceiling",
                 Params({"camera.tilt_deg=0.5", "camera.lens_error_k1=0.01", "camera.focal_error=0.002"}));
  ASSERT_EQ(scene.world.calibrated_cameras.size(), 1u);
  const CameraInfo& truth = scene.world.cameras[0];
  const CameraInfo& calibrated = scene.world.calibrated_cameras[0];
  EXPECT_EQ(calibrated.distortion, std::vector<double>({0.0, 0.0, 0.0, 0.0}));
  EXPECT_EQ(truth.distortion[0], 0.01);
  EXPECT_NEAR(truth.intrinsics[0] / calibrated.intrinsics[0], 1.002, 1e-12);
  const Eigen::Vector3d axis_true = truth.T_robot_camera.rotation() * Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d axis_calibrated = calibrated.T_robot_camera.rotation() * Eigen::Vector3d::UnitZ();
  EXPECT_NEAR(std::acos(axis_true.dot(axis_calibrated)) * 180.0 / M_PI, 0.5, 1e-9);
  EXPECT_GT(axis_true.x(), 0.0);  // azimuth 0: towards the robot's front
  // The dataset gets the calibration; the simulated detections follow the true camera.
  const SimResult result = Simulate("square-ceiling", Params({"camera.tilt_deg=0.5"}), 2);
  const CameraInfo& written = result.dataset.cameras.at("up");
  EXPECT_NEAR((written.T_robot_camera.rotation() * Eigen::Vector3d::UnitZ()).z(), 1.0, 1e-12);
}

TEST(SquareCeilingTest, SeveralSquaresInALargerRoom) {
  const Scene scene = BuildScene("square-ceiling", Params({"place.squares=3"}));
  ASSERT_EQ(scene.world.markers.size(), 3u);
  EXPECT_EQ(scene.world.markers[2].key.id, "S2");
  EXPECT_NEAR(scene.world.markers[2].T_world_marker.translation().x(), 12.0, 1e-12);
  double max_x = -1e9;
  for (const StampedSE3& s : scene.truth.T_world_robot) max_x = std::max(max_x, s.T.translation().x());
  EXPECT_NEAR(max_x, 13.2, 1e-6);  // the loop goes round all three
  EXPECT_GT(scene.ir_room->room_max.x(), 14.0);
  EXPECT_THROW(BuildScene("square-ceiling", Params({"place.squares=2", "place.square_spacing_m=1.5"})),
               std::invalid_argument);
  EXPECT_THROW(BuildScene("square-ceiling", Params({"place.tape_width_m=0.9"})), std::invalid_argument);
}

// A quarter-size camera (320 x 256, same field of view) for quick renders.
Camera SmallCamera() {
  CameraInfo info;
  info.name = "small";
  info.model = CameraModel::kEquisolid;
  info.width = 320;
  info.height = 256;
  info.intrinsics = {343.28 / 4.0, 343.28 / 4.0, 160.0, 128.0};
  info.distortion = {0.0, 0.0, 0.0, 0.0};
  return Camera(info);
}

// The camera at (x, y, 0.3) looking up, image up = world +x.
SE3d Up(double x, double y) {
  return SE3d(RotationFromZY({0, 0, 1}, {-1, 0, 0}), Eigen::Vector3d(x, y, 0.3));
}

double At(const cv::Mat& image, const Eigen::Vector2d& px) {
  return image.at<std::uint8_t>(static_cast<int>(std::lround(px.y())), static_cast<int>(std::lround(px.x())));
}

TEST(IrRenderTest, TapeShinesOnlyWithTheLedsAndFallsOff) {
  const Scene scene = BuildScene("square-ceiling", Params({"ir.people=0", "ir.lamps=0"}));
  IrOptions options = IrOptionsFromParams(Params({"ir.people=0", "ir.lamps=0"}));
  const IrRenderer renderer(scene.world, *scene.ir_room, options, 3);
  const Camera camera = SmallCamera();
  const SE3d T_world_camera = Up(0.0, 0.0);
  const cv::Mat on = renderer.Render(camera, T_world_camera, 0.0, true, 0);
  const cv::Mat off = renderer.Render(camera, T_world_camera, 0.0, false, 1);
  const auto pixel = [&](double x, double y) {
    return *camera.Project(T_world_camera.inverse() * Eigen::Vector3d(x, y, 2.3));
  };
  // The middle of the solid side (marker +y = world -y) and of a dashed side's first dash.
  const Eigen::Vector2d solid = pixel(0.0, -1.0), ceiling = pixel(0.0, -0.6);
  EXPECT_GT(At(on, solid) - At(off, solid), 100.0);
  EXPECT_LT(std::abs(At(on, ceiling) - At(off, ceiling)), 25.0);
  // Further out the tape is dimmer: the same tape seen from 2.5 m to the side.
  const SE3d T_far = Up(-3.5, 0.0);
  const cv::Mat on_far = renderer.Render(camera, T_far, 0.0, true, 2);
  const Eigen::Vector2d solid_far = *camera.Project(T_far.inverse() * Eigen::Vector3d(0.0, -1.0, 2.3));
  EXPECT_LT(At(on_far, solid_far), 0.6 * At(on, solid));
  const cv::Mat off_far = renderer.Render(camera, T_far, 0.0, false, 3);
  // Still seen (the paper: to about 4 m); at a quarter of the resolution the 50 mm tape, ~1 px
  // wide there, covers its pixels only in part.
  EXPECT_GT(At(on_far, solid_far) - At(off_far, solid_far), 25.0);
  // Deterministic.
  EXPECT_EQ(cv::norm(on, renderer.Render(camera, T_world_camera, 0.0, true, 0), cv::NORM_INF), 0.0);
  // Beyond the 160 degree field of view: black.
  EXPECT_LE(on.at<std::uint8_t>(0, 0), 10);  // pixel noise only
}

TEST(IrRenderTest, LampsInBothFramesAndAPersonNearTheLeds) {
  const Scene scene = BuildScene("square-ceiling", Params({}));
  const IrOptions options = IrOptionsFromParams(Params({"ir.lamp_flicker=0"}));
  const IrRenderer renderer(scene.world, *scene.ir_room, options, 4);
  const Camera camera = SmallCamera();
  const Eigen::Vector2d lamp = scene.ir_room->lamps[0];
  SE3d T_world_camera = Up(lamp.x() - 0.5, lamp.y());
  // Keep the person out of this view: look from where the person is not.
  const std::vector<Eigen::Vector2d> people = renderer.PeopleAt(0.0);
  ASSERT_EQ(people.size(), 1u);
  const Eigen::Vector2d lamp_px =
      *camera.Project(T_world_camera.inverse() * Eigen::Vector3d(lamp.x(), lamp.y(), 2.3));
  if ((people[0] - lamp).norm() > 1.0) {
    EXPECT_GE(At(renderer.Render(camera, T_world_camera, 0.0, true, 0), lamp_px), 240.0);
    EXPECT_GE(At(renderer.Render(camera, T_world_camera, 0.0, false, 1), lamp_px), 240.0);
  }
  // The camera 0.4 m from the person's axis: the point of the person facing it, at 0.8 m.
  const Eigen::Vector2d p = people[0];
  const Eigen::Vector2d away = p.x() > 0.0 ? Eigen::Vector2d(-1, 0) : Eigen::Vector2d(1, 0);
  T_world_camera = Up(p.x() + 0.4 * away.x(), p.y());
  const Eigen::Vector3d surface(p.x() + options.person_radius_m * away.x(), p.y(), 0.8);
  const std::optional<Eigen::Vector2d> px = camera.Project(T_world_camera.inverse() * surface);
  ASSERT_TRUE(px.has_value());
  const double on = At(renderer.Render(camera, T_world_camera, 0.0, true, 2), *px);
  const double off = At(renderer.Render(camera, T_world_camera, 0.0, false, 3), *px);
  EXPECT_GT(on - off, 30.0);
  // People move: 0.5 s later the person stands elsewhere.
  EXPECT_NEAR((renderer.PeopleAt(0.5)[0] - p).norm(), 0.6, 0.6);
  EXPECT_GT((renderer.PeopleAt(0.5)[0] - p).norm(), 0.0);
}

TEST(IrRenderTest, BadOptionsAreRefused) {
  const Scene scene = BuildScene("square-ceiling", Params({}));
  IrOptions options;
  options.tape_albedo = 1.5;
  std::string why;
  EXPECT_FALSE(options.Check(&why));
  EXPECT_EQ(why, "ir: albedos must be in [0, 1]");
  EXPECT_THROW(IrRenderer(scene.world, *scene.ir_room, options, 0), std::invalid_argument);
  IrRoom flat = *scene.ir_room;
  flat.room_max = flat.room_min;
  EXPECT_THROW(IrRenderer(scene.world, flat, IrOptions{}, 0), std::invalid_argument);
}

TEST(IrRenderTest, RenderedDatasetHasLedPairs) {
  const ParamSet params = Params({"path.half_side_m=0"});  // two turns on the spot, 8 s
  const SimResult result = Simulate("square-ceiling", params, 5);
  const fs::path dir = fs::temp_directory_path() / ("waymark_ir_test_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  RenderStats stats;
  WriteSimDataset(result, params, 5, dir, false, [&](const fs::path& temp) {
    stats = RenderIrRun(result, IrOptionsFromParams(params), 5, 40, temp);
  });
  EXPECT_EQ(stats.images % 2, 0);
  EXPECT_GE(stats.images, 4);
  const Dataset dataset = LoadDataset(dir);
  ASSERT_EQ(static_cast<long>(dataset.images.size()), stats.images);
  for (size_t i = 0; i + 1 < dataset.images.size(); i += 2) {
    const ImageEntry& on = dataset.images[i];
    const ImageEntry& off = dataset.images[i + 1];
    EXPECT_NE(on.path.find("-on.png"), std::string::npos) << on.path;
    EXPECT_EQ(off.path, on.path.substr(0, on.path.size() - 7) + "-off.png");
    EXPECT_NEAR(off.stamp_s - on.stamp_s, 0.06, 1e-12);
    const cv::Mat a = cv::imread((dir / on.path).string(), cv::IMREAD_UNCHANGED);
    EXPECT_EQ(a.cols, 1280);
    EXPECT_EQ(a.rows, 1024);
  }
  // Ground-truth corners of the square at every on frame.
  std::ifstream corners(dir / "groundtruth" / "corners.jsonl");
  std::string line;
  int lines = 0;
  while (std::getline(corners, line)) {
    EXPECT_NE(line.find("\"square\""), std::string::npos);
    ++lines;
  }
  EXPECT_EQ(lines, stats.images / 2);
  fs::remove_all(dir);
}

TEST(IrRenderTest, InterpolateTrajectoryClampedBetweenSamples) {
  Trajectory truth = {{0.0, SE3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, 0))},
                      {1.0, SE3d(Eigen::Quaterniond(Eigen::AngleAxisd(1.0, Eigen::Vector3d::UnitZ())),
                                 Eigen::Vector3d(2, 0, 0))}};
  const SE3d mid = InterpolateTrajectoryClamped(truth, 0.25);
  EXPECT_NEAR(mid.translation().x(), 0.5, 1e-12);
  EXPECT_NEAR(mid.yaw(), 0.25, 1e-12);
  EXPECT_NEAR(InterpolateTrajectoryClamped(truth, 5.0).translation().x(), 2.0, 1e-12);
}

}  // namespace
}  // namespace waymark::sim
