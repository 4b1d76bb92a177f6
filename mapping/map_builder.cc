#include "mapping/map_builder.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "mapping/boards.h"
#include "mapping/global_problem.h"
#include "mapping/outlier_rejection.h"
#include "mapping/residuals.h"
#include "util/check.h"
#include "util/format.h"
#include "util/stats.h"

namespace waymark {
namespace {

void FillReprojection(const Survey& survey, const GlobalProblem& problem, const std::vector<int>& kept,
                      MapBuildResult* result) {
  std::map<std::string, std::vector<double>> per_camera;  // squared px per observation (sum over its corners)
  for (int o : kept) {
    const SurveyObservation& obs = survey.observations[o];
    const double sigma = CornerSigmaPx(survey.cameras.at(obs.camera));
    per_camera[obs.camera].push_back(problem.SquaredError(o) * sigma * sigma);
  }
  for (auto& [camera, squares] : per_camera) {
    double sum = 0.0;
    std::vector<double> rms;  // per observation
    for (double s : squares) {
      sum += s;
      rms.push_back(std::sqrt(s / 4.0));
    }
    std::sort(rms.begin(), rms.end());
    const size_t n = rms.size();
    result->reprojection.push_back({camera, n, std::sqrt(sum / (4.0 * n)), QuantileOfSorted(rms, 0.5)});
  }
}

void FillOutputs(const Survey& survey, const Initialization& init, const GlobalProblem& problem,
                 const std::vector<int>& kept, const std::vector<std::string>& gauges,
                 MapBuildResult* result) {
  std::set<int> mapped;
  std::vector<std::set<int>> component_frames(init.components);
  for (int o : kept) {
    mapped.insert(survey.observations[o].marker);
    component_frames[init.frame_component[survey.observations[o].frame]].insert(survey.observations[o].frame);
  }
  for (int m : mapped) {
    MapMarker marker;
    marker.key = survey.markers[m].key;
    marker.size_m = survey.markers[m].size_m;
    marker.T_world_marker = problem.Marker(m);
    marker.fixed = survey.markers[m].known && survey.markers[m].known->fixed;
    marker.square_tape = survey.markers[m].square_tape;
    marker.component = init.marker_component[m];
    result->map.markers.push_back(marker);
  }
  // Each board with a mapped code, with those codes (the others are not in the map).
  for (size_t b = 0; b < survey.boards.size(); ++b) {
    MapBoard board;
    board.name = survey.boards[b].name;
    for (int m : survey.boards[b].markers) {
      if (mapped.count(m) == 0 || !problem.BoardPlaced(static_cast<int>(b))) continue;
      board.members.push_back({survey.markers[m].key, survey.markers[m].T_board_marker});
      board.component = init.marker_component[m];
    }
    if (board.members.empty()) continue;
    board.has_pose = true;
    board.T_world_board = problem.Board(static_cast<int>(b));
    board.fixed = survey.boards[b].fixed_pose.has_value();
    result->map.boards.push_back(board);
  }
  for (int c = 0; c < init.components; ++c) {
    ComponentSummary summary;
    summary.component = c;
    summary.markers =
        std::count_if(mapped.begin(), mapped.end(), [&](int m) { return init.marker_component[m] == c; });
    summary.frames = component_frames[c].size();
    summary.gauge = gauges[c];
    result->components.push_back(summary);
  }
  result->trajectories.assign(init.components, Trajectory());
  for (size_t f = 0; f < survey.frames.size(); ++f) {
    const int c = init.frame_component[f];
    if (c >= 0 && problem.FramePlaced(static_cast<int>(f))) {
      result->trajectories[c].push_back({survey.frames[f].stamp_s, problem.Robot(static_cast<int>(f))});
    }
  }
  for (ComponentSummary& summary : result->components) {
    summary.trajectory_poses = result->trajectories[summary.component].size();
  }
  if (!result->trajectories.empty()) result->trajectory = result->trajectories[0];
}

}  // namespace

bool MapBuildOptions::Check(std::string* why) const {
  WAYMARK_CHECK_OPTION(ingest.Check(why) && id_check.Check(why), nullptr);
  WAYMARK_CHECK_OPTION(IsFinitePositive(calibration_sigma), "calibration_sigma must be finite and > 0");
  WAYMARK_CHECK_OPTION(
      IsFinitePositive(cauchy_scale) && IsFinitePositive(outlier_chi2) && IsFinitePositive(payload_sigma_m) &&
          IsFinitePositive(payload_yaw_sigma_rad),
      "cauchy_scale, outlier_chi2, payload_sigma_m and payload_yaw_sigma_rad must be finite and > 0");
  WAYMARK_CHECK_OPTION(!odometry_calibration || calibrate_odometry,
                       "a given odometry calibration needs calibrate_odometry");
  WAYMARK_CHECK_OPTION(!odometry_calibration || OdometryCalibrationValid(*odometry_calibration),
                       kOdometryCalibrationRule);
  WAYMARK_CHECK_OPTION(
      !odometry_calibration_sigma ||
          (odometry_calibration && OdometryCalibrationSigmaValid(*odometry_calibration_sigma)),
      "odometry_calibration_sigma needs odometry_calibration, and must be three finite numbers > 0");
  WAYMARK_CHECK_OPTION(replace_rounds >= 0, "replace_rounds must be >= 0");
  WAYMARK_CHECK_OPTION(odometry_noise_rounds >= 0 && odometry_noise_threshold >= 1.0 &&
                           std::isfinite(odometry_noise_threshold) && max_odometry_variance_scale >= 1.0 &&
                           std::isfinite(max_odometry_variance_scale),
                       "odometry_noise_rounds must be >= 0, odometry_noise_threshold and "
                       "max_odometry_variance_scale finite and >= 1");
  WAYMARK_CHECK_OPTION(min_frames >= 1 && max_iterations >= 1 && num_threads >= 1,
                       "min_frames, max_iterations and num_threads must be >= 1");
  return true;
}

MapBuildResult BuildMap(const Dataset& dataset, const MapBuildOptions& options) {
  std::vector<PhaseTime> ingest;
  PhaseClock clock(&ingest);
  const Survey survey = IngestDataset(dataset, options.ingest);
  clock.Lap("ingest");
  MapBuildResult result = BuildMapFromSurvey(survey, options);
  result.phases.insert(result.phases.begin(), ingest.begin(), ingest.end());
  for (const auto& [reason, count] : dataset.warnings.counts) {
    result.notes.push_back("input: " + std::to_string(count) + " x " + reason);
  }
  return result;
}

MapBuildResult BuildMapFromSurvey(const Survey& survey, const MapBuildOptions& options) {
  std::string why;
  if (!options.Check(&why)) throw std::runtime_error("map build options: " + why);
  const auto progress = [&](const std::string& line) {
    if (options.progress) options.progress(line);
  };
  MapBuildResult result;
  result.frames = survey.frames.size();
  result.notes = survey.notes;
  progress("initializing " + std::to_string(survey.frames.size()) + " frames, " +
           std::to_string(survey.markers.size()) + " codes, " + std::to_string(survey.observations.size()) +
           " observations");
  const auto start = std::chrono::steady_clock::now();
  PhaseClock clock(&result.phases);
  std::vector<int> inconsistent;
  if (options.check_ids) inconsistent = FindInconsistentIds(survey, MakeCameras(survey), options.id_check);
  clock.Lap("id check");
  for (int o : inconsistent) {
    const SurveyObservation& obs = survey.observations[o];
    result.outliers.push_back(
        {survey.markers[obs.marker].key, survey.frames[obs.frame].stamp_s, obs.camera, 0.0,
         "id inconsistent with the code's other views along the odometry (misdecoded?)"});
  }
  const Survey checked = WithoutObservations(survey, inconsistent);
  InitializerOptions initializer = options.initializer;
  if (options.calibrate_odometry && options.odometry_calibration) {
    initializer.graph.given_calibration = options.odometry_calibration;
    initializer.graph.given_calibration_sigma = options.odometry_calibration_sigma;
  }
  Initialization init = Initialize(checked, initializer);
  result.phases.insert(result.phases.end(), init.phases.begin(), init.phases.end());
  result.notes.insert(result.notes.end(), init.notes.begin(), init.notes.end());  // local maps, links
  if (const int joined = JoinBoardComponents(checked, &init); joined > 0) {
    result.notes.push_back(std::to_string(joined + 1) +
                           " groups of codes that share no observation are one map: codes of one board");
  }
  const std::vector<std::string> boards = DescribeBoards(checked);
  result.notes.insert(result.notes.end(), boards.begin(), boards.end());
  result.init_time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return OptimizeSurvey(checked, init, options, std::move(result));
}

MapBuildResult OptimizeSurvey(const Survey& survey, const Initialization& init,
                              const MapBuildOptions& options, MapBuildResult result) {
  const auto progress = [&](const std::string& line) {
    if (options.progress) options.progress(line);
  };
  GlobalProblem problem(survey, init, options);
  const std::vector<int> active = UsableObservations(survey, init, &result);
  std::vector<std::string> gauges;
  const auto start = std::chrono::steady_clock::now();
  PhaseClock clock(&result.phases);
  // A corner behind its camera at the current values only gets a finite penalty
  // (factors/corner_observation.h), which would drag the solve: such observations (a
  // misdecoded id, a wrong placement) are set aside for the solve that follows.
  const auto in_front = [&](const std::vector<int>& observations) {
    std::vector<int> kept;
    for (int o : observations) {
      if (std::isfinite(problem.SquaredError(o))) kept.push_back(o);
    }
    return kept;
  };
  const auto record = [&](const std::string& stage, const ceres::Solver::Summary& summary) {
    result.solves.push_back({stage, static_cast<int>(summary.iterations.size()),
                             summary.total_time_in_seconds, summary.linear_solver_time_in_seconds,
                             summary.jacobian_evaluation_time_in_seconds,
                             summary.residual_evaluation_time_in_seconds});
  };
  ceres::Solver::Summary robust = problem.Solve(in_front(active), true, &gauges);
  record("robust", robust);
  clock.Lap("robust solve");
  int iterations = static_cast<int>(robust.iterations.size());
  // An odometry noise model that understates the odometry's real noise (a drifting VIO given a
  // wheel odometry's figures) would let the odometry override consistent corners, which the
  // gate below would then reject. The odometry's own residuals after the robust solve measure
  // it: when their variance per degree of freedom is well above the stated one, the odometry's
  // covariance is scaled by it and the robust solve repeated (a variance component estimate;
  // never scaled down: the estimate is biased low).
  for (int round = 0; round < options.odometry_noise_rounds; ++round) {
    const double factor = problem.OdometryVarianceFactor();
    if (!(factor > options.odometry_noise_threshold)) break;
    problem.SetOdometryVarianceScale(std::min(factor, options.max_odometry_variance_scale));
    robust = problem.Solve(in_front(active), true, &gauges);
    record("robust with the odometry noise scaled", robust);
    iterations += static_cast<int>(robust.iterations.size());
    if (factor >= options.max_odometry_variance_scale) break;
  }
  if (problem.OdometryVarianceScale() != 1.0) {
    result.odometry_noise_scale = std::sqrt(problem.OdometryVarianceScale());
    result.notes.push_back(
        "odometry noise estimated from the data: " + FormatSignificant(*result.odometry_noise_scale, 3) +
        " x the stated odometry_sigma (its residuals after the robust solve)");
  }
  const std::map<std::string, Camera> cameras = MakeCameras(survey);
  for (int round = 0; round < options.replace_rounds; ++round) {
    const size_t moved = problem.ReplaceOutlyingMarkers(active, cameras);
    if (moved == 0) break;
    progress("re-placed " + std::to_string(moved) + " code(s) with outlying views");
    const double first_cost = robust.initial_cost;
    robust = problem.Solve(in_front(active), true, &gauges);
    record("robust after re-placing", robust);
    robust.initial_cost = first_cost;
    iterations += static_cast<int>(robust.iterations.size());
  }
  const std::vector<int> kept = RejectOutliers(
      survey, problem, RemoveDuplicateCodes(survey, init, problem, active, &result), options, &result);
  clock.Lap("re-placing and outliers");
  const ceres::Solver::Summary final_summary = problem.Solve(kept, false, &gauges);
  record("final", final_summary);
  clock.Lap("final solve");
  result.solver_time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  result.iterations = iterations + static_cast<int>(final_summary.iterations.size());
  result.termination = ceres::TerminationTypeToString(final_summary.termination_type) + std::string(": ") +
                       final_summary.message;
  result.observations = kept.size();
  result.initial_cost = robust.initial_cost;
  result.final_cost = final_summary.final_cost;
  result.odometry_calibration = problem.Calibration();
  result.odometry_calibration_given = result.odometry_calibration && !problem.CalibrationEstimated();
  for (const auto& [name, T_robot_camera] : problem.Mounts()) {
    result.mounts.push_back({name, survey.cameras.at(name).T_robot_camera, T_robot_camera, std::nullopt});
  }
  for (const auto& [name, deviations] : problem.Wiggles()) {
    CameraWiggleSummary w;
    w.camera = name;
    w.frames = deviations.size();
    for (const SE3d& W : deviations) {
      const Vector6d delta = SE3d().BoxMinus(W);
      w.rms_rad += delta.head<3>().squaredNorm();
      w.rms_m += delta.tail<3>().squaredNorm();
      w.max_rad = std::max(w.max_rad, delta.head<3>().norm());
      w.max_m = std::max(w.max_m, delta.tail<3>().norm());
    }
    w.rms_rad = std::sqrt(w.rms_rad / std::max<size_t>(1, w.frames));
    w.rms_m = std::sqrt(w.rms_m / std::max<size_t>(1, w.frames));
    result.wiggles.push_back(w);
  }
  FillReprojection(survey, problem, kept, &result);
  FillOutputs(survey, init, problem, kept, gauges, &result);
  clock.Lap("outputs");
  if (options.compute_covariance) {
    progress("marker covariances");
    const auto covariance_start = std::chrono::steady_clock::now();
    std::vector<std::optional<Matrix6d>> covariance;
    std::vector<std::optional<CovarianceFactor>> factors;
    std::map<std::string, Matrix6d> mount_covariance;
    std::vector<std::optional<Matrix6d>> board_covariance;
    result.covariance_computed =
        problem.Covariances(options.covariance_factor_rank, &covariance, &factors,
                            &result.odometry_calibration_covariance, &mount_covariance, &board_covariance);
    if (result.covariance_computed) {
      for (CameraMountEstimate& mount : result.mounts) {
        if (const auto it = mount_covariance.find(mount.camera); it != mount_covariance.end())
          mount.covariance = it->second;
      }
      for (MapMarker& marker : result.map.markers) {
        const int m = survey.FindMarker(marker.key);
        marker.covariance = covariance[m];
        marker.covariance_factor = factors[m];
      }
      for (MapBoard& board : result.map.boards) {
        const int b = survey.markers[survey.FindMarker(board.members.front().key)].board;
        board.covariance = board_covariance[b];
      }
    } else {
      result.notes.push_back("marker covariances could not be computed (rank-deficient problem)");
    }
    result.covariance_time_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - covariance_start).count();
    clock.Lap("covariance");
  }
  return result;
}

}  // namespace waymark
