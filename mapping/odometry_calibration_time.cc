#include "mapping/odometry_calibration_time.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include "geometry/pose.h"

namespace waymark {
namespace {

struct Heading {
  double stamp_s;
  double theta;  // unwrapped
};

// Each pose's heading about z (2 atan2(q_z, q_w): the planar yaw), unwrapped along the series.
std::vector<Heading> Headings(const Trajectory& trajectory, double shift_s) {
  std::vector<Heading> out;
  out.reserve(trajectory.size());
  for (const StampedSE3& pose : trajectory) {
    const Eigen::Quaterniond& q = pose.T.rotation();
    const double theta = 2.0 * std::atan2(q.z(), q.w());
    if (out.empty()) {
      out.push_back({pose.stamp_s + shift_s, theta});
    } else {
      const double d = theta - out.back().theta;
      out.push_back({pose.stamp_s + shift_s, out.back().theta + std::atan2(std::sin(d), std::cos(d))});
    }
  }
  return out;
}

// The heading at t, linear between the samples around it; nullopt at or before the first stamp
// and after the last.
std::optional<double> HeadingAt(const std::vector<Heading>& series, double t) {
  const auto it = std::lower_bound(series.begin(), series.end(), t,
                                   [](const Heading& h, double s) { return h.stamp_s < s; });
  if (it == series.begin() || it == series.end()) return std::nullopt;
  const Heading& a = *(it - 1);
  const Heading& b = *it;
  return a.theta + (t - a.stamp_s) / (b.stamp_s - a.stamp_s) * (b.theta - a.theta);
}

}  // namespace

std::vector<TurnStep> TurnSteps(const Trajectory& smoothed, const Trajectory& odometry,
                                double odometry_delay_s, double step_s) {
  std::vector<TurnStep> steps;
  if (smoothed.size() < 2 || odometry.size() < 2 || !(step_s > 0.0)) return steps;
  const std::vector<Heading> g = Headings(smoothed, 0.0);
  const std::vector<Heading> c = Headings(odometry, odometry_delay_s);
  const double end = std::min(g.back().stamp_s, c.back().stamp_s);
  // t advances by repeated addition, as the script does (the same sample instants to the last bit).
  for (double t = std::max(g.front().stamp_s, c.front().stamp_s); t + step_s < end; t += step_s) {
    const auto g0 = HeadingAt(g, t), g1 = HeadingAt(g, t + step_s);
    const auto c0 = HeadingAt(c, t), c1 = HeadingAt(c, t + step_s);
    TurnStep step;
    if (g0 && g1 && c0 && c1) step = {true, *g1 - *g0, *c1 - *c0};
    steps.push_back(step);
  }
  return steps;
}

CalibrationTimeFit FitTurnScaleCorrelation(const std::vector<std::vector<TurnStep>>& datasets,
                                           const CalibrationTimeOptions& options) {
  CalibrationTimeFit fit;
  const int lags = static_cast<int>(options.max_lag_s / options.step_s);
  std::vector<double> num(lags + 1, 0.0), den(lags + 1, 0.0);
  for (const std::vector<TurnStep>& steps : datasets) {
    double gc = 0.0, cc = 0.0;
    size_t valid = 0;
    for (const TurnStep& s : steps) {
      if (!s.valid) continue;
      gc += s.smoothed * s.odometry;
      cc += s.odometry * s.odometry;
      ++valid;
    }
    if (valid == 0 || !(cc > 0.0)) {
      fit.constant_turn_scale.push_back(0.0);
      fit.steps.push_back(valid);
      continue;
    }
    const double k = gc / cc;
    fit.constant_turn_scale.push_back(k - 1.0);
    fit.steps.push_back(valid);
    std::vector<double> e(steps.size(), 0.0);
    for (size_t i = 0; i < steps.size(); ++i) {
      if (steps[i].valid) e[i] = steps[i].smoothed - k * steps[i].odometry;
    }
    for (int lag = 1; lag <= lags; ++lag) {
      for (size_t i = 0; i + lag < steps.size(); ++i) {
        if (!steps[i].valid || !steps[i + lag].valid) continue;
        const double cij = steps[i].odometry * steps[i + lag].odometry;
        num[lag] += e[i] * e[i + lag] * cij;
        den[lag] += cij * cij;
      }
    }
  }
  for (int lag = 1; lag <= lags; ++lag) {
    const double r = den[lag] > 0.0 ? num[lag] / den[lag] : 0.0;
    if (!(r > 0.0)) break;
    fit.autocovariance.emplace_back(lag * options.step_s, r);
  }
  if (fit.autocovariance.size() < 2) return fit;
  double sw = 0.0, ml = 0.0, my = 0.0;
  for (const auto& [l, r] : fit.autocovariance) {
    sw += r;
    ml += r * l;
    my += r * std::log(r);
  }
  ml /= sw;
  my /= sw;
  double sxy = 0.0, sxx = 0.0;
  for (const auto& [l, r] : fit.autocovariance) {
    sxy += r * (l - ml) * (std::log(r) - my);
    sxx += r * (l - ml) * (l - ml);
  }
  const double slope = sxy / sxx;
  if (!(slope < 0.0)) return fit;
  fit.fitted = true;
  fit.time_s = -1.0 / slope;
  fit.sigma = std::sqrt(std::exp(my - slope * ml));
  return fit;
}

}  // namespace waymark
