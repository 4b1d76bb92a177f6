// Map learning: one global optimization over every marker pose and every frame's robot pose.
//
//   minimize  sum_obs rho(|r_obs|^2) + sum_links |r_odo|^2 + sum_priors |r_prior|^2
//
// r_obs:   corner reprojection of a code in an image (factors/marker_reprojection_factor.h,
//          planar_marker_reprojection_factor.h), whitened by the camera's pixel_sigma;
// r_odo:   odometry between consecutive frames (factors/odometry_se2_factor.h / _se3_factor.h)
//          with the covariance of mapping/survey.h, by default with the odometry's systematic
//          errors estimated alongside (factors/calibrated_odometry_factor.h);
// r_prior: anchors of markers.json held fixed (`fixed`) or by a pose prior (a `covariance`);
//          payload coordinates as position priors (payload_sigma_m) and yaw priors.
// Gauge, per component: anchors, else payload priors (>= 2 positions for planar surveys;
// >= 3 for free ones, whose height is then held by a weak prior on the first frame's z), else
// the component's first frame is held constant.
//
// Stages: (1) initialization (mapping/initializer.h); (2) solve with the Cauchy loss
// rho(s) = c^2 log(1 + s / c^2) (misdecoded ids, planar flips), repeated after re-placing codes
// with outlying views by consensus (replace_rounds); (3) observations whose whitened
// squared error exceeds outlier_chi2 are outliers, reported and removed, and codes left with
// fewer than min_frames frames are reported and not mapped; (4) solve again with the plain
// squared loss; (5) marker covariances, the marker blocks of H^-1 with H = J^T J of the final
// problem (mapping/marginal_covariance.h: selected inverse, linear in the survey; equal to
// ceres::Covariance), converted from the manifold's tangent to map.json's right perturbation
// [rx ry rz tx ty tz] (factors/pose_block.h).
#pragma once

#include <Eigen/Core>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "geometry/types.h"
#include "mapping/build_stats.h"
#include "mapping/id_consistency.h"
#include "mapping/initializer.h"
#include "mapping/survey.h"

namespace waymark {

struct MapBuildOptions {
  IngestOptions ingest;
  InitializerOptions initializer;
  // Views whose id disagrees with the code's other views along the odometry are set aside
  // before initialization and reported (mapping/id_consistency.h).
  bool check_ids = true;
  IdCheckOptions id_check;
  double cauchy_scale = 3.0;   // whitened units (sigmas)
  double outlier_chi2 = 40.0;  // on the 8 whitened residuals of one observation
  // After the robust solve, codes with outlying views are re-placed by consensus at the solved
  // frame poses and the robust solve repeated, up to this many times.
  int replace_rounds = 2;
  // After the robust solve, when the odometry's whitened residuals have a variance per degree
  // of freedom above odometry_noise_threshold (in units of the stated odometry_sigma), the
  // odometry's covariance is scaled by it (at most max_odometry_variance_scale) and the robust
  // solve repeated, up to this many times (0: the stated model is taken as is).
  int odometry_noise_rounds = 3;
  double odometry_noise_threshold = 2.0;
  double max_odometry_variance_scale = 1e4;
  int min_frames = 2;  // codes seen in fewer frames are reported, not mapped
  double payload_sigma_m = 0.01;
  double payload_yaw_sigma_rad = 0.02;
  // Estimate the odometry's systematic errors with the map (factors/calibrated_odometry_factor.h),
  // held near 0 by a prior of this sigma.
  bool calibrate_odometry = true;
  double calibration_sigma = 0.05;
  // The calibration known already (e.g. MapBuildResult::odometry_calibration of an earlier survey
  // by the same robot): held at this value, in the initialization too, instead of estimated;
  // with odometry_calibration_sigma, the mean of its prior instead (the survey refines it).
  // Needs calibrate_odometry.
  std::optional<Eigen::Vector3d> odometry_calibration;
  std::optional<Eigen::Vector3d> odometry_calibration_sigma;
  int max_iterations = 200;
  int num_threads = 1;  // Jacobian evaluation, linear solver, covariance Jacobian
  bool compute_covariance = true;
  // Columns k of each marker's covariance_factor (mapping/map_covariance.h); 0: none.
  int covariance_factor_rank = 20;
  std::function<void(const std::string&)> progress;  // progress lines, if set
  bool Check(std::string* why) const;
};

struct RejectedObservation {
  MarkerKey key;
  double stamp_s = 0.0;
  std::string camera;
  double rms_px = 0.0;  // after the robust solve; 0 when rejected before it
  std::string reason;
};

struct UnmappedMarker {
  MarkerKey key;
  std::string reason;
};

struct CameraReprojection {
  std::string camera;
  size_t observations = 0;
  double rms_px = 0.0;     // over corners
  double median_px = 0.0;  // of the observations' RMS (as waymark map score)
};

struct ComponentSummary {
  int component = 0;
  size_t markers = 0;
  size_t frames = 0;            // seeing a mapped code
  size_t trajectory_poses = 0;  // in the smoothed trajectory (odometry-only frames too)
  std::string gauge;
};

// One Ceres solve of stages (2) and (4), where its time went (Ceres' summary).
struct SolveStageSummary {
  std::string stage;  // "robust", "robust after re-placing", "final"
  int iterations = 0;
  double total_s = 0.0;
  double linear_solver_s = 0.0;
  double jacobian_s = 0.0;  // Jacobian and residual evaluations
  double residual_s = 0.0;  // residual-only evaluations
};

// A camera mount estimated by the build (extrinsic self-calibration: the camera file gives
// T_robot_camera_sigma): the file's mount, the estimate and, with the covariances computed,
// the estimate's covariance in its body tangent [r, t] (geometry/pose.h).
struct CameraMountEstimate {
  std::string camera;
  SE3d given;
  SE3d estimated;
  std::optional<Matrix6d> covariance;
};

// The per-frame deviations of a camera off its mount (frame_wiggle_sigma) the build estimated:
// how many frames, their RMS rotation and translation, the largest.
struct CameraWiggleSummary {
  std::string camera;
  size_t frames = 0;
  double rms_rad = 0.0, rms_m = 0.0, max_rad = 0.0, max_m = 0.0;
};

struct MapBuildResult {
  MarkerMap map;
  Trajectory trajectory;                 // smoothed T_world_robot of the frames of component 0
  std::vector<Trajectory> trajectories;  // per component c, in its own world frame (c = index)
  std::vector<ComponentSummary> components;
  std::vector<CameraReprojection> reprojection;
  std::vector<RejectedObservation> outliers;
  std::vector<UnmappedMarker> unmapped;
  size_t frames = 0;
  size_t observations = 0;     // used in the final solve
  double initial_cost = 0.0;   // of the robust solve
  double final_cost = 0.0;     // of the final solve (half the sum of squares)
  double init_time_s = 0.0;    // id check and initialization
  double solver_time_s = 0.0;  // robust and final solves, outlier stages
  double covariance_time_s = 0.0;
  int iterations = 0;
  std::vector<SolveStageSummary> solves;  // in the order they ran
  // Every phase of the build (mapping/build_stats.h): ingest, id check, the initializer's
  // phases, solves, outlier stages, covariance; with the process's peak memory.
  std::vector<PhaseTime> phases;
  std::string termination;  // Ceres' final termination type and message
  bool covariance_computed = false;
  // The odometry's systematic errors c = [k_rad_per_m, turn_scale, distance_scale]
  // (factors/calibrated_odometry_factor.h) of the final solve: estimated (from a given prior or
  // the default one), or held as given (odometry_calibration_given); nullopt when
  // calibrate_odometry is off or no odometry link entered the problem. The covariance of an
  // estimate, when the covariances were computed.
  std::optional<Eigen::Vector3d> odometry_calibration;
  bool odometry_calibration_given = false;
  std::optional<Eigen::Matrix3d> odometry_calibration_covariance;
  // The factor by which the build scaled the stated odometry noise (sigma, not variance), when
  // the odometry's residuals showed it understated (MapBuildOptions::odometry_noise_rounds).
  std::optional<double> odometry_noise_scale;
  std::vector<CameraMountEstimate> mounts;   // by camera name
  std::vector<CameraWiggleSummary> wiggles;  // by camera name
  std::vector<std::string> notes;
};

// Throws std::runtime_error for bad input (see mapping/survey.h) or options.
MapBuildResult BuildMap(const Dataset& dataset, const MapBuildOptions& options = {});
MapBuildResult BuildMapFromSurvey(const Survey& survey, const MapBuildOptions& options = {});

// Stages (2) to (5) from a given initialization (e.g. one built by hand in a test); `result`
// carries what earlier stages reported.
MapBuildResult OptimizeSurvey(const Survey& survey, const Initialization& init,
                              const MapBuildOptions& options, MapBuildResult result = {});

}  // namespace waymark
