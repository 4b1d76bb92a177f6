// Point-landmark maps from range-bearing observations of one or several planar datasets (robots,
// or survey days in one building), tied through the landmarks they share.
//
//   minimize  sum_obs rho(|r_rb|^2) + sum_links |r_odo|^2 + sum_robots |r_cal|^2 + sum_starts |r_start|^2
//
// r_rb:    range and bearing of a landmark from a robot node (factors/range_bearing_factor.h),
//          sigma_range = a + b * range and sigma_bearing, estimated from the data (below) unless
//          the observation carries its own sigmas, with the sensor's constant range and bearing
//          offsets and its bearing scale error estimated per dataset (BiasedRangeBearingFactor,
//          weak prior);
// r_odo:   the odometry between consecutive nodes of one dataset with its systematic errors
//          (factors/calibrated_odometry_factor.h; one calibration block per dataset, r_cal its
//          weak prior), covariance of a random walk in distance, turn and time:
//            sigma_t^2 = q_t (d + d0),  sigma_theta^2 = q_r (|dtheta| + c_d d + th0)
//          with d0 = 1 mm and th0 = 1 mrad per link so that a standstill is not infinitely certain;
// r_start: dataset.yaml start_prior of each dataset (when use_start_priors).
// Nodes: one per range-bearing stamp and at least every keyframe_interval_s, at odometry poses
// interpolated at the stamp. Gauge: the start priors; without them the first dataset's first node
// is held at the identity and every other dataset is placed, when it first shares two landmarks
// with the map, by a rigid 2-D fit of its dead-reckoned landmark positions to the mapped ones.
//
// Stages: (1) incremental solves over growing time windows (window_s): new nodes are predicted
// by the calibrated odometry from the last solved node, new landmarks placed from their first
// observation; Cauchy loss (cauchy_scale, whitened units). (2) noise_rounds rounds of: the range
// sigma line a + b r is fitted to the robust spread (1.4826 MAD) of the range residuals of every
// observation in range bins, the bearing sigma to that of the bearing residuals; observations
// whose whitened squared bearing residual exceeds outlier_chi2_1dof are set aside as outliers, and
// of the others those whose whitened squared range residual exceeds it keep their bearing alone
// (BiasedBearingFactor; separate_range_outliers, else one 2-dof test against outlier_chi2); from
// the second round on (redundancy_noise) the measurement sigmas come instead from each residual
// group's sum of squares over its redundancy (variance components: sum (1 - h_r) with h_r each
// row's leverage, mapping/marginal_covariance.h), since the fitted poses absorb part of every
// residual and the plain spreads come out too small; q_t, q_r are
// scaled so that the odometry's disagreement with the solved trajectory over windows of noise_window_s
// matches the model; solve again. (2b) the odometry's delay behind the measurements (commanded velocities
// lead the motion; RangeBearingNoise::odometry_delay_s), per dataset: nodes take the odometry at stamp -
// delay; the delay minimizes the dataset's own cost over a grid in
// [-max_odometry_delay_s, max_odometry_delay_s] (every grid delay re-solved), refined by a
// parabola, kept when a likelihood-ratio test (1 dof, 95 %) prefers it to 0; one more round of (2) follows.
// (3) a final solve with the plain squared loss; landmarks seen fewer than min_observations times are
// reported, not mapped. (3b) The landmarks' covariance from the final problem (below). (4) The range error
// common to the landmarks of one frame (RangeBearingNoise::range_scale_sigma and range_scale_time_s, for the
// EKF) from the final residuals (range_bearing_map.cc, EstimateRangeScale). (5) The correlation time of
// the odometry's turn scale variation from the smoothed trajectories against the odometry
// (mapping/odometry_calibration_time.h; the EKF's odometry calibration as a Gauss-Markov process).
//
// Sensor model (map.json range_bearing_sensor, docs/formats.md): each dataset's sensor offsets and
// scales (range offset, bearing offset, bearing scale, depth share, range scale), its odometry
// calibration and its noise as estimated; and, for a robot that is not in the map (the online
// localizer's prior, online/range_bearing_localizer.h), each entry's mean over the datasets and
// the spread of a new draw from them: the normal sigma whose 95 % interval is the Student-t
// predictive interval of a new draw, s sqrt(1 + 1/N) t_0.975(N - 1) / 1.96 (s the datasets' sample
// standard deviation, N their number; three robots: 2.5 s), capped at the build's own prior sigma
// for it (and that sigma with N < 2); an entry the build held (the depth share and range scale of
// the distance model) has mean and sigma 0.
//
// Landmark covariance (3b): Sigma = the landmarks' block of H^-1, H = J^T J of the final problem
// (squared loss) over every free block (nodes, landmarks, calibrations, sensor offsets and scales),
// in the gauge of the start priors (else of the held first node); H^-1 B by the sparse LDL^T of
// mapping/marginal_covariance.h (B selecting the 2 N landmark columns). Each landmark's 2 x 2 block
// is its position_covariance (z row and column 0: a planar map); the top k = min(covariance_rank,
// 2 N) eigenpairs of Sigma give F = V_k Lambda_k^(1/2), each landmark's two rows of F its
// position_covariance_factor (z row 0): the landmarks' errors are correlated (they share the
// surveying robots' trajectories), and a filter that takes them as independent grows overconfident
// (online/range_bearing_localizer.h).
#pragma once

#include <functional>
#include <map>
#include <string>
#include <vector>

#include "geometry/types.h"
#include "mapping/odometry_calibration_time.h"

namespace waymark {

struct RangeBearingBuildOptions {
  double keyframe_interval_s = 0.5;
  double window_s = 60.0;
  double cauchy_scale = 3.0;
  double outlier_chi2 = 13.8;  // 2 degrees of freedom, 99.9 %
  // Range and bearing tested apart (chi-square 1 dof, 99.9 %): a range outlier keeps its bearing.
  bool separate_range_outliers = true;
  double outlier_chi2_1dof = 10.83;
  int min_observations = 3;
  int noise_rounds = 3;
  // Stage (2) from the second round on: each noise group's variance from its residuals and their
  // redundancy (variance components, range_bearing_map.cc EstimateNoiseByRedundancy), not from
  // their robust spread alone (which the fitted poses shrink).
  bool redundancy_noise = true;
  double noise_window_s = 5.0;
  bool use_start_priors = true;
  double calibration_sigma = 0.2;
  // The sensor's constant range and bearing offsets, one pair per dataset, held near 0 by a
  // prior of these sigmas (factors/range_bearing_factor.h, BiasedRangeBearingFactor).
  double sensor_bias_sigma_m = 0.2;
  double sensor_bias_sigma_rad = 0.05;
  // The sensor's bearing scale error (BiasedRangeBearingFactor), one per dataset, held near 0 by a
  // prior of this sigma.
  double sensor_bearing_scale_sigma = 0.1;
  // The sensor's depth share c_depth and range scale error s_range (BiasedRangeBearingFactor:
  // range read as (1 + s_range) ((1 - c_depth) distance + c_depth depth), depth = distance
  // cos(bearing)), one each per dataset, held near 0 by weak priors of these sigmas; 0 = held at
  // 0 (both 0, the default: the distance model). `waymark map build --depth-ranges`: 1 and 0.1,
  // with odometry_measurement_space.
  double sensor_depth_share_sigma = 0.0;
  double sensor_range_scale_sigma = 0.0;
  // The odometry's translation error whitened in the measurement's units (times 1 +
  // distance_scale; factors/calibrated_odometry_factor.h): the cost is then the same for the
  // whole map scaled with the range and distance scales, and a free range scale is not pulled
  // short. False (default): in the corrected increment's units.
  bool odometry_measurement_space = false;

  // Stage (2b): the odometry delay's search range and grid step; 0 = no delay estimated.
  double max_odometry_delay_s = 0.5;
  double odometry_delay_step_s = 0.1;
  RangeBearingNoise initial_noise;  // the starting point of the estimation (stage 2)
  // Stage (3b): each mapped landmark's position covariance and the rank-k factor of their joint
  // covariance (map.json position_covariance, position_covariance_factor); the joint covariance
  // (and so the factor) only for at most max_joint_covariance_landmarks landmarks.
  bool landmark_covariance = true;
  int covariance_rank = 20;
  int max_joint_covariance_landmarks = 500;
  // Stage (5): the odometry calibration's correlation time (map.json range_bearing_sensor
  // calibration_time_s; mapping/odometry_calibration_time.h, steps of calibration_time_step_s,
  // lags up to calibration_time_max_lag_s); false: not estimated (the key absent).
  bool calibration_time = true;
  double calibration_time_step_s = 1.0;
  double calibration_time_max_lag_s = 60.0;
  int max_iterations = 50;
  int num_threads = 1;
  std::function<void(const std::string&)> progress;
  bool Check(std::string* why) const;
};

struct RangeBearingDatasetSummary {
  std::string name;
  size_t nodes = 0;
  size_t observations = 0;  // range-bearing observations of landmarks used in the final solve
  size_t outliers = 0;
  size_t range_outliers = 0;  // observations whose range was set aside and bearing kept (in `observations`)
  Eigen::Vector3d odometry_calibration = Eigen::Vector3d::Zero();
  Eigen::Vector2d sensor_bias = Eigen::Vector2d::Zero();  // range offset (m), bearing offset (rad)
  double bearing_scale = 0.0;  // the sensor's bearing scale error (bearings read 1 + this times too large)
  double depth_share = 0.0;    // c_depth (0 unless estimated)
  double range_scale = 0.0;    // s_range (0 unless estimated)
  RangeBearingNoise noise;     // this dataset's, as estimated (odometry_delay_s: its own)
  std::string gauge;           // "start prior", "held", "placed at t=..."
};

struct RangeBearingBuildResult {
  MarkerMap map;                                   // point landmarks, component 0
  std::map<std::string, Trajectory> trajectories;  // smoothed T_world_robot per dataset name
  std::vector<RangeBearingDatasetSummary> datasets;
  RangeBearingNoise noise;  // as estimated over all datasets (odometry and delay: the datasets' median)
  std::vector<std::pair<MarkerKey, std::string>> unmapped;
  size_t observations = 0;
  size_t outliers = 0;
  size_t range_outliers = 0;  // set aside for their range only, their bearing used (in `observations`)
  double range_rms_m = 0.0;   // residuals of the inliers, final solve
  double bearing_rms_rad = 0.0;
  double solver_time_s = 0.0;
  std::vector<std::string> notes;
  CalibrationTimeFit calibration_time;  // stage (5); fitted false when not estimated or no fit
};

// True when some dataset has range-bearing observations (the map build then uses this builder).
bool HasRangeBearing(const std::vector<const Dataset*>& datasets);

// Throws std::runtime_error for unusable input: a dataset without odometry, a non-planar one, a
// dataset that shares fewer than two landmarks with the others when it has no start prior.
RangeBearingBuildResult BuildRangeBearingMap(const std::vector<const Dataset*>& datasets,
                                             const RangeBearingBuildOptions& options = {});

}  // namespace waymark
