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
