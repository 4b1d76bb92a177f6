#include "mapping/odometry_calibration_time.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "geometry/pose.h"

namespace waymark {
namespace {

// Turn steps of `datasets` robots over `steps` seconds each: the odometry's turn c ~ N(0, 0.3 rad)
// per 1 s step, the true turn g = (1 + k + s_i) c + white noise (3 mrad), the turn scale's
// variation s_i a first-order Gauss-Markov (AR(1)) process of correlation time tau_s and
// stationary sigma, each robot with its own constant k.
std::vector<std::vector<TurnStep>> GaussMarkovTurns(double tau_s, double sigma, int datasets, int steps,
                                                    unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  const double phi = std::exp(-1.0 / tau_s);
  std::vector<std::vector<TurnStep>> out;
  for (int d = 0; d < datasets; ++d) {
    const double k = 0.02 * (d - 1);
    double s = sigma * normal(rng);
    std::vector<TurnStep> series;
    for (int i = 0; i < steps; ++i) {
      const double c = 0.3 * normal(rng);
      series.push_back({true, (1.0 + k + s) * c + 0.003 * normal(rng), c});
      s = phi * s + sigma * std::sqrt(1.0 - phi * phi) * normal(rng);
    }
    out.push_back(series);
  }
  return out;
}

// The estimator recovers a known Gauss-Markov turn scale: three robots of 50 minutes each (about
// the data of a three-robot map), sigma 0.05, correlation times 5 and 10 s: T within 25 %, sigma
// within 10 % (seed 7: 6.09 and 9.74 s, sigma 0.048 and 0.051). The method is biased at the ends
// (the fit runs to the first lag with R <= 0, whose noisy positive tail flattens the line): the
// same series give 4.99 s for T = 2 s and 14.5 s for T = 20 s (sigma 0.036 and 0.053), the
// direction checked below.
TEST(OdometryCalibrationTimeTest, RecoversGaussMarkovTimeAndSigma) {
  for (const double tau : {5.0, 10.0}) {
    const CalibrationTimeFit fit = FitTurnScaleCorrelation(GaussMarkovTurns(tau, 0.05, 3, 3000, 7));
    ASSERT_TRUE(fit.fitted) << tau;

    EXPECT_NEAR(fit.time_s, tau, 0.25 * tau);
    EXPECT_NEAR(fit.sigma, 0.05, 0.005) << tau;
    ASSERT_EQ(fit.constant_turn_scale.size(), 3u);
    EXPECT_NEAR(fit.constant_turn_scale[0], -0.02, 0.01);
    EXPECT_NEAR(fit.constant_turn_scale[2], 0.02, 0.01);
    EXPECT_EQ(fit.steps[1], 3000u);
    ASSERT_GE(fit.autocovariance.size(), 2u);
    EXPECT_EQ(fit.autocovariance[0].first, 1.0);
  }
  const CalibrationTimeFit short_time = FitTurnScaleCorrelation(GaussMarkovTurns(2.0, 0.05, 3, 3000, 7));
  ASSERT_TRUE(short_time.fitted);
  EXPECT_GT(short_time.time_s, 2.0);
  EXPECT_LT(short_time.time_s, 6.0);
  const CalibrationTimeFit long_time = FitTurnScaleCorrelation(GaussMarkovTurns(20.0, 0.05, 3, 3000, 7));
  ASSERT_TRUE(long_time.fitted);
  EXPECT_LT(long_time.time_s, 20.0);
  EXPECT_GT(long_time.time_s, 10.0);
}

// Other step lengths and lag limits: the lags are in seconds; the fit stops at max_lag_s.
TEST(OdometryCalibrationTimeTest, StepAndMaxLag) {
  CalibrationTimeOptions options;
  options.step_s = 0.5;
  options.max_lag_s = 3.0;
  // tau 4 s at 0.5 s steps: 8 steps (seed 3: 5.05 s, within 30 %).
  const CalibrationTimeFit fit = FitTurnScaleCorrelation(GaussMarkovTurns(8.0, 0.05, 3, 4000, 3), options);
  ASSERT_TRUE(fit.fitted);
  ASSERT_EQ(fit.autocovariance.size(), 6u);
  EXPECT_EQ(fit.autocovariance.back().first, 3.0);
  EXPECT_NEAR(fit.time_s, 4.0, 1.2);
}

// No fit: no data, or a single positive lag; invalid steps are skipped.
TEST(OdometryCalibrationTimeTest, NoFitWithoutDecayingAutocovariance) {
  EXPECT_FALSE(FitTurnScaleCorrelation({}).fitted);
  std::vector<std::vector<TurnStep>> none = {std::vector<TurnStep>(100)};
  const CalibrationTimeFit empty = FitTurnScaleCorrelation(none);
  EXPECT_FALSE(empty.fitted);
  EXPECT_TRUE(empty.autocovariance.empty());
  EXPECT_EQ(empty.steps[0], 0u);
  // Alternating residuals: R(1) < 0 stops the fit at once.
  std::vector<TurnStep> alternating;
  for (int i = 0; i < 200; ++i) alternating.push_back({true, (i % 2 ? 1.1 : 0.9) * 0.2, 0.2});
  const CalibrationTimeFit stops = FitTurnScaleCorrelation({alternating});
  EXPECT_FALSE(stops.fitted);
  EXPECT_TRUE(stops.autocovariance.empty());
  // A growing autocovariance (slope >= 0): no decay, no fit. Period 8 plus period 2 with powers
  // 1 and 1/2 (times 0.05^2): R(1) = 0.21, R(2) = 0.5, R(3) < 0 (times 0.05^2).
  std::vector<TurnStep> growing;
  for (int i = 0; i < 800; ++i) {
    const double s =
        0.05 * (std::sqrt(2.0) * std::cos(M_PI * i / 4.0) + std::sqrt(0.5) * (i % 2 ? -1.0 : 1.0));
    growing.push_back({true, (1.0 + s) * 0.2, 0.2});
  }
  const CalibrationTimeFit no_decay = FitTurnScaleCorrelation({growing});
  ASSERT_EQ(no_decay.autocovariance.size(), 2u);
  EXPECT_LT(no_decay.autocovariance[0].second, no_decay.autocovariance[1].second);
  EXPECT_FALSE(no_decay.fitted);
}

// TurnSteps: headings unwrapped (a robot turning 0.7 rad/s wraps every 9 s), the odometry's
// stamps moved by its delay, steps from the later start; a smoothed turn 3 % larger than the
// odometry's is the constant turn scale +0.03.
TEST(OdometryCalibrationTimeTest, TurnStepsFromTrajectories) {
  const double rate = 0.7, delay = 0.2;
  Trajectory odometry, smoothed;
  for (int i = 0; i <= 1000; ++i) {
    const double t = 100.0 + 0.1 * i;
    odometry.push_back({t, SE3d::FromXYZYaw(0.0, 0.0, 0.0, rate * (t - 100.0))});
  }
  for (int i = 0; i <= 200; ++i) {
    const double t = 100.5 + 0.5 * i;  // the true motion: the odometry's at t - delay, 3 % more turn
    smoothed.push_back({t, SE3d::FromXYZYaw(1.0, 2.0, 0.0, 1.03 * rate * (t - delay - 100.0))});
  }
  const std::vector<TurnStep> steps = TurnSteps(smoothed, odometry, delay, 1.0);
  // From 100.5 (the smoothed start; the odometry's, moved, is 100.2) while t + 1 < 200.2: 99 steps;
  // the first starts at a sample of both series (a lower_bound hit), so it is skipped as the
  // script skips it.
  ASSERT_EQ(steps.size(), 99u);
  EXPECT_FALSE(steps[0].valid);
  for (size_t i = 1; i < steps.size(); ++i) {
    ASSERT_TRUE(steps[i].valid) << i;
    EXPECT_NEAR(steps[i].odometry, rate, 1e-9) << i;
    EXPECT_NEAR(steps[i].smoothed, 1.03 * rate, 1e-9) << i;
  }
  const CalibrationTimeFit fit = FitTurnScaleCorrelation({steps});
  EXPECT_NEAR(fit.constant_turn_scale[0], 0.03, 1e-9);
  EXPECT_EQ(fit.steps[0], 98u);
  EXPECT_TRUE(TurnSteps({}, odometry, 0.0, 1.0).empty());
}

}  // namespace
}  // namespace waymark
