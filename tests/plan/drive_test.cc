// plan/drive.h: the closed loop in the rooms scenario, against the true map.
#include "plan/drive.h"

#include <gtest/gtest.h>

#include "sim/scenarios.h"
#include "sim/simulator.h"

namespace waymark::plan {
namespace {

MarkerMap TrueMap(const sim::ParamSet& params, const Eigen::Vector3d& shift) {
  MarkerMap map = *sim::Simulate("rooms", params, 0).dataset.groundtruth_markers;
  for (MapMarker& m : map.markers)
    m.T_world_marker = SE3d(m.T_world_marker.rotation(), m.T_world_marker.translation() + shift);
  return map;
}

// Room 0's centre, through the door at x = 4, to room 1's centre facing +y.
Route DoorRoute() {
  Route route;
  for (const Eigen::Vector3d& p :
       {Eigen::Vector3d(2, 2, 0), Eigen::Vector3d(4, 2, 0), Eigen::Vector3d(6, 2, M_PI / 2)}) {
    RouteWaypoint w;
    w.x_y_yaw = p;
    route.waypoints.push_back(w);
  }
  route.goal_yaw_given = true;
  return route;
}

TEST(SimStepperTest, DrivesExactArcsAndDrawsFramesAtTheCameraRate) {
  const sim::ParamSet params = sim::ScenarioParams("rooms");
  sim::SimStepper stepper("rooms", params, 3, SE2d(2, 2, 0));
  EXPECT_EQ(stepper.first().frames.size(), 1u);  // one camera, a frame at the start
  long frames = 0;
  for (int k = 0; k < 20; ++k) frames += static_cast<long>(stepper.Advance(0.3, 0.0).frames.size());
  EXPECT_EQ(frames, 10);  // 10 Hz camera, 20 Hz odometry
  EXPECT_NEAR(stepper.T_world_robot().x(), 2.3, 1e-12);
  for (int k = 0; k < 20; ++k) stepper.Advance(0.0, M_PI / 2);
  EXPECT_NEAR(stepper.T_world_robot().theta(), M_PI / 2, 1e-12);
  const sim::SimResult result = stepper.Finish();
  EXPECT_EQ(result.dataset.odometry.size(), 41u);
  EXPECT_EQ(result.dataset.groundtruth_trajectory->size(), 41u);
  EXPECT_EQ(result.dataset.detections.size(), 21u);
  EXPECT_NEAR(result.stats.path_length_m, 0.3, 1e-9);
  EXPECT_THROW(sim::SimStepper("warehouse-drone", sim::ScenarioParams("warehouse-drone"), 0, SE2d()),
               std::invalid_argument);
}

TEST(DriveTest, ThroughTheDoorToTheGoalWithoutLosingTheFilter) {
  const sim::ParamSet params = sim::ScenarioParams("rooms");
  const DriveResult result =
      DriveRoute("rooms", params, 1, DoorRoute(), TrueMap(params, Eigen::Vector3d::Zero()), std::nullopt,
                 DriveOptions());
  EXPECT_TRUE(result.report.reached) << result.report.outcome;
  EXPECT_LT(result.report.goal_error_m, 0.05);
  EXPECT_LT(result.report.goal_yaw_error_rad, 0.05);
  EXPECT_EQ(result.report.times_lost, 0);
  EXPECT_EQ(result.report.frames_lost, 0);
  EXPECT_GT(result.report.path_length_m, 3.9);
  EXPECT_FALSE(result.online.empty());
  EXPECT_EQ(result.sim.dataset.groundtruth_trajectory->size(), result.sim.dataset.odometry.size());
}

// The controller steers by the localizer's pose: against a map shifted by 10 cm (the robot set
// down where the unshifted map says) the robot stops where the shifted map puts the goal, 10 cm
// off the true goal.
TEST(DriveTest, SteersByTheEstimateNotByTheTruth) {
  const sim::ParamSet params = sim::ScenarioParams("rooms");
  DriveOptions options;
  options.T_world_map = SE2d();
  const DriveResult result = DriveRoute("rooms", params, 1, DoorRoute(),
                                        TrueMap(params, Eigen::Vector3d(0, 0.1, 0)), std::nullopt, options);
  EXPECT_TRUE(result.report.reached) << result.report.outcome;
  EXPECT_NEAR(result.report.final_truth.y(), 2.0 - 0.1, 0.03);
  ASSERT_TRUE(result.report.final_estimate);
  EXPECT_NEAR((*result.report.final_estimate - result.report.goal).head<2>().norm(), 0.0, 0.006);
}

TEST(DriveTest, BadOptionsAreErrors) {
  DriveOptions options;
  options.lookahead_m = 0.0;
  const sim::ParamSet params = sim::ScenarioParams("rooms");
  EXPECT_THROW(DriveRoute("rooms", params, 1, DoorRoute(), MarkerMap(), std::nullopt, options),
               std::invalid_argument);
  EXPECT_THROW(DriveRoute("rooms", params, 1, Route(), MarkerMap(), std::nullopt, DriveOptions()),
               std::invalid_argument);
}

}  // namespace
}  // namespace waymark::plan
