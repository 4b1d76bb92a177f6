// online/range_bearing_localizer.h: F and H against central differences (asserted), a zero
// innovation keeps the mean and shrinks P, P stays symmetric positive definite, unknown codes
// and gross outliers are rejected and counted, a long run of rejections makes the filter lost
// (and it regains the track), and the Monte-Carlo mean NEES lies inside its 95 % bounds.
#include "online/range_bearing_localizer.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <cmath>
#include <functional>
#include <random>

#include "online/chi_square.h"
#include "tests/online/jacobian_check.h"

namespace waymark {
namespace {

MarkerMap TwoLandmarks() {
  MarkerMap map;
  for (const auto& [id, x, y] : {std::tuple<const char*, double, double>{"1", 3.0, 1.0}, {"2", 2.0, -2.0}}) {
    MapMarker m;
    m.is_point = true;
    m.key = {kFamilyBarcode, id};
    m.T_world_marker = SE3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(x, y, 0.0));
    map.markers.push_back(m);
  }
  return map;
}

RangeBearingObservation Sighting(const std::string& id, const Eigen::Vector2d& z) {
  RangeBearingObservation obs;
  obs.key = {kFamilyBarcode, id};
  obs.range_m = z[0];
  obs.bearing_rad = z[1];
  return obs;
}

TEST(RangeBearingLocalizer, JacobiansMatchCentralDifferences) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  for (int trial = 0; trial < 10; ++trial) {
    RangeBearingLocalizer::Vector6 x6;
    x6 << u(rng), u(rng), u(rng), 0.01 * u(rng), 0.05 * u(rng), 0.05 * u(rng), 0.05 * u(rng), 0.01 * u(rng),
        0.01 * u(rng), 0.02 * u(rng);
    const Eigen::Vector3d x = x6.head<3>();
    const SE2d M(0.3 * u(rng), 0.1 * u(rng), 0.2 * u(rng));
    const double phi = 0.5 + 0.1 * u(rng);  // the range scale's decay over the increment
    const auto predict = [&](const Eigen::VectorXd& s) -> Eigen::VectorXd {
      Eigen::VectorXd next = RangeBearingLocalizer::PredictState(s, M, phi);
      next[2] = s[2] + WrapAngle(next[2] - s[2]);  // unwrapped, for the differences
      return next;
    };
    const Eigen::MatrixXd F_numeric = testing::NumericJacobian(predict, x6);
    EXPECT_LT((F_numeric - RangeBearingLocalizer::PredictJacobian(x6, M, phi)).cwiseAbs().maxCoeff(), 1e-6);
    // With no calibration error the prediction is the composition T * M.
    RangeBearingLocalizer::Vector6 plain = x6;
    plain.segment<3>(3).setZero();
    plain[8] = 0.0;
    const SE2d composed = SE2d(x[0], x[1], x[2]) * M;
    const RangeBearingLocalizer::Vector6 predicted = RangeBearingLocalizer::PredictState(plain, M);
    EXPECT_NEAR(predicted[0], composed.x(), 1e-12);
    EXPECT_NEAR(predicted[1], composed.y(), 1e-12);
    EXPECT_NEAR(WrapAngle(predicted[2] - composed.theta()), 0.0, 1e-12);
    const Eigen::Vector2d l(u(rng) + 4.0, u(rng));
    const auto measure = [&](const Eigen::VectorXd& s) -> Eigen::VectorXd {
      return RangeBearingLocalizer::Measure(s, l);
    };
    const auto wrap = [](Eigen::VectorXd d) {
      d[1] = WrapAngle(d[1]);
      return d;
    };
    const Eigen::MatrixXd H_numeric = testing::NumericJacobian(measure, x, 1e-6, wrap);
    EXPECT_LT((H_numeric - RangeBearingLocalizer::MeasureJacobian(x, l)).cwiseAbs().maxCoeff(), 1e-6);
    // The whole state's h (range scale and offsets included).
    const auto measure_state = [&](const Eigen::VectorXd& s) -> Eigen::VectorXd {
      return RangeBearingLocalizer::MeasureState(s, l);
    };
    const Eigen::MatrixXd H_state_numeric = testing::NumericJacobian(measure_state, x6, 1e-6, wrap);
    EXPECT_LT((H_state_numeric - RangeBearingLocalizer::MeasureStateJacobian(x6, l)).cwiseAbs().maxCoeff(),
              1e-6);
    const Eigen::Vector2d h = RangeBearingLocalizer::MeasureState(x6, l),
                          h_pose = RangeBearingLocalizer::Measure(x, l);
    EXPECT_NEAR(h[0], (1.0 + x6[8]) * h_pose[0] + x6[6], 1e-12);
    EXPECT_NEAR(WrapAngle(h[1] - ((1.0 + x6[9]) * h_pose[1] + x6[7])), 0.0, 1e-12);
  }
}

TEST(RangeBearingLocalizer, ZeroInnovationKeepsTheMeanAndShrinksP) {
  const SE2d start(0.5, 0.2, 0.1);
  RangeBearingLocalizer filter(TwoLandmarks(), {}, start, Eigen::Vector3d(0.04, 0.04, 0.01).asDiagonal());
  const Eigen::Vector3d x(start.x(), start.y(), start.theta());
  const Eigen::Matrix3d P_before = filter.covariance();
  EXPECT_EQ(filter.Update(Sighting("1", RangeBearingLocalizer::Measure(x, {3.0, 1.0}))),
            RangeBearingUpdate::kAccepted);
  EXPECT_NEAR((Eigen::Vector3d(filter.pose().x(), filter.pose().y(), filter.pose().theta()) - x).norm(), 0.0,
              1e-12);
  EXPECT_LT(filter.covariance().trace(), P_before.trace());
  EXPECT_LT((filter.covariance() - filter.covariance().transpose()).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_EQ(Eigen::LLT<Eigen::Matrix3d>(filter.covariance()).info(), Eigen::Success);
}

TEST(RangeBearingLocalizer, UnknownCodesAndGrossOutliersAreRejectedAndCounted) {
  RangeBearingLocalizer filter(TwoLandmarks(), {}, SE2d(), Eigen::Vector3d(0.01, 0.01, 0.001).asDiagonal());
  EXPECT_EQ(filter.Update(Sighting("99", {2.0, 0.1})), RangeBearingUpdate::kUnknownLandmark);
  EXPECT_EQ(filter.Update(Sighting("1", {8.0, 0.3})), RangeBearingUpdate::kGated);  // true range 3.16
  EXPECT_EQ(filter.counts().at("unknown landmark"), 1);
  EXPECT_EQ(filter.counts().at("gated"), 1);
  EXPECT_NEAR(filter.pose().x(), 0.0, 1e-15);
  EXPECT_FALSE(filter.lost());
}

TEST(RangeBearingLocalizer, LostAfterRejectionsInARowThenRegained) {
  RangeBearingLocalizerOptions options;
  options.lost_rejections = 3;
  // Two landmarks cannot tell a bearing scale error from the pose: none here.
  options.bearing_scale_sigma = 1e-6;
  // The filter believes it is at the origin; the robot is at (1, 0.5) heading 0.
  RangeBearingLocalizer filter(TwoLandmarks(), options, SE2d(),
                               Eigen::Vector3d(1e-4, 1e-4, 1e-5).asDiagonal());
  const Eigen::Vector3d truth(1.0, 0.5, 0.0);
  for (int i = 0; i < 3; ++i) filter.Update(Sighting("1", RangeBearingLocalizer::Measure(truth, {3.0, 1.0})));
  EXPECT_TRUE(filter.lost());
  for (int i = 0; i < 30; ++i) {
    filter.Update(Sighting("1", RangeBearingLocalizer::Measure(truth, {3.0, 1.0})));
    filter.Update(Sighting("2", RangeBearingLocalizer::Measure(truth, {2.0, -2.0})));
  }
  EXPECT_FALSE(filter.lost());
  EXPECT_NEAR(filter.pose().x(), 1.0, 0.05);
  EXPECT_NEAR(filter.pose().y(), 0.5, 0.05);
  EXPECT_EQ(filter.counts().at("became lost"), 1);
  EXPECT_EQ(filter.counts().at("regained"), 1);
}

// Mean NEES of the pose over `runs` Monte Carlo runs of 50 steps: the truth moves by the
// odometry increment plus the model's odometry noise; the ranges of a frame share a
// Gauss-Markov scale error when options.noise.range_scale_sigma > 0 (time step dt_s); both
// landmarks are measured every `update_every` steps with independent range noise of sigma
// `range_sigma(range)` and the model's bearing noise; each run's bearing scale error is drawn
// from the filter's prior (options.bearing_scale_sigma).
double MonteCarloMeanNees(const RangeBearingLocalizerOptions& options, unsigned seed, int update_every,
                          double dt_s, const std::function<double(double)>& range_sigma, int runs) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, 1.0);
  const MarkerMap map = TwoLandmarks();
  const double scale_sigma = options.noise.range_scale_sigma;
  double sum = 0.0;
  for (int run = 0; run < runs; ++run) {
    const Eigen::Vector3d sigma0(0.05, 0.05, 0.02);
    SE2d truth;
    const SE2d start(sigma0[0] * n(rng), sigma0[1] * n(rng), sigma0[2] * n(rng));
    RangeBearingLocalizer filter(map, options, start, Eigen::Matrix3d(sigma0.cwiseAbs2().asDiagonal()));
    double scale = scale_sigma > 0.0 ? scale_sigma * n(rng) : 0.0;
    const double bearing_scale = options.bearing_scale_sigma * n(rng);
    const double phi = scale_sigma > 0.0 ? std::exp(-dt_s / options.noise.range_scale_time_s) : 0.0;
    for (int step = 0; step < 50; ++step) {
      const SE2d M(0.05, 0.0, 0.01);
      // The true increment differs from M by the model's noise.
      const double d = 0.05;
      const double st = std::sqrt(options.noise.odometry_q_t * (d + 1e-3));
      const double sr = std::sqrt(options.noise.odometry_q_r * (0.01 + 0.1 * d + 1e-3));
      truth = truth * SE2d(0.05 + st * n(rng), st * n(rng), 0.01 + sr * n(rng));
      if (scale_sigma > 0.0) scale = phi * scale + std::sqrt(1.0 - phi * phi) * scale_sigma * n(rng);
      filter.Predict(M, dt_s);
      if (step % update_every == update_every - 1) {
        const Eigen::Vector3d x(truth.x(), truth.y(), truth.theta());
        for (const char* id : {"1", "2"}) {
          const Eigen::Vector2d l = map.Find({kFamilyBarcode, id})->T_world_marker.translation().head<2>();
          Eigen::Vector2d z = RangeBearingLocalizer::Measure(x, l);
          z[0] = (1.0 + scale) * z[0] + range_sigma(z[0]) * n(rng);
          z[1] = WrapAngle((1.0 + bearing_scale) * z[1] + options.noise.bearing_rad * n(rng));
          filter.Update(Sighting(id, z));
        }
      }
    }
    const Eigen::Vector3d e(truth.x() - filter.pose().x(), truth.y() - filter.pose().y(),
                            WrapAngle(truth.theta() - filter.pose().theta()));
    sum += e.dot(filter.covariance().llt().solve(e));
  }
  return sum / runs;
}

TEST(RangeBearingLocalizer, MonteCarloNeesInsideBounds) {
  RangeBearingLocalizerOptions options;
  options.noise.range_a_m = 0.05;
  options.noise.range_b = 0.01;
  options.noise.bearing_rad = 0.02;
  options.noise.odometry_q_t = 1e-4;
  options.noise.odometry_q_r = 1e-4;
  options.noise.odometry_c_d = 0.1;
  const int runs = 200;
  const double mean = MonteCarloMeanNees(
      options, 11, 5, 0.0, [](double r) { return 0.05 + 0.01 * r; }, runs);
  EXPECT_GT(mean, ChiSquareQuantile(0.025, 3 * runs) / runs);
  EXPECT_LT(mean, ChiSquareQuantile(0.975, 3 * runs) / runs);
}

TEST(RangeBearingLocalizer, MonteCarloNeesInsideBoundsWithARangeScaleCommonToTheFrame) {
  // The ranges of a frame share a scale error (Gauss-Markov, sigma 5 %, 1 s); the filter carries
  // it in its state; its NEES stays inside the bounds.
  RangeBearingLocalizerOptions options;
  options.noise.range_a_m = 0.05;
  options.noise.range_b = 0.06;
  options.noise.bearing_rad = 0.02;
  options.noise.odometry_q_t = 1e-4;
  options.noise.odometry_q_r = 1e-4;
  options.noise.odometry_c_d = 0.1;
  options.noise.range_scale_sigma = 0.05;
  options.noise.range_scale_time_s = 1.0;
  const int runs = 200;
  // The independent part: the model's total range sigma without the common 5 %.
  const auto independent = [](double r) {
    const double total = 0.05 + 0.06 * r, common = 0.05 * r;
    return std::sqrt(total * total - common * common);
  };
  const double mean = MonteCarloMeanNees(options, 12, 2, 0.1, independent, runs);
  EXPECT_GT(mean, ChiSquareQuantile(0.025, 3 * runs) / runs);
  EXPECT_LT(mean, ChiSquareQuantile(0.975, 3 * runs) / runs);
}

TEST(RangeBearingLocalizer, TheBearingScaleIsEstimated) {
  // The sensor reads every bearing 6 % too large; the robot drives a circle among six
  // landmarks seeing each at bearings up to 0.6 rad; the filter's k_bearing converges to it.
  MarkerMap map;
  for (int i = 0; i < 6; ++i) {
    MapMarker m;
    m.is_point = true;
    m.key = {kFamilyBarcode, std::to_string(i)};
    m.T_world_marker = SE3d(Eigen::Quaterniond::Identity(),
                            Eigen::Vector3d(4.0 * std::cos(i * M_PI / 3), 4.0 * std::sin(i * M_PI / 3), 0.0));
    map.markers.push_back(m);
  }
  std::mt19937 rng(21);
  std::normal_distribution<double> n(0.0, 1.0);
  RangeBearingLocalizerOptions options;
  options.noise.bearing_rad = 0.005;
  options.noise.odometry_q_t = 1e-4;
  options.noise.odometry_q_r = 1e-4;
  SE2d truth(2.0, 0.0, M_PI / 2);
  RangeBearingLocalizer filter(map, options, truth,
                               Eigen::Vector3d(0.01, 0.01, 0.01).cwiseAbs2().asDiagonal());
  for (int step = 0; step < 600; ++step) {
    const SE2d M(0.05, 0.0, 0.025);
    truth = truth * M;
    filter.Predict(M, 0.1);
    const Eigen::Vector3d x(truth.x(), truth.y(), truth.theta());
    for (const MapMarker& m : map.markers) {
      Eigen::Vector2d z = RangeBearingLocalizer::Measure(x, m.T_world_marker.translation().head<2>());
      if (std::abs(z[1]) > 0.6) continue;
      z[0] += 0.02 * n(rng);
      z[1] = WrapAngle(1.06 * z[1] + options.noise.bearing_rad * n(rng));
      filter.Update(Sighting(m.key.id, z));
    }
  }
  EXPECT_NEAR(filter.bearing_scale(), 0.06, 0.01);
  EXPECT_NEAR(filter.pose().x(), truth.x(), 0.05);
  EXPECT_NEAR(filter.pose().y(), truth.y(), 0.05);
}

TEST(RangeBearingLocalizer, RefusesBadInput) {
  RangeBearingLocalizerOptions options;
  options.noise.bearing_rad = 0.0;
  EXPECT_THROW(RangeBearingLocalizer(TwoLandmarks(), options, SE2d(), Eigen::Matrix3d::Identity()),
               std::invalid_argument);
  EXPECT_THROW(RangeBearingLocalizer(TwoLandmarks(), {}, SE2d(), -Eigen::Matrix3d::Identity()),
               std::invalid_argument);
}

}  // namespace
}  // namespace waymark
