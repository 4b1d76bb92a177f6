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

// The variance factor that makes the NEES of several runs consistent on average: the pooled mean
// NEES over all their samples divided by the dof, 3 (sum_i mean_i n_i / (3 sum_i n_i)); runs with
// no samples are skipped. Throws std::invalid_argument when no run has a sample.
double PooledVarianceFactor(const std::vector<NeesResult>& runs);

// The integrated autocorrelation time tau_int of a series (above; 1 for fewer than 3 values or
// a constant series).
double IntegratedAutocorrelationTime(const std::vector<double>& series);
// The 95 % interval of the mean of n independent chi-square(dof) draws, chi2inv(p, dof n) / n for
// p = 0.025, 0.975; n > 0 real (Wilson-Hilferty above 3000 degrees of freedom).
std::pair<double, double> MeanChiSquareBounds(double n, int dof);

// Throws std::runtime_error when no pose associates with the ground truth.
NeesResult ComputeNees(const Trajectory& groundtruth, const Trajectory& poses,
                       const std::vector<Eigen::Matrix3d>& covariances, double max_dt_s);

}  // namespace waymark
