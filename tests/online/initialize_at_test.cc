// Localizer::InitializeAt: tracking from a known start pose, before any code.
#include <gtest/gtest.h>

#include "online/localizer.h"

namespace waymark {
namespace {

CameraInfo FrontCamera() {
  CameraInfo camera;
  camera.name = "front";
  camera.width = 640;
  camera.height = 480;
  camera.intrinsics = {450, 450, 320, 240};
  camera.distortion = {0, 0, 0, 0, 0};
  return camera;
}

TEST(InitializeAtTest, TracksFromTheGivenPoseAndItsCovariance) {
  Localizer localizer(LocalizerOptions(), MarkerMap(), {FrontCamera()});
  EXPECT_EQ(localizer.tracking(), TrackingStatus::kUninitialized);
  const Eigen::Matrix3d covariance = Eigen::Vector3d(0.0025, 0.0025, 0.0025).asDiagonal();
  ASSERT_EQ(localizer.InitializeAt(1.0, SE3d::FromXYZYaw(2.0, 3.0, 0.0, 0.5), covariance), StepStatus::kOk);
  EXPECT_EQ(localizer.tracking(), TrackingStatus::kTracking);
  EXPECT_EQ(localizer.counters().initializations, 1);
  const PoseOutput out = localizer.Output();
  ASSERT_TRUE(out.T_world_robot && out.covariance);
  EXPECT_NEAR(out.T_world_robot->translation().x(), 2.0, 1e-12);
  EXPECT_NEAR(out.T_world_robot->yaw(), 0.5, 1e-12);
  EXPECT_TRUE(out.covariance->isApprox(covariance));
  // Odometry moves it: 1 m forward along the heading.
  EXPECT_EQ(localizer.AddOdometry(1.0, SE3d()), StepStatus::kOk);
  EXPECT_EQ(localizer.AddOdometry(2.0, SE3d::FromXYZYaw(1.0, 0.0, 0.0, 0.0)), StepStatus::kOk);
  EXPECT_NEAR(localizer.Output().T_world_robot->translation().x(), 2.0 + std::cos(0.5), 1e-9);
  EXPECT_GT((*localizer.Output().covariance)(1, 1), covariance(1, 1));
}

TEST(InitializeAtTest, BadCovarianceOrOldStampChangesNothing) {
  Localizer localizer(LocalizerOptions(), MarkerMap(), {FrontCamera()});
  EXPECT_EQ(localizer.InitializeAt(0.0, SE3d(), Eigen::Matrix2d::Identity()), StepStatus::kInvalidInput);
  EXPECT_EQ(localizer.InitializeAt(0.0, SE3d(), -Eigen::Matrix3d::Identity()), StepStatus::kInvalidInput);
  EXPECT_EQ(localizer.tracking(), TrackingStatus::kUninitialized);
  EXPECT_EQ(localizer.AddOdometry(5.0, SE3d()), StepStatus::kOk);
  EXPECT_EQ(localizer.InitializeAt(4.0, SE3d(), Eigen::Matrix3d::Identity()), StepStatus::kTimeWentBackwards);
  EXPECT_EQ(localizer.tracking(), TrackingStatus::kUninitialized);
}

}  // namespace
}  // namespace waymark
