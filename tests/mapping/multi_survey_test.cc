// mapping/multi_survey.h: two surveys laid end to end in time with a gap, cameras renamed,
// known markers merged, the smoothed trajectory split back to each survey's own stamps;
// surveys that disagree are refused.
#include "mapping/multi_survey.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace waymark {
namespace {

using ::testing::HasSubstr;

Dataset Survey(const std::string& name, double t0) {
  Dataset d;
  d.config.name = name;
  d.config.cameras = {"cam0"};
  CameraInfo camera;
  camera.name = "cam0";
  d.cameras["cam0"] = camera;
  for (int i = 0; i < 10; ++i) d.odometry.push_back({t0 + i, SE3d()});
  DetectionFrame frame;
  frame.stamp_s = t0 + 2.5;
  frame.camera = "cam0";
  d.detections.push_back(frame);
  MapMarker known;
  known.key = {"qr", "A"};
  known.size_m = 0.1;
  d.known_markers = MarkerMap{};
  d.known_markers->markers.push_back(known);
  return d;
}

TEST(MultiSurvey, CombineAndSplit) {
  const Dataset a = Survey("a", 100.0), b = Survey("b", 50.0);
  const CombinedSurvey combined = CombineSurveys({&a, &b}, 10.0);
  ASSERT_EQ(combined.parts.size(), 2u);
  EXPECT_EQ(combined.parts[0].offset_s, 0.0);
  EXPECT_DOUBLE_EQ(combined.parts[1].begin_s, 119.0);  // a ends at 109, then a 10 s gap
  EXPECT_EQ(combined.dataset.config.cameras, (std::vector<std::string>{"a.cam0", "b.cam0"}));
  EXPECT_EQ(combined.dataset.odometry.size(), 20u);
  EXPECT_EQ(combined.dataset.detections[1].camera, "b.cam0");
  EXPECT_DOUBLE_EQ(combined.dataset.detections[1].stamp_s, 119.0 + 2.5);
  EXPECT_EQ(combined.dataset.known_markers->markers.size(), 1u);
  for (size_t i = 1; i < combined.dataset.odometry.size(); ++i)
    EXPECT_GT(combined.dataset.odometry[i].stamp_s, combined.dataset.odometry[i - 1].stamp_s);
  const std::map<std::string, Trajectory> parts = SplitTrajectory(combined, combined.dataset.odometry);
  ASSERT_EQ(parts.at("b").size(), 10u);
  EXPECT_NEAR(parts.at("b").front().stamp_s, 50.0, 1e-9);
  EXPECT_NEAR(parts.at("a").back().stamp_s, 109.0, 1e-9);
}

TEST(MultiSurvey, DisagreementsAreRefused) {
  const Dataset a = Survey("a", 0.0);
  Dataset b = Survey("b", 0.0);
  b.config.default_marker_size_m = 0.2;
  EXPECT_THROW(CombineSurveys({&a, &b}, 10.0), std::runtime_error);
  Dataset c = Survey("c", 0.0);
  c.known_markers->markers[0].size_m = 0.3;
  try {
    CombineSurveys({&a, &c}, 10.0);
    ADD_FAILURE() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_THAT(e.what(), HasSubstr("c: markers.json entry qr:A differs"));
  }
  const Dataset twin = Survey("a", 0.0);
  EXPECT_THROW(CombineSurveys({&a, &twin}, 10.0), std::runtime_error);
}

}  // namespace
}  // namespace waymark
