// Tests of the pose priors: SE(3) with a full covariance, SE(2), position-only (x, y and
// x, y, z) and yaw. Hand-computed residuals, zero at the prior, Jacobians against
// ceres::GradientChecker under the real manifolds at ten random states each, bad input.
#include <gtest/gtest.h>

#include <array>
#include <memory>
#include <random>
#include <stdexcept>

#include "factors/pose_block.h"
#include "factors/pose_prior_se2_factor.h"
#include "factors/pose_prior_se3_factor.h"
#include "factors/position_prior_factor.h"
#include "factors/yaw_prior_factor.h"
#include "tests/factors/factor_test_util.h"

namespace waymark {
namespace {

using testing::kNaN;

TEST(PosePriorSE3Factor, NominalHandComputed) {
  // Prior (Rz(90 deg), (1, 2, 3)); block (Rz(90 deg) Rx(0.1), (1, 2.2, 3)):
  // delta = [(0.1, 0, 0), Rz(-90 deg) (0, 0.2, 0)] = [(0.1, 0, 0), (0.2, 0, 0)];
  // sigmas 0.05 rad and 0.1 m give r = (2, 0, 0, 2, 0, 0).
  const SE3d prior = SE3d::FromXYZYaw(1.0, 2.0, 3.0, M_PI / 2);
  Vector6d variances;
  variances << 0.0025, 0.0025, 0.0025, 0.01, 0.01, 0.01;
  const std::unique_ptr<ceres::CostFunction> cost(PosePriorSE3Factor::Create(prior, variances.asDiagonal()));
  double block[7];
  SE3ToBlock(SE3d(prior.rotation() * Eigen::Quaterniond(Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitX())),
                  Eigen::Vector3d(1.0, 2.2, 3.0)),
             block);
  const double* parameters[] = {block};
  Vector6d residuals = Vector6d::Constant(kNaN);
  ASSERT_TRUE(cost->Evaluate(parameters, residuals.data(), nullptr));
  Vector6d expected;
  expected << 2, 0, 0, 2, 0, 0;
  EXPECT_LT((residuals - expected).norm(), 1e-12) << residuals.transpose();
  SE3ToBlock(prior, block);
  residuals.setConstant(kNaN);
  ASSERT_TRUE(cost->Evaluate(parameters, residuals.data(), nullptr));
  EXPECT_LT(residuals.norm(), 1e-12);
}

TEST(PosePriorSE2Factor, NominalHandComputed) {
  // Prior (1, 1, 90 deg); block (1, 1.5, 90 deg - 0.2 + 2 pi): delta = (0.5, 0, -0.2);
  // sigmas 0.25 m and 0.1 rad give r = (2, 0, -2).
  const Eigen::Matrix3d covariance = Eigen::Vector3d(0.0625, 0.0625, 0.01).asDiagonal();
  const std::unique_ptr<ceres::CostFunction> cost(
      PosePriorSE2Factor::Create(SE2d(1.0, 1.0, M_PI / 2), covariance));
  double block[3] = {1.0, 1.5, M_PI / 2 - 0.2 + 2 * M_PI};
  const double* parameters[] = {block};
  std::array<double, 3> residuals = {kNaN, kNaN, kNaN};
  ASSERT_TRUE(cost->Evaluate(parameters, residuals.data(), nullptr));
  EXPECT_NEAR(residuals[0], 2.0, 1e-12);
  EXPECT_NEAR(residuals[1], 0.0, 1e-12);
  EXPECT_NEAR(residuals[2], -2.0, 1e-12);
}

TEST(PositionPriorFactor, NominalHandComputed) {
  double block[7];
  SE3ToBlock(SE3d(testing::ForwardCameraRotation(0.3), Eigen::Vector3d(4.0, -1.0, 2.5)), block);
  const double* parameters[] = {block};
  // x, y only: (4 - 3.8, -1 - (-1.1)) / 0.05 = (4, 2); z is free.
  const std::unique_ptr<ceres::CostFunction> xy(
      PositionPriorXYFactor::Create(Eigen::Vector2d(3.8, -1.1), 0.05));
  std::array<double, 2> residuals_xy = {kNaN, kNaN};
  ASSERT_TRUE(xy->Evaluate(parameters, residuals_xy.data(), nullptr));
  EXPECT_NEAR(residuals_xy[0], 4.0, 1e-12);
  EXPECT_NEAR(residuals_xy[1], 2.0, 1e-12);
  // x, y, z with a full covariance: |r|^2 = e^T Sigma^-1 e.
  Eigen::Matrix3d covariance;
  covariance << 0.04, 0.01, 0.0, 0.01, 0.09, -0.02, 0.0, -0.02, 0.25;
  const Eigen::Vector3d prior(3.8, -1.1, 2.0);
  const std::unique_ptr<ceres::CostFunction> xyz(PositionPriorXYZFactor::Create(prior, covariance));
  std::array<double, 3> residuals_xyz = {kNaN, kNaN, kNaN};
  ASSERT_TRUE(xyz->Evaluate(parameters, residuals_xyz.data(), nullptr));
  const Eigen::Vector3d error = Eigen::Vector3d(4.0, -1.0, 2.5) - prior;
  EXPECT_NEAR(Eigen::Map<Eigen::Vector3d>(residuals_xyz.data()).squaredNorm(),
              error.dot(covariance.ldlt().solve(error)), 1e-10);
}

TEST(YawPriorFactor, NominalHandComputed) {
  // A floor marker (z up) turned to yaw 170 deg; prior -170 deg: the wrapped error is -20 deg,
  // not 340; sigma 10 deg gives r = -2. Roll and pitch do not change the yaw of the x axis
  // here (a tilt about the x axis).
  const double deg = M_PI / 180.0;
  const std::unique_ptr<ceres::CostFunction> cost(YawPriorFactor::Create(-170 * deg, 10 * deg));
  const Eigen::Quaterniond q = Eigen::Quaterniond(Eigen::AngleAxisd(170 * deg, Eigen::Vector3d::UnitZ())) *
                               Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitX()));
  double block[7];
  SE3ToBlock(SE3d(q, Eigen::Vector3d(1, 2, 0)), block);
  const double* parameters[] = {block};
  double residual = kNaN;
  ASSERT_TRUE(cost->Evaluate(parameters, &residual, nullptr));
  EXPECT_NEAR(residual, -2.0, 1e-12);
  // Undefined yaw: the x axis vertical.
  SE3ToBlock(SE3d(Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitY())),
                  Eigen::Vector3d::Zero()),
             block);
  EXPECT_FALSE(cost->Evaluate(parameters, &residual, nullptr));
}

TEST(PriorFactors, GradientCheckTenRandomStates) {
  const SE3Manifold se3;
  std::mt19937 rng(31);
  std::uniform_real_distribution<double> coordinate(-10.0, 10.0), angle(-3.0, 3.0);
  Eigen::Matrix<double, 6, 6> A = Eigen::Matrix<double, 6, 6>::Random() * 0.1;
  const Matrix6d covariance_3d = A * A.transpose() + 1e-3 * Matrix6d::Identity();
  for (int trial = 0; trial < 10; ++trial) {
    const SE3d prior = testing::RandomSE3(rng, 10.0);
    Vector6d delta;
    delta << testing::RandomVector(rng, 1.4), testing::RandomVector(rng, 1.0);  // |dr| < pi
    double block[7];
    SE3ToBlock(prior.BoxPlus(delta), block);
    const std::unique_ptr<ceres::CostFunction> se3_prior(PosePriorSE3Factor::Create(prior, covariance_3d));
    testing::ExpectGradientsMatch(*se3_prior, {&se3}, {block}, 1e-6, "SE(3) prior");
    const std::unique_ptr<ceres::CostFunction> xy(
        PositionPriorXYFactor::Create(Eigen::Vector2d(coordinate(rng), coordinate(rng)), 0.1));
    testing::ExpectGradientsMatch(*xy, {&se3}, {block}, 1e-6, "xy prior");
    const std::unique_ptr<ceres::CostFunction> xyz(
        PositionPriorXYZFactor::Create(testing::RandomVector(rng, 10.0), 0.1));
    testing::ExpectGradientsMatch(*xyz, {&se3}, {block}, 1e-6, "xyz prior");
    // Yaw: the block's yaw within 2.5 rad of the prior (away from the +-pi cut).
    const double yaw_prior = angle(rng);
    const Eigen::Quaterniond q =
        Eigen::Quaterniond(Eigen::AngleAxisd(yaw_prior + 0.8 * angle(rng), Eigen::Vector3d::UnitZ())) *
        ExpSO3(testing::RandomVector(rng, 0.6));
    SE3ToBlock(SE3d(q, testing::RandomVector(rng, 5.0)), block);
    const std::unique_ptr<ceres::CostFunction> yaw(YawPriorFactor::Create(yaw_prior, 0.1));
    testing::ExpectGradientsMatch(*yaw, {&se3}, {block}, 1e-6, "yaw prior");

    const SE2d prior_2d(coordinate(rng), coordinate(rng), angle(rng));
    const SE2d T_2d = prior_2d * SE2d(angle(rng), angle(rng), 0.8 * angle(rng));
    double block_2d[3] = {T_2d.x(), T_2d.y(), T_2d.theta() + 2 * M_PI * (trial % 3 - 1)};
    const std::unique_ptr<ceres::CostFunction> se2_prior(
        PosePriorSE2Factor::Create(prior_2d, Eigen::Vector3d(0.01, 0.02, 0.03).asDiagonal()));
    testing::ExpectGradientsMatch(*se2_prior, {nullptr}, {block_2d}, 1e-6, "SE(2) prior");
  }
}

TEST(PriorFactors, RejectBadInput) {
  EXPECT_THROW(PosePriorSE3Factor(SE3d(), Matrix6d::Identity() * -1.0), std::invalid_argument);
  EXPECT_THROW(PosePriorSE2Factor(SE2d(), Eigen::Matrix3d::Zero()), std::invalid_argument);
  EXPECT_THROW(PositionPriorXYFactor::Create(Eigen::Vector2d(kNaN, 0.0), 0.1), std::invalid_argument);
  EXPECT_THROW(PositionPriorXYZFactor::Create(Eigen::Vector3d::Zero(), 0.0), std::invalid_argument);
  EXPECT_THROW(YawPriorFactor(kNaN, 0.1), std::invalid_argument);
  EXPECT_THROW(YawPriorFactor(0.0, -0.1), std::invalid_argument);
  try {
    YawPriorFactor(0.0, 0.0);
    ADD_FAILURE() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "yaw prior: sigma must be finite and > 0, got 0");
  }
}

}  // namespace
}  // namespace waymark
