// Tests of the SE(2) and SE(3) odometry between-factors and of the covariance helper:
// hand-computed residuals, zero at the truth, angle wrapping, whitening with a non-diagonal
// covariance, Jacobians against ceres::GradientChecker under the real manifolds, bad input.
#include <gtest/gtest.h>

#include <array>
#include <memory>
#include <random>
#include <stdexcept>

#include "factors/calibrated_odometry_factor.h"
#include "factors/odometry_covariance.h"
#include "factors/odometry_se2_factor.h"
#include "factors/odometry_se3_factor.h"
#include "factors/pose_block.h"
#include "tests/factors/factor_test_util.h"

namespace waymark {
namespace {

using testing::kNaN;

TEST(OdometrySE2Factor, NominalHandComputed) {
  // a at the origin heading +x, b one metre ahead turned left by 90 degrees. The odometry says
  // 0.9 m ahead and 80 degrees: delta = (R(-80 deg) (0.1, 0), 10 deg) = (0.1 cos 80, -0.1 sin 80,
  // 10 deg); with sigma_t = 0.05 m and sigma_r = 0.1 rad the whitened residual is
  // (2 cos 80, -2 sin 80, (pi / 18) / 0.1).
  const Eigen::Matrix3d covariance = Eigen::Vector3d(0.05 * 0.05, 0.05 * 0.05, 0.1 * 0.1).asDiagonal();
  const std::unique_ptr<ceres::CostFunction> cost(
      OdometrySE2Factor::Create(SE2d(0.9, 0.0, 80.0 * M_PI / 180.0), covariance));
  double a[3] = {0.0, 0.0, 0.0};
  double b[3] = {1.0, 0.0, M_PI / 2};
  const double* parameters[] = {a, b};
  std::array<double, 3> residuals = {kNaN, kNaN, kNaN};
  ASSERT_TRUE(cost->Evaluate(parameters, residuals.data(), nullptr));
  EXPECT_NEAR(residuals[0], 2.0 * std::cos(80.0 * M_PI / 180.0), 1e-12);
  EXPECT_NEAR(residuals[1], -2.0 * std::sin(80.0 * M_PI / 180.0), 1e-12);
  EXPECT_NEAR(residuals[2], (M_PI / 18.0) / 0.1, 1e-12);

  // The same increment seen from a rotated and translated a, with angles 2 pi apart: zero.
  const SE2d T_world_a(3.0, -1.0, 3.0);
  const SE2d T_world_b = T_world_a * SE2d(0.9, 0.0, 80.0 * M_PI / 180.0);
  double a2[3] = {T_world_a.x(), T_world_a.y(), T_world_a.theta() - 2 * M_PI};
  double b2[3] = {T_world_b.x(), T_world_b.y(), T_world_b.theta() + 4 * M_PI};
  const double* parameters2[] = {a2, b2};
  residuals = {kNaN, kNaN, kNaN};
  ASSERT_TRUE(cost->Evaluate(parameters2, residuals.data(), nullptr));
  for (double r : residuals) EXPECT_NEAR(r, 0.0, 1e-10);
}

TEST(OdometrySE3Factor, NominalHandComputed) {
  // a at the origin, b = (Rz(30 deg), (1, 0, 0)); measured (Rz(20 deg), (1, 0.1, 0)).
  // delta = [Log(Rz(-20) Rz(30)), Rz(-20) ((1, 0, 0) - (1, 0.1, 0))]
  //       = [(0, 0, 10 deg), (-0.1 sin 20, -0.1 cos 20, 0)]; sigmas 0.1 rad and 0.01 m.
  const double deg = M_PI / 180.0;
  Vector6d variances;
  variances << 0.01, 0.01, 0.01, 1e-4, 1e-4, 1e-4;
  const std::unique_ptr<ceres::CostFunction> cost(
      OdometrySE3Factor::Create(SE3d::FromXYZYaw(1.0, 0.1, 0.0, 20 * deg), variances.asDiagonal()));
  double a[7], b[7];
  SE3ToBlock(SE3d(), a);
  SE3ToBlock(SE3d::FromXYZYaw(1.0, 0.0, 0.0, 30 * deg), b);
  const double* parameters[] = {a, b};
  Vector6d residuals = Vector6d::Constant(kNaN);
  ASSERT_TRUE(cost->Evaluate(parameters, residuals.data(), nullptr));
  Vector6d expected;
  expected << 0, 0, 10 * deg / 0.1, -0.1 * std::sin(20 * deg) / 0.01, -0.1 * std::cos(20 * deg) / 0.01, 0;
  EXPECT_LT((residuals - expected).norm(), 1e-10) << residuals.transpose();
}

TEST(OdometrySE3Factor, ZeroAtTheTruthAndFullCovarianceWhitening) {
  std::mt19937 rng(21);
  Eigen::Matrix<double, 6, 6> A = Eigen::Matrix<double, 6, 6>::Random() * 0.1;
  const Matrix6d covariance = A * A.transpose() + 1e-3 * Matrix6d::Identity();
  for (int trial = 0; trial < 10; ++trial) {
    const SE3d T_world_a = testing::RandomSE3(rng, 5.0), T_world_b = testing::RandomSE3(rng, 5.0);
    const SE3d T_a_b = T_world_a.inverse() * T_world_b;
    double a[7], b[7];
    SE3ToBlock(T_world_a, a);
    SE3ToBlock(T_world_b, b);
    const double* parameters[] = {a, b};
    const std::unique_ptr<ceres::CostFunction> exact(OdometrySE3Factor::Create(T_a_b, covariance));
    Vector6d residuals = Vector6d::Constant(kNaN);
    ASSERT_TRUE(exact->Evaluate(parameters, residuals.data(), nullptr));
    EXPECT_LT(residuals.norm(), 1e-9);
    // A measured increment off by a known delta: |r|^2 = delta^T Sigma^-1 delta.
    Vector6d delta;
    delta << testing::RandomVector(rng, 0.2), testing::RandomVector(rng, 0.3);
    const std::unique_ptr<ceres::CostFunction> off(
        OdometrySE3Factor::Create(T_a_b.BoxPlus(-delta), covariance));
    ASSERT_TRUE(off->Evaluate(parameters, residuals.data(), nullptr));
    const SE3d measured = T_a_b.BoxPlus(-delta);
    const Vector6d error = measured.BoxMinus(T_a_b);
    const double chi2 = error.dot(covariance.ldlt().solve(error));
    EXPECT_NEAR(residuals.squaredNorm(), chi2, 1e-9 * chi2);
  }
}

TEST(OdometryFactors, GradientCheckTenRandomStates) {
  const SE3Manifold se3;
  std::mt19937 rng(22);
  std::uniform_real_distribution<double> coordinate(-10.0, 10.0), angle(-3.0, 3.0);
  Eigen::Matrix3d A2 = Eigen::Matrix3d::Random() * 0.1;
  const Eigen::Matrix3d covariance_2d = A2 * A2.transpose() + 1e-3 * Eigen::Matrix3d::Identity();
  Eigen::Matrix<double, 6, 6> A3 = Eigen::Matrix<double, 6, 6>::Random() * 0.1;
  const Matrix6d covariance_3d = A3 * A3.transpose() + 1e-3 * Matrix6d::Identity();
  for (int trial = 0; trial < 10; ++trial) {
    // b = a * measured * (dx, dy, dtheta) with |dtheta| <= 2.5 rad, so the wrapped angle stays away
    // from its +-pi cut; block angles are unwrapped by multiples of 2 pi.
    const SE2d T_world_a(coordinate(rng), coordinate(rng), angle(rng));
    const SE2d measured_2d(coordinate(rng), coordinate(rng), angle(rng));
    const SE2d T_world_b =
        T_world_a * measured_2d * SE2d(0.3 * angle(rng), 0.3 * angle(rng), 0.8 * angle(rng));
    double a2[3] = {T_world_a.x(), T_world_a.y(), T_world_a.theta() + 2 * M_PI * (trial % 3)};
    double b2[3] = {T_world_b.x(), T_world_b.y(), T_world_b.theta() - 2 * M_PI * (trial % 2)};
    const std::unique_ptr<ceres::CostFunction> se2_cost(
        OdometrySE2Factor::Create(measured_2d, covariance_2d));
    testing::ExpectGradientsMatch(*se2_cost, {nullptr, nullptr}, {a2, b2}, 1e-6, "SE(2)");

    double a3[7], b3[7];
    const SE3d T_world_a3 = testing::RandomSE3(rng, 10.0);
    SE3ToBlock(T_world_a3, a3);
    // Residual rotations from small to ~2.5 rad, away from the pi cut of the logarithm.
    const SE3d measured = testing::RandomSE3(rng, 3.0);
    Vector6d delta;
    delta << testing::RandomVector(rng, 1.4), testing::RandomVector(rng, 1.0);
    SE3ToBlock(T_world_a3 * measured.BoxPlus(delta), b3);
    const std::unique_ptr<ceres::CostFunction> se3_cost(OdometrySE3Factor::Create(measured, covariance_3d));
    testing::ExpectGradientsMatch(*se3_cost, {&se3, &se3}, {a3, b3}, 1e-6, "SE(3)");
  }
}

TEST(OdometryCovariance, ScalesWithDistanceAndAngleWithAFloor) {
  const OdometrySigma sigma{0.02, 0.05};
  // 2 m and 0.5 rad: sigma_t = hypot(0.04, 1e-4), sigma_r = hypot(0.025, 1e-4).
  const Matrix6d cov3 = OdometryCovarianceSE3(sigma, SE3d::FromXYZYaw(0.0, 2.0, 0.0, 0.5));
  const double sigma_t = std::hypot(0.04, 1e-4), sigma_r = std::hypot(0.025, 1e-4);
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(cov3(i, i), sigma_r * sigma_r, 1e-15);
    EXPECT_NEAR(cov3(3 + i, 3 + i), sigma_t * sigma_t, 1e-15);
  }
  EXPECT_EQ((cov3 - Matrix6d(cov3.diagonal().asDiagonal())).norm(), 0.0);
  const Eigen::Matrix3d cov2 = OdometryCovarianceSE2(sigma, SE2d(0.0, -2.0, -0.5));
  EXPECT_NEAR(cov2(0, 0), sigma_t * sigma_t, 1e-15);
  EXPECT_NEAR(cov2(1, 1), sigma_t * sigma_t, 1e-15);
  EXPECT_NEAR(cov2(2, 2), sigma_r * sigma_r, 1e-15);
  // A standstill is not infinitely certain: the floor remains, and the factor accepts it.
  const Eigen::Matrix3d standstill = OdometryCovarianceSE2(sigma, SE2d());
  EXPECT_NEAR(standstill(0, 0), 1e-8, 1e-20);
  EXPECT_NEAR(standstill(2, 2), 1e-8, 1e-20);
  EXPECT_NO_THROW(OdometrySE2Factor(SE2d(), standstill));
  const Matrix6d custom = OdometryCovarianceSE3(OdometrySigma{}, SE3d(), OdometryNoiseFloor{0.01, 0.02});
  EXPECT_NEAR(custom(0, 0), 4e-4, 1e-18);
  EXPECT_NEAR(custom(5, 5), 1e-4, 1e-18);
}

TEST(OdometryCovariance, RandomWalkIsLinearInTimeAndPath) {
  OdometrySigma sigma{0.02, 0.02};
  EXPECT_FALSE(sigma.HasRandomWalk());
  sigma.trans_per_sqrt_s = 0.1;
  sigma.rot_per_sqrt_m = 0.2;
  EXPECT_TRUE(sigma.HasRandomWalk());
  const OdometryWalkVariance a = OdometryRandomWalk(sigma, 1.0, 2.0), b = OdometryRandomWalk(sigma, 3.0, 5.0);
  const OdometryWalkVariance sum = OdometryRandomWalk(sigma, 4.0, 7.0);
  EXPECT_NEAR(a.translation + b.translation, sum.translation, 1e-15);
  EXPECT_NEAR(a.rotation + b.rotation, sum.rotation, 1e-15);
  EXPECT_NEAR(sum.translation, 0.01 * 4.0, 1e-15);
  EXPECT_NEAR(sum.rotation, 0.04 * 7.0, 1e-15);
  EXPECT_EQ(OdometryRandomWalk(OdometrySigma{0.1, 0.1}, 10.0, 10.0).translation, 0.0);
  sigma.rot_per_sqrt_s = -1.0;
  EXPECT_THROW(OdometryRandomWalk(sigma, 1.0, 1.0), std::invalid_argument);
  EXPECT_THROW(OdometryCovarianceSE3(sigma, SE3d()), std::invalid_argument);
  sigma.rot_per_sqrt_s = 0.0;
  EXPECT_THROW(OdometryRandomWalk(sigma, -1.0, 1.0), std::invalid_argument);
  EXPECT_THROW(OdometryRandomWalk(sigma, 1.0, kNaN), std::invalid_argument);
}

TEST(OdometryCovariance, RejectsBadSigmas) {
  EXPECT_THROW(OdometryCovarianceSE2(OdometrySigma{-0.1, 0.1}, SE2d()), std::invalid_argument);
  EXPECT_THROW(OdometryCovarianceSE3(OdometrySigma{0.1, kNaN}, SE3d()), std::invalid_argument);
  EXPECT_THROW(OdometryCovarianceSE3(OdometrySigma{0.1, 0.1}, SE3d(), OdometryNoiseFloor{0.0, 0.1}),
               std::invalid_argument);
  EXPECT_THROW(OdometrySE3Factor(SE3d(), Matrix6d::Zero()), std::invalid_argument);
  EXPECT_THROW(OdometrySE2Factor(SE2d(), -Eigen::Matrix3d::Identity()), std::invalid_argument);
}

// The calibrated factor in the measurement's units: the translation error times 1 + distance_scale,
// so that the map scaled by lambda with 1 + distance_scale divided by lambda costs the same (a
// free metric scale is not pulled short), with its gradients.
TEST(CalibratedOdometrySE2Factor, MeasurementSpaceIsScaleInvariantAndGradientCheck) {
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const Eigen::Matrix3d covariance = Eigen::Vector3d(0.01, 0.02, 0.005).asDiagonal();
  for (int trial = 0; trial < 10; ++trial) {
    const SE2d M(0.5 + 0.3 * u(rng), 0.1 * u(rng), 0.3 * u(rng));
    double a[3] = {u(rng), u(rng), u(rng)};
    double b[3] = {a[0] + 0.5 + 0.1 * u(rng), a[1] + 0.1 * u(rng), a[2] + 0.3 * u(rng)};
    double c[3] = {0.05 * u(rng), 0.05 * u(rng), 0.1 * u(rng)};
    const std::unique_ptr<ceres::CostFunction> plain(CalibratedOdometrySE2Factor::Create(M, covariance));
    const std::unique_ptr<ceres::CostFunction> measured(
        CalibratedOdometrySE2Factor::Create(M, covariance, true));
    const double* parameters[3] = {a, b, c};
    double r_plain[3], r_measured[3];
    ASSERT_TRUE(plain->Evaluate(parameters, r_plain, nullptr));
    ASSERT_TRUE(measured->Evaluate(parameters, r_measured, nullptr));
    // Diagonal covariance: each row is the plain one times its factor.
    EXPECT_NEAR(r_measured[0], (1.0 + c[2]) * r_plain[0], 1e-12);
    EXPECT_NEAR(r_measured[1], (1.0 + c[2]) * r_plain[1], 1e-12);
    EXPECT_NEAR(r_measured[2], r_plain[2], 1e-12);
    // Scale the poses' positions by lambda and 1 + distance_scale by 1 / lambda.
    const double lambda = 1.07;
    double a_s[3] = {lambda * a[0], lambda * a[1], a[2]}, b_s[3] = {lambda * b[0], lambda * b[1], b[2]};
    double c_s[3] = {c[0], c[1], (1.0 + c[2]) / lambda - 1.0};
    const double* scaled[3] = {a_s, b_s, c_s};
    double r_scaled[3], r_plain_scaled[3];
    ASSERT_TRUE(measured->Evaluate(scaled, r_scaled, nullptr));
    ASSERT_TRUE(plain->Evaluate(scaled, r_plain_scaled, nullptr));
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(r_scaled[i], r_measured[i], 1e-12) << i;
    // The plain factor's translation error grows with the map.
    EXPECT_NEAR(r_plain_scaled[0], lambda * r_plain[0], 1e-12);
    testing::ExpectGradientsMatch(*measured, {nullptr, nullptr, nullptr}, {a, b, c}, 1e-6,
                                  "calibrated SE(2), measurement space");
  }
}
}  // namespace
}  // namespace waymark
