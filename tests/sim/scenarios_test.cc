// The corridor's path.* and camera.* keys: a second, different run through the same place.
// The defaults keep the original path (from (0, 0) facing +x, counter-clockwise on the centre
// line); path.clockwise, path.start_corner, path.inset_m and path.overlap_m change only the path, never the
// codes, walls or cameras; camera.image_scale scales the images with the same field of view.
#include "sim/scenarios.h"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

namespace waymark::sim {
namespace {

Scene Corridor(const std::vector<std::string>& sets) {
  ParamSet params = ScenarioParams("corridor");
  for (const std::string& s : sets) params.SetAssignment(s);
  return BuildScene("corridor", params);
}

// Twice the signed area enclosed by the path's positions (shoelace): > 0 counter-clockwise.
double SignedArea2(const Trajectory& path) {
  double sum = 0.0;
  for (size_t i = 0; i + 1 < path.size(); ++i) {
    const Eigen::Vector3d& a = path[i].T.translation();
    const Eigen::Vector3d& b = path[i + 1].T.translation();
    sum += a.x() * b.y() - b.x() * a.y();
  }
  return sum;
}

void ExpectAt(const SE3d& T, double x, double y, double yaw_rad) {
  EXPECT_NEAR(T.translation().x(), x, 1e-9);
  EXPECT_NEAR(T.translation().y(), y, 1e-9);
  EXPECT_NEAR(std::remainder(T.yaw() - yaw_rad, 2.0 * M_PI), 0.0, 1e-9);
}

TEST(CorridorPathTest, DefaultIsCounterClockwiseOnTheCentreLineFromTheOrigin) {
  const Trajectory& path = Corridor({}).truth.T_world_robot;
  ExpectAt(path.front().T, 0.0, 0.0, 0.0);
  ExpectAt(path.back().T, 0.0, 0.0, 0.0);
  EXPECT_NEAR(SignedArea2(path), 2.0 * 12.0 * 8.0, 1e-6);  // the 12 x 8 m centre line
}

TEST(CorridorPathTest, ClockwiseFromTheOppositeCornerDrivesTheLoopBackwards) {
  const Trajectory& path = Corridor({"path.clockwise=true", "path.start_corner=2"}).truth.T_world_robot;
  ExpectAt(path.front().T, 12.0, 8.0, -0.5 * M_PI);  // towards corner 1 at (12, 0)
  ExpectAt(path.back().T, 12.0, 8.0, -0.5 * M_PI);
  EXPECT_NEAR(SignedArea2(path), -2.0 * 12.0 * 8.0, 1e-6);
  const Trajectory& ccw = Corridor({"path.start_corner=2"}).truth.T_world_robot;
  ExpectAt(ccw.front().T, 12.0, 8.0, M_PI);  // towards corner 3 at (0, 8)
}

TEST(CorridorPathTest, InsetLoopStaysInsideTheCentreLine) {
  const double inset_m = 0.2;
  const Scene scene = Corridor({"path.inset_m=0.2", "path.clockwise=true"});
  const Trajectory& path = scene.truth.T_world_robot;
  ExpectAt(path.front().T, inset_m, inset_m, 0.5 * M_PI);
  for (const StampedSE3& s : path) {
    const Eigen::Vector3d& p = s.T.translation();
    // On one of the four sides of [i, 12 - i] x [i, 8 - i].
    const double to_side = std::min({std::abs(p.x() - inset_m), std::abs(p.x() - (12.0 - inset_m)),
                                     std::abs(p.y() - inset_m), std::abs(p.y() - (8.0 - inset_m))});
    ASSERT_LT(to_side, 1e-9) << p.transpose();
  }
  EXPECT_NEAR(scene.truth.LengthM(), 2.0 * (12.0 + 8.0) - 8.0 * inset_m, 1e-6);
  EXPECT_NEAR(Corridor({"path.inset_m=-0.2"}).truth.LengthM(), 2.0 * (12.0 + 8.0) + 8.0 * inset_m, 1e-6);
}

TEST(CorridorPathTest, OverlapDrivesOnAlongTheFirstSideAfterTheLoop) {
  const Trajectory& path = Corridor({"path.overlap_m=3"}).truth.T_world_robot;
  ExpectAt(path.front().T, 0.0, 0.0, 0.0);
  ExpectAt(path.back().T, 3.0, 0.0, 0.0);  // past the start, facing the way it first drove
  EXPECT_NEAR(Corridor({"path.overlap_m=3"}).truth.LengthM(), 2.0 * (12.0 + 8.0) + 3.0, 1e-6);
  // Never further than the first side's length (12 m).
  EXPECT_NEAR(Corridor({"path.overlap_m=50"}).truth.LengthM(), 2.0 * (12.0 + 8.0) + 12.0, 1e-6);
}

TEST(CorridorPathTest, PathKeysLeaveThePlaceAlone) {
  const Scene base = Corridor({});
  const Scene other =
      Corridor({"path.clockwise=true", "path.start_corner=3", "path.inset_m=0.1", "path.overlap_m=2"});
  ASSERT_EQ(base.world.markers.size(), other.world.markers.size());
  for (size_t i = 0; i < base.world.markers.size(); ++i) {
    EXPECT_EQ(base.world.markers[i].key, other.world.markers[i].key);
    EXPECT_TRUE(base.world.markers[i].T_world_marker.matrix() ==
                other.world.markers[i].T_world_marker.matrix());
  }
  EXPECT_EQ(base.world.occluders.size(), other.world.occluders.size());
  ASSERT_EQ(base.world.cameras.size(), other.world.cameras.size());
  for (size_t i = 0; i < base.world.cameras.size(); ++i) {
    EXPECT_EQ(base.world.cameras[i].intrinsics, other.world.cameras[i].intrinsics);
  }
  EXPECT_NE(base.truth.T_world_robot.size(), 0u);
}

TEST(CorridorPathTest, InsetThatPutsTheCamerasIntoAWallIsRefused) {
  // Corridor 1.2 m wide: the cameras sit 0.12 m off the robot's centre.
  EXPECT_THROW(Corridor({"path.inset_m=0.45"}), std::invalid_argument);
  EXPECT_THROW(Corridor({"path.inset_m=-0.45"}), std::invalid_argument);
  EXPECT_NO_THROW(Corridor({"path.inset_m=0.4"}));
  ParamSet params = ScenarioParams("corridor");
  EXPECT_THROW(params.SetAssignment("path.start_corner=4"), std::invalid_argument);
}

TEST(CorridorCameraTest, ImageScaleKeepsTheFieldOfView) {
  const Scene full = Corridor({});
  const Scene half = Corridor({"camera.image_scale=0.5"});
  ASSERT_EQ(full.world.cameras.size(), 2u);
  for (size_t i = 0; i < 2; ++i) {
    const CameraInfo& a = full.world.cameras[i];
    const CameraInfo& b = half.world.cameras[i];
    EXPECT_EQ(b.width, a.width / 2);
    EXPECT_EQ(b.height, a.height / 2);
    for (int k = 0; k < 4; ++k) EXPECT_DOUBLE_EQ(b.intrinsics[k], 0.5 * a.intrinsics[k]);
    EXPECT_EQ(b.distortion, a.distortion);
    EXPECT_DOUBLE_EQ(std::atan2(0.5 * b.width, b.intrinsics[0]), std::atan2(0.5 * a.width, a.intrinsics[0]));
  }
}

}  // namespace
}  // namespace waymark::sim
