// Initialization (mapping/initializer.h) on small synthetic surveys with exact truth: a code
// whose first view is flipped, and disconnected groups.
#include "mapping/initializer.h"

#include <gtest/gtest.h>

#include <random>

#include "geometry/marker_pose.h"
#include "tests/mapping/synthetic_wall.h"

namespace waymark {
namespace {

using testing::ForwardCamera;
using testing::WallCode;

constexpr double kDeg = M_PI / 180.0;

// Builds a planar survey: robots at the given poses (consecutive ones joined by exact odometry
// unless a break is listed), each seeing the listed codes with Gaussian corner noise.
class SurveyBuilder {
 public:
  SurveyBuilder() {
    survey_.motion = MotionModel::kPlanar;
    survey_.cameras["cam0"] = ForwardCamera();
  }
  int AddCode(const std::string& id, const SE3d& T_world_marker, double size_m) {
    SurveyMarker marker;
    marker.key = {"qr", id};
    marker.size_m = size_m;
    survey_.markers.push_back(marker);
    codes_.push_back(T_world_marker);
    return static_cast<int>(codes_.size()) - 1;
  }
  // A frame seeing `codes`; linked by odometry to the previous frame when `linked`.
  void AddFrame(const SE3d& T_world_robot, const std::vector<int>& codes, bool linked, std::mt19937* rng,
                double sigma_px = 0.5) {
    const int f = static_cast<int>(survey_.frames.size());
    SurveyFrame frame;
    frame.stamp_s = 0.1 * f;
    survey_.frames.push_back(frame);
    if (linked && f > 0) {
      OdometryLink link;
      link.frame_a = f - 1;
      link.frame_b = f;
      link.T_a_b = robots_.back().inverse() * T_world_robot;
      link.covariance_se3 = Matrix6d::Identity() * 1e-6;
      link.covariance_se2 = Eigen::Matrix3d::Identity() * 1e-6;
      survey_.odometry_links.push_back(link);
    }
    robots_.push_back(T_world_robot);
    const Camera camera(survey_.cameras["cam0"]);
    const SE3d T_camera_world = (T_world_robot * camera.info().T_robot_camera).inverse();
    std::normal_distribution<double> noise(0.0, sigma_px);
    for (int m : codes) {
      SurveyObservation obs;
      obs.frame = f;
      obs.marker = m;
      obs.camera = "cam0";
      const auto corners_marker = MarkerCorners(survey_.markers[m].size_m);
      for (int k = 0; k < 4; ++k) {
        const auto px = camera.Project(T_camera_world * (codes_[m] * corners_marker[k]));
        EXPECT_TRUE(px.has_value());
        obs.corners_px[k] = *px + Eigen::Vector2d(noise(*rng), noise(*rng));
      }
      survey_.frames[f].observations.push_back(static_cast<int>(survey_.observations.size()));
      survey_.markers[m].observations.push_back(static_cast<int>(survey_.observations.size()));
      survey_.observations.push_back(obs);
    }
  }
  // markers.json gives code m as a prior of these sigmas (rad, m) at `T_world_marker`.
  void SetPrior(int m, const SE3d& T_world_marker, double sigma_rad, double sigma_m) {
    MapMarker known;
    known.key = survey_.markers[m].key;
    known.size_m = survey_.markers[m].size_m;
    known.T_world_marker = T_world_marker;
    Vector6d variances;
    variances << Eigen::Vector3d::Constant(sigma_rad * sigma_rad),
        Eigen::Vector3d::Constant(sigma_m * sigma_m);
    known.covariance = Matrix6d(variances.asDiagonal());
    survey_.markers[m].known = known;
  }
  const Survey& survey() const { return survey_; }
  const SE3d& robot(int f) const { return robots_[f]; }
  const SE3d& code(int m) const { return codes_[m]; }

 private:
  Survey survey_;
  std::vector<SE3d> robots_;
  std::vector<SE3d> codes_;
};

// A robot driving 1 m along x towards a small oblique code 2.5 m ahead, 20 frames.
SurveyBuilder DriveTowardsCode(unsigned seed) {
  std::mt19937 rng(seed);
  SurveyBuilder builder;
  const int code = builder.AddCode("A", WallCode(Eigen::Vector3d(3.2, 0.5, 0.35), 25.0 * kDeg), 0.08);
  for (int i = 0; i < 20; ++i)
    builder.AddFrame(SE3d::FromXYZYaw(0.05 * i, 0.0, 0.0, 0.0), {code}, true, &rng);
  return builder;
}

// True when the best single-view solution of the survey's first observation is the flipped one.
bool FirstViewFlipped(const SurveyBuilder& builder) {
  const Survey& survey = builder.survey();
  const Camera camera(survey.cameras.at("cam0"));
  const MarkerPoseEstimate estimate = EstimateMarkerPose(survey.observations[0].corners_px, 0.08, camera);
  const SE3d T_world_marker =
      builder.robot(0) * camera.info().T_robot_camera * estimate.best().T_camera_marker;
  return RotationAngleBetween(T_world_marker, builder.code(0)) > 20.0 * kDeg;
}

TEST(InitializerTest, FlippedFirstViewIsCorrected) {
  // The first noise seed whose first view's best single-view pose is the flipped one.
  unsigned seed = 0;
  while (seed < 500 && !FirstViewFlipped(DriveTowardsCode(seed))) ++seed;
  ASSERT_LT(seed, 500u) << "no seed gives a flipped first view";
  const SurveyBuilder builder = DriveTowardsCode(seed);
  const Initialization init = Initialize(builder.survey());
  ASSERT_EQ(init.components, 1);
  ASSERT_TRUE(init.T_world_marker[0].has_value());
  // The first frame is the identity, as the true first robot pose is.
  ASSERT_TRUE(init.T_world_robot[0].has_value());
  EXPECT_LT(init.T_world_robot[0]->translation().norm(), 1e-9);
  EXPECT_LT(RotationAngleBetween(*init.T_world_marker[0], builder.code(0)), 3.0 * kDeg) << "seed " << seed;
  EXPECT_LT((init.T_world_marker[0]->translation() - builder.code(0).translation()).norm(), 0.05);
  EXPECT_GT(init.local_maps.size(), 1u);  // 1 m of travel: several local maps, linked
  EXPECT_EQ(init.tree.size(), init.local_maps.size() - 1);
  EXPECT_GT(init.marker_link_quality[0], 0.0);
}

// A robot turning in place (sim rooms: a code seen only from a room's centre) looking at a small
// oblique code 2 m away; frames at their true poses, as after the global solve.
SurveyBuilder TurnInPlaceBeforeCode(unsigned seed) {
  std::mt19937 rng(seed);
  SurveyBuilder builder;
  builder.AddCode("B", WallCode(Eigen::Vector3d(2.0, 0.0, 0.3), 25.0 * kDeg), 0.08);
  for (int i = 0; i < 12; ++i) {
    builder.AddFrame(SE3d::FromXYZYaw(0.0, 0.0, 0.0, (-11.0 + 2.0 * i) * kDeg), {0}, true, &rng);
  }
  return builder;
}

std::vector<std::optional<SE3d>> TrueFrames(const SurveyBuilder& builder) {
  std::vector<std::optional<SE3d>> T_world_robot;
  for (size_t f = 0; f < builder.survey().frames.size(); ++f) {
    T_world_robot.push_back(builder.robot(static_cast<int>(f)));
  }
  return T_world_robot;
}

TEST(InitializerTest, OtherFlipBranchTurnsAFlippedCodeBack) {
  const SurveyBuilder builder = TurnInPlaceBeforeCode(3);
  const Survey& survey = builder.survey();
  const std::map<std::string, Camera> cameras = MakeCameras(survey);
  const std::vector<SingleView> views = ComputeSingleViews(survey, cameras, 3.0);
  const std::vector<std::optional<SE3d>> T_world_robot = TrueFrames(builder);
  // The mirrored pose: rotated by twice the viewing angle (25 degrees) about the vertical.
  const SE3d truth = builder.code(0);
  const Eigen::Quaterniond mirror(Eigen::AngleAxisd(-50.0 * kDeg, Eigen::Vector3d::UnitZ()));
  const SE3d flipped(mirror * truth.rotation(), truth.translation());
  const LocalMapOptions options;
  const std::optional<SE3d> back =
      OtherFlipBranch(survey, cameras, views, T_world_robot, 0, flipped, options);
  ASSERT_TRUE(back.has_value());
  EXPECT_LT(RotationAngleBetween(*back, truth), 3.0 * kDeg);
  EXPECT_LT((back->translation() - truth.translation()).norm(), 0.02);
  // On the true branch nothing changes; nor without a view in a placed frame.
  EXPECT_FALSE(OtherFlipBranch(survey, cameras, views, T_world_robot, 0, truth, options).has_value());
  const std::vector<std::optional<SE3d>> none(T_world_robot.size());
  EXPECT_FALSE(OtherFlipBranch(survey, cameras, views, none, 0, flipped, options).has_value());
}

// A code seen head-on has no second branch to try.
TEST(InitializerTest, OtherFlipBranchLeavesAHeadOnCode) {
  std::mt19937 rng(5);
  SurveyBuilder builder;
  builder.AddCode("C", WallCode(Eigen::Vector3d(1.5, 0.0, 0.3), 0.0), 0.1);
  for (int i = 0; i < 5; ++i) {
    builder.AddFrame(SE3d::FromXYZYaw(0.0, 0.0, 0.0, (-2.0 + i) * kDeg), {0}, true, &rng);
  }
  const std::map<std::string, Camera> cameras = MakeCameras(builder.survey());
  const std::vector<SingleView> views = ComputeSingleViews(builder.survey(), cameras, 3.0);
  EXPECT_FALSE(OtherFlipBranch(builder.survey(), cameras, views, TrueFrames(builder), 0, builder.code(0), {})
                   .has_value());
}

TEST(InitializerTest, DisconnectedGroupsBecomeComponents) {
  std::mt19937 rng(5);
  SurveyBuilder builder;
  const int a = builder.AddCode("A", WallCode(Eigen::Vector3d(2.0, 0.2, 0.35), 0.0), 0.10);
  const int b = builder.AddCode("B", WallCode(Eigen::Vector3d(2.0, -0.3, 0.35), 10.0 * kDeg), 0.10);
  const int c = builder.AddCode("C", WallCode(Eigen::Vector3d(12.0, 0.0, 0.35), 0.0), 0.10);
  for (int i = 0; i < 5; ++i)
    builder.AddFrame(SE3d::FromXYZYaw(0.05 * i, 0.0, 0.0, 0.0), {a, b}, i > 0, &rng);
  builder.AddFrame(SE3d::FromXYZYaw(5.0, 5.0, 0.0, 0.0), {}, false, &rng);  // sees nothing, no odometry
  for (int i = 0; i < 5; ++i)
    builder.AddFrame(SE3d::FromXYZYaw(10.0 + 0.05 * i, 0.0, 0.0, 0.0), {c}, i > 0, &rng);
  const Initialization init = Initialize(builder.survey());
  EXPECT_EQ(init.components, 2);
  EXPECT_EQ(init.marker_component, (std::vector<int>{0, 0, 1}));
  EXPECT_EQ(init.frame_component[5], -1);
  EXPECT_FALSE(init.T_world_robot[5].has_value());
  ASSERT_EQ(init.gauge.size(), 2u);
  for (int m : {a, b, c}) ASSERT_TRUE(init.T_world_marker[m].has_value()) << m;  // nothing dropped
  // Each component has its own frame: its first frame is the identity there.
  EXPECT_LT(init.T_world_robot[0]->translation().norm(), 1e-9);
  EXPECT_LT(init.T_world_robot[6]->translation().norm(), 1e-9);
  // Inside each component the geometry is right: code C 2 m ahead of frame 6.
  const SE3d T_robot6_c = init.T_world_robot[6]->inverse() * *init.T_world_marker[c];
  const SE3d truth_6_c = builder.robot(6).inverse() * builder.code(c);
  EXPECT_LT((T_robot6_c.translation() - truth_6_c.translation()).norm(), 0.05);
  // Codes A and B 0.5 m apart (a near-frontal code's orientation is loose; its position is not).
  const Eigen::Vector3d a_to_b =
      init.T_world_marker[b]->translation() - init.T_world_marker[a]->translation();
  EXPECT_LT((a_to_b - (builder.code(b).translation() - builder.code(a).translation())).norm(), 0.02);
  EXPECT_FALSE(init.notes.empty());
}

}  // namespace
}  // namespace waymark

namespace waymark {
namespace {

// A rough survey as TagSLAM's test10 gives it: codes whose priors (sigma 0.5 m, 0.1 rad) are up
// to 0.3 m and 0.08 rad off, in groups that share no observation (no odometry; most frames
// see one code). The groups holding priors are one component in the world frame, initialized
// near the truth there; a group without any prior stays a component of its own.
TEST(InitializerTest, GroupsWithPriorsAreOneComponentInTheWorldFrame) {
  std::mt19937 rng(11);
  SurveyBuilder builder;
  const int a = builder.AddCode("A", WallCode(Eigen::Vector3d(2.0, 0.2, 0.35), 0.0), 0.10);
  const int b = builder.AddCode("B", WallCode(Eigen::Vector3d(2.0, -0.3, 0.35), 10.0 * kDeg), 0.10);
  const int c = builder.AddCode("C", WallCode(Eigen::Vector3d(12.0, 0.0, 0.35), 0.0), 0.10);
  const int d = builder.AddCode("D", WallCode(Eigen::Vector3d(22.0, 5.0, 0.35), -15.0 * kDeg), 0.10);
  const int e = builder.AddCode("E", WallCode(Eigen::Vector3d(32.0, 0.0, 0.35), 0.0), 0.10);
  const auto off = [](const SE3d& T, double dx, double dy, double dyaw) {
    return SE3d(Eigen::Quaterniond(Eigen::AngleAxisd(dyaw, Eigen::Vector3d::UnitZ())) * T.rotation(),
                T.translation() + Eigen::Vector3d(dx, dy, 0.1));
  };
  builder.SetPrior(a, off(builder.code(a), 0.3, -0.1, 0.08), 0.1, 0.5);
  builder.SetPrior(b, off(builder.code(b), -0.2, 0.2, -0.05), 0.1, 0.5);
  builder.SetPrior(c, off(builder.code(c), 0.25, 0.15, 0.06), 0.1, 0.5);
  builder.SetPrior(d, off(builder.code(d), -0.3, -0.2, -0.08), 0.1, 0.5);
  for (int i = 0; i < 4; ++i)
    builder.AddFrame(SE3d::FromXYZYaw(0.05 * i, 0.1 * i, 0.0, 0.02 * i), {a, b}, false, &rng);
  for (int i = 0; i < 4; ++i)
    builder.AddFrame(SE3d::FromXYZYaw(10.0 + 0.05 * i, 0.0, 0.0, 0.0), {c}, false, &rng);
  for (int i = 0; i < 4; ++i)
    builder.AddFrame(SE3d::FromXYZYaw(20.0, 5.0 + 0.05 * i, 0.0, 0.0), {d}, false, &rng);
  for (int i = 0; i < 4; ++i)
    builder.AddFrame(SE3d::FromXYZYaw(30.0 + 0.05 * i, 0.0, 0.0, 0.0), {e}, false, &rng);
  const Initialization init = Initialize(builder.survey());
  ASSERT_EQ(init.components, 2);
  EXPECT_EQ(init.marker_component, (std::vector<int>{0, 0, 0, 0, 1}));
  for (int f = 0; f < 12; ++f) EXPECT_EQ(init.frame_component[f], 0) << f;
  for (int f = 12; f < 16; ++f) EXPECT_EQ(init.frame_component[f], 1) << f;
  ASSERT_EQ(init.gauge.size(), 2u);
  EXPECT_EQ(init.gauge[0], "4 anchor marker(s)");
  // In the world frame, each group within its priors' errors of the truth (0.3 m, 0.08 rad at
  // most, and the group of A and B fitted to both); the frames seeing one code each too.
  for (int m : {a, b, c, d}) {
    EXPECT_LT((init.T_world_marker[m]->translation() - builder.code(m).translation()).norm(), 0.5) << m;
  }
  for (int f = 0; f < 12; ++f) {
    EXPECT_LT((init.T_world_robot[f]->translation() - builder.robot(f).translation()).norm(), 1.0) << f;
  }
  // Inside the group of A and B the geometry is the images', not the priors'.
  const Eigen::Vector3d a_to_b =
      init.T_world_marker[b]->translation() - init.T_world_marker[a]->translation();
  EXPECT_LT((a_to_b - (builder.code(b).translation() - builder.code(a).translation())).norm(), 0.02);
  EXPECT_FALSE(init.notes.empty());
}

}  // namespace
}  // namespace waymark
