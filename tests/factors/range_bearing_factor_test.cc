// factors/range_bearing_factor.h: zero at the truth, one hand-computed value (residuals
// pre-filled with NaN), gradient checks against numeric differentiation at ten random states,
// the degenerate case and bad input.
#include "factors/range_bearing_factor.h"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>

#include "tests/factors/factor_test_util.h"

namespace waymark {
namespace {

TEST(RangeBearingFactor, ZeroAtTruthAndHandComputed) {
  // Robot at (1, 2) facing +y; landmark at (1, 5): 3 m straight ahead.
  double robot[3] = {1.0, 2.0, M_PI / 2};
  double landmark[2] = {1.0, 5.0};
  const double* parameters[2] = {robot, landmark};
  double residuals[2] = {testing::kNaN, testing::kNaN};
  const std::unique_ptr<ceres::CostFunction> exact(RangeBearingFactor::Create(3.0, 0.0, 0.1, 0.01));
  ASSERT_TRUE(exact->Evaluate(parameters, residuals, nullptr));
  EXPECT_NEAR(residuals[0], 0.0, 1e-12);
  EXPECT_NEAR(residuals[1], 0.0, 1e-12);
  // Measured 2.8 m at bearing 0.1 rad: the landmark is 0.2 m farther and 0.1 rad to the right.
  const std::unique_ptr<ceres::CostFunction> off(RangeBearingFactor::Create(2.8, 0.1, 0.1, 0.01));
  residuals[0] = residuals[1] = testing::kNaN;
  ASSERT_TRUE(off->Evaluate(parameters, residuals, nullptr));
  EXPECT_NEAR(residuals[0], 2.0, 1e-12);
  EXPECT_NEAR(residuals[1], -10.0, 1e-12);
  // Landmark behind-left at (0, 1) from robot at origin facing +x: range 1, bearing pi/2... and wrap:
  // measured -3.1 rad for a true bearing of +3.1 rad gives a residual of 2 pi - 6.2 rad, not 6.2 rad.
  double robot0[3] = {0.0, 0.0, 0.0};
  double behind[2] = {std::cos(3.1), std::sin(3.1)};
  const double* wrap_parameters[2] = {robot0, behind};
  const std::unique_ptr<ceres::CostFunction> wrap(RangeBearingFactor::Create(1.0, -3.1, 1.0, 1.0));
  ASSERT_TRUE(wrap->Evaluate(wrap_parameters, residuals, nullptr));
  EXPECT_NEAR(residuals[1], 6.2 - 2 * M_PI, 1e-9);
}

TEST(RangeBearingFactor, GradientCheckTenRandomStates) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> coordinate(-8.0, 8.0), angle(-3.0, 3.0), range(0.5, 6.0);
  for (int trial = 0; trial < 10; ++trial) {
    double robot[3] = {coordinate(rng), coordinate(rng), angle(rng) + 2 * M_PI * (trial % 3 - 1)};
    const double r = range(rng), b = angle(rng);
    double landmark[2] = {robot[0] + r * std::cos(robot[2] + b), robot[1] + r * std::sin(robot[2] + b)};
    const std::unique_ptr<ceres::CostFunction> cost(
        RangeBearingFactor::Create(r + 0.1 * angle(rng), WrapAngle(b + 0.05 * angle(rng)), 0.05, 0.02));
    testing::ExpectGradientsMatch(*cost, {nullptr, nullptr}, {robot, landmark}, 1e-6, "range-bearing");
  }
}

TEST(RangeBearingFactor, BiasedHandComputedAndGradientCheck) {
  double robot[3] = {1.0, 2.0, M_PI / 2};
  double landmark[2] = {1.0, 5.0};
  double sensor[5] = {0.1, 0.02, 0.0, 0.0, 0.0};  // ranges read 10 cm long, bearings 0.02 rad to the left
  const double* parameters[3] = {robot, landmark, sensor};
  double residuals[2] = {testing::kNaN, testing::kNaN};
  const std::unique_ptr<ceres::CostFunction> exact(BiasedRangeBearingFactor::Create(3.1, 0.02, 0.1, 0.01));
  ASSERT_TRUE(exact->Evaluate(parameters, residuals, nullptr));
  EXPECT_NEAR(residuals[0], 0.0, 1e-12);
  EXPECT_NEAR(residuals[1], 0.0, 1e-12);
  // A bearing scale error of 5 %: the landmark at (0, 5) from the robot at (1, 2) facing +y is
  // atan2(1, 3) = 0.32175 rad to the left, read as 1.05 * 0.32175 + 0.02 rad.
  double scaled_sensor[5] = {0.1, 0.02, 0.05, 0.0, 0.0};
  double left[2] = {0.0, 5.0};
  const double* scaled_parameters[3] = {robot, left, scaled_sensor};
  const double bearing = std::atan2(1.0, 3.0), range = std::sqrt(10.0);
  const std::unique_ptr<ceres::CostFunction> scaled(
      BiasedRangeBearingFactor::Create(range + 0.1, 1.05 * bearing + 0.02, 0.1, 0.01));
  ASSERT_TRUE(scaled->Evaluate(scaled_parameters, residuals, nullptr));
  EXPECT_NEAR(residuals[0], 0.0, 1e-12);
  EXPECT_NEAR(residuals[1], 0.0, 1e-12);
  // Read without the scale: 0.05 * bearing / 0.01 sigmas short.
  scaled_sensor[2] = 0.0;
  ASSERT_TRUE(scaled->Evaluate(scaled_parameters, residuals, nullptr));
  EXPECT_NEAR(residuals[1], -0.05 * bearing / 0.01, 1e-9);
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  for (int trial = 0; trial < 10; ++trial) {
    double r[3] = {u(rng), u(rng), 0.0};
    double l[2] = {r[0] + 2.0 + std::abs(u(rng)), r[1] + u(rng)};
    // Facing the landmark within 0.5 rad: a camera's bearings stay far from +-pi, where the
    // scaled bearing jumps.
    r[2] = std::atan2(l[1] - r[1], l[0] - r[0]) + u(rng) / 6.0;
    double b[5] = {0.05 * u(rng), 0.01 * u(rng), 0.02 * u(rng), 0.5 + 0.1 * u(rng), 0.01 * u(rng)};
    const std::unique_ptr<ceres::CostFunction> cost(
        BiasedRangeBearingFactor::Create(2.5, 0.1 * u(rng), 0.05, 0.02));
    testing::ExpectGradientsMatch(*cost, {nullptr, nullptr, nullptr}, {r, l, b}, 1e-6,
                                  "biased range-bearing");
  }
  // The prior: [b_range / 0.2, b_bearing / 0.05, k_bearing / 0.1, c_depth / 1, s_range / 0.5].
  const std::unique_ptr<ceres::CostFunction> prior(SensorBiasPrior::Create(0.2, 0.05, 0.1, 1.0, 0.5));
  double offsets[5] = {0.1, 0.01, 0.05, 0.9, 0.02};
  const double* prior_parameters[1] = {offsets};
  double prior_residuals[5];
  ASSERT_TRUE(prior->Evaluate(prior_parameters, prior_residuals, nullptr));
  EXPECT_NEAR(prior_residuals[0], 0.5, 1e-12);
  EXPECT_NEAR(prior_residuals[1], 0.2, 1e-12);
  EXPECT_NEAR(prior_residuals[2], 0.5, 1e-12);
  EXPECT_NEAR(prior_residuals[3], 0.9, 1e-12);
  EXPECT_NEAR(prior_residuals[4], 0.04, 1e-12);
}

TEST(RangeBearingFactor, DepthShareAndRangeScaleHandComputed) {
  // The landmark at (0, 5) from the robot at (1, 2) facing +y: distance sqrt(10), bearing
  // atan2(1, 3), depth along the axis 3 m. A sensor reading (1 + s) ((1 - c) d + c depth) + b.
  double robot[3] = {1.0, 2.0, M_PI / 2};
  double landmark[2] = {0.0, 5.0};
  const double d = std::sqrt(10.0), bearing = std::atan2(1.0, 3.0);
  for (const double c : {0.0, 0.5, 1.0}) {
    for (const double scale : {0.0, 0.03}) {
      double sensor[5] = {0.05, 0.0, 0.0, c, scale};
      const double read = (1.0 + scale) * ((1.0 - c) * d + c * 3.0) + 0.05;
      const std::unique_ptr<ceres::CostFunction> cost(
          BiasedRangeBearingFactor::Create(read, bearing, 0.1, 0.01));
      const double* parameters[3] = {robot, landmark, sensor};
      double residuals[2] = {testing::kNaN, testing::kNaN};
      ASSERT_TRUE(cost->Evaluate(parameters, residuals, nullptr));
      EXPECT_NEAR(residuals[0], 0.0, 1e-12) << c << " " << scale;
      EXPECT_NEAR(residuals[1], 0.0, 1e-12);
      // The same reading taken as a distance (c = 0, s = 0): (d - read) / sigma.
      double plain[5] = {0.05, 0.0, 0.0, 0.0, 0.0};
      const double* plain_parameters[3] = {robot, landmark, plain};
      ASSERT_TRUE(cost->Evaluate(plain_parameters, residuals, nullptr));
      EXPECT_NEAR(residuals[0], (d + 0.05 - read) / 0.1, 1e-9);
    }
  }
}

TEST(RangeBearingFactor, BearingAloneIsTheBiasedFactorsBearingRowWithItsGradients) {
  std::mt19937 rng(10);
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  for (int trial = 0; trial < 10; ++trial) {
    double r[3] = {u(rng), u(rng), 0.0};
    double l[2] = {r[0] + 2.0 + std::abs(u(rng)), r[1] + u(rng)};
    r[2] = std::atan2(l[1] - r[1], l[0] - r[0]) + u(rng) / 6.0;
    double b[5] = {0.05 * u(rng), 0.01 * u(rng), 0.02 * u(rng), 0.5 + 0.1 * u(rng), 0.01 * u(rng)};
    const double range = 2.5 + 0.5 * u(rng), bearing = 0.1 * u(rng);
    const std::unique_ptr<ceres::CostFunction> both(
        BiasedRangeBearingFactor::Create(range, bearing, 0.05, 0.02));
    const std::unique_ptr<ceres::CostFunction> alone(BiasedBearingFactor::Create(range, bearing, 0.05, 0.02));
    const double* parameters[3] = {r, l, b};
    double residuals[2], residual = testing::kNaN;
    ASSERT_TRUE(both->Evaluate(parameters, residuals, nullptr));
    ASSERT_TRUE(alone->Evaluate(parameters, &residual, nullptr));
    EXPECT_EQ(alone->num_residuals(), 1);
    EXPECT_EQ(residual, residuals[1]);
    testing::ExpectGradientsMatch(*alone, {nullptr, nullptr, nullptr}, {r, l, b}, 1e-6, "biased bearing");
  }
}

TEST(RangeBearingFactor, LandmarkAtTheRobotIsRejected) {
  double robot[3] = {1.0, 1.0, 0.3};
  double landmark[2] = {1.0, 1.0 + 1e-4};
  const double* parameters[2] = {robot, landmark};
  double residuals[2];
  const std::unique_ptr<ceres::CostFunction> cost(RangeBearingFactor::Create(1.0, 0.0, 0.1, 0.1));
  EXPECT_FALSE(cost->Evaluate(parameters, residuals, nullptr));
}

TEST(RangeBearingFactor, RejectsBadInput) {
  EXPECT_THROW(RangeBearingFactor(0.0, 0.0, 0.1, 0.1), std::invalid_argument);
  EXPECT_THROW(RangeBearingFactor(1.0, std::nan(""), 0.1, 0.1), std::invalid_argument);
  EXPECT_THROW(RangeBearingFactor(1.0, 0.0, 0.0, 0.1), std::invalid_argument);
  EXPECT_THROW(RangeBearingFactor(1.0, 0.0, 0.1, -1.0), std::invalid_argument);
}

}  // namespace
}  // namespace waymark
