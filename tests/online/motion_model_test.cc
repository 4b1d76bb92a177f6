#include "online/motion_model.h"

#include <gtest/gtest.h>

#include "online/ekf_state.h"
#include "tests/online/jacobian_check.h"

namespace waymark {
namespace {

using testing::NumericJacobian;

// Wraps the last entry (yaw) of a difference vector.
Eigen::VectorXd WrapLast(Eigen::VectorXd v) {
  v(v.size() - 1) = WrapAngle(v(v.size() - 1));
  return v;
}

constexpr double kTolerance = 1e-7;

TEST(MotionModelTest, PlanarIncrementJacobiansMatchCentralDifferences) {
  const OdometryNoise noise;
  for (const Eigen::Vector3d& x : {Eigen::Vector3d(1.0, -2.0, 0.3), Eigen::Vector3d(-4.0, 0.5, 3.0)}) {
    const Eigen::Vector3d u(0.07, -0.02, 0.05);
    const MotionPrediction p = PredictPlanarIncrement(x, SE2d(u.x(), u.y(), u.z()), noise);
    const auto f_x = [&](const Eigen::VectorXd& xx) -> Eigen::VectorXd {
      return PredictPlanarIncrement(xx, SE2d(u.x(), u.y(), u.z()), noise).mean;
    };
    const auto f_u = [&](const Eigen::VectorXd& uu) -> Eigen::VectorXd {
      return PredictPlanarIncrement(x, SE2d(uu(0), uu(1), uu(2)), noise).mean;
    };
    EXPECT_LT((p.F - NumericJacobian(f_x, x, 1e-6, WrapLast)).norm(), kTolerance);
    EXPECT_LT((p.G - NumericJacobian(f_u, u, 1e-6, WrapLast)).norm(), kTolerance);
  }
}

TEST(MotionModelTest, UnicycleMatchesSeed000AndItsJacobians) {
  const OdometryNoise noise;
  const Eigen::Vector3d x(0.5, 1.5, -2.0);
  const double v = 0.4, omega = 0.6, dt = 0.05;
  const MotionPrediction p = PredictUnicycle(x, v, omega, dt, noise);
  // Seed 000, eq. (6).
  EXPECT_NEAR(p.mean(0), x(0) + v * dt * std::cos(x(2) + omega * dt / 2), 1e-15);
  EXPECT_NEAR(p.mean(1), x(1) + v * dt * std::sin(x(2) + omega * dt / 2), 1e-15);
  EXPECT_NEAR(p.mean(2), x(2) + omega * dt, 1e-15);
  const auto f_x = [&](const Eigen::VectorXd& xx) -> Eigen::VectorXd {
    return PredictUnicycle(xx, v, omega, dt, noise).mean;
  };
  // u = [d, a] = [v dt, omega dt].
  const auto f_u = [&](const Eigen::VectorXd& uu) -> Eigen::VectorXd {
    return PredictUnicycle(x, uu(0) / dt, uu(1) / dt, dt, noise).mean;
  };
  EXPECT_LT((p.F - NumericJacobian(f_x, x, 1e-6, WrapLast)).norm(), kTolerance);
  EXPECT_LT((p.G - NumericJacobian(f_u, Eigen::Vector2d(v * dt, omega * dt), 1e-7, WrapLast)).norm(),
            kTolerance);
}

TEST(MotionModelTest, FreeIncrementJacobiansMatchCentralDifferences) {
  const OdometryNoise noise;
  const Eigen::Matrix3d R_level =
      (Eigen::AngleAxisd(0.15, Eigen::Vector3d::UnitY()) * Eigen::AngleAxisd(-0.1, Eigen::Vector3d::UnitX()))
          .toRotationMatrix();
  const Eigen::Vector4d x(1.0, 2.0, 1.5, 0.8);
  const SE3d increment(
      Eigen::Quaterniond(Eigen::AngleAxisd(0.1, Eigen::Vector3d(0.2, -0.3, 1.0).normalized())),
      Eigen::Vector3d(0.1, 0.02, -0.03));
  const MotionPrediction p = PredictFreeIncrement(x, R_level, increment, noise);
  const auto f_x = [&](const Eigen::VectorXd& xx) -> Eigen::VectorXd {
    return PredictFreeIncrement(xx, R_level, increment, noise).mean;
  };
  // u = [dt, dphi]: increment (dR Exp(dphi), dt).
  const auto f_u = [&](const Eigen::VectorXd& uu) -> Eigen::VectorXd {
    const SE3d perturbed(increment.rotation() * ExpSO3(uu.tail<3>()), increment.translation() + uu.head<3>());
    return PredictFreeIncrement(x, R_level, perturbed, noise).mean;
  };
  EXPECT_LT((p.F - NumericJacobian(f_x, x, 1e-6, WrapLast)).norm(), kTolerance);
  EXPECT_LT((p.G - NumericJacobian(f_u, Eigen::VectorXd::Zero(6), 1e-6, WrapLast)).norm(), kTolerance);
  // The mean is the composition T_world_robot * increment.
  const SE3d T_world_robot(
      Eigen::Matrix3d(Eigen::AngleAxisd(x(3), Eigen::Vector3d::UnitZ()).toRotationMatrix() * R_level),
      Eigen::Vector3d(x.head<3>()));
  const SE3d composed = T_world_robot * increment;
  EXPECT_LT((p.mean.head<3>() - composed.translation()).norm(), 1e-12);
  EXPECT_NEAR(p.mean(3), composed.yaw(), 1e-12);
}

TEST(MotionModelTest, NoiseScalesWithTravelAndHasAFloor) {
  OdometryNoise noise;
  noise.sigma = {0.05, 0.1};
  noise.floor_trans_m = 1e-3;
  noise.floor_rot_rad = 2e-3;
  noise.heading_per_sqrt_m = 0.0;
  const MotionPrediction still = PredictPlanarIncrement(Eigen::Vector3d::Zero(), SE2d(0, 0, 0), noise);
  EXPECT_NEAR(still.Qu(0, 0), 1e-6, 1e-18);
  EXPECT_NEAR(still.Qu(2, 2), 4e-6, 1e-18);
  const MotionPrediction moved = PredictPlanarIncrement(Eigen::Vector3d::Zero(), SE2d(0.3, 0.4, -0.5), noise);
  EXPECT_NEAR(std::sqrt(moved.Qu(0, 0)), 0.05 * 0.5 + 1e-3, 1e-12);
  EXPECT_NEAR(std::sqrt(moved.Qu(2, 2)), 0.1 * 0.5 + 2e-3, 1e-12);
  std::string why;
  noise.floor_rot_rad = 0.0;
  EXPECT_FALSE(noise.Check(&why));
  EXPECT_NE(why.find("floor"), std::string::npos);
}

// The heading random walk adds heading_per_sqrt_m^2 * distance to the heading variance of
// every increment (and of the unicycle), so the heading variance after D metres is the same
// at any odometry rate.
TEST(MotionModelTest, HeadingWalkGrowsWithDistanceNotRate) {
  OdometryNoise noise;
  noise.sigma = {0.0, 0.0};
  noise.heading_per_sqrt_m = 0.01;
  const double floor_variance = noise.floor_rot_rad * noise.floor_rot_rad;
  const MotionPrediction step = PredictPlanarIncrement(Eigen::Vector3d::Zero(), SE2d(0.3, 0.4, 0.0), noise);
  EXPECT_NEAR(step.Qu(2, 2), 1e-4 * 0.5 + floor_variance, 1e-15);
  const MotionPrediction unicycle = PredictUnicycle(Eigen::Vector3d::Zero(), 0.5, 0.0, 2.0, noise);
  EXPECT_NEAR(unicycle.Qu(1, 1), 1e-4 * 1.0 + floor_variance, 1e-15);
  for (int steps : {10, 100}) {
    noise.floor_rot_rad = 1e-12;
    Eigen::Matrix3d P = Eigen::Matrix3d::Zero();
    for (int k = 0; k < steps; ++k) {
      const MotionPrediction p = PredictPlanarIncrement(Eigen::Vector3d::Zero(), SE2d(4.0 / steps, 0.0, 0.0), noise);
      P = p.F * P * p.F.transpose() + p.G * p.Qu * p.G.transpose();
    }
    EXPECT_NEAR(P(2, 2), 1e-4 * 4.0, 1e-12) << steps << " steps";
  }
  std::string why;
  noise.heading_per_sqrt_m = -1.0;
  EXPECT_FALSE(noise.Check(&why));
  EXPECT_NE(why.find("heading_per_sqrt_m"), std::string::npos);
}

}  // namespace
}  // namespace waymark
