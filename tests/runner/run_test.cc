// The dataset runner (runner/run.h): SE(3) interpolation of the odometry to the frame instant,
// tight vs loose on the simulated corridor, a map of another place, codes absent from the map,
// time going backwards, frames outside the odometry, the live stream's waiting for odometry.
#include "runner/run.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <functional>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <random>

#include "detect/synthetic.h"
#include "geometry/camera.h"
#include "sim/simulator.h"

namespace waymark {
namespace {

// Position RMSE of the tracked poses against the ground truth at the same stamps.
double PositionRmse(const Trajectory& estimate, const Trajectory& truth) {
  std::map<double, SE3d> truth_by_stamp;
  for (const StampedSE3& pose : truth) truth_by_stamp[pose.stamp_s] = pose.T;
  double sum = 0.0;
  long n = 0;
  for (const StampedSE3& pose : estimate) {
    const auto it = truth_by_stamp.find(pose.stamp_s);
    if (it == truth_by_stamp.end()) continue;
    sum += (pose.T.translation() - it->second.translation()).squaredNorm();
    ++n;
  }
  EXPECT_GT(n, 0);
  return std::sqrt(sum / std::max<long>(n, 1));
}

const sim::SimResult& Corridor() {
  static const sim::SimResult result = sim::Simulate("corridor", sim::ScenarioParams("corridor"), 7);
  return result;
}

LocalizeRun RunCorridor(CorrectionMode mode, const MarkerMap& map) {
  const Dataset& dataset = Corridor().dataset;
  LocalizeRunOptions options;
  options.localizer = DefaultLocalizerOptions(dataset);
  options.localizer.mode = mode;
  return RunLocalizer(dataset, map, options);
}

TEST(ScrewTest, ExpLogRoundTripAndConstantTwist) {
  std::mt19937 rng(3);
  std::normal_distribution<double> normal(0.0, 1.0);
  for (int i = 0; i < 50; ++i) {
    Vector6d xi;
    for (int k = 0; k < 6; ++k) xi(k) = normal(rng);
    if (xi.head<3>().norm() > 3.0) xi.head<3>() *= 3.0 / xi.head<3>().norm();
    EXPECT_LT((LogSE3Screw(ExpSE3Screw(xi)) - xi).norm(), 1e-9) << i;
  }
  // Planar constant (v, omega): the arc x = v/w sin(w t), y = v/w (1 - cos(w t)), yaw = w t.
  const double v = 0.8, w = 0.9;
  const auto arc = [&](double t) {
    return SE3d::FromXYZYaw(v / w * std::sin(w * t), v / w * (1.0 - std::cos(w * t)), 0.0, w * t);
  };
  const SE3d T_a = SE3d::FromXYZYaw(1.0, 2.0, 0.0, 0.3) * arc(0.4);
  const SE3d T_b = SE3d::FromXYZYaw(1.0, 2.0, 0.0, 0.3) * arc(0.9);
  const SE3d T_mid = InterpolateScrew(T_a, T_b, 0.3);
  const SE3d T_true = SE3d::FromXYZYaw(1.0, 2.0, 0.0, 0.3) * arc(0.4 + 0.3 * 0.5);
  EXPECT_LT((T_mid.translation() - T_true.translation()).norm(), 1e-12);
  EXPECT_LT(RotationAngleBetween(T_mid, T_true), 1e-12);
  // Ends are exact.
  EXPECT_LT((InterpolateScrew(T_a, T_b, 1.0).translation() - T_b.translation()).norm(), 1e-12);
  EXPECT_LT((InterpolateScrew(T_a, T_b, 0.0).translation() - T_a.translation()).norm(), 1e-12);
}

// A robot on a constant-twist arc with odometry at 10 Hz and a forward camera that sees one
// code at t = 0 only; later frames (between odometry samples) are empty, so the pose there is
// the initial pose moved by the odometry interpolated to the frame instant.
struct ArcCase {
  Dataset dataset;
  MarkerMap map;
  static SE3d Odometry(double t) {
    const double v = 0.5, w = 0.6;
    return SE3d::FromXYZYaw(v / w * std::sin(w * t), v / w * (1.0 - std::cos(w * t)), 0.0, w * t);
  }
  ArcCase() {
    CameraInfo camera;
    camera.name = "front";
    camera.width = 640;
    camera.height = 480;
    camera.intrinsics = {500.0, 500.0, 320.0, 240.0};
    camera.distortion = {0.0, 0.0, 0.0, 0.0, 0.0};
    Eigen::Matrix3d R_robot_camera;
    R_robot_camera << 0, 0, 1, -1, 0, 0, 0, -1, 0;
    camera.T_robot_camera = SE3d(R_robot_camera, Eigen::Vector3d(0.0, 0.0, 0.3));
    dataset.config.cameras = {"front"};
    dataset.cameras["front"] = camera;
    Eigen::Matrix3d R_world_marker;
    R_world_marker << 0, 0, -1, -1, 0, 0, 0, 1, 0;
    MapMarker marker;
    marker.key = {kFamilyQr, "ahead"};
    marker.size_m = 0.35;
    // Turned 40 deg about z and seen from 1.2 m: a single-image pose without ambiguity, and
    // large enough in the image (~120 px) for the QR detector in the image test.
    marker.T_world_marker =
        SE3d(Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()).toRotationMatrix() * R_world_marker,
             Eigen::Vector3d(1.2, 0.1, 0.35));
    map.markers.push_back(marker);
    for (int i = 0; i <= 10; ++i) dataset.odometry.push_back({0.1 * i, Odometry(0.1 * i)});
    DetectionFrame first{0.0, "front", {}, std::nullopt, std::nullopt};
    const Camera model(camera);
    const SE3d T_camera_marker = camera.T_robot_camera.inverse() * marker.T_world_marker;
    MarkerObservation observation{marker.key, {}, std::nullopt};
    const auto corners = MarkerCorners(marker.size_m);
    for (int j = 0; j < 4; ++j) observation.corners_px[j] = *model.Project(T_camera_marker * corners[j]);
    first.markers.push_back(observation);
    dataset.detections.push_back(first);
    for (double t : {0.25, 0.55, 0.83})
      dataset.detections.push_back({t, "front", {}, std::nullopt, std::nullopt});
  }
};

TEST(RunLocalizerTest, OdometryInterpolatedExactlyToTheFrameInstant) {
  const ArcCase arc;
  LocalizeRunOptions options;
  options.localizer = DefaultLocalizerOptions(arc.dataset);
  const LocalizeRun run = RunLocalizer(arc.dataset, arc.map, options);
  ASSERT_EQ(run.outputs.size(), 4u);
  ASSERT_EQ(run.trajectory.size(), 4u);
  const SE3d T_world_robot0 = run.trajectory[0].T;
  for (size_t i = 1; i < run.trajectory.size(); ++i) {
    const double t = run.trajectory[i].stamp_s;
    const SE3d expected = T_world_robot0 * ArcCase::Odometry(0.0).inverse() * ArcCase::Odometry(t);
    EXPECT_LT((run.trajectory[i].T.translation() - expected.translation()).norm(), 1e-9) << t;
    EXPECT_LT(std::abs(WrapAngle(run.trajectory[i].T.yaw() - expected.yaw())), 1e-9) << t;
  }
  EXPECT_EQ(run.warnings.size(), 0u) << run.warnings.front();
  EXPECT_EQ(run.latency_ms.size(), 4u);
}

// The same run from images: the code drawn at its exact corners in the first image, the others
// blank, and one image file missing (a counted warning, the frame skipped).
TEST(RunLocalizerTest, DetectsOnTheDatasetsImages) {
  ArcCase arc;
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("waymark_run_test_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  arc.dataset.dir = dir;
  for (size_t i = 0; i < arc.dataset.detections.size(); ++i) {
    const DetectionFrame& frame = arc.dataset.detections[i];
    cv::Mat image(480, 640, CV_8U, cv::Scalar(128));
    if (!frame.markers.empty()) DrawSymbol(QrSymbol("ahead"), frame.markers[0].corners_px, &image);
    const std::string name = "image" + std::to_string(i) + ".png";
    ASSERT_TRUE(cv::imwrite((dir / name).string(), image));
    arc.dataset.images.push_back({frame.stamp_s, "front", name});
  }
  arc.dataset.images.push_back({0.9, "front", "absent.png"});
  LocalizeRunOptions options;
  options.localizer = DefaultLocalizerOptions(arc.dataset);
  options.detect_images = true;
  const LocalizeRun from_images = RunLocalizer(arc.dataset, arc.map, options);
  options.detect_images = false;
  const LocalizeRun from_detections = RunLocalizer(arc.dataset, arc.map, options);
  std::filesystem::remove_all(dir);
  ASSERT_EQ(from_images.outputs.size(), 4u);
  ASSERT_EQ(from_images.trajectory.size(), 4u);
  EXPECT_LT(
      (from_images.trajectory[0].T.translation() - from_detections.trajectory[0].T.translation()).norm(),
      0.01);
  EXPECT_GT(from_images.latency_ms[0], from_detections.latency_ms[0]);  // detection time counted
  ASSERT_EQ(from_images.warnings.size(), 1u);
  EXPECT_NE(from_images.warnings[0].find(kWarnImage), std::string::npos) << from_images.warnings[0];
  EXPECT_NE(from_images.warnings[0].find("absent.png"), std::string::npos) << from_images.warnings[0];
  EXPECT_EQ(DetectionFamilies(arc.map, {}), std::vector<std::string>{"qr"});
}

TEST(RunLocalizerTest, FramesOutsideTheOdometryAreCountedWarnings) {
  ArcCase arc;
  arc.dataset.odometry.erase(arc.dataset.odometry.begin() + 6, arc.dataset.odometry.end());  // ends at 0.5 s
  LocalizeRunOptions options;
  options.localizer = DefaultLocalizerOptions(arc.dataset);
  const LocalizeRun run = RunLocalizer(arc.dataset, arc.map, options);
  ASSERT_EQ(run.warnings.size(), 1u);
  EXPECT_NE(run.warnings[0].find(kWarnOutsideOdometry), std::string::npos) << run.warnings[0];
  EXPECT_NE(run.warnings[0].find(": 2 (first: front frame at t=0.55)"), std::string::npos) << run.warnings[0];
}

TEST(RunLocalizerTest, TimeGoingBackwardsIsACountedWarning) {
  ArcCase arc;
  std::swap(arc.dataset.odometry[3], arc.dataset.odometry[4]);  // 0.4 before 0.3: 0.3 is ignored
  arc.dataset.detections.push_back({0.5, "front", {}, std::nullopt, std::nullopt});  // after 0.83
  LocalizeRunOptions options;
  options.localizer = DefaultLocalizerOptions(arc.dataset);
  const LocalizeRun run = RunLocalizer(arc.dataset, arc.map, options);
  ASSERT_EQ(run.warnings.size(), 1u);
  EXPECT_NE(run.warnings[0].find(kWarnTimeBackwards), std::string::npos);
  EXPECT_NE(run.warnings[0].find(": 2 (first: odometry at t=0.3"), std::string::npos) << run.warnings[0];
  ASSERT_EQ(run.outputs.size(), 5u);
  EXPECT_FALSE(run.outputs.back().T_world_robot) << "a frame from the past gets no pose";
  EXPECT_EQ(run.trajectory.size(), 4u);
  EXPECT_EQ(run.counters.rejected_inputs, 1);  // the old frame; the old odometry never reached it
}

TEST(RunLocalizerTest, TightBeatsLooseOnTheCorridor) {
  const sim::SimResult& sim = Corridor();
  const MarkerMap& map = *sim.dataset.groundtruth_markers;
  const LocalizeRun tight = RunCorridor(CorrectionMode::kTightCorners, map);
  const LocalizeRun loose = RunCorridor(CorrectionMode::kLoosePose, map);
  const Trajectory& truth = *sim.dataset.groundtruth_trajectory;
  const double tight_m = PositionRmse(tight.trajectory, truth);
  const double loose_m = PositionRmse(loose.trajectory, truth);
  std::cout << "corridor seed 7: tight " << tight_m << " m, loose " << loose_m << " m over "
            << tight.trajectory.size() << " / " << loose.trajectory.size() << " tracked frames of "
            << tight.outputs.size() << "\n";
  EXPECT_LT(tight_m, 0.5 * loose_m);
  EXPECT_LT(tight_m, 0.02);
  EXPECT_GT(tight.trajectory.size(), 0.95 * sim.dataset.detections.size() / 2);  // 2 cameras per stamp
  EXPECT_EQ(tight.outputs.size(), sim.dataset.detections.size());
  EXPECT_EQ(tight.latency_ms.size(), tight.outputs.size());
  EXPECT_GT(tight.counters.accepted, 100);
  EXPECT_FALSE(tight.predicted.empty());
  for (size_t i = 1; i < tight.predicted.size(); ++i)
    ASSERT_LT(tight.predicted[i - 1].stamp_s, tight.predicted[i].stamp_s);
}

TEST(RunLocalizerTest, CodesAbsentFromTheMapAreCountedNeverAJump) {
  const sim::SimResult& sim = Corridor();
  MarkerMap half;
  for (size_t i = 0; i < sim.dataset.groundtruth_markers->markers.size(); i += 2)
    half.markers.push_back(sim.dataset.groundtruth_markers->markers[i]);
  const LocalizeRun run = RunCorridor(CorrectionMode::kTightCorners, half);
  bool counted = false;
  for (const std::string& line : run.warnings) counted |= line.find(kWarnUnknownCode) != std::string::npos;
  EXPECT_TRUE(counted);
  EXPECT_GT(run.counters.unknown_markers, 100);
  EXPECT_LT(PositionRmse(run.trajectory, *sim.dataset.groundtruth_trajectory), 0.03);
}

TEST(RunLocalizerTest, MapOfAnotherPlaceIsAnError) {
  const sim::SimResult& sim = Corridor();
  MarkerMap other = *sim.dataset.groundtruth_markers;
  for (MapMarker& marker : other.markers) marker.key.id = "elsewhere-" + marker.key.id;
  try {
    RunCorridor(CorrectionMode::kTightCorners, other);
    FAIL() << "expected an error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("another place"), std::string::npos) << e.what();
  }
}

TEST(RunLocalizerTest, DefaultOptionsFollowTheDataset) {
  const Dataset& dataset = Corridor().dataset;
  const LocalizerOptions options = DefaultLocalizerOptions(dataset);
  EXPECT_EQ(options.motion, dataset.config.motion);
  ASSERT_TRUE(dataset.config.odometry_sigma);
  EXPECT_EQ(options.odometry.sigma.trans_per_m, dataset.config.odometry_sigma->trans_per_m);
  EXPECT_EQ(options.odometry.sigma.rot_per_rad, dataset.config.odometry_sigma->rot_per_rad);
  Dataset free = dataset;
  free.config.motion = MotionModel::kFree;
  for (auto& [name, camera] : free.cameras) camera.pixel_sigma = 0.7;
  const LocalizerOptions free_options = DefaultLocalizerOptions(free);
  EXPECT_EQ(free_options.loose_noise.size(), 4);
  EXPECT_EQ(free_options.default_pixel_sigma_px, 0.7);
  std::string why;
  EXPECT_TRUE(free_options.Check(&why)) << why;
}

// A LocalizeStream over ArcCase's dataset and map that collects every frame output.
struct CollectingStream {
  CollectingStream(const ArcCase& arc, double late_frame_window_s = LocalizeRunOptions{}.late_frame_window_s)
      : stream(arc.dataset, arc.map, Options(arc, late_frame_window_s),
               [this](const LocalizeStream::FrameOutput& output) { outputs.push_back(output); }) {}
  static LocalizeRunOptions Options(const ArcCase& arc, double late_frame_window_s) {
    LocalizeRunOptions options;
    options.localizer = DefaultLocalizerOptions(arc.dataset);
    options.late_frame_window_s = late_frame_window_s;
    return options;
  }
  std::vector<LocalizeStream::FrameOutput> outputs;  // declared first: filled by `stream`
  LocalizeStream stream;
};

TEST(LocalizeStreamTest, AFrameWaitsForTheOdometryPastItsStamp) {
  const ArcCase arc;
  CollectingStream collecting(arc);
  LocalizeStream& stream = collecting.stream;
  const std::vector<LocalizeStream::FrameOutput>& outputs = collecting.outputs;
  stream.AddOdometry(0.0, ArcCase::Odometry(0.0));
  stream.AddFrame(arc.dataset.detections[0]);
  ASSERT_EQ(outputs.size(), 1u);
  stream.AddOdometry(0.1, ArcCase::Odometry(0.1));
  stream.AddOdometry(0.2, ArcCase::Odometry(0.2));
  stream.AddFrame(arc.dataset.detections[1]);  // t = 0.25 waits for 0.3
  EXPECT_EQ(outputs.size(), 1u);
  stream.AddOdometry(0.3, ArcCase::Odometry(0.3));
  ASSERT_EQ(outputs.size(), 2u);
  const SE3d expected = *outputs[0].pose.T_world_robot * ArcCase::Odometry(0.25);
  EXPECT_LT((outputs[1].pose.T_world_robot->translation() - expected.translation()).norm(), 1e-9);
  // Without odometry past it, a frame is released once the input is odometry_wait_s ahead.
  stream.AddFrame({0.55, "front", {}, std::nullopt, std::nullopt});
  stream.AddFrame(
      {0.55 + LocalizeRunOptions{}.odometry_wait_s + 0.01, "front", {}, std::nullopt, std::nullopt});
  EXPECT_EQ(outputs.size(), 3u);
  stream.Flush();
  EXPECT_EQ(outputs.size(), 4u);
  EXPECT_EQ(stream.warnings().Count(kWarnOutsideOdometry), 2);
}

// A frame that arrives after newer odometry (a slower camera pipeline) is used at its own stamp
// when it is at most late_frame_window_s late; without the window it is rejected.
TEST(LocalizeStreamTest, ALateFrameIsUsedAtItsStampWithinTheWindow) {
  const ArcCase arc;
  for (double window_s : {0.2, 0.0}) {
    CollectingStream collecting(arc, window_s);
    LocalizeStream& stream = collecting.stream;
    const std::vector<LocalizeStream::FrameOutput>& outputs = collecting.outputs;
    stream.AddOdometry(0.0, ArcCase::Odometry(0.0));
    stream.AddFrame(arc.dataset.detections[0]);
    for (double t : {0.1, 0.2, 0.3, 0.4}) stream.AddOdometry(t, ArcCase::Odometry(t));
    stream.AddFrame(arc.dataset.detections[1]);  // t = 0.25, 0.15 s late
    ASSERT_EQ(outputs.size(), 2u);
    if (window_s > 0.0) {
      ASSERT_TRUE(outputs[1].pose.T_world_robot.has_value());
      const SE3d expected = *outputs[0].pose.T_world_robot * ArcCase::Odometry(0.25);
      EXPECT_LT((outputs[1].pose.T_world_robot->translation() - expected.translation()).norm(), 1e-9);
      EXPECT_EQ(outputs[1].pose.stamp_s, 0.25);
      EXPECT_EQ(stream.warnings().Total(), 0);
    } else {
      EXPECT_EQ(outputs[1].result.status, StepStatus::kTimeWentBackwards);
      EXPECT_EQ(stream.warnings().Count(kWarnTimeBackwards), 1);
    }
  }
}

// [Bach]'s input: (v, omega) samples integrated along the unicycle's arc give the same poses
// as the odometry poses of that arc.
TEST(LocalizeStreamTest, VelocitiesPredictLikeTheOdometryOfTheSameArc) {
  const ArcCase arc;
  CollectingStream collecting(arc);
  LocalizeStream& stream = collecting.stream;
  const std::vector<LocalizeStream::FrameOutput>& outputs = collecting.outputs;
  size_t f = 0;
  for (int i = 0; i <= 10; ++i) {
    const double t = 0.1 * i;
    stream.AddVelocity(t, 0.5, 0.6);  // ArcCase's constant twist
    for (; f < arc.dataset.detections.size() && arc.dataset.detections[f].stamp_s <= t; ++f)
      stream.AddFrame(arc.dataset.detections[f]);
  }
  stream.Flush();
  ASSERT_EQ(outputs.size(), 4u);
  for (const LocalizeStream::FrameOutput& output : outputs) {
    ASSERT_TRUE(output.pose.T_world_robot.has_value());
    const SE3d expected = *outputs[0].pose.T_world_robot * ArcCase::Odometry(output.pose.stamp_s);
    EXPECT_LT((output.pose.T_world_robot->translation() - expected.translation()).norm(), 1e-9);
  }
  EXPECT_EQ(stream.warnings().Total(), 0);
  stream.AddVelocity(0.5, 0.5, 0.6);
  EXPECT_EQ(stream.warnings().Count(kWarnTimeBackwards), 1);
}

// Odometry stamped on a clock 0.3 s ahead of the images: with the offset given, the run is the
// one with synchronized stamps; without it, the poses are off.
TEST(RunLocalizerTest, OdometryTimeOffsetIsApplied) {
  const ArcCase arc;
  Dataset shifted = arc.dataset;
  for (StampedSE3& sample : shifted.odometry) sample.stamp_s += 0.3;
  LocalizeRunOptions options;
  options.localizer = DefaultLocalizerOptions(arc.dataset);
  const LocalizeRun reference = RunLocalizer(arc.dataset, arc.map, options);
  const LocalizeRun unsynced = RunLocalizer(shifted, arc.map, options);
  options.odometry_time_offset_s = 0.3;
  const LocalizeRun corrected = RunLocalizer(shifted, arc.map, options);
  ASSERT_EQ(corrected.trajectory.size(), reference.trajectory.size());
  double unsynced_worst_m = 0.0;
  for (size_t i = 0; i < reference.trajectory.size(); ++i) {
    EXPECT_LT((corrected.trajectory[i].T.translation() - reference.trajectory[i].T.translation()).norm(),
              1e-9);
    if (i < unsynced.trajectory.size()) {
      unsynced_worst_m =
          std::max(unsynced_worst_m,
                   (unsynced.trajectory[i].T.translation() - reference.trajectory[i].T.translation()).norm());
    }
  }
  EXPECT_GT(unsynced_worst_m, 0.05);
  options.odometry_time_offset_s = std::nan("");
  std::string why;
  EXPECT_FALSE(options.Check(&why));
}

TEST(RealtimePacerTest, ReleasesInputsAtThePaceOfTheirStamps) {
  RealtimePacer pacer;
  const auto start = std::chrono::steady_clock::now();
  pacer.WaitFor(100.0);   // the first stamp is "now"
  pacer.WaitFor(100.08);  // 80 ms later
  pacer.WaitFor(99.0);    // older: no wait
  const double elapsed_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_GE(elapsed_s, 0.08);
  EXPECT_LT(elapsed_s, 2.0);  // a loaded machine may oversleep, never by seconds
}

}  // namespace
}  // namespace waymark

namespace waymark {
namespace {

double SecondsOf(const std::function<void()>& work) {
  const auto start = std::chrono::steady_clock::now();
  work();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// Issue 18, finding 6: a stamp jump from 0 to 1e6 waited 11 days, one of 1e12 overflowed the
// clock conversion and did not wait at all. Each gap now waits at most the cap, and says so.
TEST(RealtimePacerTest, GapsAreCappedAndCounted) {
  RealtimePacer pacer(0.2);
  pacer.WaitFor(0.0);
  EXPECT_NEAR(SecondsOf([&] { pacer.WaitFor(0.1); }), 0.1, 0.08);  // a normal gap: waited
  EXPECT_NEAR(SecondsOf([&] { pacer.WaitFor(1e6); }), 0.2, 0.1);   // capped
  EXPECT_NEAR(SecondsOf([&] { pacer.WaitFor(1e18); }), 0.2, 0.1);  // no overflow: still waits
  EXPECT_LT(SecondsOf([&] { pacer.WaitFor(5.0); }), 0.05);         // backwards: no wait
  EXPECT_EQ(pacer.shortened_gaps(), 2);
  EXPECT_EQ(pacer.Summary(), "--realtime: 2 stamp gaps longer than 0.2 s were waited as 0.2 s");
  EXPECT_EQ(RealtimePacer().Summary(), "");
}

}  // namespace
}  // namespace waymark
