// End to end through the `waymark` binary: `waymark sim` writes a small survey, `waymark map
// build` maps it, `waymark map info` and `waymark map merge` read the result; bad inputs give
// one line on stderr, a non-zero exit and no output file.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <string>

#include "eval/map_metrics.h"
#include "geometry/pose.h"
#include "io/camera_io.h"
#include "io/map_io.h"
#include "io/tum_io.h"
#include "io/util.h"
#include "tests/cli/cli_test_util.h"

namespace waymark {
namespace {

namespace fs = std::filesystem;

class MapCliTest : public CliTest {
 protected:
  MapCliTest() : CliTest("map_cli") {}

  // A small corridor loop (4 m x 3 m) with 50 cm code spacing.
  fs::path SmallSurvey() const {
    const fs::path survey = dir_ / "survey";
    const RunResult sim = Run("sim corridor --out " + survey.string() +
                              " --seed 5 --set place.loop_length_m=4 --set place.loop_width_m=3 "
                              "--set place.spacing_m=0.5");
    EXPECT_EQ(sim.exit_code, 0) << sim.err;
    return survey;
  }

  // Replaces the first occurrence of `from` in a file.
  static void Edit(const fs::path& file, const std::string& from, const std::string& to) {
    std::string text = ReadTextFile(file);
    const size_t at = text.find(from);
    ASSERT_NE(at, std::string::npos) << from << " not in " << file;
    text.replace(at, from.size(), to);
    AtomicWriteFile(file, text);
  }
};

TEST_F(MapCliTest, BuildWritesMapAndTrajectoryAndSummary) {
  const fs::path survey = SmallSurvey();
  const RunResult build = Run("map build " + survey.string() + " --out " + (dir_ / "map.json").string() +
                              " --trajectory " + (dir_ / "smoothed.tum").string());
  ASSERT_EQ(build.exit_code, 0) << build.err;
  EXPECT_NE(build.out.find("component 0:"), std::string::npos) << build.out;
  EXPECT_NE(build.out.find("reprojection left: RMS"), std::string::npos) << build.out;
  EXPECT_NE(build.out.find("outliers rejected:"), std::string::npos);
  EXPECT_NE(build.out.find("solver:"), std::string::npos);
  EXPECT_TRUE(build.err.empty()) << "progress must stay off stderr in a pipe: " << build.err;
  const MarkerMap map = ReadMap(dir_ / "map.json");
  const eval::MapEvalResult error = eval::EvaluateMap(map, ReadMap(survey / "groundtruth/markers.json"));
  EXPECT_LE(error.position_rmse_m, 0.01);
  EXPECT_GT(ReadTum(dir_ / "smoothed.tum").size(), 100u);
  for (const MapMarker& m : map.markers) EXPECT_TRUE(m.fixed || m.covariance.has_value()) << m.key.ToString();

  const RunResult info = Run("map info " + (dir_ / "map.json").string());
  ASSERT_EQ(info.exit_code, 0) << info.err;
  EXPECT_NE(info.out.find("markers: " + std::to_string(map.markers.size())), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("components: 1"), std::string::npos) << info.out;
  // The error the covariances predict after alignment, in the build's summary and from map info.
  EXPECT_NE(info.out.find("component 0: "), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("mm RMS after alignment"), std::string::npos) << info.out;
  EXPECT_NE(build.out.find("mm RMS after alignment"), std::string::npos) << build.out;
}

// Issue 18, finding 4: `map build --out ok.json --trajectory afile/t.tum` exited 1 but left
// ok.json; the same file for two outputs is refused before the build.
TEST_F(MapCliTest, SeveralOutputsAreAllOrNothing) {
  const fs::path survey = SmallSurvey();
  AtomicWriteFile(dir_ / "afile", "a plain file\n");
  const RunResult build = Run("map build " + survey.string() + " --out " + (dir_ / "ok.json").string() +
                              " --trajectory " + (dir_ / "afile" / "t.tum").string());
  EXPECT_EQ(build.exit_code, 1);
  EXPECT_NE(build.err.find("afile/t.tum"), std::string::npos) << build.err;
  EXPECT_FALSE(fs::exists(dir_ / "ok.json"));
  const RunResult same = Run("map build " + survey.string() + " --out " + (dir_ / "m.json").string() +
                             " --report " + (dir_ / "m.json").string());
  EXPECT_EQ(same.exit_code, 1);
  EXPECT_NE(same.err.find("--out and --report name the same file"), std::string::npos) << same.err;
  EXPECT_FALSE(fs::exists(dir_ / "m.json"));
}

// Extrinsic self-calibration (issue 13, item 4): a camera file with T_robot_camera_sigma has its
// mount estimated; --cameras-out writes every camera with the estimate in place of the given one.
TEST_F(MapCliTest, CameraMountWithASigmaIsCalibratedAndWritten) {
  const fs::path survey = SmallSurvey();
  const CameraInfo truth = ReadCameraYaml(survey / "cameras" / "right.yaml");
  CameraInfo perturbed = truth;
  Vector6d delta;
  delta << 0.6, -0.5, 0.62, 0.5, 0.4, -0.77;  // 2 deg about a tilted axis, 3 cm
  delta.head<3>() *= (2.0 * M_PI / 180.0) / delta.head<3>().norm();
  delta.tail<3>() *= 0.03 / delta.tail<3>().norm();
  perturbed.T_robot_camera = truth.T_robot_camera * SE3d::Exp(delta);
  perturbed.T_robot_camera_sigma = std::array<double, 2>{0.05, 0.05};
  WriteCameraYaml(survey / "cameras" / "right.yaml", perturbed);

  const RunResult build =
      Run("map build " + survey.string() + " --out " + (dir_ / "map.json").string() + " --report " +
          (dir_ / "report.json").string() + " --cameras-out " + (dir_ / "calibrated").string());
  ASSERT_EQ(build.exit_code, 0) << build.err;
  EXPECT_NE(build.out.find("camera mount right (estimated): t ["), std::string::npos) << build.out;
  EXPECT_NE(build.out.find("cameras: 2 file(s) in "), std::string::npos) << build.out;
  const CameraInfo calibrated = ReadCameraYaml(dir_ / "calibrated" / "right.yaml");
  EXPECT_FALSE(calibrated.T_robot_camera_sigma.has_value());
  const double rotation_deg =
      RotationAngleBetween(calibrated.T_robot_camera, truth.T_robot_camera) * 180.0 / M_PI;
  // A planar survey cannot see the mount's height (it trades with the codes' heights; the prior
  // holds it): the horizontal offset is what the survey determines.
  const double translation_mm =
      1e3 * (calibrated.T_robot_camera.translation() - truth.T_robot_camera.translation()).head<2>().norm();
  EXPECT_LT(rotation_deg, 0.2) << build.out;
  EXPECT_LT(translation_mm, 5.0) << build.out;
  const CameraInfo left = ReadCameraYaml(dir_ / "calibrated" / "left.yaml");  // as given
  EXPECT_EQ(left.T_robot_camera.translation(),
            ReadCameraYaml(survey / "cameras" / "left.yaml").T_robot_camera.translation());
  const nlohmann::json report = nlohmann::json::parse(ReadTextFile(dir_ / "report.json"));
  ASSERT_EQ(report["camera_mounts"].size(), 1u);
  EXPECT_EQ(report["camera_mounts"][0]["camera"], "right");
  EXPECT_NEAR(report["camera_mounts"][0]["moved_m"].get<double>(), 0.03, 0.005);
  // Sigmas from the covariance: the rotation well determined; a translation sigma never above
  // the prior's (in a planar survey the mount's height trades with the codes' heights).
  ASSERT_TRUE(report["camera_mounts"][0].contains("sigma_t_m"));
  for (const auto& sigma : report["camera_mounts"][0]["sigma_rot_rad"])
    EXPECT_LT(sigma.get<double>(), 0.2 * M_PI / 180.0);
  for (const auto& sigma : report["camera_mounts"][0]["sigma_t_m"])
    EXPECT_LE(sigma.get<double>(), 0.05 + 1e-9);
  EXPECT_TRUE(report["outliers"].empty()) << build.out;

  // The perturbed mount held as given instead: the build rejects views it cannot fit.
  perturbed.T_robot_camera_sigma.reset();
  WriteCameraYaml(survey / "cameras" / "right.yaml", perturbed);
  const RunResult fixed = Run("map build " + survey.string() + " --out " + (dir_ / "fixed.json").string() +
                              " --report " + (dir_ / "fixed.json.report").string());
  ASSERT_EQ(fixed.exit_code, 0) << fixed.err;
  const nlohmann::json fixed_report = nlohmann::json::parse(ReadTextFile(dir_ / "fixed.json.report"));
  EXPECT_TRUE(fixed_report["camera_mounts"].empty());
  EXPECT_LT(fixed_report["observations_used"].get<size_t>(), report["observations_used"].get<size_t>());
}

// frame_wiggle_sigma: each frame's pose of the camera gets its own small deviation off the
// mount; the summary and the report give their spread, and the map stays as good.
TEST_F(MapCliTest, FrameWiggleIsEstimatedAndReported) {
  const fs::path survey = SmallSurvey();
  CameraInfo right = ReadCameraYaml(survey / "cameras" / "right.yaml");
  right.frame_wiggle_sigma = std::array<double, 2>{0.01, 0.01};
  WriteCameraYaml(survey / "cameras" / "right.yaml", right);
  const RunResult build =
      Run("map build " + survey.string() + " --out " + (dir_ / "map.json").string() + " --report " +
          (dir_ / "report.json").string() + " --cameras-out " + (dir_ / "cams").string());
  ASSERT_EQ(build.exit_code, 0) << build.err;
  EXPECT_NE(build.out.find("camera wiggle right (each frame's pose off the mount, "), std::string::npos)
      << build.out;
  const nlohmann::json report = nlohmann::json::parse(ReadTextFile(dir_ / "report.json"));
  ASSERT_EQ(report["camera_wiggles"].size(), 1u);
  EXPECT_GT(report["camera_wiggles"][0]["frames"].get<size_t>(), 100u);
  // The survey's cameras are synchronized: the deviations stay well inside their prior.
  EXPECT_LT(report["camera_wiggles"][0]["rms_rad"].get<double>(), 0.01);
  EXPECT_LT(report["camera_wiggles"][0]["rms_m"].get<double>(), 0.01);
  EXPECT_TRUE(report["camera_mounts"].empty());  // the mount itself is held
  EXPECT_EQ(ReadCameraYaml(dir_ / "cams" / "right.yaml").frame_wiggle_sigma, right.frame_wiggle_sigma);
  const eval::MapEvalResult error =
      eval::EvaluateMap(ReadMap(dir_ / "map.json"), ReadMap(survey / "groundtruth/markers.json"));
  EXPECT_LE(error.position_rmse_m, 0.01);
}

// Offline results depend on the input alone: two builds at two threads, the second beside busy
// threads on every core, write the same map and trajectory byte for byte. Without odometry the
// frames are eliminated first by a Schur complement (mapping/global_problem.cc), whose threaded
// sums used to land in a different order each run (every run of this survey differed); with
// odometry and with each frame's camera wiggle, the other two paths of the solve.
TEST_F(MapCliTest, BuildIsTheSameAtAnyLoad) {
  const fs::path survey = SmallSurvey();
  const auto build_twice = [&](const std::string& name) {
    std::string files[2];
    for (int run = 0; run < 2; ++run) {
      const fs::path map = dir_ / (name + std::to_string(run) + ".json");
      const fs::path trajectory = dir_ / (name + std::to_string(run) + ".tum");
      std::optional<CpuHog> hog;
      if (run == 1) hog.emplace();
      const RunResult build = Run("map build " + survey.string() + " --threads 2 --out " + map.string() +
                                  " --trajectory " + trajectory.string());
      EXPECT_EQ(build.exit_code, 0) << name << ": " << build.err;
      files[run] = ReadTextFile(map) + ReadTextFile(trajectory);
    }
    EXPECT_GT(files[0].size(), 1000u) << name;
    EXPECT_TRUE(files[0] == files[1]) << name << ": the two builds differ";
  };
  build_twice("odometry");
  CameraInfo right = ReadCameraYaml(survey / "cameras" / "right.yaml");
  right.frame_wiggle_sigma = std::array<double, 2>{0.01, 0.01};
  WriteCameraYaml(survey / "cameras" / "right.yaml", right);
  build_twice("wiggle");
  fs::remove(survey / "odometry.tum");
  Edit(survey / "dataset.yaml", "odometry_sigma:", "# odometry_sigma:");
  build_twice("no-odometry-wiggle");
  right.frame_wiggle_sigma.reset();
  WriteCameraYaml(survey / "cameras" / "right.yaml", right);
  build_twice("no-odometry");
}

// Issue 13, item 3: an odometry noise model that understates the odometry ten times (a drone
// whose odometry drifts ten times more than dataset.yaml says) let the odometry override the
// corners, and the gate rejected 1 317 of 4 561 correct views (29 %). The build now measures the
// odometry's noise on its residuals and scales the stated one: no correct view is rejected by
// the gate beyond a handful.
TEST_F(MapCliTest, UnderstatedOdometryNoiseIsEstimatedAndCornersKept) {
  const fs::path survey = dir_ / "drone";
  const RunResult sim = Run("sim warehouse-drone --out " + survey.string() +
                            " --seed 3 --set odometry.trans_per_m=0.1 --set odometry.rot_per_rad=0.1 "
                            "--set odometry.yaw_drift_deg_per_m=2 --set odometry.scale_error=0.05");
  ASSERT_EQ(sim.exit_code, 0) << sim.err;
  Edit(survey / "dataset.yaml", "odometry_sigma: {trans_per_m: 0.1, rot_per_rad: 0.1}",
       "odometry_sigma: {trans_per_m: 0.01, rot_per_rad: 0.01}");
  const RunResult build = Run("map build " + survey.string() + " --out " + (dir_ / "map.json").string() +
                              " --report " + (dir_ / "report.json").string() + " --no-covariance");
  ASSERT_EQ(build.exit_code, 0) << build.err;
  EXPECT_NE(build.out.find("odometry noise estimated from the data: "), std::string::npos) << build.out;
  const nlohmann::json report = nlohmann::json::parse(ReadTextFile(dir_ / "report.json"));
  const size_t gated =
      report["outliers_by_reason"].value("reprojection error above the outlier gate", size_t{0});
  EXPECT_LT(gated, report["observations_used"].get<size_t>() / 100) << build.out;
  // The id check sets none of these correct views aside (its visits, mapping/id_consistency.h).
  EXPECT_EQ(report["outliers"].size(), gated) << build.out;
  const eval::MapEvalResult error =
      eval::EvaluateMap(ReadMap(dir_ / "map.json"), ReadMap(survey / "groundtruth/markers.json"));
  EXPECT_LE(error.position_rmse_m, 0.008);
}

// Issue 13, item 3: the same drone (visual odometry drifting ten times the default), its noise
// stated as a VIO's: the white terms at a tenth of the truth, as above, and random walks per second
// and per metre (docs/mapping.md, "Odometry noise models"). No view is rejected for any reason
// (every view of the simulation is correct), and the map is as accurate as with the true noise.
TEST_F(MapCliTest, DriftingVioWithARandomWalkModelKeepsEveryCorrectView) {
  const fs::path survey = dir_ / "drone";
  const RunResult sim = Run("sim warehouse-drone --out " + survey.string() +
                            " --seed 3 --set odometry.trans_per_m=0.1 --set odometry.rot_per_rad=0.1 "
                            "--set odometry.yaw_drift_deg_per_m=2 --set odometry.scale_error=0.05");
  ASSERT_EQ(sim.exit_code, 0) << sim.err;
  Edit(
      survey / "dataset.yaml", "odometry_sigma: {trans_per_m: 0.1, rot_per_rad: 0.1}",
      "odometry_sigma: {trans_per_m: 0.01, rot_per_rad: 0.01, trans_per_sqrt_s: 0.02, rot_per_sqrt_s: 0.01}");
  const RunResult build = Run("map build " + survey.string() + " --out " + (dir_ / "map.json").string() +
                              " --report " + (dir_ / "report.json").string() + " --no-covariance");
  ASSERT_EQ(build.exit_code, 0) << build.err;
  const nlohmann::json report = nlohmann::json::parse(ReadTextFile(dir_ / "report.json"));
  EXPECT_EQ(report["outliers"].size(), 0u) << build.out;
  const eval::MapEvalResult error =
      eval::EvaluateMap(ReadMap(dir_ / "map.json"), ReadMap(survey / "groundtruth/markers.json"));
  EXPECT_LE(error.position_rmse_m, 0.004);  // 2.6 mm measured; 4.4 mm with the true white noise stated
}

// --cameras-out: one camera survey only; an impossible directory writes nothing.
TEST_F(MapCliTest, CamerasOutErrors) {
  const fs::path survey = SmallSurvey();
  const RunResult two = Run("map build " + survey.string() + " " + survey.string() + " --out " +
                            (dir_ / "m.json").string() + " --cameras-out " + (dir_ / "c").string());
  EXPECT_EQ(two.exit_code, 1);
  EXPECT_NE(two.err.find("--cameras-out is for one dataset"), std::string::npos) << two.err;
  AtomicWriteFile(dir_ / "afile", "a plain file\n");
  const RunResult bad = Run("map build " + survey.string() + " --out " + (dir_ / "m.json").string() +
                            " --cameras-out " + (dir_ / "afile" / "cams").string());
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_NE(bad.err.find("afile/cams"), std::string::npos) << bad.err;
  EXPECT_FALSE(fs::exists(dir_ / "m.json"));
  EXPECT_FALSE(fs::exists(dir_ / "c"));
}

TEST_F(MapCliTest, MergeKeepsTheMapFrameAndUnseenCodes) {
  const fs::path survey = SmallSurvey();
  ASSERT_EQ(Run("map build " + survey.string() + " --out " + (dir_ / "map.json").string()).exit_code, 0);
  // A map with one extra code the survey never sees: it must be carried over unchanged.
  MarkerMap map = ReadMap(dir_ / "map.json");
  MapMarker extra = map.markers.front();
  extra.key.id = "not-in-survey";
  extra.covariance.reset();  // and so no joint factor either
  extra.covariance_factor.reset();
  map.markers.push_back(extra);
  WriteMap(dir_ / "map_plus.json", map);
  const RunResult merge = Run("map merge " + (dir_ / "map_plus.json").string() + " " + survey.string() +
                              " --out " + (dir_ / "merged.json").string());
  ASSERT_EQ(merge.exit_code, 0) << merge.err;
  EXPECT_NE(merge.out.find("carried over unchanged"), std::string::npos) << merge.out;
  const MarkerMap merged = ReadMap(dir_ / "merged.json");
  ASSERT_NE(merged.Find(extra.key), nullptr);
  EXPECT_EQ(merged.Find(extra.key)->T_world_marker.translation(), extra.T_world_marker.translation());
  const eval::MapEvalResult error = eval::EvaluateMap(merged, ReadMap(survey / "groundtruth/markers.json"));
  EXPECT_LE(error.position_rmse_m, 0.01);
  // The build's options that merge does not run are refused, not ignored.
  for (const std::string option : {"--range-model distance", "--depth-ranges", "--trajectory-dir d"}) {
    const RunResult refused = Run("map merge " + (dir_ / "map_plus.json").string() + " " + survey.string() +
                                  " --out " + (dir_ / "refused.json").string() + " " + option);
    EXPECT_EQ(refused.exit_code, 1) << option;
    EXPECT_NE(refused.err.find("is for map build, not map merge"), std::string::npos) << refused.err;
    EXPECT_FALSE(fs::exists(dir_ / "refused.json"));
  }
}

// The shipped demo survey has images only: map build reads no detections.jsonl there, says
// so, and with --detect-images detects on the images itself.
TEST_F(MapCliTest, ImagesOnlySurveyNeedsDetectImagesThenMaps) {
  const fs::path survey = fs::path(WAYMARK_SOURCE_DIR) / "data/demo/survey";
  ASSERT_FALSE(fs::exists(survey / "detections.jsonl"));
  const RunResult plain = Run("map build " + survey.string() + " --out " + (dir_ / "map.json").string());
  EXPECT_NE(plain.exit_code, 0);
  EXPECT_NE(plain.err.find("--detect-images"), std::string::npos) << plain.err;
  EXPECT_FALSE(fs::exists(dir_ / "map.json"));
  const RunResult families =
      Run("map build " + survey.string() + " --families qr --out " + (dir_ / "map.json").string());
  EXPECT_NE(families.exit_code, 0);
  EXPECT_NE(families.err.find("--families is for --detect-images"), std::string::npos) << families.err;

  const RunResult build = Run("map build " + survey.string() + " --detect-images --families qr --out " +
                              (dir_ / "map.json").string());
  ASSERT_EQ(build.exit_code, 0) << build.err;
  const MarkerMap map = ReadMap(dir_ / "map.json");
  EXPECT_GE(map.markers.size(), 25u);
  const eval::MapEvalResult error = eval::EvaluateMap(map, ReadMap(survey / "groundtruth/markers.json"));
  EXPECT_LE(error.position_rmse_m, 0.02);
}

TEST_F(MapCliTest, SurveyWithoutAnyCodeIsAnErrorAndWritesNothing) {
  const fs::path survey = SmallSurvey();
  std::istringstream lines(ReadTextFile(survey / "detections.jsonl"));
  std::string line, emptied;
  while (std::getline(lines, line)) {
    const size_t at = line.find("\"markers\"");
    ASSERT_NE(at, std::string::npos) << line;
    emptied += line.substr(0, at) + "\"markers\": []}\n";
  }
  AtomicWriteFile(survey / "detections.jsonl", emptied);
  const RunResult build = Run("map build " + survey.string() + " --out " + (dir_ / "map.json").string());
  EXPECT_NE(build.exit_code, 0);
  EXPECT_NE(build.err.find("hold no code"), std::string::npos) << build.err;
  EXPECT_FALSE(fs::exists(dir_ / "map.json"));
}

TEST_F(MapCliTest, UnknownCameraIsAnErrorAndWritesNothing) {
  const fs::path survey = SmallSurvey();
  Edit(survey / "detections.jsonl", "\"camera\":\"left\"", "\"camera\":\"cam9\"");
  const RunResult build = Run("map build " + survey.string() + " --out " + (dir_ / "map.json").string());
  EXPECT_NE(build.exit_code, 0);
  EXPECT_NE(build.err.find("cam9"), std::string::npos) << build.err;
  EXPECT_FALSE(fs::exists(dir_ / "map.json"));
}

TEST_F(MapCliTest, MarkerWithoutSizeIsAnErrorAndWritesNothing) {
  const fs::path survey = SmallSurvey();
  Edit(survey / "dataset.yaml", "default_marker_size_m:", "# default_marker_size_m:");
  // markers.json gives every simulated code's size: keep only its anchors (with their sizes),
  // so the other codes have no size from anywhere.
  MarkerMap known = ReadMap(survey / "markers.json", nullptr, MapPoses::kOptional);
  known.markers.erase(std::remove_if(known.markers.begin(), known.markers.end(),
                                     [](const MapMarker& m) { return !m.has_pose; }),
                      known.markers.end());
  WriteMap(survey / "markers.json", known);
  const RunResult build = Run("map build " + survey.string() + " --out " + (dir_ / "map.json").string() +
                              " --trajectory " + (dir_ / "t.tum").string());
  EXPECT_NE(build.exit_code, 0);
  EXPECT_NE(build.err.find("has no size"), std::string::npos) << build.err;
  EXPECT_FALSE(fs::exists(dir_ / "map.json"));
  EXPECT_FALSE(fs::exists(dir_ / "t.tum"));
}

TEST_F(MapCliTest, OdometryGapIsReported) {
  const fs::path survey = SmallSurvey();
  // Drop 3 s of odometry in the middle.
  Trajectory odometry = ReadTum(survey / "odometry.tum");
  const double t0 = odometry[odometry.size() / 2].stamp_s;
  Trajectory gapped;
  for (const StampedSE3& p : odometry) {
    if (p.stamp_s < t0 || p.stamp_s > t0 + 3.0) gapped.push_back(p);
  }
  WriteTum(survey / "odometry.tum", gapped);
  const RunResult build = Run("map build " + survey.string() + " --out " + (dir_ / "map.json").string());
  ASSERT_EQ(build.exit_code, 0) << build.err;
  EXPECT_NE(build.out.find("odometry: gap of"), std::string::npos) << build.out;
}

TEST_F(MapCliTest, OdometryCalibrationIsReportedAndCanBeGiven) {
  const fs::path survey = SmallSurvey();
  const RunResult estimated = Run("map build " + survey.string() + " --out " + (dir_ / "map.json").string() +
                                  " --report " + (dir_ / "report.json").string());
  ASSERT_EQ(estimated.exit_code, 0) << estimated.err;
  EXPECT_NE(estimated.out.find("odometry calibration (estimated): heading drift"), std::string::npos)
      << estimated.out;
  const nlohmann::json report = nlohmann::json::parse(ReadTextFile(dir_ / "report.json"));
  ASSERT_TRUE(report.contains("odometry_calibration")) << report.dump();
  EXPECT_FALSE(report["odometry_calibration"]["given"].get<bool>());
  EXPECT_EQ(report["odometry_calibration"]["sigma"].size(), 3u);

  const RunResult given =
      Run("map build " + survey.string() + " --out " + (dir_ / "map2.json").string() + " --report " +
          (dir_ / "report2.json").string() + " --odometry-calibration 0.003,-0.005,0");
  ASSERT_EQ(given.exit_code, 0) << given.err;
  EXPECT_NE(given.out.find("odometry calibration (given)"), std::string::npos) << given.out;
  const nlohmann::json report2 = nlohmann::json::parse(ReadTextFile(dir_ / "report2.json"));
  EXPECT_TRUE(report2["odometry_calibration"]["given"].get<bool>());
  EXPECT_DOUBLE_EQ(report2["odometry_calibration"]["k_rad_per_m"].get<double>(), 0.003);
  EXPECT_DOUBLE_EQ(report2["odometry_calibration"]["turn_scale"].get<double>(), -0.005);

  for (const char* bad : {"0.003,-0.005", "0.003,x,0", "0,-1,0", "0,0,0,0.1,0,0.1"}) {
    const RunResult run = Run("map build " + survey.string() + " --out " + (dir_ / "bad.json").string() +
                              " --odometry-calibration " + bad);
    EXPECT_NE(run.exit_code, 0) << bad;
    EXPECT_NE(run.err.find("calibration"), std::string::npos) << bad << ": " << run.err;
    EXPECT_EQ(std::count(run.err.begin(), run.err.end(), '\n'), 1) << run.err;
    EXPECT_FALSE(fs::exists(dir_ / "bad.json")) << bad;
  }
  const RunResult both = Run("map build " + survey.string() + " --out " + (dir_ / "bad.json").string() +
                             " --odometry-calibration 0,0,0 --no-calibration");
  EXPECT_NE(both.exit_code, 0);
  EXPECT_NE(both.err.find("exclude each other"), std::string::npos) << both.err;
}

// Item 6 of issue 13: per camera RMS and median, rejected observations by reason and by code,
// time and peak memory per phase, in the summary and in --report.
TEST_F(MapCliTest, ReportHasMedianPhasesPeakMemoryAndOutlierTallies) {
  const fs::path survey = SmallSurvey();
  const RunResult build = Run("map build " + survey.string() + " --out " + (dir_ / "map.json").string() +
                              " --report " + (dir_ / "report.json").string());
  ASSERT_EQ(build.exit_code, 0) << build.err;
  EXPECT_NE(build.out.find("px, median "), std::string::npos) << build.out;
  EXPECT_NE(build.out.find("phases: ingest "), std::string::npos) << build.out;
  EXPECT_NE(build.out.find("MiB"), std::string::npos) << build.out;
  const nlohmann::json report = nlohmann::json::parse(ReadTextFile(dir_ / "report.json"));
  ASSERT_FALSE(report["reprojection"].empty()) << report.dump();
  const double rms = report["reprojection"][0]["rms_px"].get<double>();
  const double median = report["reprojection"][0]["median_px"].get<double>();
  EXPECT_GT(median, 0.0);
  EXPECT_LE(median, 1.5 * rms);
  std::vector<std::string> phases;
  for (const auto& p : report["phases"]) {
    phases.push_back(p["phase"].get<std::string>());
    EXPECT_GE(p["seconds"].get<double>(), 0.0);
  }
  for (const std::string name : {"ingest", "single views", "local maps", "local map graph", "robust solve",
                                 "final solve", "covariance"}) {
    EXPECT_NE(std::find(phases.begin(), phases.end(), name), phases.end()) << name;
  }
  EXPECT_GT(report["peak_rss_mb"].get<double>(), 1.0);
  size_t by_reason = 0, by_code = 0;
  for (const auto& [reason, n] : report["outliers_by_reason"].items()) by_reason += n.get<size_t>();
  for (const auto& [code, n] : report["outliers_by_code"].items()) by_code += n.get<size_t>();
  EXPECT_EQ(by_reason, report["outliers"].size());
  EXPECT_EQ(by_code, report["outliers"].size());
}

TEST_F(MapCliTest, PayloadSigmaMustBePositive) {
  const fs::path survey = SmallSurvey();
  for (const char* bad : {"0", "-0.01", "x"}) {
    const RunResult run = Run("map build " + survey.string() + " --out " + (dir_ / "bad.json").string() +
                              " --payload-sigma " + bad);
    EXPECT_NE(run.exit_code, 0) << bad;
    EXPECT_NE(run.err.find("payload"), std::string::npos) << bad << ": " << run.err;
    EXPECT_FALSE(fs::exists(dir_ / "bad.json")) << bad;
  }
  const RunResult good = Run("map build " + survey.string() + " --out " + (dir_ / "map.json").string() +
                             " --payload-sigma 0.002");
  EXPECT_EQ(good.exit_code, 0) << good.err;
}

TEST_F(MapCliTest, MissingOutputAndBadVerbAreErrors) {
  EXPECT_NE(Run("map build " + dir_.string()).exit_code, 0);
  const RunResult verb = Run("map frobnicate");
  EXPECT_NE(verb.exit_code, 0);
  EXPECT_NE(verb.err.find("unknown verb"), std::string::npos) << verb.err;
  const RunResult missing =
      Run("map build " + (dir_ / "nope").string() + " --out " + (dir_ / "m.json").string());
  EXPECT_NE(missing.exit_code, 0);
  EXPECT_FALSE(fs::exists(dir_ / "m.json"));
}

}  // namespace
}  // namespace waymark
