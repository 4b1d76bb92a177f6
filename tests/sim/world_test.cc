#include "sim/world.h"

#include <gtest/gtest.h>

#include <cmath>

#include "geometry/camera.h"

namespace waymark::sim {
namespace {

// A 640x480 pinhole camera without distortion, f = 500 px.
Camera PlainCamera() {
  CameraInfo info;
  info.name = "cam";
  info.width = 640;
  info.height = 480;
  info.intrinsics = {500.0, 500.0, 320.0, 240.0};
  info.distortion = {0.0, 0.0, 0.0, 0.0, 0.0};
  return Camera(info);
}

// Camera at the world origin looking along world +x, image down = world -z.
SE3d CameraAtOrigin() { return SE3d(RotationFromZY({1, 0, 0}, {0, 0, -1}), Eigen::Vector3d::Zero()); }

// A 10 cm code at distance d along +x, facing the camera, turned by yaw about world z.
SimMarker CodeAt(double d, double yaw_deg) {
  SimMarker m;
  m.key = {"qr", "A"};
  m.size_m = 0.1;
  const double yaw = yaw_deg * M_PI / 180.0;
  m.T_world_marker = WallMarkerPose({d, 0, 0}, {-std::cos(yaw), std::sin(yaw), 0});
  return m;
}

TEST(WorldTest, RotationFromZYIsAProperRotationWithTheGivenAxes) {
  const Eigen::Matrix3d R = RotationFromZY({0, 2, 0}, {0, 0.3, -5}).toRotationMatrix();
  EXPECT_NEAR(R.determinant(), 1.0, 1e-12);
  EXPECT_TRUE(R.col(2).isApprox(Eigen::Vector3d(0, 1, 0), 1e-12));
  EXPECT_NEAR(R.col(1).dot(Eigen::Vector3d(0, 0.3, -5).normalized()), std::cos(std::atan2(0.3, 5)), 1e-12);
  EXPECT_THROW(RotationFromZY({0, 0, 1}, {0, 0, 2}), std::invalid_argument);
}

TEST(WorldTest, WallMarkerIsUprightAndFacesOut) {
  // On a wall facing +y, read from +y: x to the viewer's right (world -x), y up.
  const Eigen::Matrix3d R = WallMarkerPose({0, 0, 1}, {0, 1, 0}).rotation_matrix();
  EXPECT_TRUE(R.col(0).isApprox(Eigen::Vector3d(-1, 0, 0), 1e-12));
  EXPECT_TRUE(R.col(1).isApprox(Eigen::Vector3d(0, 0, 1), 1e-12));
  EXPECT_TRUE(R.col(2).isApprox(Eigen::Vector3d(0, 1, 0), 1e-12));
}

TEST(WorldTest, SegmentOcclusionByAWallButNotByItsOwnWall) {
  const std::vector<Occluder> walls = {VerticalWall({1, -1}, {1, 1}, 0.0, 2.0)};
  EXPECT_TRUE(SegmentOccluded(walls, {0, 0, 1}, {2, 0, 1}));
  EXPECT_FALSE(SegmentOccluded(walls, {0, 0, 3}, {2, 0, 3}));      // above the wall
  EXPECT_FALSE(SegmentOccluded(walls, {0, 1.5, 1}, {2, 1.5, 1}));  // beside it
  EXPECT_FALSE(SegmentOccluded(walls, {0, 0, 1}, {1, 0.5, 1}));    // ends on the wall
  EXPECT_FALSE(SegmentOccluded(walls, {0, 0, 1}, {0.9, 0, 1}));    // stops short
  EXPECT_FALSE(SegmentOccluded(walls, {0, -2, 1}, {0, 2, 1}));     // parallel
}

TEST(WorldTest, VisibleCornersAreTheProjectionsInDesignOrder) {
  const Camera camera = PlainCamera();
  const auto px = VisibleCorners(camera, CameraAtOrigin(), CodeAt(1.0, 0.0), {}, {});
  ASSERT_TRUE(px.has_value());
  // Top-left of the upright code is up-left in the image: (320 - 25, 240 - 25).
  EXPECT_NEAR((*px)[0].x(), 295.0, 1e-9);
  EXPECT_NEAR((*px)[0].y(), 215.0, 1e-9);
  EXPECT_NEAR((*px)[1].x(), 345.0, 1e-9);
  EXPECT_NEAR((*px)[2].y(), 265.0, 1e-9);
  EXPECT_NEAR((*px)[3].x(), 295.0, 1e-9);
}

TEST(WorldTest, LimitsRangeAngleImageAndOcclusion) {
  const Camera camera = PlainCamera();
  const SE3d T_world_camera = CameraAtOrigin();
  VisibilityLimits limits{0.5, 2.0, 45.0, 2.0};
  EXPECT_TRUE(VisibleCorners(camera, T_world_camera, CodeAt(1.0, 0.0), {}, limits));
  EXPECT_FALSE(VisibleCorners(camera, T_world_camera, CodeAt(0.4, 0.0), {}, limits));  // too close
  EXPECT_FALSE(VisibleCorners(camera, T_world_camera, CodeAt(2.1, 0.0), {}, limits));  // too far
  EXPECT_TRUE(VisibleCorners(camera, T_world_camera, CodeAt(1.0, 44.0), {}, limits));
  EXPECT_FALSE(VisibleCorners(camera, T_world_camera, CodeAt(1.0, 46.0), {}, limits));   // too oblique
  EXPECT_FALSE(VisibleCorners(camera, T_world_camera, CodeAt(1.0, 180.0), {}, limits));  // its back
  EXPECT_FALSE(VisibleCorners(camera, T_world_camera, CodeAt(-1.0, 180.0), {}, {}));     // behind the camera
  // Partly outside the image: the code's centre 0.64 m to the side at 1 m (f = 500 px).
  SimMarker edge = CodeAt(1.0, 0.0);
  edge.T_world_marker = SE3d(edge.T_world_marker.rotation(), Eigen::Vector3d(1.0, -0.64, 0.0));
  EXPECT_FALSE(VisibleCorners(camera, T_world_camera, edge, {}, limits));
  const std::vector<Occluder> wall = {VerticalWall({0.5, -1}, {0.5, 1}, -1.0, 1.0)};
  EXPECT_FALSE(VisibleCorners(camera, T_world_camera, CodeAt(1.0, 0.0), wall, limits));
}

}  // namespace
}  // namespace waymark::sim
