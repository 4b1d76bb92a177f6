// Renderer tests: corners detected on rendered codes (no noise, moderate blur) against the
// exact ground truth, determinism per seed, and the error paths.
#include "sim/render.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "detect/detector.h"
#include "geometry/camera.h"
#include "sim/test_scenes.h"

namespace waymark::sim {
namespace {

// The camera of sim/test_scenes.h, 1.2 m above the floor, looking along +x.
SE3d CameraPose() { return TestCameraPose(); }

// One code `range_m` ahead, shifted left/up by `offset_m`, turned by `yaw_deg` about the
// vertical; a textured wall 5 cm behind it.
World OneCodeWorld(const std::string& family, const std::string& id, double range_m, double yaw_deg,
                   const Eigen::Vector2d& offset_m) {
  World world;
  SimMarker marker;
  marker.key = {family, id};
  marker.size_m = 0.1;
  const double yaw_rad = yaw_deg * M_PI / 180.0;
  marker.T_world_marker = WallMarkerPose(Eigen::Vector3d(range_m, offset_m.x(), 1.2 + offset_m.y()),
                                         Eigen::Vector3d(-std::cos(yaw_rad), std::sin(yaw_rad), 0.0));
  world.markers.push_back(marker);
  world.occluders.push_back(VerticalWall({range_m + 0.3, 3.0}, {range_m + 0.3, -3.0}, 0.0, 2.5));
  return world;
}

RenderOptions NoNoise() {
  RenderOptions options;
  options.noise_sigma = 0.0;
  options.blur_sigma_px = 0.7;  // moderate blur
  return options;
}

// RMS (px, over the four corners) between the detection of the code and the truth; -1 if
// the code is not detected with its exact id.
double CornerRmsPx(const World& world, const RenderOptions& options, double* width_px) {
  const Camera camera = TestCamera();
  const Renderer renderer(world, options);
  const std::vector<MarkerObservation> truth = renderer.GroundTruth(camera, CameraPose());
  if (truth.size() != 1) return -2.0;
  *width_px = ShortestSidePx(truth[0].corners_px);
  const cv::Mat image = renderer.Render(camera, CameraPose(), 7, 0);
  const auto detector = CreateDetector(truth[0].key.family);
  for (const MarkerObservation& obs : detector->Detect(image)) {
    if (obs.key != truth[0].key) continue;
    double sum_sq = 0.0;
    for (int k = 0; k < 4; ++k) {
      sum_sq += (obs.corners_px[k] - truth[0].corners_px[k]).squaredNorm();
      if (std::getenv("RENDER_TEST_VERBOSE")) {
        std::printf("  corner %d error (%.3f, %.3f) px\n", k,
                    obs.corners_px[k].x() - truth[0].corners_px[k].x(),
                    obs.corners_px[k].y() - truth[0].corners_px[k].y());
      }
    }
    return std::sqrt(sum_sq / 4.0);
  }
  return -1.0;
}

struct Case {
  std::string family, id;
  double range_m, yaw_deg;
  Eigen::Vector2d offset_m;
};

TEST(RenderTest, DetectedCornersMatchTruthWithoutNoise) {
  const std::vector<Case> cases = {
      {"qr", "0/2/10", 1.0, 0.0, {0.0, 0.0}},        {"qr", "C017", 1.6, 35.0, {0.25, -0.15}},
      {"datamatrix", "1011", 1.0, 0.0, {-0.2, 0.1}}, {"datamatrix", "A01", 1.5, -35.0, {0.1, 0.1}},
      {"apriltag-36h11", "5", 1.2, 0.0, {0.3, 0.2}}, {"apriltag-36h11", "17", 1.8, 40.0, {-0.2, -0.1}},
  };
  // Measured 2026-11-23: pooled 0.066 px, worst code 0.151 px (the oblique 45 px QR: its
  // 1-module finder ring is 2.2 px wide). Guards: pooled <= 0.1 px, every code <= 0.2 px.
  double sum_sq_px = 0.0;
  for (const Case& c : cases) {
    double width_px = 0.0;
    const double rms_px =
        CornerRmsPx(OneCodeWorld(c.family, c.id, c.range_m, c.yaw_deg, c.offset_m), NoNoise(), &width_px);
    std::printf("%-15s %-7s range %.1f m yaw %5.1f deg: width %.1f px, corner RMS %.3f px\n",
                c.family.c_str(), c.id.c_str(), c.range_m, c.yaw_deg, width_px, rms_px);
    ASSERT_GE(width_px, 40.0) << c.family << " " << c.id;
    ASSERT_GE(rms_px, 0.0) << c.family << " " << c.id << " not detected";
    EXPECT_LE(rms_px, 0.2) << c.family << " " << c.id;
    sum_sq_px += rms_px * rms_px;
  }
  const double pooled_rms_px = std::sqrt(sum_sq_px / cases.size());
  std::printf("pooled corner RMS over %zu codes: %.3f px\n", cases.size(), pooled_rms_px);
  EXPECT_LE(pooled_rms_px, 0.1);
}

TEST(RenderTest, GroundTruthIsTheProjectionOfTheCorners) {
  const World world = OneCodeWorld("qr", "x", 1.0, 20.0, {0.1, 0.0});
  const Camera camera = TestCamera();
  const auto truth = Renderer(world, NoNoise()).GroundTruth(camera, CameraPose());
  ASSERT_EQ(truth.size(), 1u);
  const SE3d T_camera_marker = CameraPose().inverse() * world.markers[0].T_world_marker;
  const auto corners_marker = MarkerCorners(0.1);
  for (int k = 0; k < 4; ++k) {
    const Eigen::Vector2d px = *camera.Project(T_camera_marker * corners_marker[k]);
    EXPECT_LT((px - truth[0].corners_px[k]).norm(), 1e-9);
  }
  // Top-left is left of top-right and above bottom-left (upright, docs/design.md order).
  EXPECT_LT(truth[0].corners_px[0].x(), truth[0].corners_px[1].x());
  EXPECT_LT(truth[0].corners_px[0].y(), truth[0].corners_px[3].y());
}

TEST(RenderTest, DeterministicPerSeed) {
  const World world = OneCodeWorld("datamatrix", "1011", 1.0, 10.0, {0.0, 0.0});
  const RenderOptions options;  // with noise, gradient and exposure
  const Camera camera = TestCamera();
  const Renderer renderer(world, options);
  const cv::Mat a = renderer.Render(camera, CameraPose(), 3, 11);
  const cv::Mat b = Renderer(world, options).Render(camera, CameraPose(), 3, 11);
  const cv::Mat c = renderer.Render(camera, CameraPose(), 4, 11);
  const cv::Mat d = renderer.Render(camera, CameraPose(), 3, 12);
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(a, c, cv::NORM_L1), 0.0);
  EXPECT_GT(cv::norm(a, d, cv::NORM_L1), 0.0);
  // The geometry does not depend on the seed.
  EXPECT_EQ(cv::norm(renderer.RenderAlbedo(camera, CameraPose()), renderer.RenderAlbedo(camera, CameraPose()),
                     cv::NORM_INF),
            0.0);
}

TEST(RenderTest, CodeSeenFromBehindIsNotDrawn) {
  World world = OneCodeWorld("qr", "back", 1.0, 180.0, {0.0, 0.0});
  const Camera camera = TestCamera();
  const Renderer renderer(world, NoNoise());
  EXPECT_TRUE(renderer.GroundTruth(camera, CameraPose()).empty());
  const cv::Mat albedo = renderer.RenderAlbedo(camera, CameraPose());
  double min_value = 0.0, max_value = 0.0;
  cv::minMaxLoc(albedo(cv::Rect(600, 440, 80, 80)), &min_value, &max_value);
  EXPECT_GT(min_value, 0.2);  // wall texture only, no dark module
}

TEST(RenderTest, RejectsUndrawableFamiliesAndBadOptions) {
  EXPECT_THROW(Renderer(OneCodeWorld("square", "1", 1.0, 0.0, {0, 0}), NoNoise()), std::invalid_argument);
  EXPECT_THROW(Renderer(OneCodeWorld("apriltag-36h11", "x1", 1.0, 0.0, {0, 0}), NoNoise()),
               std::invalid_argument);
  RenderOptions bad = NoNoise();
  bad.supersample = 0;
  std::string why;
  EXPECT_FALSE(bad.Check(&why));
  EXPECT_NE(why.find("supersample"), std::string::npos);
  EXPECT_THROW(Renderer(OneCodeWorld("qr", "1", 1.0, 0.0, {0, 0}), bad), std::invalid_argument);
}

}  // namespace
}  // namespace waymark::sim
