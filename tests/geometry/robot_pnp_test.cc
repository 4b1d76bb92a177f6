// Robust PnP of a robot over several codes (geometry/robot_pnp.h): the fit from a perturbed
// start, and its information matrix against the scatter of fits to noisy corners.
#include "geometry/robot_pnp.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <random>
#include <vector>

#include "tests/test_cameras.h"

namespace waymark {
namespace {

// A robot looking along +x through a camera 0.2 m up (camera z forward, y down), and three
// 16 cm codes on a wall 1.5-2 m ahead, facing the robot.
struct Scene {
  Camera camera{[] {
    CameraInfo info = testing::IdealPinholeInfo("cam0", 640, 480, 500.0);
    Eigen::Matrix3d R_robot_camera;
    R_robot_camera << 0, 0, 1, -1, 0, 0, 0, -1, 0;
    info.T_robot_camera = SE3d(R_robot_camera, Eigen::Vector3d(0.0, 0.0, 0.2));
    return info;
  }()};
  SE3d T_world_robot = SE3d::FromXYZYaw(0.4, -0.1, 0.0, 0.1);
  std::vector<SE3d> codes;
  std::vector<std::array<Eigen::Vector2d, 4>> corners;

  Scene() {
    Eigen::Matrix3d R_world_marker;  // marker z towards -x (facing the robot), marker x along -y
    R_world_marker << 0, 0, -1, -1, 0, 0, 0, 1, 0;
    for (const Eigen::Vector3d& t :
         {Eigen::Vector3d(2.2, 0.3, 0.4), Eigen::Vector3d(2.0, -0.5, 0.1), Eigen::Vector3d(2.4, 0.0, -0.2)}) {
      codes.emplace_back(R_world_marker, t);
    }
    corners.resize(codes.size());
  }
  // Projects the corners, with Gaussian noise of sigma_px.
  void Observe(double sigma_px, std::mt19937* rng) {
    std::normal_distribution<double> noise(0.0, sigma_px);
    const SE3d T_camera_world = (T_world_robot * camera.info().T_robot_camera).inverse();
    for (size_t i = 0; i < codes.size(); ++i) {
      const std::array<Eigen::Vector3d, 4> q = MarkerCorners(0.16);
      for (int k = 0; k < 4; ++k) {
        const std::optional<Eigen::Vector2d> px = camera.Project(T_camera_world * codes[i] * q[k]);
        ASSERT_TRUE(px.has_value());
        corners[i][k] = *px + Eigen::Vector2d(noise(*rng), noise(*rng));
      }
    }
  }
  std::vector<PnpView> Views(double sigma_px) const {
    std::vector<PnpView> views;
    for (size_t i = 0; i < codes.size(); ++i)
      views.push_back({&camera, &corners[i], sigma_px, 0.16, codes[i]});
    return views;
  }
};

TEST(RobotPnpTest, RecoversThePoseFromAPerturbedStart) {
  Scene scene;
  std::mt19937 rng(1);
  scene.Observe(0.0, &rng);
  const SE3d start = scene.T_world_robot * SE3d::FromXYZYaw(0.1, -0.05, 0.03, 0.08);
  for (const bool planar : {false, true}) {
    const SE3d fitted = RefineRobotPose(scene.Views(1.0), start, planar, 4.0, 50);
    EXPECT_LT((fitted.translation() - scene.T_world_robot.translation()).norm(), 1e-7);
    EXPECT_LT(RotationAngleBetween(fitted, scene.T_world_robot), 1e-7);
    const std::vector<std::optional<double>> errors = RobotPnpErrors(scene.Views(1.0), fitted, nullptr);
    ASSERT_EQ(errors.size(), 3u);
    for (const std::optional<double>& e : errors) EXPECT_LT(e.value_or(1.0), 1e-10);
  }
}

// The information J^T J is the inverse covariance of the fit: the scatter of 400 fits to
// corners with 0.5 px noise matches its inverse (Mahalanobis distances average 6, the dof).
TEST(RobotPnpTest, InformationMatchesTheScatterOfNoisyFits) {
  Scene scene;
  std::mt19937 rng(2);
  constexpr double kSigmaPx = 0.5;
  Matrix6d information;
  scene.Observe(0.0, &rng);
  RobotPnpErrors(scene.Views(kSigmaPx), scene.T_world_robot, &information);
  constexpr int kRuns = 400;
  double sum = 0.0;
  for (int run = 0; run < kRuns; ++run) {
    scene.Observe(kSigmaPx, &rng);
    const SE3d fitted = RefineRobotPose(scene.Views(kSigmaPx), scene.T_world_robot, false, 1e3, 50);
    const Vector6d d = scene.T_world_robot.BoxMinus(fitted);  // right perturbation [dr, dt]
    sum += d.dot(information * d);                            // d^T Sigma^-1 d with Sigma = information^-1
  }
  EXPECT_NEAR(sum / kRuns, 6.0, 0.6);
  // A view that does not project has no error and no information.
  std::vector<PnpView> views = scene.Views(kSigmaPx);
  views[0].T_world_marker = scene.T_world_robot * SE3d::FromXYZYaw(-2.0, 0.0, 0.2, 0.0);  // behind
  const std::vector<std::optional<double>> errors = RobotPnpErrors(views, scene.T_world_robot, &information);
  EXPECT_FALSE(errors[0].has_value());
  EXPECT_TRUE(errors[1].has_value());
}

}  // namespace
}  // namespace waymark
