// Local maps (mapping/local_maps.h): fusion of a code over several views with variance-based
// rejection, link quality, the maximum-quality spanning forest and its placement.
#include "mapping/local_maps.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <set>

#include "geometry/robot_pnp.h"
#include "tests/mapping/synthetic_wall.h"

namespace waymark {
namespace {

using testing::ForwardCamera;
using testing::WallCode;

constexpr double kDeg = M_PI / 180.0;

struct Views {
  std::vector<std::array<Eigen::Vector2d, 4>> corners;  // owned here; FusionView points into it
  std::vector<FusionView> fusion;
};

// Views of a code of edge size_m at T_world_marker from robots at T_world_robot, with corner
// noise sigma_px; `jitter_m` moves the code by that much (random direction) in every view.
Views MakeViews(const Camera& camera, const std::vector<SE3d>& T_world_robot, const SE3d& T_world_marker,
                double size_m, double sigma_px, double jitter_m, std::mt19937* rng) {
  std::normal_distribution<double> noise(0.0, 1.0);
  Views views;
  views.corners.reserve(T_world_robot.size());
  for (const SE3d& T_world_robot_i : T_world_robot) {
    const Eigen::Vector3d jitter(noise(*rng), noise(*rng), noise(*rng));
    const SE3d T_moved(T_world_marker.rotation(),
                       T_world_marker.translation() + jitter_m * jitter.normalized());
    const SE3d T_world_camera = T_world_robot_i * camera.info().T_robot_camera;
    std::array<Eigen::Vector2d, 4> corners;
    const auto corners_marker = MarkerCorners(size_m);
    for (int k = 0; k < 4; ++k) {
      const auto px = camera.Project(T_world_camera.inverse() * (T_moved * corners_marker[k]));
      EXPECT_TRUE(px.has_value());
      corners[k] = *px + sigma_px * Eigen::Vector2d(noise(*rng), noise(*rng));
    }
    views.corners.push_back(corners);
  }
  for (size_t i = 0; i < T_world_robot.size(); ++i) {
    views.fusion.push_back({&camera, T_world_robot[i] * camera.info().T_robot_camera, &views.corners[i],
                            camera.info().pixel_sigma.value()});
  }
  return views;
}

// A robot at the origin turning in place from -10 to +10 degrees, n frames.
std::vector<SE3d> TurningRobot(int n) {
  std::vector<SE3d> poses;
  for (int i = 0; i < n; ++i)
    poses.push_back(SE3d::FromXYZYaw(0.0, 0.0, 0.0, (-10.0 + 20.0 * i / (n - 1)) * kDeg));
  return poses;
}

TEST(LocalMapsTest, FusesViewsAndRejectsAnUnstableCode) {
  const Camera camera(ForwardCamera());
  std::mt19937 rng(7);
  const SE3d T_world_marker = WallCode(Eigen::Vector3d(1.5, 0.2, 0.35), 15.0 * kDeg);
  const std::vector<SE3d> robots = TurningRobot(20);
  LocalMapOptions options;

  const Views steady = MakeViews(camera, robots, T_world_marker, 0.10, 0.5, 0.0, &rng);
  const std::optional<FusedPose> fused =
      FuseMarkerViews(steady.fusion, 0.10, {T_world_marker}, false, options);
  ASSERT_TRUE(fused.has_value());
  EXPECT_EQ(fused->views, 20);
  EXPECT_TRUE(fused->stable) << fused->why;
  EXPECT_LT((fused->T_frame_marker.translation() - T_world_marker.translation()).norm(), 0.01);
  EXPECT_LT(RotationAngleBetween(fused->T_frame_marker, T_world_marker), 2.0 * kDeg);
  EXPECT_GT(fused->rms_sigma, 0.7);
  EXPECT_LT(fused->rms_sigma, 1.3);
  // Fusing 20 views: the predicted position sigma is well below one view's depth error.
  EXPECT_LT(fused->position_sigma_m, 0.01);

  // The same code moving by 3 cm between views: its corners vary far beyond the noise.
  const Views moving = MakeViews(camera, robots, T_world_marker, 0.10, 0.5, 0.03, &rng);
  const std::optional<FusedPose> unstable =
      FuseMarkerViews(moving.fusion, 0.10, {T_world_marker}, false, options);
  ASSERT_TRUE(unstable.has_value());
  EXPECT_FALSE(unstable->stable);
  EXPECT_GT(unstable->rms_sigma, options.max_rms_sigma);
  EXPECT_NE(unstable->why.find("views disagree"), std::string::npos) << unstable->why;

  // A small code far away, seen twice: consistent, but too uncertain for a tight gate.
  LocalMapOptions tight = options;
  tight.max_position_sigma_m = 0.002;
  const SE3d T_far = WallCode(Eigen::Vector3d(4.0, 0.0, 0.3), 0.0);
  const Views far = MakeViews(camera, TurningRobot(2), T_far, 0.05, 0.5, 0.0, &rng);
  const std::optional<FusedPose> uncertain = FuseMarkerViews(far.fusion, 0.05, {T_far}, false, tight);
  ASSERT_TRUE(uncertain.has_value());
  EXPECT_FALSE(uncertain->stable);
  EXPECT_NE(uncertain->why.find("too uncertain"), std::string::npos) << uncertain->why;
  EXPECT_GT(uncertain->position_sigma_m, 3.0 * fused->position_sigma_m);
}

TEST(LocalMapsTest, BothFlipBranchesAreTriedAndTheTrueOneWins) {
  const Camera camera(ForwardCamera());
  std::mt19937 rng(11);
  // Small code, 25 degrees oblique, 2 m away: single views are ambiguous.
  const SE3d T_world_marker = WallCode(Eigen::Vector3d(2.0, 0.0, 0.3), 25.0 * kDeg);
  const Views views = MakeViews(camera, TurningRobot(30), T_world_marker, 0.08, 0.5, 0.0, &rng);
  // The mirrored pose: rotated by twice the viewing angle about the vertical through the code.
  const SE3d flipped(Eigen::Quaterniond(Eigen::AngleAxisd(-50.0 * kDeg, Eigen::Vector3d::UnitZ())) *
                         T_world_marker.rotation(),
                     T_world_marker.translation());
  LocalMapOptions options;
  const std::optional<FusedPose> fused =
      FuseMarkerViews(views.fusion, 0.08, {flipped, T_world_marker}, false, options);
  ASSERT_TRUE(fused.has_value());
  EXPECT_LT(RotationAngleBetween(fused->T_frame_marker, T_world_marker), 3.0 * kDeg);
  EXPECT_TRUE(std::isfinite(fused->alt_chi2));
  EXPECT_GT(fused->alt_chi2, fused->chi2);
  EXPECT_TRUE(fused->resolved);
  // Only the flipped seed: the fit stays in the flipped branch (why both seeds are needed).
  const std::optional<FusedPose> one = FuseMarkerViews(views.fusion, 0.08, {flipped}, false, options);
  ASSERT_TRUE(one.has_value());
  EXPECT_GT(RotationAngleBetween(one->T_frame_marker, T_world_marker), 20.0 * kDeg);
  EXPECT_NEAR(one->chi2, fused->alt_chi2, 1e-6 * fused->alt_chi2);
}

// A fused pose at T with an isotropic covariance: rotation sigma_rad, translation sigma_m.
FusedPose Fused(const SE3d& T, double sigma_rad, double sigma_m) {
  FusedPose fused;
  fused.T_frame_marker = T;
  fused.covariance.setZero();
  fused.covariance.diagonal() << Eigen::Vector3d::Constant(sigma_rad * sigma_rad),
      Eigen::Vector3d::Constant(sigma_m * sigma_m);
  fused.stable = true;
  fused.resolved = true;
  return fused;
}

// Three local maps of three frames (no odometry): A and B share code 0, A and C code 1, B and
// C code 2.
struct ThreeMaps {
  Survey survey;
  std::vector<LocalMap> maps;
};

ThreeMaps MakeThreeMaps(double sigma_ab, double sigma_ac, double sigma_bc) {
  ThreeMaps t;
  t.survey.frames.resize(3);
  t.maps.resize(3);
  for (int i = 0; i < 3; ++i) {
    t.maps[i].component = 0;
    t.maps[i].frames = {i};
    t.maps[i].T_ref_robot = {SE3d::Identity()};
  }
  const SE3d code(Eigen::Quaterniond::Identity(), Eigen::Vector3d(1.0, 0.0, 0.0));
  t.maps[0].codes[0] = Fused(code, sigma_ab, sigma_ab);
  t.maps[1].codes[0] = Fused(code, sigma_ab, sigma_ab);
  t.maps[0].codes[1] = Fused(code, sigma_ac, sigma_ac);
  t.maps[2].codes[1] = Fused(code, sigma_ac, sigma_ac);
  t.maps[1].codes[2] = Fused(code, sigma_bc, sigma_bc);
  t.maps[2].codes[2] = Fused(code, sigma_bc, sigma_bc);
  return t;
}

const LocalMapLink* FindLink(const std::vector<LocalMapLink>& links, int marker) {
  for (const LocalMapLink& link : links) {
    if (link.marker == marker) return &link;
  }
  return nullptr;
}

TEST(LocalMapsTest, LinkQualityOrdersStrongOverWeak) {
  ThreeMaps t = MakeThreeMaps(0.001, 0.01, 0.005);
  const std::vector<LocalMapLink> links = FindLocalMapLinks(t.survey, t.maps, LocalMapOptions());
  ASSERT_EQ(links.size(), 3u);
  const LocalMapLink* ab = FindLink(links, 0);
  const LocalMapLink* ac = FindLink(links, 1);
  const LocalMapLink* bc = FindLink(links, 2);
  ASSERT_TRUE(ab && ac && bc);
  EXPECT_GT(ab->quality, bc->quality);
  EXPECT_GT(bc->quality, ac->quality);
  // Hand value: q = (-1, 0, 0) in the marker frame, D Sigma D^T per map = 3 s^2 + 2 s^2, two
  // maps, plus the rotation at 1 m: sigma^2 = 2 (5 s^2) + 2 (3 s^2) = 16 s^2.
  EXPECT_NEAR(ab->sigma_m, 4.0 * 0.001, 1e-12);
  EXPECT_NEAR(ab->quality, 1.0 / (4.0 * 0.001), 1e-6);

  // An unresolved flip or an unstable code weakens the link by the penalties.
  t.maps[1].codes[0].resolved = false;
  t.maps[2].codes[2].stable = false;
  const std::vector<LocalMapLink> penalized = FindLocalMapLinks(t.survey, t.maps, LocalMapOptions());
  EXPECT_NEAR(FindLink(penalized, 0)->quality, ab->quality / kAmbiguousPenalty, 1e-9);
  EXPECT_NEAR(FindLink(penalized, 2)->quality, bc->quality / kUnstablePenalty, 1e-9);
}

TEST(LocalMapsTest, SpanningForestPrefersStrongLinks) {
  const ThreeMaps t = MakeThreeMaps(0.001, 0.01, 0.005);
  const std::vector<LocalMapLink> links = FindLocalMapLinks(t.survey, t.maps, LocalMapOptions());
  const std::vector<int> forest = SpanningForest(3, links);
  ASSERT_EQ(forest.size(), 2u);
  std::set<int> markers;
  for (int l : forest) markers.insert(links[l].marker);
  EXPECT_EQ(markers, (std::set<int>{0, 2}));  // A-B and B-C, not the weak A-C

  // Placement composes the tree's links: B seen 1 m ahead of A, C 1 m left of B.
  std::vector<LocalMapLink> chain(2);
  chain[0] = {0, 1, 0, SE3d::FromXYZYaw(1.0, 0.0, 0.0, 0.5), 0.01, 100.0};
  chain[1] = {1, 2, 1, SE3d::FromXYZYaw(0.0, 1.0, 0.0, 0.0), 0.01, 100.0};
  const std::vector<SE3d> placed = PlaceLocalMaps(4, chain, {0, 1}, true);
  ASSERT_EQ(placed.size(), 4u);
  EXPECT_LT(placed[0].translation().norm(), 1e-12);
  const Eigen::Vector3d expected_c = Eigen::Vector3d(1.0 - std::sin(0.5), std::cos(0.5), 0.0);
  EXPECT_LT((placed[2].translation() - expected_c).norm(), 1e-12);
  EXPECT_NEAR(placed[2].yaw(), 0.5, 1e-12);
  EXPECT_LT(placed[3].translation().norm(), 1e-12);  // an unlinked map is its own root
}

TEST(LocalMapsTest, RobotPnpRecoversAPerturbedPose) {
  const Camera camera(ForwardCamera());
  std::mt19937 rng(3);
  const SE3d T_world_robot = SE3d::FromXYZYaw(0.3, -0.2, 0.0, 5.0 * kDeg);
  std::vector<SE3d> codes = {WallCode(Eigen::Vector3d(2.0, 0.3, 0.35), 0.0),
                             WallCode(Eigen::Vector3d(2.2, -0.6, 0.3), 10.0 * kDeg)};
  const SE3d start = SE3d::FromXYZYaw(0.25, -0.1, 0.0, 2.0 * kDeg);
  for (const double sigma_px : {0.0, 0.5}) {
    std::vector<Views> views;
    for (const SE3d& code : codes)
      views.push_back(MakeViews(camera, {T_world_robot}, code, 0.1, sigma_px, 0.0, &rng));
    std::vector<PnpView> pnp;
    for (size_t i = 0; i < codes.size(); ++i)
      pnp.push_back({&camera, &views[i].corners[0], 0.5, 0.1, codes[i]});
    const SE3d refined = RefineRobotPose(pnp, start, true, 3.0, 50);
    // Exact without noise; with 0.5 px, two 10 cm codes 2 m away fix the pose to about 2 cm.
    const double tolerance_m = sigma_px == 0.0 ? 1e-6 : 0.03;
    EXPECT_LT((refined.translation() - T_world_robot.translation()).norm(), tolerance_m);
    EXPECT_LT(RotationAngleBetween(refined, T_world_robot), sigma_px == 0.0 ? 1e-6 : 1.0 * kDeg);
    EXPECT_EQ(refined.translation().z(), 0.0);
  }
  // Nothing to refine against: the start comes back.
  const SE3d same = RefineRobotPose({}, start, true, 3.0, 20);
  EXPECT_LT((same.translation() - start.translation()).norm(), 1e-12);
}

TEST(LocalMapsTest, OptionsAreChecked) {
  LocalMapOptions options;
  std::string why;
  EXPECT_TRUE(options.Check(&why));
  options.max_travel_m = -1.0;
  EXPECT_FALSE(options.Check(&why));
  EXPECT_NE(why.find("local map"), std::string::npos);
  options = LocalMapOptions();
  options.max_frames = 0;
  EXPECT_FALSE(options.Check(&why));
}

}  // namespace
}  // namespace waymark
