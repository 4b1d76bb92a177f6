#include "runner/range_bearing_run.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <tuple>
#include <vector>

#include "online/chi_square.h"
#include "util/stats.h"

namespace waymark {
namespace {

SE2d OdometryAt(const Trajectory& odometry, double stamp_s) {
  return SE2d::FromSE3(*InterpolateTrajectory(odometry, stamp_s, 1e9));
}

}  // namespace

RangeBearingRun RunRangeBearingLocalizer(const Dataset& dataset, const MarkerMap& map,
                                         const RangeBearingLocalizerOptions& options) {
  const std::string& name = dataset.config.name;
  if (dataset.odometry.size() < 2)
    throw std::runtime_error(name + ": the range-bearing localizer needs odometry");
  const auto& prior = dataset.config.start_prior;
  if (!prior) {
    throw std::runtime_error(name +
                             ": the range-bearing localizer needs dataset.yaml start_prior (the start pose; "
                             "e.g. `waymark import mrclam --known-start`)");
  }
  // The odometry pose stamped t describes the robot at t + odometry_delay_s.
  Trajectory odometry = dataset.odometry;
  for (StampedSE3& point : odometry) point.stamp_s += options.noise.odometry_delay_s;
  const Eigen::Vector3d sigma(prior->sigma_m, prior->sigma_m, prior->sigma_rad);
  RangeBearingLocalizer filter(map, options, SE2d::FromSE3(prior->T_world_robot),
                               Eigen::Matrix3d(sigma.cwiseAbs2().asDiagonal()));
  RangeBearingRun run;
  SE2d T_odom_last = SE2d::FromSE3(odometry.front().T);
  double t_last = odometry.front().stamp_s;
  const auto advance = [&](double stamp_s) {
    const SE2d T_odom_now = OdometryAt(odometry, stamp_s);
    filter.Predict(T_odom_last.inverse() * T_odom_now, stamp_s - t_last);
    T_odom_last = T_odom_now;
    t_last = stamp_s;
  };
  const auto output = [&](double stamp_s) {
    if (filter.lost()) {
      ++run.outputs_withheld;
      return;
    }
    run.outputs_while_lost += filter.lost();  // never: the check above
    if (!run.poses.empty() && run.poses.back().stamp_s == stamp_s) {
      run.poses.back().T = filter.pose().ToSE3();
      run.covariances.back() = options.variance_factor * filter.covariance();
      return;
    }
    run.poses.push_back({stamp_s, filter.pose().ToSE3()});
    run.covariances.push_back(options.variance_factor * filter.covariance());
  };
  output(odometry.front().stamp_s);
  size_t frame = 0;
  const std::vector<RangeBearingFrame>& frames = dataset.range_bearing;
  while (frame < frames.size() && frames[frame].stamp_s < odometry.front().stamp_s) {
    ++run.counts["frames outside odometry"];
    ++frame;
  }
  for (size_t i = 1; i < odometry.size(); ++i) {
    for (; frame < frames.size() && frames[frame].stamp_s <= odometry[i].stamp_s; ++frame) {
      advance(frames[frame].stamp_s);
      for (const RangeBearingObservation& obs : frames[frame].landmarks) filter.Update(obs);
      output(frames[frame].stamp_s);
    }
    advance(odometry[i].stamp_s);
    output(odometry[i].stamp_s);
  }
  run.counts["frames outside odometry"] += static_cast<long>(frames.size() - frame);
  for (const auto& [key, count] : filter.counts()) run.counts[key] += count;
  run.mean_nis = filter.mean_nis();
  run.final_sensor.odometry_calibration = ConvertOdometryCalibration(filter.calibration());  // the map's form
  run.final_sensor.range_offset_m = filter.sensor_bias()[0];
  run.final_sensor.bearing_offset_rad = filter.sensor_bias()[1];
  run.final_sensor.bearing_scale = filter.bearing_scale();
  run.final_sensor.depth_share = filter.depth_share();
  run.final_sensor.range_scale = filter.robot_range_scale();
  return run;
}

double IntegratedAutocorrelationTime(const std::vector<double>& series) {
  const size_t n = series.size();
  if (n < 3) return 1.0;
  double mean = 0.0;
  for (const double v : series) mean += v;
  mean /= static_cast<double>(n);
  std::vector<double> centred(n);
  double c0 = 0.0;
  for (size_t i = 0; i < n; ++i) {
    centred[i] = series[i] - mean;
    c0 += centred[i] * centred[i];
  }
  if (!(c0 > 0.0)) return 1.0;
  double tau = 1.0;
  for (size_t k = 1; k <= n / 2; ++k) {
    double c = 0.0;
    for (size_t i = 0; i + k < n; ++i) c += centred[i] * centred[i + k];
    const double rho = c / c0;
    if (rho <= 0.0) break;
    tau += 2.0 * rho;
  }
  return std::clamp(tau, 1.0, static_cast<double>(n));
}

std::pair<double, double> MeanChiSquareBounds(double n, int dof) {
  if (!(n > 0.0) || dof < 1) throw std::invalid_argument("MeanChiSquareBounds: n must be > 0 and dof >= 1");
  const double k = dof * n;
  const auto quantile = [k](double p, double z) {
    if (k > 3000.0) {
      const double a = 2.0 / (9.0 * k);
      return k * std::pow(1.0 - a + z * std::sqrt(a), 3);
    }
    // Bisection on the monotone CDF P(k / 2, x / 2).
    double lo = 0.0, hi = k + 20.0 * std::sqrt(2.0 * k) + 50.0;
    for (int it = 0; it < 200 && hi - lo > 1e-12 * std::max(1.0, hi); ++it) {
      const double mid = 0.5 * (lo + hi);
      (RegularizedLowerGamma(0.5 * k, 0.5 * mid) < p ? lo : hi) = mid;
    }
    return 0.5 * (lo + hi);
  };
  constexpr double kZ975 = 1.959963984540054;
  return {quantile(0.025, -kZ975) / n, quantile(0.975, kZ975) / n};
}

NeesResult ComputeNees(const Trajectory& groundtruth, const Trajectory& poses,
                       const std::vector<Eigen::Matrix3d>& covariances, double max_dt_s,
                       double truth_yaw_rad) {
  NeesResult result;
  result.sample_lower = ChiSquareQuantile(0.025, 3);
  result.sample_upper = ChiSquareQuantile(0.975, 3);
  double sum = 0.0, sum_position = 0.0, sum_heading = 0.0;
  std::vector<double> series;
  size_t inside = 0, inside_position = 0, inside_heading = 0;
  const double lower2 = ChiSquareQuantile(0.025, 2), upper2 = ChiSquareQuantile(0.975, 2);
  const double lower1 = ChiSquareQuantile(0.025, 1), upper1 = ChiSquareQuantile(0.975, 1);
  for (size_t i = 0; i < poses.size(); ++i) {
    const std::optional<SE3d> truth = InterpolateTrajectory(groundtruth, poses[i].stamp_s, max_dt_s);
    if (!truth) continue;
    const SE2d T_true = SE2d::FromSE3(*truth), T = SE2d::FromSE3(poses[i].T);
    const Eigen::Vector3d e(T_true.x() - T.x(), T_true.y() - T.y(),
                            WrapAngle(T_true.theta() + truth_yaw_rad - T.theta()));
    const Eigen::LLT<Eigen::Matrix3d> llt(covariances[i]);
    if (llt.info() != Eigen::Success) continue;
    const double nees = e.dot(llt.solve(e));
    sum += nees;
    series.push_back(nees);
    inside += nees >= result.sample_lower && nees <= result.sample_upper;
    const double position = e.head<2>().dot(covariances[i].topLeftCorner<2, 2>().ldlt().solve(e.head<2>()));
    const double heading = e[2] * e[2] / covariances[i](2, 2);
    sum_position += position;
    sum_heading += heading;
    inside_position += position >= lower2 && position <= upper2;
    inside_heading += heading >= lower1 && heading <= upper1;
    ++result.samples;
  }
  if (result.samples == 0) throw std::runtime_error("NEES: no pose associates with the ground truth");
  const double n = static_cast<double>(result.samples);
  result.mean = sum / n;
  result.share_inside = inside / n;
  result.mean_position = sum_position / n;
  result.mean_heading = sum_heading / n;
  result.share_inside_position = inside_position / n;
  result.share_inside_heading = inside_heading / n;
  std::tie(result.mean_lower, result.mean_upper) = MeanChiSquareBounds(n, 3);
  result.autocorrelation_time = IntegratedAutocorrelationTime(series);
  result.effective_samples = n / result.autocorrelation_time;
  std::tie(result.mean_lower_correlated, result.mean_upper_correlated) =
      MeanChiSquareBounds(result.effective_samples, 3);
  return result;
}

RangeBearingLocalizerOptions LocalizerOptionsFromMap(const MarkerMap& map, bool sensor_prior) {
  RangeBearingLocalizerOptions options;
  if (sensor_prior && map.range_bearing_sensor) {
    SensorPriorFromMap(*map.range_bearing_sensor, &options);
    if (map.range_bearing_sensor->calibration_time)
      options.calibration_time_s =
          Eigen::Vector3d::Constant(map.range_bearing_sensor->calibration_time->time_s);
  }
  if (map.range_bearing_noise) options.noise = *map.range_bearing_noise;
  return options;
}

std::optional<TruthYawEstimate> EstimateTruthYaw(const Trajectory& groundtruth, const Trajectory& odometry,
                                                 const TruthYawOptions& options) {
  constexpr double kMaxTruthGapS = 0.05;
  constexpr double kMaxError = 0.5;
  // The chord's direction at the window's middle, in the window's start frame.
  const auto direction = [](const SE2d& from, const SE2d& to) {
    const SE2d relative = from.inverse() * to;
    return std::atan2(relative.y(), relative.x()) - 0.5 * relative.theta();
  };
  std::vector<double> errors;
  size_t start = 0;
  while (start + 1 < odometry.size()) {
    const SE2d odometry_from = SE2d::FromSE3(odometry[start].T);
    size_t end = start + 1;
    while (end < odometry.size() && odometry[end].stamp_s - odometry[start].stamp_s <= options.max_window_s &&
           (odometry_from.translation() - SE2d::FromSE3(odometry[end].T).translation()).norm() <
               options.min_travel_m) {
      ++end;
    }
    if (end >= odometry.size()) break;
    const SE2d odometry_to = SE2d::FromSE3(odometry[end].T);
    const std::optional<SE3d> truth_from =
        InterpolateTrajectory(groundtruth, odometry[start].stamp_s, kMaxTruthGapS);
    const std::optional<SE3d> truth_to =
        InterpolateTrajectory(groundtruth, odometry[end].stamp_s, kMaxTruthGapS);
    const bool moved =
        (odometry_from.translation() - odometry_to.translation()).norm() >= options.min_travel_m;
    if (moved && truth_from && truth_to) {
      const SE2d a = SE2d::FromSE3(*truth_from), b = SE2d::FromSE3(*truth_to);
      const bool straight =
          std::abs(WrapAngle(odometry_to.theta() - odometry_from.theta())) <= options.max_turn_rad &&
          std::abs(WrapAngle(b.theta() - a.theta())) <= options.max_turn_rad;
      if (straight && (a.translation() - b.translation()).norm() >= 0.5 * options.min_travel_m) {
        const double e = WrapAngle(direction(a, b) - direction(odometry_from, odometry_to));
        if (std::abs(e) <= kMaxError) errors.push_back(e);
      }
    }
    start = end;
  }
  if (errors.size() < std::max<size_t>(options.min_windows, 1)) return std::nullopt;
  TruthYawEstimate estimate;
  estimate.windows = errors.size();
  estimate.yaw_rad = Median(errors);
  std::vector<double> deviations;
  for (const double e : errors) deviations.push_back(std::abs(e - estimate.yaw_rad));
  estimate.spread_rad = 1.4826 * Median(deviations);
  return estimate;
}

double LeaveOneOutVarianceFactor(const std::vector<NeesResult>& runs) {
  double sum_log = 0.0;
  int count = 0;
  for (const NeesResult& run : runs) {
    if (run.samples == 0) continue;
    if (!(run.mean > 0.0)) throw std::invalid_argument("variance factor: a run's mean NEES is not positive");
    sum_log += std::log(run.mean / 3.0);
    ++count;
  }
  if (count == 0) throw std::invalid_argument("variance factor: no NEES sample in any run");
  return std::exp(sum_log / count);
}

double PooledVarianceFactor(const std::vector<NeesResult>& runs) {
  double sum = 0.0;
  double samples = 0.0;
  for (const NeesResult& run : runs) {
    if (run.samples == 0) continue;
    sum += run.mean * static_cast<double>(run.samples);
    samples += static_cast<double>(run.samples);
  }
  if (!(samples > 0.0)) throw std::invalid_argument("variance factor: no NEES sample in any run");
  return sum / (3.0 * samples);
}

}  // namespace waymark
