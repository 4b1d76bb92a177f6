#include "sim/motion.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace waymark::sim {
namespace {

TEST(MotionTest, PlanarPathReachesItsWaypointsAtTheRate) {
  PlanarPathBuilder path(SE2d(0, 0, 0), 20.0, 0.5, M_PI / 2);
  path.DriveTo({2.0, 0.0});
  path.DriveTo({2.0, 1.0});
  const SimTrajectory t = path.Build(0.1);
  // 2 m at 0.5 m/s = 80 steps, a 90 degree turn at 90 deg/s = 20 steps, 1 m = 40 steps.
  ASSERT_EQ(t.T_world_robot.size(), 1u + 80 + 20 + 40);
  EXPECT_NEAR(t.T_world_robot.back().stamp_s, 140 * 0.05, 1e-9);
  EXPECT_TRUE(t.T_world_robot.back().T.translation().isApprox(Eigen::Vector3d(2.0, 1.0, 0.1), 1e-12));
  EXPECT_NEAR(t.T_world_robot.back().T.yaw(), M_PI / 2, 1e-12);
  EXPECT_NEAR(t.LengthM(), 3.0, 1e-9);
}

TEST(MotionTest, CarryStartsANewSegmentAfterAGap) {
  PlanarPathBuilder path(SE2d(0, 0, 0), 10.0, 1.0, 1.0);
  path.DriveTo({1.0, 0.0});
  path.CarryTo(SE2d(10, 0, 1), 30.0);
  path.Wait(1.0);
  const SimTrajectory t = path.Build();
  EXPECT_EQ(t.segment.front(), 0);
  EXPECT_EQ(t.segment.back(), 1);
  EXPECT_NEAR(t.LengthM(), 1.0, 1e-9);  // the carry is not travelled
  const WheelOdometryModel exact;
  std::mt19937_64 rng(1);
  const Trajectory odometry = SimulateWheelOdometry(t, exact, &rng);
  for (size_t k = 0; k < t.T_world_robot.size(); ++k) {
    if (t.segment[k] == 1) {
      EXPECT_EQ(odometry[k].T.translation().norm(), 0.0);  // restarted, standing still
    }
  }
}

TEST(MotionTest, WheelOdometryWithoutErrorsIsExact) {
  PlanarPathBuilder path(SE2d(1, 2, 0.3), 20.0, 0.4, 1.0);
  path.DriveTo({3, 3});
  path.TurnBy(-2.0);
  path.DriveTo({0, 0});
  const SimTrajectory t = path.Build();
  std::mt19937_64 rng(1);
  const Trajectory odometry = SimulateWheelOdometry(t, WheelOdometryModel(), &rng);
  const SE3d T_world_odom = t.T_world_robot.front().T;
  for (size_t k = 0; k < odometry.size(); ++k) {
    EXPECT_LT((T_world_odom * odometry[k].T.translation() - t.T_world_robot[k].T.translation()).norm(), 1e-9);
  }
}

TEST(MotionTest, WheelRadiusMismatchCurvesAStraightRun) {
  PlanarPathBuilder path(SE2d(0, 0, 0), 20.0, 0.5, 1.0);
  path.DriveTo({10, 0});
  WheelOdometryModel model;
  model.track_width_m = 0.4;
  model.wheel_radius_error_right = 0.01;  // right wheel larger: it reads less, odometry turns right
  std::mt19937_64 rng(1);
  const Trajectory odometry = SimulateWheelOdometry(path.Build(), model, &rng);
  // Heading error: (s / 1.01 - s) / 0.4 over s = 10 m.
  EXPECT_NEAR(odometry.back().T.yaw(), (10.0 / 1.01 - 10.0) / 0.4, 1e-9);
}

TEST(MotionTest, VisualOdometryScaleErrorScalesTheDistance) {
  FlightPathBuilder flight({0, 0, 1}, 0.0, 20.0, 1.0, 1.0, 0.0);
  flight.FlyTo({5, 0, 1});
  VisualOdometryModel model;
  model.scale_error = 0.02;
  std::mt19937_64 rng(1);
  const Trajectory odometry = SimulateVisualOdometry(flight.Build(), model, &rng);
  EXPECT_NEAR(odometry.back().T.translation().x(), 5.1, 1e-9);
  EXPECT_NEAR(odometry.back().T.translation().norm(), 5.1, 1e-9);
}

TEST(MotionTest, FlightWobblesButKeepsItsCourse) {
  FlightPathBuilder flight({0, 0, 1}, 0.0, 20.0, 0.5, 1.0, 3.0 * M_PI / 180.0);
  flight.YawTo(M_PI / 2);
  flight.FlyTo({0, 4, 2});
  const SimTrajectory t = flight.Build();
  double max_tilt = 0.0;
  for (const StampedSE3& s : t.T_world_robot) {
    const Eigen::Vector3d up = s.T.rotation() * Eigen::Vector3d::UnitZ();
    max_tilt = std::max(max_tilt, std::acos(std::min(1.0, up.z())));
  }
  EXPECT_GT(max_tilt, 1.0 * M_PI / 180.0);
  EXPECT_LT(max_tilt, 4.5 * M_PI / 180.0);
  EXPECT_TRUE(t.T_world_robot.back().T.translation().isApprox(Eigen::Vector3d(0, 4, 2), 1e-12));
  EXPECT_NEAR(t.T_world_robot.back().T.yaw(), M_PI / 2, 0.06);
}

}  // namespace
}  // namespace waymark::sim
