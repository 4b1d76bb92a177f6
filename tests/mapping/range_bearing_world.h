// A synthetic room for the range-bearing tests: point landmarks on a grid and robots driving
// loops among them, with odometry that has a scale bias and noise, and range-bearing sightings
// with range noise growing with range; ground truth kept in the datasets.
#pragma once

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "geometry/pose.h"
#include "geometry/types.h"
#include "geometry/unicycle.h"

namespace waymark::testing {

struct RangeBearingWorldOptions {
  double sigma_range_a_m = 0.03, sigma_range_b = 0.02, sigma_bearing_rad = 0.01;
  double outlier_share = 0.0;  // share of sightings replaced by a random range and bearing
  double duration_s = 120.0;
  bool start_prior = true;
  // The commands take effect this much later (the odometry lags the motion it commands), and
  // the turn rate swings by this much (rad/s) with a period of 8 s so that the lag shows.
  double odometry_delay_s = 0.0;
  double turn_swing_rad_s = 0.0;
  // A range scale error common to each frame's landmarks: a Gauss-Markov process of this
  // stationary sigma and correlation time.
  double range_scale_sigma = 0.0;
  double range_scale_time_s = 1.0;
  // The sensor reads every bearing (1 + bearing_scale) times too large.
  double bearing_scale = 0.0;
  // The sensor reads (1 + depth_range_scale) ((1 - depth_share) range + depth_share range cos(bearing))
  // as the range (a camera ranging a code by its apparent size reads its depth: depth_share 1).
  double depth_share = 0.0;
  double depth_range_scale = 0.0;
};

inline MarkerMap RangeBearingLandmarks() {
  MarkerMap map;
  int id = 10;
  for (double x = -4.0; x <= 4.0; x += 2.0) {
    for (double y : {-3.0, 3.0}) {
      MapMarker m;
      m.is_point = true;
      m.key = {kFamilyBarcode, std::to_string(id++)};
      m.T_world_marker = SE3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(x, y, 0.0));
      map.markers.push_back(m);
    }
  }
  return map;
}

// Robot `index` drives an ellipse (radius and phase depending on index) at 0.3 m/s.
inline Dataset RangeBearingRobot(int index, unsigned seed, const RangeBearingWorldOptions& options) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  const MarkerMap landmarks = RangeBearingLandmarks();
  Dataset dataset;
  dataset.config.name = "robot" + std::to_string(index);
  dataset.config.motion = MotionModel::kPlanar;
  const double rate_hz = 20.0, v = 0.3, radius = 2.0 + 0.5 * index;
  const double w = v / radius * (index % 2 == 0 ? 1.0 : -1.0);
  SE2d T_world_true(0.0, -radius * (index % 2 == 0 ? 1.0 : -1.0), 0.0);
  std::vector<VelocitySample> commanded;
  Trajectory truth;
  const int steps = static_cast<int>(options.duration_s * rate_hz);
  double range_scale = 0.0, last_frame_s = 1000.0;
  for (int i = 0; i <= steps; ++i) {
    const double t = 1000.0 + i / rate_hz;
    truth.push_back({t, T_world_true.ToSE3()});
    // The wheels do 3 % more than commanded, with noise, the command of odometry_delay_s ago;
    // the command is what the file holds.
    const auto turn = [&](double at_s) {
      return w + options.turn_swing_rad_s * std::sin(2.0 * M_PI * (at_s - 1000.0) / 8.0);
    };
    commanded.push_back({t, v, turn(t)});
    const double w_applied = turn(std::max(1000.0, t - options.odometry_delay_s));
    const double v_true = 1.03 * v * (1.0 + 0.02 * normal(rng)), w_true = w_applied + 0.01 * normal(rng);
    T_world_true = IntegrateArc(T_world_true, v_true, w_true, 1.0 / rate_hz);
    if (i % 4 == 0 && i > 0) {
      RangeBearingFrame frame;
      frame.stamp_s = t;
      if (options.range_scale_sigma > 0.0) {
        const double phi = std::exp(-(t - last_frame_s) / options.range_scale_time_s);
        range_scale =
            phi * range_scale + std::sqrt(1.0 - phi * phi) * options.range_scale_sigma * normal(rng);
        last_frame_s = t;
      }
      const SE2d T = SE2d::FromSE3(truth.back().T);
      for (const MapMarker& m : landmarks.markers) {
        const Eigen::Vector2d p = T.inverse() * Eigen::Vector2d(m.T_world_marker.translation().head<2>());
        const double range = p.norm(), bearing = std::atan2(p.y(), p.x());
        if (range > 5.0 || std::abs(bearing) > 0.5) continue;
        RangeBearingObservation obs;
        obs.key = m.key;
        if (uniform(rng) < options.outlier_share) {
          obs.range_m = 0.5 + 4.0 * uniform(rng);
          obs.bearing_rad = -0.5 + uniform(rng);
        } else {
          const double sensed = (1.0 + options.depth_range_scale) *
                                ((1.0 - options.depth_share) * range + options.depth_share * p.x());
          obs.range_m = (1.0 + range_scale) * sensed +
                        (options.sigma_range_a_m + options.sigma_range_b * range) * normal(rng);
          obs.bearing_rad =
              WrapAngle((1.0 + options.bearing_scale) * bearing + options.sigma_bearing_rad * normal(rng));
        }
        frame.landmarks.push_back(obs);
      }
      if (!frame.landmarks.empty()) dataset.range_bearing.push_back(frame);
    }
  }
  dataset.odometry = IntegrateVelocities(commanded);
  dataset.has_odometry_file = dataset.has_range_bearing_file = true;
  dataset.groundtruth_trajectory = truth;
  dataset.groundtruth_markers = landmarks;
  if (options.start_prior) dataset.config.start_prior = StartPrior{truth.front().T, 0.01, 0.01};
  return dataset;
}

}  // namespace waymark::testing
