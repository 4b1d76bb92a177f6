// Survey ingest: bad input named by file, odometry gaps split (never bridged), link covariances,
// the stamp-uncertainty term and the odometry time-offset estimate on a synthetic survey.
#include "mapping/survey.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <string>

#include "factors/odometry_covariance.h"
#include "tests/mapping/synthetic_wall.h"

namespace waymark {
namespace {

using ::testing::HasSubstr;
using testing::kMarkerSizeM;
using testing::SyntheticSurvey;
using testing::TrueRobotPose;
using testing::WallMarkers;

bool HasNote(const Survey& survey, const std::string& text) {
  for (const std::string& note : survey.notes) {
    if (note.find(text) != std::string::npos) return true;
  }
  return false;
}

TEST(SurveyTest, DetectionOfAnUnknownCameraNamesFileAndCamera) {
  Dataset dataset = SyntheticSurvey(0.0);
  dataset.detections[3].camera = "cam9";
  try {
    IngestDataset(dataset);
    FAIL() << "expected an error";
  } catch (const std::runtime_error& e) {
    EXPECT_THAT(e.what(), HasSubstr("detections.jsonl: detection frame 4"));
    EXPECT_THAT(e.what(), HasSubstr("camera 'cam9' is not a camera of the dataset (known: cam0)"));
  }
}

TEST(SurveyTest, MarkerWithoutSizeNamesTheMarkerAndTheFiles) {
  Dataset dataset = SyntheticSurvey(0.0);
  dataset.config.default_marker_size_m.reset();
  try {
    IngestDataset(dataset);
    FAIL() << "expected an error";
  } catch (const std::runtime_error& e) {
    EXPECT_THAT(e.what(), HasSubstr("marker apriltag-36h11:"));
    EXPECT_THAT(e.what(), HasSubstr("has no size: it is not in markers.json and dataset.yaml has no "
                                    "default_marker_size_m"));
  }
  // A size-only entry of markers.json is enough.
  dataset.known_markers = MarkerMap();
  for (const auto& [key, T] : WallMarkers()) {
    MapMarker entry;
    entry.key = key;
    entry.size_m = kMarkerSizeM;
    entry.has_pose = false;
    dataset.known_markers->markers.push_back(entry);
  }
  const Survey survey = IngestDataset(dataset);
  EXPECT_EQ(survey.markers.size(), 3u);
  for (const SurveyMarker& m : survey.markers) EXPECT_FALSE(m.known.has_value());
}

TEST(SurveyTest, NonFiniteStampIsAnError) {
  Dataset dataset = SyntheticSurvey(0.0);
  dataset.detections[5].stamp_s = std::nan("");
  EXPECT_THROW(IngestDataset(dataset), std::runtime_error);
}

TEST(SurveyTest, OdometryGapSplitsAndIsNeverBridged) {
  Dataset dataset = SyntheticSurvey(0.0);
  Trajectory odometry;
  for (const StampedSE3& p : dataset.odometry) {
    if (p.stamp_s < 7.95 || p.stamp_s > 11.05) odometry.push_back(p);  // samples 7.9 and 11.1 s: a 3.2 s gap
  }
  dataset.odometry = odometry;
  const Survey survey = IngestDataset(dataset);
  EXPECT_EQ(survey.odometry_segments, 2);
  EXPECT_TRUE(HasNote(survey, "odometry: gap of 3.2 s")) << survey.notes.front();
  for (const SurveyFrame& frame : survey.frames) {
    const bool in_gap = frame.stamp_s > 7.9 && frame.stamp_s < 11.1;
    EXPECT_EQ(frame.T_odom_robot.has_value(), !in_gap) << frame.stamp_s;
    EXPECT_EQ(frame.segment, in_gap ? -1 : (frame.stamp_s < 8.0 ? 0 : 1)) << frame.stamp_s;
  }
  for (const OdometryLink& link : survey.odometry_links) {
    const double t_a = survey.frames[link.frame_a].stamp_s, t_b = survey.frames[link.frame_b].stamp_s;
    EXPECT_FALSE(t_a < 8.0 && t_b > 11.0) << "link across the gap: " << t_a << " -> " << t_b;
  }
  // 101 frames 0.2 s apart; the 16 at 8.0 .. 11.0 s have no odometry, which takes the 17 links
  // that touch them: 100 - 17 = 83 links.
  EXPECT_EQ(survey.odometry_links.size(), 83u);
}

TEST(SurveyTest, InterpolationAndLinkCovarianceAreTheSumOfIncrements) {
  const Dataset dataset = SyntheticSurvey(0.0);
  const SE3d mid = *InterpolateTrajectory(dataset.odometry, 1.05, 1.0);
  const SE3d a = TrueRobotPose(1.0), b = TrueRobotPose(1.1);
  EXPECT_LT((mid.translation() - 0.5 * (a.translation() + b.translation())).norm(), 1e-12);
  EXPECT_FALSE(InterpolateTrajectory(dataset.odometry, 100.0, 1.0).has_value());

  IngestOptions options;
  options.estimate_time_offset = false;
  const Survey survey = IngestDataset(dataset, options);
  ASSERT_EQ(survey.odometry_links.size(), 100u);
  const OdometryLink& link = survey.odometry_links[10];  // frames 2.0 s -> 2.2 s, samples 2.0, 2.1, 2.2
  const OdometrySigma sigma{0.02, 0.02};
  const OdometryNoiseFloor tiny{1e-12, 1e-12};
  Matrix6d expected = OdometryCovarianceSE3(sigma, TrueRobotPose(2.0).inverse() * TrueRobotPose(2.1), tiny) +
                      OdometryCovarianceSE3(sigma, TrueRobotPose(2.1).inverse() * TrueRobotPose(2.2), tiny);
  const OdometryNoiseFloor floor;
  expected.diagonal() += (Vector6d() << Eigen::Vector3d::Constant(floor.sigma_rad * floor.sigma_rad),
                          Eigen::Vector3d::Constant(floor.sigma_m * floor.sigma_m))
                             .finished();
  EXPECT_LT((link.covariance_se3 - expected).norm(), 1e-13);
  EXPECT_LT(link.T_a_b.BoxMinus(TrueRobotPose(2.0).inverse() * TrueRobotPose(2.2)).norm(), 1e-12);
}

// The random-walk terms add their variance over the link's duration and path (the samples'
// translations summed) on every axis.
TEST(SurveyTest, LinkCovarianceAddsTheRandomWalkOverTheLinksDurationAndPath) {
  Dataset dataset = SyntheticSurvey(0.0);
  IngestOptions options;
  options.estimate_time_offset = false;
  const Survey plain = IngestDataset(dataset, options);
  OdometrySigma sigma{0.02, 0.02};
  sigma.trans_per_sqrt_s = 0.03;
  sigma.rot_per_sqrt_s = 0.002;
  sigma.trans_per_sqrt_m = 0.01;
  sigma.rot_per_sqrt_m = 0.005;
  dataset.config.odometry_sigma = sigma;
  const Survey walk = IngestDataset(dataset, options);
  ASSERT_EQ(walk.odometry_links.size(), plain.odometry_links.size());
  const OdometryLink& a = plain.odometry_links[10];  // frames 2.0 s -> 2.2 s, samples 2.0, 2.1, 2.2
  const OdometryLink& b = walk.odometry_links[10];
  const double path_m = (TrueRobotPose(2.0).inverse() * TrueRobotPose(2.1)).translation().norm() +
                        (TrueRobotPose(2.1).inverse() * TrueRobotPose(2.2)).translation().norm();
  const OdometryWalkVariance expected = OdometryRandomWalk(sigma, 0.2, path_m);
  const Vector6d added = b.covariance_se3.diagonal() - a.covariance_se3.diagonal();
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(added(i), expected.rotation, 1e-12);
  for (int i = 3; i < 6; ++i) EXPECT_NEAR(added(i), expected.translation, 1e-12);
  const Eigen::Vector3d added_se2 = b.covariance_se2.diagonal() - a.covariance_se2.diagonal();
  EXPECT_NEAR(added_se2(0), expected.translation, 1e-12);
  EXPECT_NEAR(added_se2(2), expected.rotation, 1e-12);
}

// At constant velocity v along robot x, a clock error eps moves each end of an increment by v eps:
// j_a = -v e_x, j_b = +v e_x, so the term adds 2 sigma^2 v^2 to the x variance and nothing else.
TEST(SurveyTest, StampTermAddsTwoSigmaSquaredVelocitySquaredAlongTheMotion) {
  Dataset dataset = SyntheticSurvey(0.0);
  const double v_mps = 0.5;
  for (StampedSE3& p : dataset.odometry) p.T = SE3d::FromXYZYaw(v_mps * p.stamp_s, 0.0, 0.0, 0.0);
  IngestOptions plain, with_term;
  plain.estimate_time_offset = with_term.estimate_time_offset = false;
  with_term.stamp_sigma_s = 0.03;
  const Survey a = IngestDataset(dataset, plain), b = IngestDataset(dataset, with_term);
  ASSERT_EQ(a.odometry_links.size(), b.odometry_links.size());
  const Matrix6d added = b.odometry_links[20].covariance_se3 - a.odometry_links[20].covariance_se3;
  Matrix6d expected = Matrix6d::Zero();
  expected(3, 3) = 2.0 * std::pow(0.03 * v_mps, 2);
  EXPECT_LT((added - expected).norm(), 1e-9) << added;
  EXPECT_EQ(b.odometry_stamp_sigma_s, 0.03);
}

// Samples at 0, 1, 2, 3 s at x = 0, 0, 1, 1: the interval velocities are 0, 1, 0 m/s, so a = 1 m/s^2
// around both frames (0.5 s and 1.5 s, mid-interval: s = 0.5, D = 1 s) and each adds
// (0.5 * 1 * 0.25 * 1)^2 = 0.015625 m^2 per translation axis; no rotation, no rotation term.
TEST(SurveyTest, InterpolationTermFollowsTheOdometrysAcceleration) {
  Dataset dataset = SyntheticSurvey(0.0);
  dataset.detections = {DetectionFrame{}, DetectionFrame{}};
  dataset.detections[0].stamp_s = 0.5;
  dataset.detections[1].stamp_s = 1.5;
  for (DetectionFrame& frame : dataset.detections) frame.camera = "cam0";
  dataset.odometry.clear();
  const double x_m[] = {0.0, 0.0, 1.0, 1.0};
  for (int i = 0; i < 4; ++i) dataset.odometry.push_back({1.0 * i, SE3d::FromXYZYaw(x_m[i], 0.0, 0.0, 0.0)});
  IngestOptions without;
  without.max_odometry_gap_s = 2.0;
  without.interpolation_noise = false;
  IngestOptions with = without;
  with.interpolation_noise = true;
  const Survey a = IngestDataset(dataset, without), b = IngestDataset(dataset, with);
  ASSERT_EQ(b.odometry_links.size(), 1u);
  Matrix6d expected = Matrix6d::Zero();
  expected.diagonal().tail<3>().setConstant(2.0 * 0.015625);
  EXPECT_LT((b.odometry_links[0].covariance_se3 - a.odometry_links[0].covariance_se3 - expected).norm(),
            1e-12);
  EXPECT_NEAR(b.odometry_links[0].covariance_se2(0, 0) - a.odometry_links[0].covariance_se2(0, 0), 0.03125,
              1e-12);
}

TEST(SurveyTest, EstimatesTheOdometryTimeOffsetAndAppliesIt) {
  for (const double truth_s : {-0.5, 0.3}) {
    const Survey survey = IngestDataset(SyntheticSurvey(truth_s));
    EXPECT_NEAR(survey.odometry_time_offset_s, truth_s, 0.02);
    EXPECT_TRUE(HasNote(survey, "applied")) << truth_s;
    EXPECT_EQ(survey.odometry_stamp_sigma_s, IngestOptions().unsynced_stamp_sigma_s);
    // Increments read on the corrected clock are the true ones (up to interpolation between the
    // 10 Hz samples, which the 5 Hz frames straddle when the offset is not a multiple of 0.1 s).
    double worst_m = 0.0;
    for (const OdometryLink& link : survey.odometry_links) {
      const SE3d truth = TrueRobotPose(survey.frames[link.frame_a].stamp_s).inverse() *
                         TrueRobotPose(survey.frames[link.frame_b].stamp_s);
      worst_m = std::max(worst_m, (link.T_a_b.translation() - truth.translation()).norm());
    }
    EXPECT_LT(worst_m, 0.01) << truth_s;
  }
}

TEST(SurveyTest, SynchronizedOdometryKeepsZeroOffset) {
  const Dataset dataset = SyntheticSurvey(0.0);
  const Survey survey = IngestDataset(dataset);
  EXPECT_EQ(survey.odometry_time_offset_s, 0.0);
  EXPECT_EQ(survey.odometry_stamp_sigma_s, 0.0);
  const std::optional<TimeOffsetEstimate> estimate =
      EstimateOdometryTimeOffset(survey, dataset.odometry, IngestOptions());
  ASSERT_TRUE(estimate.has_value());
  EXPECT_NEAR(estimate->offset_s, 0.0, 0.02);
  EXPECT_GT(estimate->pairs, 100u);
  // A given offset is used as given, without estimating.
  IngestOptions given;
  given.odometry_time_offset_s = 0.25;
  const Survey shifted = IngestDataset(dataset, given);
  EXPECT_EQ(shifted.odometry_time_offset_s, 0.25);
  EXPECT_TRUE(HasNote(shifted, "time offset 0.25 s (given)"));
}

TEST(SurveyTest, OptionsAreChecked) {
  const std::pair<void (*)(IngestOptions*), std::string> cases[] = {
      {[](IngestOptions* o) { o->max_odometry_gap_s = 0.0; }, "max_odometry_gap_s"},
      {[](IngestOptions* o) { o->stamp_sigma_s = -1.0; }, "stamp_sigma_s"},
      {[](IngestOptions* o) { o->odometry_time_offset_s = std::nan(""); }, "odometry_time_offset_s"},
      {[](IngestOptions* o) { o->time_offset_min_gain = 1.0; }, "time_offset_min_gain"},
      {[](IngestOptions* o) { o->offset_window_s = 0.0; }, "offset_window_s"},
  };
  for (const auto& [mutate, field] : cases) {
    IngestOptions options;
    mutate(&options);
    std::string why;
    EXPECT_FALSE(options.Check(&why)) << field;
    EXPECT_THAT(why, HasSubstr(field));
    EXPECT_THROW(IngestDataset(SyntheticSurvey(0.0), options), std::runtime_error) << field;
  }
}

}  // namespace
}  // namespace waymark
