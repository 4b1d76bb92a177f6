// Scoring a solution on a survey's observations (mapping/map_score.h), on the synthetic wall
// survey whose true map and trajectory are known, and the 3-D line fit.
#include "mapping/map_score.h"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "tests/mapping/synthetic_wall.h"

namespace waymark {
namespace {

using testing::kMarkerSizeM;
using testing::SyntheticSurvey;
using testing::TrueRobotPose;
using testing::WallMarkers;

MarkerMap TrueMap() {
  MarkerMap map;
  for (const auto& [key, T_world_marker] : WallMarkers()) {
    MapMarker m;
    m.key = key;
    m.size_m = kMarkerSizeM;
    m.T_world_marker = T_world_marker;
    map.markers.push_back(m);
  }
  return map;
}

Trajectory TrueTrajectory(const Dataset& dataset) {
  Trajectory trajectory;
  for (const DetectionFrame& frame : dataset.detections)
    trajectory.push_back({frame.stamp_s, TrueRobotPose(frame.stamp_s)});
  return trajectory;
}

TEST(MapScoreTest, TruthScoresTheCornerNoise) {
  const Dataset dataset = SyntheticSurvey(0.0);
  const MapScore score = ScoreMap(dataset, TrueMap(), TrueTrajectory(dataset));
  EXPECT_EQ(score.all.observations, score.observations);
  EXPECT_EQ(score.without_pose + score.without_marker + score.not_projected, 0u);
  // Corner noise 0.3 px per axis: the RMS over corners of the 2-D error is 0.3 * sqrt(2) = 0.42 px.
  EXPECT_NEAR(score.all.rms_px, 0.3 * std::sqrt(2.0), 0.03);
  ASSERT_EQ(score.per_camera.size(), 1u);
  EXPECT_EQ(score.per_camera[0].name, "cam0");
  ASSERT_EQ(score.per_marker.size(), 3u);
  for (const ReprojectionStats& s : score.per_marker) EXPECT_NEAR(s.rms_px, 0.42, 0.05) << s.name;
  EXPECT_LE(score.all.median_px, score.all.max_px);
}

TEST(MapScoreTest, WrongMarkerShowsAndMissingPosesAreCounted) {
  const Dataset dataset = SyntheticSurvey(0.0);
  MarkerMap map = TrueMap();
  map.markers[1].T_world_marker =
      map.markers[1].T_world_marker * SE3d::Exp((Vector6d() << 0, 0, 0, 0.05, 0, 0).finished());
  Trajectory trajectory = TrueTrajectory(dataset);
  trajectory.erase(trajectory.begin() + 10);
  const MapScore score = ScoreMap(dataset, map, trajectory);
  EXPECT_EQ(score.without_pose, dataset.detections[10].markers.size());
  ASSERT_EQ(score.per_marker.size(), 3u);
  EXPECT_GT(score.per_marker[1].rms_px, 5.0);  // 5 cm at 1.5 to 3 m: 12 to 23 px
  EXPECT_LT(score.per_marker[0].rms_px, 0.5);
}

// Two solutions on exactly the same observations: the frames another trajectory has no pose for
// are left out (and counted apart), whether or not the scored trajectory has poses there.
TEST(MapScoreTest, FramesOfAnotherTrajectoryRestrictTheScoredObservations) {
  const Dataset dataset = SyntheticSurvey(0.0);
  MarkerMap map = TrueMap();
  Trajectory trajectory = TrueTrajectory(dataset);
  // Frame 10's pose is far off in the scored solution; the other solution has no pose for it.
  trajectory[10].T = trajectory[10].T * SE3d::Exp((Vector6d() << 0, 0, 0, 0.2, 0, 0).finished());
  const MapScore all = ScoreMap(dataset, map, trajectory);
  MapScoreOptions options;
  options.frames_of = TrueTrajectory(dataset);
  options.frames_of->erase(options.frames_of->begin() + 10);
  const MapScore same = ScoreMap(dataset, map, trajectory, options);
  const size_t left_out = dataset.detections[10].markers.size();
  ASSERT_GT(left_out, 0u);
  EXPECT_EQ(all.outside_frames_of, 0u);
  EXPECT_EQ(same.outside_frames_of, left_out);
  EXPECT_EQ(same.without_pose, 0u);
  EXPECT_EQ(same.all.observations + left_out, all.all.observations);
  EXPECT_GT(all.all.max_px, 10.0);  // frame 10, 20 cm off: 19 px
  EXPECT_LT(same.all.max_px, 3.0);  // corner noise only
  EXPECT_NE(FormatMapScore(same).find("in frames --frames-of has no pose for"), std::string::npos);
}

TEST(MapScoreTest, MissingMarkerIsSolvedWithTheTrajectoryHeldFixed) {
  const Dataset dataset = SyntheticSurvey(0.0);
  MarkerMap map = TrueMap();
  const MapMarker removed = map.markers[2];
  map.markers.erase(map.markers.begin() + 2);
  const MapScore unsolved = ScoreMap(dataset, map, TrueTrajectory(dataset));
  EXPECT_GT(unsolved.without_marker, 50u);
  MapScoreOptions options;
  options.solve_missing_markers = true;
  const MapScore solved = ScoreMap(dataset, map, TrueTrajectory(dataset), options);
  ASSERT_EQ(solved.solved_markers.size(), 1u);
  EXPECT_EQ(solved.solved_markers[0], removed.key);
  EXPECT_EQ(solved.without_marker, 0u);
  const MapMarker* found = solved.map.Find(removed.key);
  ASSERT_NE(found, nullptr);
  EXPECT_LT((found->T_world_marker.translation() - removed.T_world_marker.translation()).norm(), 0.003);
  EXPECT_LT(RotationAngleBetween(found->T_world_marker, removed.T_world_marker), 0.01);
  EXPECT_NEAR(solved.all.rms_px, 0.42, 0.03);
}

TEST(MapScoreTest, WithoutTrajectoryFramesAreSolvedFromTheMap) {
  const Dataset dataset = SyntheticSurvey(0.0);
  const MapScore score = ScoreMap(dataset, TrueMap(), std::nullopt);
  size_t frames_with_codes = 0;
  for (const DetectionFrame& frame : dataset.detections) frames_with_codes += frame.markers.empty() ? 0 : 1;
  EXPECT_EQ(score.frames_solved, frames_with_codes);
  EXPECT_EQ(score.all.observations, score.observations);
  // Six pose parameters per frame fitted to its corners: below the noise, never far below.
  EXPECT_LT(score.all.rms_px, 0.42);
  EXPECT_GT(score.all.rms_px, 0.2);
}

TEST(MapScoreTest, BadInputIsAnError) {
  const Dataset dataset = SyntheticSurvey(0.0);
  MarkerMap map = TrueMap();
  map.markers[0].size_m = 0.0;
  EXPECT_THROW(ScoreMap(dataset, map, TrueTrajectory(dataset)), std::runtime_error);
  MapScoreOptions options;
  options.stamp_tolerance_s = -1.0;
  EXPECT_THROW(ScoreMap(dataset, TrueMap(), TrueTrajectory(dataset), options), std::runtime_error);
}

// Hand-computed: (-1,0,0), (1,0,0), (0,d,0), (0,-d,0) have scatter diag(2, 2 d^2, 0), so the line is
// the x axis through the origin; distances 0, 0, d, d: RMS d / sqrt(2), max d.
TEST(MapScoreTest, LineFitOfASymmetricCross) {
  const double d = 0.01;
  const LineFit fit = FitLine({{-1, 0, 0}, {1, 0, 0}, {0, d, 0}, {0, -d, 0}});
  EXPECT_LT(fit.point.norm(), 1e-15);
  EXPECT_NEAR(std::abs(fit.direction.x()), 1.0, 1e-12);
  EXPECT_NEAR(fit.rms_m, d / std::sqrt(2.0), 1e-12);
  EXPECT_NEAR(fit.max_m, d, 1e-12);
  const LineFit exact = FitLine({{0, 0, 1}, {1, 2, 3}, {2, 4, 5}});
  EXPECT_LT(exact.rms_m, 1e-12);
  EXPECT_THROW(FitLine({{1, 2, 3}}), std::invalid_argument);
  EXPECT_THROW(FitLine({{1, 2, 3}, {1, 2, 3}}), std::invalid_argument);
}

}  // namespace
}  // namespace waymark
