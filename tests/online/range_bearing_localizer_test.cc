// online/range_bearing_localizer.h: F and H against central differences (asserted), a zero
// innovation keeps the mean and shrinks P, P stays symmetric positive definite, unknown codes
// and gross outliers are rejected and counted, a long run of rejections makes the filter lost
// (and it regains the track), and the Monte-Carlo mean NEES lies inside its 95 % bounds; the
// iterated update reaches the MAP estimate of its prior and one sighting (the plain EKF does not),
// and while lost the update iterates relocalization_iterations times.
#include "online/range_bearing_localizer.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <cmath>
#include <cstdio>
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

// Options with only the pose estimated (every calibration and sensor state held) and the map
// taken as exact: the prior of the state is then the pose's covariance alone.
RangeBearingLocalizerOptions PoseOnlyOptions(int update_iterations) {
  RangeBearingLocalizerOptions options;
  options.calibration_sigma.setZero();
  options.sensor_bias_sigma.setZero();
  options.bearing_scale_sigma = 0.0;
  options.map_uncertainty = RangeBearingMapUncertainty::kIgnore;
  options.update_iterations = update_iterations;
  return options;
}

TEST(RangeBearingLocalizer, JacobiansMatchCentralDifferences) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  for (int trial = 0; trial < 10; ++trial) {
    RangeBearingLocalizer::Vector6 x6;
    x6 << u(rng), u(rng), u(rng), 0.01 * u(rng), 0.05 * u(rng), 0.05 * u(rng), 0.05 * u(rng), 0.01 * u(rng),
        0.01 * u(rng), 0.02 * u(rng), 0.3 * u(rng), 0.02 * u(rng), 0.05 * u(rng);
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
    plain[12] = 0.0;
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
    // The landmark's own Jacobian, and the augmented state's [x, xi, eta] with
    // l = l_map + F xi + eta (k = 3), as the update composes them.
    const auto measure_landmark = [&](const Eigen::VectorXd& p) -> Eigen::VectorXd {
      return RangeBearingLocalizer::MeasureState(x6, p);
    };
    const Eigen::Matrix2d H_l = RangeBearingLocalizer::MeasureLandmarkJacobian(x6, l);
    EXPECT_LT((testing::NumericJacobian(measure_landmark, l, 1e-6, wrap) - H_l).cwiseAbs().maxCoeff(), 1e-6);
    Eigen::Matrix<double, 2, 3> F_l;
    F_l << 0.03 * u(rng), 0.01 * u(rng), 0.02 * u(rng), 0.01 * u(rng), 0.03 * u(rng), 0.02 * u(rng);
    constexpr int n = RangeBearingLocalizer::kStateSize;
    Eigen::VectorXd augmented(n + 5);
    augmented << x6, 0.5 * u(rng), 0.5 * u(rng), 0.5 * u(rng), 0.01 * u(rng), 0.01 * u(rng);
    const auto measure_augmented = [&](const Eigen::VectorXd& z) -> Eigen::VectorXd {
      const Eigen::Vector2d p = l + F_l * z.segment<3>(n) + z.segment<2>(n + 3);
      return RangeBearingLocalizer::MeasureState(z.head<n>(), p);
    };
    const Eigen::Vector2d l_now = l + F_l * augmented.segment<3>(n) + augmented.segment<2>(n + 3);
    const RangeBearingLocalizer::Vector6 x_now = augmented.head<n>();
    Eigen::Matrix<double, 2, n + 5> H_augmented;
    const Eigen::Matrix2d H_l_now = RangeBearingLocalizer::MeasureLandmarkJacobian(x_now, l_now);
    H_augmented << RangeBearingLocalizer::MeasureStateJacobian(x_now, l_now), H_l_now * F_l, H_l_now;
    EXPECT_LT((testing::NumericJacobian(measure_augmented, augmented, 1e-6, wrap) - H_augmented)
                  .cwiseAbs()
                  .maxCoeff(),
              1e-6);
    const Eigen::Vector2d h = RangeBearingLocalizer::MeasureState(x6, l),
                          h_pose = RangeBearingLocalizer::Measure(x, l);
    // The range read (1 - c_depth) r + c_depth p_x, p_x = r cos(beta): the depth along the axis.
    EXPECT_NEAR(h[0],
                (1.0 + x6[8] + x6[11]) * (1.0 - x6[10] + x6[10] * std::cos(h_pose[1])) * h_pose[0] + x6[6],
                1e-9);
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

// The stationarity condition of the MAP estimate of the pose from its prior N(x0, P0) and one
// sighting z (noise R): x - x0 = P0 H(x)^T R^-1 (z - h(x)), its norm (0 at the optimum).
double MapConditionResidual(const Eigen::Vector3d& x0, const Eigen::Matrix3d& P0, const Eigen::Vector3d& x,
                            const Eigen::Vector2d& l, const Eigen::Vector2d& z, const Eigen::Matrix2d& R) {
  const Eigen::Vector2d h = RangeBearingLocalizer::Measure(x, l);
  const Eigen::Vector2d y(z[0] - h[0], WrapAngle(z[1] - h[1]));
  const Eigen::Matrix<double, 2, 3> H = RangeBearingLocalizer::MeasureJacobian(x, l);
  Eigen::Vector3d dx = x - x0;
  dx[2] = WrapAngle(dx[2]);
  return (dx - P0 * H.transpose() * R.inverse() * y).norm();
}

TEST(RangeBearingLocalizer, TheIteratedUpdateIsTheMapEstimateOfPriorAndSighting) {
  // A wide prior (as after the filter was lost): 0.5 m and 0.4 rad; the sighting is from a pose
  // 0.4 m and 0.3 rad away from the prior's mean, where h is far from linear.
  const Eigen::Vector3d x0(0.0, 0.0, 0.0), truth(0.3, -0.25, 0.3);
  const Eigen::Matrix3d P0 = Eigen::Vector3d(0.25, 0.25, 0.16).asDiagonal();
  const Eigen::Vector2d l(3.0, 1.0);
  const Eigen::Vector2d z = RangeBearingLocalizer::Measure(truth, l);
  const RangeBearingNoise noise;  // R: the default range and bearing sigmas, no common range part
  const double sigma_range = noise.range_a_m + noise.range_b * z[0];
  const Eigen::Matrix2d R =
      Eigen::Vector2d(sigma_range * sigma_range, noise.bearing_rad * noise.bearing_rad).asDiagonal();
  double residual[2] = {0.0, 0.0};
  for (const int iterations : {1, 20}) {
    RangeBearingLocalizerOptions options = PoseOnlyOptions(iterations);
    options.gate_chi2 = 1e6;  // the prior is far off: accept
    RangeBearingLocalizer filter(TwoLandmarks(), options, SE2d(x0[0], x0[1], x0[2]), P0);
    ASSERT_EQ(filter.Update(Sighting("1", z)), RangeBearingUpdate::kAccepted);
    const Eigen::Vector3d x(filter.pose().x(), filter.pose().y(), filter.pose().theta());
    residual[iterations == 1 ? 0 : 1] = MapConditionResidual(x0, P0, x, l, z, R);
    EXPECT_EQ(Eigen::LLT<Eigen::Matrix3d>(filter.covariance()).info(), Eigen::Success);
  }
  // The plain EKF stops after one linearization (far from the optimum); the iterations reach it.
  EXPECT_GT(residual[0], 1e-2);
  EXPECT_LT(residual[1], 1e-8);
}

TEST(RangeBearingLocalizer, TheIteratedUpdateIsTheMapEstimateWithTheSensorStates) {
  // The same with the sensor's states estimated too: every entry of the state satisfies
  // x - x0 = P0 H(x)^T R^-1 (z - h(x)) (P0 diagonal: the start's and the options' sigmas).
  using Vector = RangeBearingLocalizer::Vector6;
  RangeBearingLocalizerOptions options;
  options.map_uncertainty = RangeBearingMapUncertainty::kIgnore;
  options.gate_chi2 = 1e6;
  options.depth_share_mean = 0.9;
  options.depth_share_sigma = 0.05;
  options.range_scale_state_sigma = 0.05;
  options.noise.range_scale_sigma = 0.02;
  Vector x0 = Vector::Zero(), sigma = Vector::Zero();
  x0.segment<3>(3) = options.calibration_mean;
  x0[10] = options.depth_share_mean;
  sigma << 0.5, 0.5, 0.4, options.calibration_sigma, options.sensor_bias_sigma,
      options.noise.range_scale_sigma, options.bearing_scale_sigma, options.depth_share_sigma,
      options.range_scale_state_sigma, 0.0;
  const Eigen::Vector3d truth(0.3, -0.25, 0.3);
  const Eigen::Vector2d l(3.0, 1.0);
  Eigen::Vector2d z = RangeBearingLocalizer::Measure(truth, l);
  z[0] *= 1.05;
  const double total = options.noise.range_a_m + options.noise.range_b * z[0];
  const double common = options.noise.range_scale_sigma * z[0];
  const Eigen::Matrix2d R =
      Eigen::Vector2d(total * total - common * common, options.noise.bearing_rad * options.noise.bearing_rad)
          .asDiagonal();
  double residual[2] = {0.0, 0.0};
  for (const int iterations : {1, 30}) {
    options.update_iterations = iterations;
    RangeBearingLocalizer filter(TwoLandmarks(), options, SE2d(),
                                 Eigen::Matrix3d(sigma.head<3>().cwiseAbs2().asDiagonal()));
    ASSERT_EQ(filter.Update(Sighting("1", z)), RangeBearingUpdate::kAccepted);
    Vector x;
    x << filter.pose().x(), filter.pose().y(), filter.pose().theta(), filter.calibration(),
        filter.sensor_bias(), filter.range_scale(), filter.bearing_scale(), filter.depth_share(),
        filter.robot_range_scale(), filter.turn_fluctuation();
    const Eigen::Vector2d h = RangeBearingLocalizer::MeasureState(x, l);
    const Eigen::Vector2d y(z[0] - h[0], WrapAngle(z[1] - h[1]));
    const Eigen::Matrix<double, 2, RangeBearingLocalizer::kStateSize> H =
        RangeBearingLocalizer::MeasureStateJacobian(x, l);
    Vector dx = x - x0;
    dx[2] = WrapAngle(dx[2]);
    residual[iterations == 1 ? 0 : 1] =
        (dx - sigma.cwiseAbs2().asDiagonal() * (H.transpose() * R.inverse() * y)).norm();
  }
  EXPECT_GT(residual[0], 1e-2);
  EXPECT_LT(residual[1], 1e-8);
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
  // Two landmarks cannot tell a bearing scale error or a depth share from the pose: none here.
  options.bearing_scale_sigma = 1e-6;
  options.depth_share_sigma = 1e-6;
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

// While lost, the update iterates relocalization_iterations times (while tracking,
// update_iterations): the filter is sure of the origin, a sighting from a pose 0.7 m and 0.35 rad
// away is gated and makes it lost (P widened by the reacquire sigmas), and the next sighting's
// update reaches the MAP estimate of the widened prior and that sighting only when iterated.
double MapResidualOfTheFirstUpdateWhileLost(int update_iterations, int relocalization_iterations) {
  RangeBearingLocalizerOptions options = PoseOnlyOptions(update_iterations);
  options.relocalization_iterations = relocalization_iterations;
  options.lost_rejections = 1;
  const Eigen::Matrix3d P_start = Eigen::Vector3d(1e-8, 1e-8, 1e-8).asDiagonal();
  RangeBearingLocalizer filter(TwoLandmarks(), options, SE2d(), P_start);
  const Eigen::Vector3d truth(0.6, -0.35, 0.35);
  const Eigen::Vector2d l(3.0, 1.0);
  const Eigen::Vector2d z = RangeBearingLocalizer::Measure(truth, l);
  EXPECT_EQ(filter.Update(Sighting("1", z)), RangeBearingUpdate::kGated);
  EXPECT_TRUE(filter.lost());
  EXPECT_EQ(filter.Update(Sighting("1", z)), RangeBearingUpdate::kAccepted);
  const double sm = options.reacquire_sigma_m, sr = options.reacquire_sigma_rad;
  const Eigen::Matrix3d P0 =
      P_start + Eigen::Vector3d(sm * sm, sm * sm, sr * sr).asDiagonal().toDenseMatrix();
  const double sigma_range = options.noise.range_a_m + options.noise.range_b * z[0];
  const Eigen::Matrix2d R =
      Eigen::Vector2d(sigma_range * sigma_range, options.noise.bearing_rad * options.noise.bearing_rad)
          .asDiagonal();
  const Eigen::Vector3d x(filter.pose().x(), filter.pose().y(), filter.pose().theta());
  return MapConditionResidual(Eigen::Vector3d::Zero(), P0, x, l, z, R);
}

TEST(RangeBearingLocalizer, RelocalizationIterationsApplyWhileLost) {
  EXPECT_LT(MapResidualOfTheFirstUpdateWhileLost(1, 20), 1e-8);
  EXPECT_GT(MapResidualOfTheFirstUpdateWhileLost(20, 1), 1e-2);
  EXPECT_GT(MapResidualOfTheFirstUpdateWhileLost(1, 1), 1e-2);
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

// Four landmarks whose map errors are correlated: Sigma = F F^T + blockdiag(D), F (8 x 3) with a
// common shift of the whole map and two random modes, D = (1 cm)^2 I.
// Six point landmarks on a circle of 4 m about the origin, 60 degrees apart.
MarkerMap SixLandmarksOnACircle() {
  MarkerMap map;
  for (int i = 0; i < 6; ++i) {
    MapMarker m;
    m.is_point = true;
    m.key = {kFamilyBarcode, std::to_string(i)};
    m.T_world_marker = SE3d(Eigen::Quaterniond::Identity(),
                            Eigen::Vector3d(4.0 * std::cos(i * M_PI / 3), 4.0 * std::sin(i * M_PI / 3), 0.0));
    map.markers.push_back(m);
  }
  return map;
}

MarkerMap FourLandmarksWithCovariance(Eigen::MatrixXd* sigma_out) {
  const double positions[4][2] = {{3.0, 1.0}, {2.0, -2.0}, {-1.0, 2.5}, {-2.0, -1.5}};
  std::mt19937 rng(5);
  std::normal_distribution<double> n(0.0, 1.0);
  Eigen::MatrixXd F = Eigen::MatrixXd::Zero(8, 3);
  for (int i = 0; i < 4; ++i) {
    F(2 * i, 0) = 0.03;  // the whole map shifted in x and y together
    F(2 * i + 1, 0) = 0.02;
    for (int r = 0; r < 2; ++r) {
      F(2 * i + r, 1) = 0.02 * n(rng);
      F(2 * i + r, 2) = 0.02 * n(rng);
    }
  }
  const Eigen::Matrix2d D = Eigen::Matrix2d::Identity() * 1e-4;
  MarkerMap map;
  for (int i = 0; i < 4; ++i) {
    MapMarker m;
    m.is_point = true;
    m.key = {kFamilyBarcode, std::to_string(i + 1)};
    m.T_world_marker =
        SE3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(positions[i][0], positions[i][1], 0.0));
    m.position_covariance = Eigen::Matrix3d::Zero();
    m.position_covariance->topLeftCorner<2, 2>() =
        F.middleRows(2 * i, 2) * F.middleRows(2 * i, 2).transpose() + D;
    m.covariance_factor = CovarianceFactor::Zero(6, 3);  // a point's: the translation rows
    m.covariance_factor->middleRows<2>(3) = F.middleRows(2 * i, 2);
    map.markers.push_back(m);
  }
  *sigma_out = F * F.transpose();
  for (int i = 0; i < 4; ++i) sigma_out->block<2, 2>(2 * i, 2 * i) += D;
  return map;
}

// Mean NEES of the pose after 100 steps (all four landmarks seen at every step: each landmark's
// map error is met a hundred times), over `runs` runs; each run draws the true landmarks from the
// map's joint covariance (the map is the truth plus one such error), the odometry noise from the
// model, no sensor bias.
double MonteCarloMeanNeesWithMapError(const RangeBearingLocalizerOptions& options, const MarkerMap& map,
                                      const Eigen::MatrixXd& sigma, unsigned seed, int runs) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, 1.0);
  const Eigen::MatrixXd L = sigma.llt().matrixL();
  double sum = 0.0;
  for (int run = 0; run < runs; ++run) {
    Eigen::VectorXd draw(8);
    for (int i = 0; i < 8; ++i) draw[i] = n(rng);
    const Eigen::VectorXd eps = L * draw;
    const Eigen::Vector3d sigma0(0.05, 0.05, 0.02);
    SE2d truth;
    const SE2d start(sigma0[0] * n(rng), sigma0[1] * n(rng), sigma0[2] * n(rng));
    RangeBearingLocalizer filter(map, options, start, Eigen::Matrix3d(sigma0.cwiseAbs2().asDiagonal()));
    for (int step = 0; step < 100; ++step) {
      const SE2d M(0.05, 0.0, 0.03);
      const double d = 0.05;
      const double st = std::sqrt(options.noise.odometry_q_t * (d + 1e-3));
      const double sr = std::sqrt(options.noise.odometry_q_r * (0.03 + 0.1 * d + 1e-3));
      truth = truth * SE2d(0.05 + st * n(rng), st * n(rng), 0.03 + sr * n(rng));
      filter.Predict(M);
      const Eigen::Vector3d x(truth.x(), truth.y(), truth.theta());
      for (int i = 0; i < 4; ++i) {
        const Eigen::Vector2d l =
            map.markers[i].T_world_marker.translation().head<2>() + eps.segment<2>(2 * i);
        Eigen::Vector2d z = RangeBearingLocalizer::Measure(x, l);
        z[0] += (options.noise.range_a_m + options.noise.range_b * z[0]) * n(rng);
        z[1] = WrapAngle(z[1] + options.noise.bearing_rad * n(rng));
        filter.Update(Sighting(map.markers[i].key.id, z));
      }
    }
    const Eigen::Vector3d e(truth.x() - filter.pose().x(), truth.y() - filter.pose().y(),
                            WrapAngle(truth.theta() - filter.pose().theta()));
    sum += e.dot(filter.covariance().llt().solve(e));
  }
  return sum / runs;
}

TEST(RangeBearingLocalizer, MapErrorsAsStatesKeepTheNeesInsideBounds) {
  // The map's landmarks are off by a correlated error of about 3-4 cm; the sightings are good to
  // 1 cm and 5 mrad and repeat. As states (estimate) or considered (Schmidt), the map error is met
  // once; added to each sighting's noise (in-noise) it is taken as new information every time,
  // and the filter grows overconfident; taken as exact (ignore), more so.
  Eigen::MatrixXd sigma;
  const MarkerMap map = FourLandmarksWithCovariance(&sigma);
  RangeBearingLocalizerOptions options;
  options.noise.range_a_m = 0.01;
  options.noise.range_b = 0.0;
  options.noise.bearing_rad = 0.005;
  options.noise.odometry_q_t = 1e-4;
  options.noise.odometry_q_r = 1e-4;
  options.noise.odometry_c_d = 0.1;
  options.calibration_sigma = Eigen::Vector3d::Constant(1e-6);  // no calibration error drawn
  options.sensor_bias_sigma = Eigen::Vector2d::Constant(1e-6);
  options.bearing_scale_sigma = 1e-6;
  const int runs = 200;
  const double lower = ChiSquareQuantile(0.025, 3 * runs) / runs,
               upper = ChiSquareQuantile(0.975, 3 * runs) / runs;
  for (const RangeBearingMapUncertainty mode :
       {RangeBearingMapUncertainty::kEstimate, RangeBearingMapUncertainty::kConsider}) {
    options.map_uncertainty = mode;
    const double mean = MonteCarloMeanNeesWithMapError(options, map, sigma, 21, runs);
    EXPECT_GT(mean, lower) << static_cast<int>(mode);
    EXPECT_LT(mean, upper) << static_cast<int>(mode);
  }
  options.map_uncertainty = RangeBearingMapUncertainty::kInNoise;
  EXPECT_GT(MonteCarloMeanNeesWithMapError(options, map, sigma, 21, runs), 2.0 * upper);
  options.map_uncertainty = RangeBearingMapUncertainty::kIgnore;
  EXPECT_GT(MonteCarloMeanNeesWithMapError(options, map, sigma, 21, runs), 2.0 * upper);
}

TEST(RangeBearingLocalizer, LandmarkStatesAreCappedAndTheMapRefinedOnlyWhenEstimated) {
  Eigen::MatrixXd sigma;
  const MarkerMap map = FourLandmarksWithCovariance(&sigma);
  RangeBearingLocalizerOptions options;
  options.max_landmark_states = 2;
  const Eigen::Vector3d truth(0.5, 0.2, 0.1);
  for (const RangeBearingMapUncertainty mode :
       {RangeBearingMapUncertainty::kEstimate, RangeBearingMapUncertainty::kConsider,
        RangeBearingMapUncertainty::kInNoise}) {
    options.map_uncertainty = mode;
    RangeBearingLocalizer filter(map, options, SE2d(0.5, 0.2, 0.1),
                                 Eigen::Vector3d(1e-4, 1e-4, 1e-5).asDiagonal());
    const bool augmented = mode != RangeBearingMapUncertainty::kInNoise;
    EXPECT_EQ(filter.map_modes(), augmented ? 3 : 0);
    for (int i = 0; i < 4; ++i) {
      const Eigen::Vector2d l =
          map.markers[i].T_world_marker.translation().head<2>() + Eigen::Vector2d(0.02, -0.01);
      ASSERT_EQ(filter.Update(Sighting(map.markers[i].key.id, RangeBearingLocalizer::Measure(truth, l))),
                RangeBearingUpdate::kAccepted);
      EXPECT_EQ(filter.landmark_states(), augmented ? std::min(i + 1, 2) : 0);
    }
    EXPECT_EQ(
        filter.counts().count("landmark states dropped") ? filter.counts().at("landmark states dropped") : 0,
        augmented ? 2 : 0);
    const Eigen::Vector2d moved =
        *filter.LandmarkPosition(map.markers[3].key) - map.markers[3].T_world_marker.translation().head<2>();
    if (mode == RangeBearingMapUncertainty::kEstimate) {
      EXPECT_GT(moved.norm(), 1e-4);
    } else {
      EXPECT_EQ(moved.norm(), 0.0);
    }
    const Eigen::MatrixXd P = filter.covariance();
    EXPECT_EQ(Eigen::LLT<Eigen::MatrixXd>(P).info(), Eigen::Success);
    EXPECT_FALSE(filter.LandmarkPosition({kFamilyBarcode, "99"}));
  }
}

// Drives `truth` 600 steps around a circle (5 cm and 0.025 rad a step), the filter predicting with
// the exact increments and updating with every landmark within 0.6 rad of the heading, read as
// scale * depth (r cos(bearing)) + sigma_range noise; returns the filter's position RMS.
double DriveACircleReadingDepths(const MarkerMap& map, double scale, double sigma_range_m,
                                 double sigma_bearing_rad, unsigned seed, SE2d truth,
                                 RangeBearingLocalizer* filter) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, 1.0);
  double sum = 0.0;
  for (int step = 0; step < 600; ++step) {
    const SE2d M(0.05, 0.0, 0.025);
    truth = truth * M;
    filter->Predict(M, 0.1);
    const Eigen::Vector3d x(truth.x(), truth.y(), truth.theta());
    for (const MapMarker& m : map.markers) {
      Eigen::Vector2d z = RangeBearingLocalizer::Measure(x, m.T_world_marker.translation().head<2>());
      if (std::abs(z[1]) > 0.6) continue;
      z[0] = scale * z[0] * std::cos(z[1]) + sigma_range_m * n(rng);
      z[1] = WrapAngle(z[1] + sigma_bearing_rad * n(rng));
      filter->Update(Sighting(m.key.id, z));
    }
    sum += (filter->pose().translation() - truth.translation()).squaredNorm();
  }
  return std::sqrt(sum / 600);
}

// A camera that ranges a code from its apparent size reads its depth p_x = r cos(bearing), not
// its distance: the filter's c_depth converges to 1, and the pose is better than with c_depth held
// at 0 (a true range assumed).
TEST(RangeBearingLocalizer, TheDepthShareIsEstimated) {
  const MarkerMap map = SixLandmarksOnACircle();
  const auto run = [&](double depth_share_sigma, double* error_rms) {
    RangeBearingLocalizerOptions options;
    options.noise.range_a_m = 0.02;
    options.noise.range_b = 0.0;
    options.noise.range_scale_sigma = 0.0;
    options.noise.bearing_rad = 0.005;
    options.noise.odometry_q_t = 1e-4;
    options.noise.odometry_q_r = 1e-4;
    options.depth_share_sigma = depth_share_sigma;
    SE2d truth(2.0, 0.0, M_PI / 2);
    RangeBearingLocalizer filter(map, options, truth,
                                 Eigen::Vector3d(0.01, 0.01, 0.01).cwiseAbs2().asDiagonal());
    *error_rms = DriveACircleReadingDepths(map, 1.0, 0.02, options.noise.bearing_rad, 23, truth, &filter);
    return filter.depth_share();
  };
  double estimated_rms = 0.0, held_rms = 0.0;
  EXPECT_NEAR(run(1.0, &estimated_rms), 1.0, 0.1);
  EXPECT_EQ(run(0.0, &held_rms), 0.0);  // the default: held at 0
  EXPECT_LT(estimated_rms, 0.5 * held_rms);
}

// A sensor that reads every range 4 % long (its depth, c = 1): the robot's range scale s_robot is
// recovered from a prior of the map's kind (mean 0.01, sigma 0.03), and the depth share starts
// at its prior mean; held at the prior's mean, the pose is worse.
TEST(RangeBearingLocalizer, TheRobotRangeScaleIsRecovered) {
  const MarkerMap map = SixLandmarksOnACircle();
  const auto run = [&](double range_scale_sigma, double* error_rms) {
    RangeBearingLocalizerOptions options;
    options.noise.range_a_m = 0.01;
    options.noise.range_b = 0.0;
    options.noise.range_scale_sigma = 0.0;
    options.noise.bearing_rad = 0.005;
    options.noise.odometry_q_t = 1e-4;
    options.noise.odometry_q_r = 1e-4;
    options.depth_share_mean = 0.98;
    options.depth_share_sigma = 0.02;
    options.range_scale_mean = 0.01;
    options.range_scale_state_sigma = range_scale_sigma;
    SE2d truth(2.0, 0.0, M_PI / 2);
    RangeBearingLocalizer filter(map, options, truth,
                                 Eigen::Vector3d(0.01, 0.01, 0.01).cwiseAbs2().asDiagonal());
    EXPECT_EQ(filter.depth_share(), 0.98);
    EXPECT_EQ(filter.robot_range_scale(), 0.01);
    *error_rms = DriveACircleReadingDepths(map, 1.04, 0.01, options.noise.bearing_rad, 29, truth, &filter);
    return filter.robot_range_scale();
  };
  double estimated_rms = 0.0, held_rms = 0.0;
  EXPECT_NEAR(run(0.03, &estimated_rms), 0.04, 0.005);
  EXPECT_EQ(run(0.0, &held_rms), 0.01);  // sigma 0: held at its mean
  EXPECT_LT(estimated_rms, 0.5 * held_rms);
}

// The prior for a robot not in the map comes from the map's range_bearing_sensor; a distance-model
// map holds the depth share and the robot's range scale at 0.
TEST(RangeBearingLocalizer, SensorPriorFromMap) {
  RangeBearingSensorModel model;
  model.depth_ranges = true;
  model.prior_mean.depth_share = 0.97;
  model.prior_sigma.depth_share = 0.02;
  model.prior_mean.range_scale = 0.03;
  model.prior_sigma.range_scale = 0.015;
  model.prior_mean.odometry_calibration = Eigen::Vector3d(0.04, 0.08, 0.03);
  model.prior_sigma.odometry_calibration = Eigen::Vector3d(0.01, 0.04, 0.02);
  model.prior_mean.range_offset_m = 0.05;
  model.prior_sigma.range_offset_m = 0.02;
  RangeBearingLocalizerOptions options;
  SensorPriorFromMap(model, &options);
  std::string why;
  EXPECT_TRUE(options.Check(&why)) << why;
  EXPECT_EQ(options.depth_share_mean, 0.97);
  EXPECT_EQ(options.range_scale_state_sigma, 0.015);
  // The map's calibration (factors/calibrated_odometry_factor.h) in the filter's form: a turn read
  // 8 % large is corrected by 1 / 1.08 there, by 1 + s_turn here.
  EXPECT_NEAR(options.calibration_mean[1], -0.08 / 1.08, 1e-15);
  EXPECT_NEAR(options.calibration_mean[0], -0.04 / 1.08, 1e-15);
  EXPECT_NEAR(options.calibration_mean[2], -0.03 / 1.03, 1e-15);
  EXPECT_NEAR(options.calibration_sigma[1], 0.04 / (1.08 * 1.08), 1e-15);
  const Eigen::Vector3d c(0.04, 0.08, 0.03);
  EXPECT_LT((ConvertOdometryCalibration(ConvertOdometryCalibration(c)) - c).norm(),
            1e-15);  // its own inverse
  RangeBearingLocalizer filter(TwoLandmarks(), options, SE2d(), Eigen::Matrix3d::Identity() * 1e-4);
  EXPECT_EQ(filter.calibration()[1], options.calibration_mean[1]);
  // Both forms correct a measured increment alike: (theta_M - k s) / (1 + turn) = (1 + s_turn) theta_M + k_f
  // s.
  const double theta_M = 0.7, s = 1.3;
  const Eigen::Vector3d f = ConvertOdometryCalibration(c);
  EXPECT_NEAR((theta_M - c[0] * s) / (1.0 + c[1]), (1.0 + f[1]) * theta_M + f[0] * s, 1e-15);
  EXPECT_NEAR(s / (1.0 + c[2]), (1.0 + f[2]) * s, 1e-15);
  EXPECT_EQ(filter.sensor_bias()[0], 0.05);
  EXPECT_EQ(filter.robot_range_scale(), 0.03);
  model.depth_ranges = false;
  SensorPriorFromMap(model, &options);
  EXPECT_EQ(options.depth_share_mean, 0.0);
  EXPECT_EQ(options.depth_share_sigma, 0.0);
  EXPECT_EQ(options.range_scale_mean, 0.0);
  EXPECT_EQ(options.range_scale_state_sigma, 0.0);
}

TEST(RangeBearingLocalizer, TheBearingScaleIsEstimated) {
  // The sensor reads every bearing 6 % too large; the robot drives a circle among six
  // landmarks seeing each at bearings up to 0.6 rad; the filter's k_bearing converges to it.
  const MarkerMap map = SixLandmarksOnACircle();
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

TEST(RangeBearingLocalizer, GaussMarkovCalibrationTransition) {
  // The discrete step: phi = exp(-dt / tau), added variance sigma^2 (1 - phi^2); tau 0: constant.
  const auto [phi, q] = RangeBearingLocalizer::GaussMarkovStep(0.1, 5.0, 0.5);
  EXPECT_NEAR(phi, std::exp(-0.1), 1e-15);
  EXPECT_NEAR(q, 0.01 * (1.0 - std::exp(-0.2)), 1e-15);
  EXPECT_EQ(RangeBearingLocalizer::GaussMarkovStep(0.1, 0.0, 0.5), std::make_pair(1.0, 0.0));
  EXPECT_EQ(RangeBearingLocalizer::GaussMarkovStep(0.1, 5.0, 0.0), std::make_pair(1.0, 0.0));
  // The state relaxes to the prior's mean, and F matches central differences.
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  RangeBearingLocalizer::Vector6 x;
  for (int i = 0; i < RangeBearingLocalizer::kStateSize; ++i) x[i] = 0.1 * u(rng);
  x[2] = 2.0 * u(rng);
  const SE2d M(0.2, 0.05, 0.3);
  const Eigen::Vector3d calibration_phi(0.9, 0.5, 0.99), mean(0.01, -0.05, 0.02);
  const RangeBearingLocalizer::Vector6 next =
      RangeBearingLocalizer::PredictState(x, M, 0.7, calibration_phi, mean, 0.8);
  EXPECT_NEAR(next[12], 0.8 * x[12], 1e-15);
  for (int i = 0; i < 3; ++i)
    EXPECT_NEAR(next[3 + i], mean[i] + calibration_phi[i] * (x[3 + i] - mean[i]), 1e-15);
  // The pose moved with the calibration before the step.
  const RangeBearingLocalizer::Vector6 constant = RangeBearingLocalizer::PredictState(x, M, 0.7);
  EXPECT_LT((next.head<3>() - constant.head<3>()).cwiseAbs().maxCoeff(), 1e-15);
  const auto predict = [&](const Eigen::VectorXd& s) -> Eigen::VectorXd {
    Eigen::VectorXd out = RangeBearingLocalizer::PredictState(s, M, 0.7, calibration_phi, mean, 0.8);
    out[2] = s[2] + WrapAngle(out[2] - s[2]);
    return out;
  };
  EXPECT_LT((testing::NumericJacobian(predict, x) -
             RangeBearingLocalizer::PredictJacobian(x, M, 0.7, calibration_phi, 0.8))
                .cwiseAbs()
                .maxCoeff(),
            1e-6);
  // In the filter, without sightings: the calibration's variance stays at its stationary sigma^2
  // (started there), and a constant calibration's does not grow.
  RangeBearingLocalizerOptions options;
  options.calibration_sigma = Eigen::Vector3d(0.01, 0.1, 0.05);
  options.calibration_time_s = Eigen::Vector3d(10.0, 5.0, 0.0);
  RangeBearingLocalizer filter(TwoLandmarks(), options, SE2d(), Eigen::Matrix3d::Identity() * 1e-4);
  for (int step = 0; step < 200; ++step) filter.Predict(SE2d(0.05, 0.0, 0.1), 0.5);
  const Eigen::Matrix3d P = filter.calibration_covariance();
  EXPECT_NEAR(P(0, 0), 1e-4, 1e-10);
  EXPECT_NEAR(P(1, 1), 1e-2, 1e-8);
  EXPECT_NEAR(P(2, 2), 0.05 * 0.05, 1e-10);
}

// A robot whose true turn scale varies (a Gauss-Markov process: sigma 0.1, tau 5 s) turns and
// drives among six landmarks for 50 s, then turns 4 rad for 20 s with no landmark in view. The
// mean NEES at the end of that blind stretch, over `runs` runs, with the filter's calibration
// correlation time tau_s (0: constant).
double MeanNeesAfterABlindTurn(double tau_s, unsigned seed, int runs, bool as_fluctuation = false) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, 1.0);
  const MarkerMap map = SixLandmarksOnACircle();
  RangeBearingLocalizerOptions options;
  options.noise.range_a_m = 0.02;
  options.noise.range_b = 0.0;
  options.noise.bearing_rad = 0.01;
  options.noise.odometry_q_t = 1e-5;
  options.noise.odometry_q_r = 1e-5;
  options.noise.odometry_c_d = 0.0;
  options.calibration_sigma = Eigen::Vector3d(1e-4, 0.1, 1e-4);
  options.calibration_time_s = Eigen::Vector3d::Constant(tau_s);
  if (as_fluctuation) {
    // The constant turn scale held near 0 (its prior), the variation as the fluctuation state.
    options.calibration_sigma[1] = 1e-4;
    options.calibration_time_s.setZero();
    options.turn_fluctuation_sigma = 0.1;
    options.turn_fluctuation_time_s = tau_s;
  }
  const double sigma = 0.1, tau = 5.0, dt = 0.5;
  const double phi = std::exp(-dt / tau);
  double sum = 0.0;
  for (int run = 0; run < runs; ++run) {
    SE2d truth;
    RangeBearingLocalizer filter(map, options, truth, Eigen::Matrix3d::Identity() * 1e-6);
    double scale = sigma * n(rng);
    for (int step = 0; step < 140; ++step) {
      const SE2d M(0.05, 0.0, 0.1);
      const double st = std::sqrt(options.noise.odometry_q_t * (0.05 + 1e-3));
      const double sr = std::sqrt(options.noise.odometry_q_r * (0.1 + 1e-3));
      truth = truth * SE2d(0.05 + st * n(rng), st * n(rng), (1.0 + scale) * 0.1 + sr * n(rng));
      scale = phi * scale + std::sqrt(1.0 - phi * phi) * sigma * n(rng);
      filter.Predict(M, dt);
      if (step >= 100) continue;  // blind
      const Eigen::Vector3d x(truth.x(), truth.y(), truth.theta());
      for (const MapMarker& m : map.markers) {
        Eigen::Vector2d z = RangeBearingLocalizer::Measure(x, m.T_world_marker.translation().head<2>());
        if (std::abs(z[1]) > 0.8) continue;
        z[0] += options.noise.range_a_m * n(rng);
        z[1] = WrapAngle(z[1] + options.noise.bearing_rad * n(rng));
        filter.Update(Sighting(m.key.id, z));
      }
    }
    const Eigen::Vector3d e(truth.x() - filter.pose().x(), truth.y() - filter.pose().y(),
                            WrapAngle(truth.theta() - filter.pose().theta()));
    sum += e.dot(filter.covariance().llt().solve(e));
  }
  return sum / runs;
}

TEST(RangeBearingLocalizer, AVaryingTurnScaleIsTrackedConsistentlyAsAGaussMarkovState) {
  const int runs = 200;
  const double lower = ChiSquareQuantile(0.025, 3 * runs) / runs,
               upper = ChiSquareQuantile(0.975, 3 * runs) / runs;
  // The filter's model matches the truth's process: the NEES is inside its bounds.
  const double gauss_markov = MeanNeesAfterABlindTurn(5.0, 21, runs);
  EXPECT_GT(gauss_markov, lower);
  EXPECT_LT(gauss_markov, upper);
  // The calibration taken as constant: its variance collapses while the sightings last, and after
  // the blind turn the filter is overconfident.
  const double constant = MeanNeesAfterABlindTurn(0.0, 21, runs);
  // The same process as the turn scale's fluctuation state (f, state 12) beside a constant turn scale.
  const double fluctuation = MeanNeesAfterABlindTurn(5.0, 21, runs, true);
  EXPECT_GT(fluctuation, lower);
  EXPECT_LT(fluctuation, upper);
  std::printf("mean NEES after the blind turn, as the turn fluctuation state: %.3f\n", fluctuation);
  std::printf("mean NEES after the blind turn: Gauss-Markov %.3f, constant %.3f, bounds [%.3f, %.3f]\n",
              gauss_markov, constant, lower, upper);
  EXPECT_GT(constant, 2.0 * upper);
}

TEST(RangeBearingLocalizer, RefusesBadInput) {
  RangeBearingLocalizerOptions options;
  options.noise.bearing_rad = 0.0;
  EXPECT_THROW(RangeBearingLocalizer(TwoLandmarks(), options, SE2d(), Eigen::Matrix3d::Identity()),
               std::invalid_argument);
  EXPECT_THROW(RangeBearingLocalizer(TwoLandmarks(), {}, SE2d(), -Eigen::Matrix3d::Identity()),
               std::invalid_argument);
  RangeBearingLocalizerOptions no_states;
  no_states.max_landmark_states = 0;
  EXPECT_THROW(RangeBearingLocalizer(TwoLandmarks(), no_states, SE2d(), Eigen::Matrix3d::Identity()),
               std::invalid_argument);
  RangeBearingLocalizerOptions bad_prior;
  bad_prior.range_scale_state_sigma = -0.1;
  EXPECT_THROW(RangeBearingLocalizer(TwoLandmarks(), bad_prior, SE2d(), Eigen::Matrix3d::Identity()),
               std::invalid_argument);
  bad_prior.range_scale_state_sigma = 0.0;
  bad_prior.depth_share_mean = std::nan("");
  EXPECT_THROW(RangeBearingLocalizer(TwoLandmarks(), bad_prior, SE2d(), Eigen::Matrix3d::Identity()),
               std::invalid_argument);
  RangeBearingLocalizerOptions bad_time;
  bad_time.calibration_time_s[1] = -1.0;
  EXPECT_THROW(RangeBearingLocalizer(TwoLandmarks(), bad_time, SE2d(), Eigen::Matrix3d::Identity()),
               std::invalid_argument);
  RangeBearingLocalizerOptions bad_iterations;
  bad_iterations.update_iterations = 0;
  EXPECT_THROW(RangeBearingLocalizer(TwoLandmarks(), bad_iterations, SE2d(), Eigen::Matrix3d::Identity()),
               std::invalid_argument);
  bad_iterations.update_iterations = 101;
  EXPECT_THROW(RangeBearingLocalizer(TwoLandmarks(), bad_iterations, SE2d(), Eigen::Matrix3d::Identity()),
               std::invalid_argument);
  EXPECT_EQ(ParseRangeBearingMapUncertainty("consider"), RangeBearingMapUncertainty::kConsider);
  EXPECT_FALSE(ParseRangeBearingMapUncertainty("schmidt"));
}

}  // namespace
}  // namespace waymark
