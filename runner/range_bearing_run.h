// The range-bearing localizer (online/range_bearing_localizer.h) driven through a dataset: its
// odometry and range_bearing.jsonl merged in time order, and the filter's consistency (NEES)
// against a ground truth.
//
// The filter starts at dataset.yaml's start_prior (its sigmas as the start covariance) at the
// first odometry stamp. The odometry's stamps are moved by the noise model's odometry_delay_s (the
// pose stamped t describes the robot at t + delay; mapping/range_bearing_map.h estimates it).
// Each odometry sample predicts; each range-bearing frame is applied at its
// own stamp, the odometry interpolated there (frames outside the odometry's span are counted and
// skipped). A pose (with its covariance) is output at every odometry stamp and every frame while
// the filter is not lost; none while it is lost.
//
// NEES of an output pose against the true pose at its stamp (interpolated, within max_dt_s):
//   e = [t_true - t, wrap(theta_true - theta)],  NEES = e^T P^-1 e   (3 dof)
// Reported: the mean over the outputs, the share of outputs inside the two-sided 95 % interval of
// chi-square(3) [0.216, 9.35], and the 95 % interval of the mean of N independent chi-square(3)
// draws, [chi2inv(0.025, 3N) / N, chi2inv(0.975, 3N) / N] (consecutive outputs are correlated,
// so this interval is the stricter reading); and the same interval for the effective number of
// independent samples of the NEES series, N_eff = N / tau_int, with the integrated
// autocorrelation time (in samples, the series in output order)
//   tau_int = 1 + 2 sum_{k=1}^{K} rho_k,  rho_k = sum_i (v_i - m)(v_{i+k} - m) / sum_i (v_i - m)^2,
// summed up to K, the last lag before the first rho_k <= 0 (at most N / 2), clamped to [1, N]:
// [chi2inv(0.025, 3 N_eff) / N_eff, chi2inv(0.975, 3 N_eff) / N_eff] (a real dof). A consistent
// filter's NEES varies slowly (its errors are correlated over the time between sightings), so the
// time-averaged NEES of one run has far fewer than N independent samples; these bounds say how far
// from 3 one run's mean may be by chance.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "geometry/types.h"
#include "online/range_bearing_localizer.h"

namespace waymark {

struct RangeBearingRun {
  Trajectory poses;                          // T_world_robot while not lost
  std::vector<Eigen::Matrix3d> covariances;  // of each pose, order [x y theta]
  std::map<std::string, long> counts;        // the localizer's counts and "frames outside odometry"
  long outputs_withheld = 0;                 // instants at which the filter was lost
  long outputs_while_lost = 0;               // poses written while lost (0 by construction; checked)
  // The normalized innovation squared y^T S^-1 y of the accepted updates (2 dof): its mean over
  // them (2 when the innovations match their predicted covariance; the gate truncates it).
  double mean_nis = 0.0;
  // The filter's calibration (in the map's form, ConvertOdometryCalibration) and sensor states at the end.
  RangeBearingSensorValues final_sensor;
};

// Throws std::runtime_error when the dataset has no odometry or no start_prior.
RangeBearingRun RunRangeBearingLocalizer(const Dataset& dataset, const MarkerMap& map,
                                         const RangeBearingLocalizerOptions& options);

struct NeesResult {
  size_t samples = 0;
  double mean = 0.0;
  double share_inside = 0.0;  // of samples inside [sample_lower, sample_upper]
  double sample_lower = 0.0, sample_upper = 0.0;
  double mean_lower = 0.0, mean_upper = 0.0;
  // Accounting for the series' autocorrelation (above): tau_int in samples, N_eff, the bounds.
  double autocorrelation_time = 1.0, effective_samples = 0.0;
  double mean_lower_correlated = 0.0, mean_upper_correlated = 0.0;
  // The same split by part: the position's (2 dof) and the heading's (1 dof) NEES, each from its
  // own marginal covariance, and the share of each inside its own per-pose 95 % interval.
  double mean_position = 0.0, mean_heading = 0.0;
  double share_inside_position = 0.0, share_inside_heading = 0.0;
};

// The EKF's options as `waymark localize` defaults them from a map: the noise model when the map
// has one; with `sensor_prior` also the sensor prior (SensorPriorFromMap) and the calibration's
// correlation time when the map has them; the variance factor 1 (localize then reads the map's).
RangeBearingLocalizerOptions LocalizerOptionsFromMap(const MarkerMap& map, bool sensor_prior = true);

// The variance factor for a run not among `runs` (the leave-one-out runs of a build): each run's
// own factor f_i = mean_i / 3 (the dof), one draw per run of how much a filter of this fleet
// underrates its error, and k = exp(mean_i log f_i), their geometric mean, unweighted by the
// runs' lengths. The runs' factors spread by a ratio (MRCLAM: 1.3-12.5), and a run's mean NEES is
// judged against bounds nearly symmetric about 3 on a log scale, so k is the value whose ratio to
// a new run's factor is smallest on average (the least squares of log f_i); the pooled mean
// (sum_i mean_i n_i / (3 sum_i n_i), PooledVarianceFactor) is the factor of all the runs' poses
// together, dominated by the run that goes worst (a robot that loses its track) and above most
// runs' own. Runs with no samples are skipped; throws std::invalid_argument when no run has a
// sample or a run's mean is not positive.
double LeaveOneOutVarianceFactor(const std::vector<NeesResult>& runs);

// The pooled mean NEES over all the runs' samples divided by the dof, 3 (above; the factor of
// `waymark map build --calibrate-online` before 2026-11-27, printed beside it). Runs with no
// samples are skipped. Throws std::invalid_argument when no run has a sample.
double PooledVarianceFactor(const std::vector<NeesResult>& runs);

// The integrated autocorrelation time tau_int of a series (above; 1 for fewer than 3 values or
// a constant series).
double IntegratedAutocorrelationTime(const std::vector<double>& series);
// The 95 % interval of the mean of n independent chi-square(dof) draws, chi2inv(p, dof n) / n for
// p = 0.025, 0.975; n > 0 real (Wilson-Hilferty above 3000 degrees of freedom).
std::pair<double, double> MeanChiSquareBounds(double n, int dof);

// The NEES against the ground truth turned by truth_yaw_rad about each true pose (the heading
// compared is theta_true + truth_yaw_rad; EstimateTruthYaw). Throws std::runtime_error when no
// pose associates with the ground truth.
NeesResult ComputeNees(const Trajectory& groundtruth, const Trajectory& poses,
                       const std::vector<Eigen::Matrix3d>& covariances, double max_dt_s,
                       double truth_yaw_rad = 0.0);

// The yaw of the odometry's frame in the ground truth's body frame, from the directions of travel.
// The filter's heading is the odometry's (the odometry moves the robot along its own x axis), while
// a motion-capture body frame sits on the robot wherever its markers were put: its heading can be
// a few hundredths of a radian off the direction the robot drives in (MRCLAM: 0.003-0.017 rad), a
// constant that a NEES against the recorded heading counts as the filter's error. Over windows of
// the odometry that move >= min_travel_m in at most max_window_s while turning less than
// max_turn_rad (in the odometry and in the truth, the truth interpolated within 0.05 s), each
// chord's direction in its start frame, turned back by half the window's turn (the direction at its
// middle), is compared: e = wrap(direction_truth - direction_odometry), windows with |e| > 0.5 rad
// dropped (a truth that stands while the odometry moves); the yaw is the median of e and its
// spread 1.4826 times the median absolute deviation. Windows do not overlap. Stamps as given (the
// odometry's delay does not turn a straight chord). nullopt with fewer than min_windows windows.
struct TruthYawEstimate {
  double yaw_rad = 0.0;  // add to the truth's heading to get the odometry's
  double spread_rad = 0.0;
  size_t windows = 0;
};
struct TruthYawOptions {
  double min_travel_m = 0.05;
  double max_window_s = 2.0;
  double max_turn_rad = 0.05;
  size_t min_windows = 20;
};
std::optional<TruthYawEstimate> EstimateTruthYaw(const Trajectory& groundtruth, const Trajectory& odometry,
                                                 const TruthYawOptions& options = {});

}  // namespace waymark
