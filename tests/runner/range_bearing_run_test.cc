// runner/range_bearing_run.h: the NEES evaluator's bounds of the mean NEES, textbook (independent
// samples) and corrected for the series' autocorrelation (effective sample size).
#include "runner/range_bearing_run.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "online/chi_square.h"

namespace waymark {
namespace {

TEST(MeanChiSquareBounds, MatchTheExactQuantileAndWidenForFewerSamples) {
  for (const int n : {1, 10, 333}) {
    const auto [lower, upper] = MeanChiSquareBounds(n, 3);
    EXPECT_NEAR(lower, ChiSquareQuantile(0.025, 3 * n) / n, 1e-6);
    EXPECT_NEAR(upper, ChiSquareQuantile(0.975, 3 * n) / n, 1e-6);
  }
  // Real n between integers, and the large-n approximation near the exact value at its switch.
  const auto [l10, u10] = MeanChiSquareBounds(10.0, 3);
  const auto [l105, u105] = MeanChiSquareBounds(10.5, 3);
  const auto [l11, u11] = MeanChiSquareBounds(11.0, 3);
  EXPECT_LT(l10, l105);
  EXPECT_LT(l105, l11);
  EXPECT_GT(u10, u105);
  EXPECT_GT(u105, u11);
  const auto [l_big, u_big] = MeanChiSquareBounds(1001.0, 3);
  EXPECT_NEAR(l_big, ChiSquareQuantile(0.025, 3003) / 1001.0, 2e-4);
  EXPECT_NEAR(u_big, ChiSquareQuantile(0.975, 3003) / 1001.0, 2e-4);
  EXPECT_THROW(MeanChiSquareBounds(0.0, 3), std::invalid_argument);
}

// The NEES of a consistent 3-dof error whose components follow AR(1) processes with coefficient
// phi: each sample is chi-square(3), consecutive samples are correlated (rho_k = phi^(2k) for the
// squares), tau_int = (1 + phi^2) / (1 - phi^2).
std::vector<double> ArNees(double phi, size_t n, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  double e[3] = {normal(rng), normal(rng), normal(rng)};
  std::vector<double> out;
  for (size_t i = 0; i < n; ++i) {
    double nees = 0.0;
    for (double& v : e) {
      v = phi * v + std::sqrt(1.0 - phi * phi) * normal(rng);
      nees += v * v;
    }
    out.push_back(nees);
  }
  return out;
}

TEST(IntegratedAutocorrelationTime, OfIndependentAndOfCorrelatedSeries) {
  EXPECT_NEAR(IntegratedAutocorrelationTime(ArNees(0.0, 20000, 1)), 1.0, 0.1);
  const double phi = 0.95, expected = (1.0 + phi * phi) / (1.0 - phi * phi);  // 19.5
  const double tau = IntegratedAutocorrelationTime(ArNees(phi, 200000, 2));
  EXPECT_NEAR(tau, expected, 0.2 * expected);
  EXPECT_EQ(IntegratedAutocorrelationTime({1.0, 2.0}), 1.0);
  EXPECT_EQ(IntegratedAutocorrelationTime({2.0, 2.0, 2.0, 2.0}), 1.0);
}

TEST(ComputeNees, CorrelatedBoundsHoldForAConsistentButCorrelatedRun) {
  // 200 runs of a consistent filter whose errors are correlated (phi 0.98, tau_int ~ 50 samples):
  // the mean NEES of a run falls inside the corrected 95 % bounds in about 95 % of the runs, and
  // far less often inside the textbook bounds (which assume 4000 independent samples).
  const double phi = 0.98;
  const size_t n = 4000;
  int inside_corrected = 0, inside_textbook = 0;
  const int runs = 200;
  for (int run = 0; run < runs; ++run) {
    std::mt19937 rng(100 + run);
    std::normal_distribution<double> normal(0.0, 1.0);
    const Eigen::Vector3d sigma(0.1, 0.2, 0.05);
    const Eigen::Matrix3d P = sigma.cwiseAbs2().asDiagonal();
    Trajectory truth, poses;
    std::vector<Eigen::Matrix3d> covariances;
    Eigen::Vector3d e(normal(rng), normal(rng), normal(rng));
    for (size_t i = 0; i < n; ++i) {
      for (int c = 0; c < 3; ++c) e[c] = phi * e[c] + std::sqrt(1.0 - phi * phi) * normal(rng);
      const double t = 0.1 * static_cast<double>(i);
      truth.push_back({t, SE2d(1.0, 2.0, 0.3).ToSE3()});
      poses.push_back({t, SE2d(1.0 - sigma[0] * e[0], 2.0 - sigma[1] * e[1], 0.3 - sigma[2] * e[2]).ToSE3()});
      covariances.push_back(P);
    }
    const NeesResult nees = ComputeNees(truth, poses, covariances, 0.01);
    EXPECT_EQ(nees.samples, n);
    EXPECT_GT(nees.mean_upper_correlated, nees.mean_upper);
    EXPECT_LT(nees.mean_lower_correlated, nees.mean_lower);
    inside_corrected += nees.mean >= nees.mean_lower_correlated && nees.mean <= nees.mean_upper_correlated;
    inside_textbook += nees.mean >= nees.mean_lower && nees.mean <= nees.mean_upper;
    if (run == 0) {
      EXPECT_NEAR(nees.autocorrelation_time, (1.0 + phi * phi) / (1.0 - phi * phi), 25.0);
      EXPECT_NEAR(nees.effective_samples * nees.autocorrelation_time, static_cast<double>(n), 1e-6);
    }
  }
  std::printf("mean NEES inside the corrected bounds in %d of %d runs, inside the textbook bounds in %d\n",
              inside_corrected, runs, inside_textbook);
  EXPECT_GE(inside_corrected, 0.88 * runs);
  EXPECT_LE(inside_textbook, 0.6 * runs);
}

// The leave-one-out variance factor: runs whose errors are drawn with k_true times the covariance
// the filter reports (a filter whose noise is mis-specified by k_true) give a pooled mean NEES / 3
// that recovers k_true; with the reported covariance scaled by it the mean NEES is 3.
TEST(PooledVarianceFactor, RecoversAKnownMisspecificationAndRejectsEmptyRuns) {
  const double k_true = 3.5;
  std::vector<NeesResult> runs;
  std::vector<NeesResult> corrected;
  for (const size_t n : {1000u, 2500u, 4000u}) {
    std::mt19937 rng(7 + static_cast<unsigned>(n));
    std::normal_distribution<double> normal(0.0, 1.0);
    const Eigen::Vector3d sigma(0.1, 0.2, 0.05);
    const Eigen::Matrix3d P = sigma.cwiseAbs2().asDiagonal();
    Trajectory truth, poses;
    std::vector<Eigen::Matrix3d> covariances, scaled;
    for (size_t i = 0; i < n; ++i) {
      const double t = 0.1 * static_cast<double>(i);
      const Eigen::Vector3d e = std::sqrt(k_true) * Eigen::Vector3d(normal(rng), normal(rng), normal(rng));
      truth.push_back({t, SE2d(1.0, 2.0, 0.3).ToSE3()});
      poses.push_back({t, SE2d(1.0 + sigma[0] * e[0], 2.0 + sigma[1] * e[1], 0.3 + sigma[2] * e[2]).ToSE3()});
      covariances.push_back(P);
    }
    runs.push_back(ComputeNees(truth, poses, covariances, 0.01));
  }
  const double k = PooledVarianceFactor(runs);
  EXPECT_NEAR(k, k_true, 0.05 * k_true);
  // Scaling P by k divides every NEES by k: the pooled mean becomes 3 (k 1).
  for (NeesResult run : runs) {
    run.mean /= k;
    corrected.push_back(run);
  }
  EXPECT_NEAR(PooledVarianceFactor(corrected), 1.0, 1e-12);
  // Samples weight the pool: a run without samples is skipped; none at all is an error.
  NeesResult empty;
  empty.mean = 100.0;
  runs.push_back(empty);
  EXPECT_EQ(PooledVarianceFactor(runs), k);
  EXPECT_THROW(PooledVarianceFactor({empty}), std::invalid_argument);
  EXPECT_THROW(PooledVarianceFactor({}), std::invalid_argument);
}

// The leave-one-out factor is the geometric mean of the runs' own factors, one per run whatever
// its length: runs at 2 and 8 times their covariance give 4 (the pooled mean of 1000 poses at 2
// and 4000 at 8 would give 6.8); a single run's factor is its own; runs without samples are
// skipped, none at all or a mean <= 0 is an error.
TEST(LeaveOneOutVarianceFactor, IsTheGeometricMeanOfTheRunsFactors) {
  NeesResult low, high, empty;
  low.samples = 1000;
  low.mean = 3.0 * 2.0;
  high.samples = 4000;
  high.mean = 3.0 * 8.0;
  empty.mean = 100.0;
  EXPECT_NEAR(LeaveOneOutVarianceFactor({low, high}), 4.0, 1e-12);
  EXPECT_NEAR(LeaveOneOutVarianceFactor({low, high, empty}), 4.0, 1e-12);
  EXPECT_NEAR(PooledVarianceFactor({low, high}), (1000.0 * 2.0 + 4000.0 * 8.0) / 5000.0, 1e-12);
  EXPECT_NEAR(LeaveOneOutVarianceFactor({high}), 8.0, 1e-12);
  EXPECT_THROW(LeaveOneOutVarianceFactor({empty}), std::invalid_argument);
  EXPECT_THROW(LeaveOneOutVarianceFactor({}), std::invalid_argument);
  NeesResult zero = low;
  zero.mean = 0.0;
  EXPECT_THROW(LeaveOneOutVarianceFactor({low, zero}), std::invalid_argument);
}

// The truth's yaw to the odometry: a robot driving squares (straight legs, turns in place, a
// reversing leg) whose motion-capture frame is turned by -0.02 rad on it; the odometry is the
// true motion in the robot's own frame with a slow heading drift and noise. The estimate is the
// yaw (0.02 within 2 mrad: add it to the truth's heading), from the straight windows only;
// with the frames aligned it is 0; a truth that never moves straight gives nullopt; the NEES of
// poses exactly on the turned truth is 0 with the yaw and large without it.
TEST(EstimateTruthYaw, RecoversTheMotionCaptureFramesYawOnTheRobot) {
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0.0, 1.0);
  const double frame_yaw = -0.02;
  Trajectory truth, odometry, truth_aligned;
  SE2d pose(0.0, 0.0, 0.0), odom(5.0, -1.0, 1.0);
  double t = 0.0;
  const double dt = 0.02;
  const auto step = [&](double v, double w) {
    const SE2d increment(v * dt, 0.0, w * dt);
    pose = pose * increment;
    const SE2d measured(v * dt * (1.0 + 0.002 * noise(rng)), 0.0005 * dt * noise(rng), w * dt + 1e-5);
    odom = odom * measured;
    t += dt;
    truth.push_back({t, (pose * SE2d(0.0, 0.0, frame_yaw)).ToSE3()});
    truth_aligned.push_back({t, pose.ToSE3()});
    odometry.push_back({t, odom.ToSE3()});
  };
  for (int lap = 0; lap < 4; ++lap) {
    for (int side = 0; side < 4; ++side) {
      for (int i = 0; i < 150; ++i) step(side == 3 && lap % 2 == 1 ? -0.3 : 0.3, 0.0);
      for (int i = 0; i < 50; ++i) step(0.0, side == 3 && lap % 2 == 1 ? 0.0 : 0.5 * M_PI);
    }
  }
  const std::optional<TruthYawEstimate> yaw = EstimateTruthYaw(truth, odometry);
  ASSERT_TRUE(yaw.has_value());
  EXPECT_NEAR(yaw->yaw_rad, -frame_yaw, 0.002);
  EXPECT_GE(yaw->windows, 50u);
  EXPECT_LT(yaw->spread_rad, 0.01);
  const std::optional<TruthYawEstimate> aligned = EstimateTruthYaw(truth_aligned, odometry);
  ASSERT_TRUE(aligned.has_value());
  EXPECT_NEAR(aligned->yaw_rad, 0.0, 0.002);
  // Turning in place only: no straight window.
  Trajectory spin_truth, spin_odometry;
  for (int i = 0; i < 500; ++i) {
    spin_truth.push_back({0.02 * i, SE2d(1.0, 1.0, 0.01 * i).ToSE3()});
    spin_odometry.push_back({0.02 * i, SE2d(0.0, 0.0, 0.01 * i).ToSE3()});
  }
  EXPECT_FALSE(EstimateTruthYaw(spin_truth, spin_odometry).has_value());
  // Poses exactly on the truth turned back by the yaw: NEES 0 against it, large without it.
  std::vector<Eigen::Matrix3d> covariances(truth_aligned.size(), Eigen::Matrix3d::Identity() * 1e-4);
  EXPECT_NEAR(ComputeNees(truth, truth_aligned, covariances, 0.01, -frame_yaw).mean, 0.0, 1e-9);
  EXPECT_GT(ComputeNees(truth, truth_aligned, covariances, 0.01).mean, 3.0);
}

// LocalizerOptionsFromMap: waymark localize's defaults from a map; the variance factor stays 1 and
// a factor <= 0 is rejected by the options' check.
TEST(LocalizerOptionsFromMap, TakesTheMapsNoiseAndCalibrationTime) {
  MarkerMap map;
  RangeBearingNoise noise;
  noise.bearing_rad = 0.0321;
  map.range_bearing_noise = noise;
  RangeBearingSensorModel model;
  model.calibration_time = RangeBearingSensorModel::CalibrationTime{12.5, 0.01};
  model.online_variance_factor = 4.0;
  map.range_bearing_sensor = model;
  RangeBearingLocalizerOptions options = LocalizerOptionsFromMap(map);
  EXPECT_EQ(options.noise.bearing_rad, 0.0321);
  EXPECT_EQ(options.calibration_time_s, Eigen::Vector3d::Constant(12.5));
  EXPECT_EQ(options.variance_factor, 1.0);
  std::string why;
  EXPECT_TRUE(options.Check(&why)) << why;
  options.variance_factor = 0.0;
  EXPECT_FALSE(options.Check(&why));
  EXPECT_NE(why.find("variance_factor"), std::string::npos);
}

}  // namespace
}  // namespace waymark
