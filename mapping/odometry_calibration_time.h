// The correlation time of a planar robot's odometry turn scale, from mapped robots' smoothed
// trajectories against their odometry (no ground truth): the range-bearing map build writes it
// into map.json range_bearing_sensor (calibration_time_s, docs/formats.md) and `waymark localize`
// takes it as the Gauss-Markov correlation time of the EKF's odometry calibration
// (online/range_bearing_localizer.h). scripts/odometry-calibration-time.py is the same method.
//
// Per dataset, over steps of step_s seconds from the later of the two trajectories' first stamps:
// the turn of the smoothed trajectory g_i and of the odometry c_i (its stamps moved by the
// dataset's odometry_delay_s; headings unwrapped, linearly interpolated; a step whose ends fall
// outside either trajectory is skipped); the residual e_i = g_i - k c_i after the dataset's own
// constant scale k = sum g c / sum c c; the turn scale's variation's autocovariance at lag L,
//   R(L) = sum_i e_i e_{i+L} c_i c_{i+L} / sum_i (c_i c_{i+L})^2,
// pooled over the datasets (lag 0 is left out: it holds the odometry's white noise). A first-order
// Gauss-Markov turn scale of stationary sigma s and correlation time T has R(L) = s^2 exp(-L step / T).
// The fit: R(L) for L = 1 .. the last lag before the first R <= 0 (at most max_lag_s), the
// least-squares line through log R(L) weighted by R(L); T = -1 / slope, s^2 = its value at lag 0.
// No fit (fitted false) with fewer than two positive lags or a slope >= 0 (no decay: constant).
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "geometry/types.h"

namespace waymark {

struct CalibrationTimeOptions {
  double step_s = 1.0;
  double max_lag_s = 60.0;
};

// One dataset's turns over consecutive steps: index n is the step [t0 + n step, t0 + (n+1) step];
// valid false for a step that could not be measured.
struct TurnStep {
  bool valid = false;
  double smoothed = 0.0;  // g: the smoothed trajectory's turn (rad)
  double odometry = 0.0;  // c: the odometry's turn (rad)
};

struct CalibrationTimeFit {
  std::vector<double> constant_turn_scale;                // per dataset: k - 1
  std::vector<size_t> steps;                              // per dataset: the valid steps
  std::vector<std::pair<double, double>> autocovariance;  // (lag s, R) for the lags of the fit
  bool fitted = false;
  double time_s = 0.0;  // T
  double sigma = 0.0;   // s, the turn scale variation's stationary sigma
};

// The fit above from each dataset's turn steps (a dataset without a valid step is skipped).
CalibrationTimeFit FitTurnScaleCorrelation(const std::vector<std::vector<TurnStep>>& datasets,
                                           const CalibrationTimeOptions& options = {});

// The turn steps of one dataset: smoothed T_world_robot against odometry T_odom_robot whose
// stamps are moved by odometry_delay_s (the pose stamped t describes the robot at t + delay).
std::vector<TurnStep> TurnSteps(const Trajectory& smoothed, const Trajectory& odometry,
                                double odometry_delay_s, double step_s);

}  // namespace waymark
