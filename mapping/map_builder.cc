#include "mapping/map_builder.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <ostream>
#include <set>
#include <sstream>

#include <ceres/ceres.h>
#include <ceres/covariance.h>

#include "factors/odometry_se2_factor.h"
#include "mapping/calibrated_odometry_factor.h"
#include "mapping/marginal_covariance.h"
#include "mapping/map_covariance.h"
#include "factors/odometry_se3_factor.h"
#include "factors/pose_prior_se3_factor.h"
#include "factors/position_prior_factor.h"
#include "factors/yaw_prior_factor.h"
#include "mapping/residuals.h"

namespace waymark {
namespace {

std::string Num(double value, int precision = 4) {
  std::ostringstream out;
  out.precision(precision);
  out << value;
  return out.str();
}

// Levenberg-Marquardt's first trust region (see GlobalProblem::Solve).
constexpr double kInitialTrustRegionRadius = 1e12;

// Forwards Ceres iterations to the progress callback.
class ProgressCallback : public ceres::IterationCallback {
 public:
  ProgressCallback(const std::function<void(const std::string&)>& progress, std::string stage)
      : progress_(progress), stage_(std::move(stage)) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& s) override {
    progress_(stage_ + ": iteration " + std::to_string(s.iteration) + ", cost " + Num(s.cost, 8));
    return ceres::SOLVER_CONTINUE;
  }

 private:
  const std::function<void(const std::string&)>& progress_;
  std::string stage_;
};

// The global problem over the placed frames and markers of a survey.
class GlobalProblem {
 public:
  GlobalProblem(const Survey& survey, const Initialization& init, const MapBuildOptions& options)
      : survey_(survey), init_(init), options_(options) {
    robot_.resize(survey.frames.size());
    marker_.resize(survey.markers.size());
    for (size_t f = 0; f < robot_.size(); ++f) {
      if (init.T_world_robot[f]) RobotToBlock(survey.motion, *init.T_world_robot[f], &robot_[f]);
    }
    for (size_t m = 0; m < marker_.size(); ++m) {
      if (init.T_world_marker[m]) SE3ToBlock(*init.T_world_marker[m], marker_[m].data());
    }
    const Eigen::Vector3d c = options.odometry_calibration.value_or(init.odometry_calibration);
    for (int i = 0; i < kOdometryCalibrationSize; ++i) calibration_[i] = c[i];
  }

  // One solve over the observations in `active` (indices), with or without the robust loss.
  ceres::Solver::Summary Solve(const std::vector<int>& active, bool robust, std::vector<std::string>* gauges);
  // Whitened squared norm of an observation at the current values (+inf behind the camera).
  double SquaredError(int o) const;
  // Marker covariances in map.json's convention and, with factor_rank > 0, the markers' rows of
  // the joint covariance factor (mapping/map_covariance.h), both from one factorization of H
  // (mapping/marginal_covariance.h); false when H is not positive definite (a free gauge).
  // With the odometry calibration estimated, its covariance goes to *calibration_covariance.
  bool Covariances(int factor_rank, std::vector<std::optional<Matrix6d>>* covariance,
                   std::vector<std::optional<CovarianceFactor>>* factors,
                   std::optional<Eigen::Matrix3d>* calibration_covariance) const;
  // The odometry calibration of the problem, nullopt when it has no calibrated odometry link.
  std::optional<Eigen::Vector3d> Calibration() const {
    if (!problem_->HasParameterBlock(calibration_.data())) return std::nullopt;
    return Eigen::Vector3d(calibration_[0], calibration_[1], calibration_[2]);
  }
  bool CalibrationEstimated() const {
    return problem_->HasParameterBlock(calibration_.data()) && !problem_->IsParameterBlockConstant(calibration_.data());
  }

  // Re-places the codes with an observation above the outlier gate by consensus over their
  // views at the current frame poses (mapping/initializer.h), and moves the codes whose other
  // planar-flip branch fits better there (OtherFlipBranch); returns how many moved.
  size_t ReplaceOutlyingMarkers(const std::vector<int>& active, const std::map<std::string, Camera>& cameras);

  bool FramePlaced(int f) const { return init_.T_world_robot[f].has_value(); }
  SE3d Robot(int f) const { return RobotFromBlock(survey_.motion, robot_[f]); }
  SE3d Marker(int m) const { return SE3FromBlock(marker_[m].data()); }

 private:
  void AddPriorsAndGauge(const std::set<int>& markers_used, std::vector<std::string>* gauges);
  void AddOdometry();
  void AddCalibratedOdometry(const OdometryLink& link);

  const Survey& survey_;
  const Initialization& init_;
  const MapBuildOptions& options_;
  std::vector<PoseBlock> robot_, marker_;
  std::array<double, kOdometryCalibrationSize> calibration_{0.0, 0.0, 0.0};
  std::unique_ptr<ceres::Problem> problem_;
  std::vector<const double*> covariance_markers_;
};

ceres::Solver::Summary GlobalProblem::Solve(const std::vector<int>& active, bool robust,
                                            std::vector<std::string>* gauges) {
  problem_ = std::make_unique<ceres::Problem>();
  std::set<int> markers_used;
  ceres::LossFunction* loss = robust ? new ceres::CauchyLoss(options_.cauchy_scale) : nullptr;
  for (int o : active) {
    const SurveyObservation& obs = survey_.observations[o];
    if (problem_->HasParameterBlock(robot_[obs.frame].data()) == false) {
      AddRobotBlock(problem_.get(), survey_.motion, &robot_[obs.frame]);
    }
    if (markers_used.insert(obs.marker).second) AddMarkerBlock(problem_.get(), &marker_[obs.marker]);
    AddCornerResidual(problem_.get(), survey_.motion, survey_.cameras.at(obs.camera),
                      survey_.markers[obs.marker].size_m, obs.corners_px, &robot_[obs.frame], &marker_[obs.marker],
                      loss);
  }
  if (loss != nullptr && active.empty()) delete loss;
  AddOdometry();
  AddPriorsAndGauge(markers_used, gauges);
  covariance_markers_.clear();
  for (int m : markers_used) {
    if (!problem_->IsParameterBlockConstant(marker_[m].data())) covariance_markers_.push_back(marker_[m].data());
  }
  // Measured on corridor loops (docs/mapping.md, speed): Cholesky of the normal equations with
  // SuiteSparse (CHOLMOD, AMD) is on par with EIGEN_SPARSE and beats SPARSE_SCHUR with the codes
  // eliminated first (the reduced system is still every frame: 640 m loop, linear solver 6x
  // slower); ITERATIVE_SCHUR + SCHUR_JACOBI crawls on the long odometry chains; Jacobi scaling and
  // non-monotonic steps change nothing. Levenberg-Marquardt starts at a trust region of 1e12
  // (Ceres' default is 1e4), i.e. at Gauss-Newton steps, and shrinks it only when a step fails:
  // Ceres damps the normal equations by diag(J^T J) / radius, and with the default every solve
  // crept along the loop's weakly constrained drift modes: each step was accepted with a model
  // fit of 1.00, the radius tripled, and the iteration count grew with the loop (640 m: 40 + 20
  // iterations -> 8 + 3, maps equal within 11 um on the accuracy scenarios). A relative cost change of 1e-6 ends the
  // robust solves, which only decide the outliers. The final solve runs to 1e-10: stopping it at
  // 1e-6 moves the maps by up to 0.08 mm now for one iteration, and left sparse-code maps up to
  // 50 % worse with the default radius (corridor d = 4 m seed 3: 45 -> 69 mm).
  ceres::Solver::Options solver_options;
  solver_options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  solver_options.sparse_linear_algebra_library_type = ceres::SUITE_SPARSE;
  solver_options.initial_trust_region_radius = kInitialTrustRegionRadius;
  solver_options.max_num_iterations = options_.max_iterations;
  solver_options.num_threads = options_.num_threads;
  solver_options.function_tolerance = robust ? 1e-6 : 1e-10;
  solver_options.parameter_tolerance = robust ? 1e-8 : 1e-10;
  std::unique_ptr<ProgressCallback> callback;
  if (options_.progress) {
    callback = std::make_unique<ProgressCallback>(options_.progress, robust ? "robust solve" : "final solve");
    solver_options.callbacks.push_back(callback.get());
  }
  ceres::Solver::Summary summary;
  ceres::Solve(solver_options, problem_.get(), &summary);
  return summary;
}

size_t GlobalProblem::ReplaceOutlyingMarkers(const std::vector<int>& active,
                                             const std::map<std::string, Camera>& cameras) {
  std::set<int> outlying;
  for (int o : active) {
    if (SquaredError(o) > options_.outlier_chi2) outlying.insert(survey_.observations[o].marker);
  }
  std::vector<std::optional<SE3d>> T_world_robot(survey_.frames.size());
  for (size_t f = 0; f < survey_.frames.size(); ++f) {
    if (FramePlaced(static_cast<int>(f))) T_world_robot[f] = Robot(static_cast<int>(f));
  }
  size_t moved = 0;
  for (int m : outlying) {
    const SurveyMarker& marker = survey_.markers[m];
    if (marker.known && marker.known->fixed) continue;
    const std::optional<SE3d> T = MarkerByConsensus(survey_, cameras, init_.views, T_world_robot, m,
                                                    options_.initializer.cauchy_scale);
    if (!T) continue;
    const SE3d before = Marker(m);
    if ((T->translation() - before.translation()).norm() > 1e-3 || RotationAngleBetween(*T, before) > 1e-3) {
      SE3ToBlock(*T, marker_[m].data());
      ++moved;
    }
  }
  // Codes left on the wrong branch of the planar ambiguity (mapping/initializer.h, OtherFlipBranch).
  LocalMapOptions fusion = options_.initializer.local_maps;
  fusion.cauchy_scale = options_.initializer.cauchy_scale;
  for (size_t m = 0; m < marker_.size(); ++m) {
    const SurveyMarker& marker = survey_.markers[m];
    const bool fixed = marker.known && marker.known->fixed;
    const int code = static_cast<int>(m);
    if (!init_.T_world_marker[m] || outlying.count(code) > 0 || fixed) continue;
    const std::optional<SE3d> T =
        OtherFlipBranch(survey_, cameras, init_.views, T_world_robot, code, Marker(code), fusion);
    if (T) {
      SE3ToBlock(*T, marker_[m].data());
      ++moved;
    }
  }
  return moved;
}

// Odometry between placed frames that are both in the problem; frames seen by no code but
// placed (odometry only) are added too, so the smoothed trajectory covers them.
void GlobalProblem::AddOdometry() {
  for (const OdometryLink& link : survey_.odometry_links) {
    if (!FramePlaced(link.frame_a) || !FramePlaced(link.frame_b)) continue;
    for (int f : {link.frame_a, link.frame_b}) {
      if (!problem_->HasParameterBlock(robot_[f].data())) AddRobotBlock(problem_.get(), survey_.motion, &robot_[f]);
    }
    if (options_.calibrate_odometry) {
      AddCalibratedOdometry(link);
    } else if (survey_.motion == MotionModel::kPlanar) {
      problem_->AddResidualBlock(OdometrySE2Factor::Create(SE2d::FromSE3(link.T_a_b), link.covariance_se2), nullptr,
                                 robot_[link.frame_a].data(), robot_[link.frame_b].data());
    } else {
      problem_->AddResidualBlock(OdometrySE3Factor::Create(link.T_a_b, link.covariance_se3), nullptr,
                                 robot_[link.frame_a].data(), robot_[link.frame_b].data());
    }
  }
}

void GlobalProblem::AddCalibratedOdometry(const OdometryLink& link) {
  if (!problem_->HasParameterBlock(calibration_.data())) {
    problem_->AddParameterBlock(calibration_.data(), kOdometryCalibrationSize);
    problem_->AddResidualBlock(
        OdometryCalibrationPrior::Create(options_.odometry_calibration.value_or(Eigen::Vector3d::Zero()),
                                         options_.odometry_calibration_sigma.value_or(
                                             Eigen::Vector3d::Constant(options_.calibration_sigma))),
        nullptr, calibration_.data());
    if (options_.odometry_calibration && !options_.odometry_calibration_sigma) {
      problem_->SetParameterBlockConstant(calibration_.data());
    }
  }
  ceres::CostFunction* cost =
      survey_.motion == MotionModel::kPlanar
          ? CalibratedOdometrySE2Factor::Create(SE2d::FromSE3(link.T_a_b), link.covariance_se2)
          : CalibratedOdometrySE3Factor::Create(link.T_a_b, link.covariance_se3);
  problem_->AddResidualBlock(cost, nullptr, robot_[link.frame_a].data(), robot_[link.frame_b].data(),
                             calibration_.data());
}

void GlobalProblem::AddPriorsAndGauge(const std::set<int>& markers_used, std::vector<std::string>* gauges) {
  gauges->assign(init_.components, "");
  std::vector<int> anchors(init_.components, 0), payloads(init_.components, 0), payloads_z(init_.components, 0);
  for (int m : markers_used) {
    const SurveyMarker& marker = survey_.markers[m];
    const int c = init_.marker_component[m];
    if (marker.known && marker.known->fixed) {
      SE3ToBlock(marker.known->T_world_marker, marker_[m].data());
      problem_->SetParameterBlockConstant(marker_[m].data());
      ++anchors[c];
    } else if (marker.known && marker.known->covariance) {
      problem_->AddResidualBlock(PosePriorSE3Factor::Create(marker.known->T_world_marker, *marker.known->covariance),
                                 nullptr, marker_[m].data());
      ++anchors[c];
    }
  }
  const bool planar = survey_.motion == MotionModel::kPlanar;
  for (int m : markers_used) {
    const SurveyMarker& marker = survey_.markers[m];
    const int c = init_.marker_component[m];
    if (!marker.payload || anchors[c] > 0) continue;
    const PayloadData& p = *marker.payload;
    if (p.z_m && !planar) {
      problem_->AddResidualBlock(
          PositionPriorFactor<3>::Create(Eigen::Vector3d(*p.x_m, *p.y_m, *p.z_m), options_.payload_sigma_m), nullptr,
          marker_[m].data());
      ++payloads_z[c];
    } else {
      problem_->AddResidualBlock(PositionPriorFactor<2>::Create(Eigen::Vector2d(*p.x_m, *p.y_m), options_.payload_sigma_m),
                                 nullptr, marker_[m].data());
    }
    if (p.yaw_rad) {
      problem_->AddResidualBlock(YawPriorFactor::Create(*p.yaw_rad, options_.payload_yaw_sigma_rad), nullptr,
                                 marker_[m].data());
    }
    ++payloads[c];
  }
  for (int c = 0; c < init_.components; ++c) {
    int first = -1;
    for (size_t f = 0; f < survey_.frames.size() && first < 0; ++f) {
      if (init_.frame_component[f] == c && problem_->HasParameterBlock(robot_[f].data())) first = static_cast<int>(f);
    }
    if (anchors[c] > 0) {
      (*gauges)[c] = std::to_string(anchors[c]) + " anchor(s) from markers.json";
    } else if (payloads[c] >= (planar ? 2 : 3)) {
      (*gauges)[c] = std::to_string(payloads[c]) + " payload position prior(s)";
      if (!planar && first >= 0 && payloads_z[c] < 3) {
        // Positions printed without z leave the height free: a weak prior on the first frame's
        // pose, tight only in z (body frame), fixes it (the map's height origin is then the
        // first frame's, and its tilt is held only weakly). Three or more codes with a z
        // (printed, or payload.default_z_m) fix height and tilt themselves.
        Vector6d variances;
        variances << 1.0, 1.0, 1.0, 1e4, 1e4, 1e-6;
        problem_->AddResidualBlock(PosePriorSE3Factor::Create(Robot(first), Matrix6d(variances.asDiagonal())), nullptr,
                                   robot_[first].data());
      }
    } else if (first >= 0) {
      problem_->SetParameterBlockConstant(robot_[first].data());
      (*gauges)[c] = "first frame held fixed";
    }
  }
}

double GlobalProblem::SquaredError(int o) const {
  const SurveyObservation& obs = survey_.observations[o];
  const CameraInfo& camera = survey_.cameras.at(obs.camera);
  std::unique_ptr<ceres::CostFunction> cost(
      survey_.motion == MotionModel::kPlanar
          ? PlanarMarkerReprojectionFactor::Create(camera, survey_.markers[obs.marker].size_m, obs.corners_px,
                                                   CornerSigmaPx(camera))
          : MarkerReprojectionFactor::Create(camera, survey_.markers[obs.marker].size_m, obs.corners_px,
                                             CornerSigmaPx(camera)));
  const double* blocks[2] = {robot_[obs.frame].data(), marker_[obs.marker].data()};
  double residuals[8];
  if (!cost->Evaluate(blocks, residuals, nullptr)) return std::numeric_limits<double>::infinity();
  double s = 0.0;
  for (double r : residuals) s += r * r;
  return s;
}

bool GlobalProblem::Covariances(int factor_rank, std::vector<std::optional<Matrix6d>>* covariance,
                                std::vector<std::optional<CovarianceFactor>>* factors,
                                std::optional<Eigen::Matrix3d>* calibration_covariance) const {
  covariance->assign(survey_.markers.size(), std::nullopt);
  factors->assign(survey_.markers.size(), std::nullopt);
  calibration_covariance->reset();
  MarginalCovarianceOptions marginal_options;
  marginal_options.num_threads = options_.num_threads;
  std::vector<const double*> marginal_blocks = covariance_markers_;  // markers first, then c
  if (CalibrationEstimated()) marginal_blocks.push_back(calibration_.data());
  const InformationFactor information(problem_.get(), marginal_blocks, marginal_options);
  if (information.size() == 0) return covariance_markers_.empty();
  if (!information.positive_definite()) return false;
  const std::vector<Eigen::MatrixXd> manifold = information.Marginals();  // marginal_blocks order
  if (CalibrationEstimated()) *calibration_covariance = Eigen::Matrix3d(manifold.back());
  std::map<const double*, size_t> index_of;
  for (size_t i = 0; i < covariance_markers_.size(); ++i) index_of[covariance_markers_[i]] = i;
  const size_t count = covariance_markers_.size();
  std::vector<size_t> markers(count);  // in covariance_markers_ order
  std::vector<SE3d> poses(count);
  std::vector<Matrix6d> marginals(count);
  for (size_t m = 0; m < survey_.markers.size(); ++m) {
    const auto it = index_of.find(marker_[m].data());
    if (it == index_of.end()) continue;
    const SE3d T_world_marker = Marker(static_cast<int>(m));
    const Matrix6d J = ManifoldToBodyTangentJacobian(T_world_marker);
    const Matrix6d body = J * Matrix6d(manifold[it->second]) * J.transpose();
    (*covariance)[m] = 0.5 * (body + body.transpose());
    markers[it->second] = m;
    poses[it->second] = T_world_marker;
    marginals[it->second] = *(*covariance)[m];
  }
  if (factor_rank <= 0) return true;
  CovarianceFactorOptions factor_options;
  factor_options.rank = factor_rank;
  const auto rows = MarkerCovarianceFactors(information, covariance_markers_, poses, marginals, factor_options);
  for (size_t i = 0; rows && i < markers.size(); ++i) (*factors)[markers[i]] = (*rows)[i];
  return true;
}

// Observations usable in the optimization: a usable single view, both ends placed.
std::vector<int> UsableObservations(const Survey& survey, const Initialization& init, MapBuildResult* result) {
  std::vector<int> active;
  for (size_t o = 0; o < survey.observations.size(); ++o) {
    const SurveyObservation& obs = survey.observations[o];
    std::string reason;
    if (!init.views[o].usable) {
      reason = "single view failed: " + init.views[o].why;
    } else if (!init.T_world_robot[obs.frame] || !init.T_world_marker[obs.marker]) {
      reason = "could not be placed";
    }
    if (reason.empty()) {
      active.push_back(static_cast<int>(o));
    } else {
      result->outliers.push_back({survey.markers[obs.marker].key, survey.frames[obs.frame].stamp_s, obs.camera, 0.0,
                                  reason});
    }
  }
  return active;
}

// Cosine of the largest angle between the faces of two codes taken for one (60 degrees).
constexpr double kMinDuplicateFacingCos = 0.5;

// Two distinct codes of one component mapped at one place (centres closer than half the
// larger code's size, faces within 60 degrees) cannot both be right: one is another code read under a wrong id (the
// same code misdecoded alike in several frames, which the id check cannot see). The code with
// fewer observations loses them, reported. Returns the observations kept.
// The pairs (i, j), i < j, of `markers` whose centres are within `gate_m` in x, in lexicographic
// order: a sweep over the markers sorted by x, linear in the survey where all pairs are not.
std::vector<std::pair<size_t, size_t>> NearbyPairs(const std::vector<SE3d>& T_world_marker, double gate_m) {
  std::vector<size_t> by_x(T_world_marker.size());
  for (size_t i = 0; i < by_x.size(); ++i) by_x[i] = i;
  const auto x = [&](size_t i) { return T_world_marker[i].translation().x(); };
  std::sort(by_x.begin(), by_x.end(), [&](size_t a, size_t b) { return x(a) < x(b); });
  std::vector<std::pair<size_t, size_t>> pairs;
  for (size_t p = 0; p < by_x.size(); ++p) {
    for (size_t q = p + 1; q < by_x.size() && x(by_x[q]) - x(by_x[p]) <= gate_m; ++q) {
      pairs.emplace_back(std::min(by_x[p], by_x[q]), std::max(by_x[p], by_x[q]));
    }
  }
  std::sort(pairs.begin(), pairs.end());
  return pairs;
}

std::vector<int> RemoveDuplicateCodes(const Survey& survey, const Initialization& init, const GlobalProblem& problem,
                                      const std::vector<int>& active, MapBuildResult* result) {
  std::map<int, std::vector<int>> observations_of;  // marker -> active observations
  for (int o : active) observations_of[survey.observations[o].marker].push_back(o);
  std::vector<int> markers;
  std::vector<SE3d> T_world_marker;
  double largest_gate_m = 0.0;
  for (const auto& [m, obs] : observations_of) {
    markers.push_back(m);
    T_world_marker.push_back(problem.Marker(m));
    largest_gate_m = std::max(largest_gate_m, 0.5 * survey.markers[m].size_m);
  }
  std::set<int> dropped;
  for (const auto& [i, j] : NearbyPairs(T_world_marker, largest_gate_m)) {
    const int a = markers[i], b = markers[j];
    if (init.marker_component[a] != init.marker_component[b] || dropped.count(a) || dropped.count(b)) continue;
    const double gate_m = 0.5 * std::max(survey.markers[a].size_m, survey.markers[b].size_m);
    const SE3d& T_world_a = T_world_marker[i];
    const SE3d& T_world_b = T_world_marker[j];
    if ((T_world_a.translation() - T_world_b.translation()).norm() > gate_m) continue;
    // Codes printed back to back on a thin wall share a place but face away from each other.
    const Eigen::Vector3d z_a = T_world_a.rotation() * Eigen::Vector3d::UnitZ();
    if (z_a.dot(T_world_b.rotation() * Eigen::Vector3d::UnitZ()) < kMinDuplicateFacingCos) continue;
    const bool a_loses = observations_of[a].size() < observations_of[b].size() ||
                         (observations_of[a].size() == observations_of[b].size() && survey.markers[b].known);
    const int loser = a_loses ? a : b, winner = a_loses ? b : a;
    if (survey.markers[loser].known && survey.markers[loser].known->fixed) continue;
    dropped.insert(loser);
    for (int o : observations_of[loser]) {
      result->outliers.push_back({survey.markers[loser].key, survey.frames[survey.observations[o].frame].stamp_s,
                                  survey.observations[o].camera, 0.0,
                                  "id conflicts with " + survey.markers[winner].key.ToString() +
                                      ", mapped at the same place (misdecoded?)"});
    }
  }
  std::vector<int> kept;
  for (int o : active) {
    if (!dropped.count(survey.observations[o].marker)) kept.push_back(o);
  }
  return kept;
}

// Stage 3: drops outliers, then codes seen in fewer than min_frames frames.
std::vector<int> RejectOutliers(const Survey& survey, const GlobalProblem& problem, const std::vector<int>& active,
                                const MapBuildOptions& options, MapBuildResult* result) {
  std::vector<int> inliers;
  std::vector<std::set<int>> frames_of_marker(survey.markers.size());
  for (int o : active) {
    const SurveyObservation& obs = survey.observations[o];
    const double s = problem.SquaredError(o);
    if (s > options.outlier_chi2) {
      const double rms_px = std::sqrt(s / 4.0) * CornerSigmaPx(survey.cameras.at(obs.camera));
      result->outliers.push_back({survey.markers[obs.marker].key, survey.frames[obs.frame].stamp_s, obs.camera, rms_px,
                                  "reprojection error above the outlier gate"});
      continue;
    }
    inliers.push_back(o);
    frames_of_marker[obs.marker].insert(obs.frame);
  }
  std::vector<int> kept;
  for (int o : inliers) {
    const int m = survey.observations[o].marker;
    const SurveyMarker& marker = survey.markers[m];
    if (static_cast<int>(frames_of_marker[m].size()) >= options.min_frames || marker.known) kept.push_back(o);
  }
  for (size_t m = 0; m < survey.markers.size(); ++m) {
    const size_t n = frames_of_marker[m].size();
    if (static_cast<int>(n) >= options.min_frames || (survey.markers[m].known && n > 0)) continue;
    result->unmapped.push_back({survey.markers[m].key, n == 0 ? "no usable observation"
                                                              : "seen in " + std::to_string(n) + " frame(s) only"});
  }
  return kept;
}

void FillReprojection(const Survey& survey, const GlobalProblem& problem, const std::vector<int>& kept,
                      MapBuildResult* result) {
  std::map<std::string, std::pair<size_t, double>> per_camera;  // observations, sum of squared px
  for (int o : kept) {
    const SurveyObservation& obs = survey.observations[o];
    const double sigma = CornerSigmaPx(survey.cameras.at(obs.camera));
    auto& entry = per_camera[obs.camera];
    ++entry.first;
    entry.second += problem.SquaredError(o) * sigma * sigma;
  }
  for (const auto& [camera, entry] : per_camera) {
    result->reprojection.push_back({camera, entry.first, std::sqrt(entry.second / (4.0 * entry.first))});
  }
}

void FillOutputs(const Survey& survey, const Initialization& init, const GlobalProblem& problem,
                 const std::vector<int>& kept, const std::vector<std::string>& gauges, MapBuildResult* result) {
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
    marker.component = init.marker_component[m];
    result->map.markers.push_back(marker);
  }
  for (int c = 0; c < init.components; ++c) {
    ComponentSummary summary;
    summary.component = c;
    summary.markers = std::count_if(mapped.begin(), mapped.end(), [&](int m) { return init.marker_component[m] == c; });
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
  if (!ingest.Check(why) || !id_check.Check(why)) return false;
  const auto positive = [](double v) { return std::isfinite(v) && v > 0.0; };
  if (!positive(calibration_sigma)) {
    *why = "calibration_sigma must be finite and > 0";
    return false;
  }
  if (!positive(cauchy_scale) || !positive(outlier_chi2) || !positive(payload_sigma_m) ||
      !positive(payload_yaw_sigma_rad)) {
    *why = "cauchy_scale, outlier_chi2, payload_sigma_m and payload_yaw_sigma_rad must be finite and > 0";
    return false;
  }
  if (odometry_calibration && !calibrate_odometry) {
    *why = "a given odometry calibration needs calibrate_odometry";
    return false;
  }
  if (odometry_calibration && !OdometryCalibrationValid(*odometry_calibration)) {
    *why = kOdometryCalibrationRule;
    return false;
  }
  if (odometry_calibration_sigma && (!odometry_calibration || !OdometryCalibrationSigmaValid(*odometry_calibration_sigma))) {
    *why = "odometry_calibration_sigma needs odometry_calibration, and must be three finite numbers > 0";
    return false;
  }
  if (replace_rounds < 0) {
    *why = "replace_rounds must be >= 0";
    return false;
  }
  if (min_frames < 1 || max_iterations < 1 || num_threads < 1) {
    *why = "min_frames, max_iterations and num_threads must be >= 1";
    return false;
  }
  return true;
}

MapBuildResult BuildMap(const Dataset& dataset, const MapBuildOptions& options) {
  const Survey survey = IngestDataset(dataset, options.ingest);
  MapBuildResult result = BuildMapFromSurvey(survey, options);
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
  std::vector<int> inconsistent;
  if (options.check_ids) inconsistent = FindInconsistentIds(survey, MakeCameras(survey), options.id_check);
  for (int o : inconsistent) {
    const SurveyObservation& obs = survey.observations[o];
    result.outliers.push_back({survey.markers[obs.marker].key, survey.frames[obs.frame].stamp_s, obs.camera, 0.0,
                               "id inconsistent with the code's other views along the odometry (misdecoded?)"});
  }
  const Survey checked = WithoutObservations(survey, inconsistent);
  InitializerOptions initializer = options.initializer;
  if (options.calibrate_odometry && options.odometry_calibration) {
    initializer.graph.given_calibration = options.odometry_calibration;
    initializer.graph.given_calibration_sigma = options.odometry_calibration_sigma;
  }
  const Initialization init = Initialize(checked, initializer);
  result.notes.insert(result.notes.end(), init.notes.begin(), init.notes.end());  // local maps, links
  result.init_time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return OptimizeSurvey(checked, init, options, std::move(result));
}

MapBuildResult OptimizeSurvey(const Survey& survey, const Initialization& init, const MapBuildOptions& options,
                              MapBuildResult result) {
  const auto progress = [&](const std::string& line) {
    if (options.progress) options.progress(line);
  };
  GlobalProblem problem(survey, init, options);
  const std::vector<int> active = UsableObservations(survey, init, &result);
  std::vector<std::string> gauges;
  const auto start = std::chrono::steady_clock::now();
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
    result.solves.push_back({stage, static_cast<int>(summary.iterations.size()), summary.total_time_in_seconds,
                             summary.linear_solver_time_in_seconds, summary.jacobian_evaluation_time_in_seconds,
                             summary.residual_evaluation_time_in_seconds});
  };
  ceres::Solver::Summary robust = problem.Solve(in_front(active), true, &gauges);
  record("robust", robust);
  int iterations = static_cast<int>(robust.iterations.size());
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
  const std::vector<int> kept =
      RejectOutliers(survey, problem, RemoveDuplicateCodes(survey, init, problem, active, &result), options, &result);
  const ceres::Solver::Summary final_summary = problem.Solve(kept, false, &gauges);
  record("final", final_summary);
  result.solver_time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  result.iterations = iterations + static_cast<int>(final_summary.iterations.size());
  result.termination = ceres::TerminationTypeToString(final_summary.termination_type) + std::string(": ") +
                       final_summary.message;
  result.observations = kept.size();
  result.initial_cost = robust.initial_cost;
  result.final_cost = final_summary.final_cost;
  result.odometry_calibration = problem.Calibration();
  result.odometry_calibration_given = result.odometry_calibration && !problem.CalibrationEstimated();
  FillReprojection(survey, problem, kept, &result);
  FillOutputs(survey, init, problem, kept, gauges, &result);
  if (options.compute_covariance) {
    progress("marker covariances");
    const auto covariance_start = std::chrono::steady_clock::now();
    std::vector<std::optional<Matrix6d>> covariance;
    std::vector<std::optional<CovarianceFactor>> factors;
    result.covariance_computed = problem.Covariances(options.covariance_factor_rank, &covariance, &factors,
                                                     &result.odometry_calibration_covariance);
    if (result.covariance_computed) {
      for (MapMarker& marker : result.map.markers) {
        const int m = survey.FindMarker(marker.key);
        marker.covariance = covariance[m];
        marker.covariance_factor = factors[m];
      }
    } else {
      result.notes.push_back("marker covariances could not be computed (rank-deficient problem)");
    }
    result.covariance_time_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - covariance_start).count();
  }
  return result;
}

}  // namespace waymark

namespace waymark {

namespace {

// Outliers counted by reason, then by code (the codes with most rejected views first).
void AppendOutlierTallies(const std::vector<RejectedObservation>& outliers, std::ostream& out) {
  if (outliers.empty()) return;
  std::map<std::string, size_t> by_reason;
  std::map<std::string, size_t> by_code;
  for (const RejectedObservation& o : outliers) {
    const std::string reason = o.reason.substr(0, o.reason.find(':'));
    ++by_reason[reason.rfind("id conflicts with ", 0) == 0 ? "id conflicts with a code mapped at the same place"
                                                            : reason];
    ++by_code[o.key.ToString()];
  }
  for (const auto& [reason, n] : by_reason) out << "  " << n << " x " << reason << "\n";
  std::vector<std::pair<std::string, size_t>> codes(by_code.begin(), by_code.end());
  std::stable_sort(codes.begin(), codes.end(), [](const auto& a, const auto& b) { return a.second > b.second; });
  out << "  by code:";
  const size_t shown = std::min<size_t>(codes.size(), 12);
  for (size_t i = 0; i < shown; ++i) out << " " << codes[i].first << " (" << codes[i].second << ")";
  if (shown < codes.size()) out << " ... " << codes.size() - shown << " more codes";
  out << "\n";
}

}  // namespace

std::string FormatOdometryCalibration(const MapBuildResult& result) {
  if (!result.odometry_calibration) return "";
  const Eigen::Vector3d& c = *result.odometry_calibration;
  const std::optional<Eigen::Matrix3d>& covariance = result.odometry_calibration_covariance;
  const auto sigma = [&](int i, double scale) {
    return covariance ? " +- " + Num(scale * std::sqrt(std::max(0.0, (*covariance)(i, i))), 2) : std::string();
  };
  std::ostringstream out;
  out << "odometry calibration (" << (result.odometry_calibration_given ? "given" : "estimated")
      << "): heading drift " << Num(c[0] * 180.0 / M_PI, 3) << sigma(0, 180.0 / M_PI) << " deg/m, turn scale "
      << Num(100.0 * c[1], 3) << sigma(1, 100.0) << " %, distance scale " << Num(100.0 * c[2], 3) << sigma(2, 100.0)
      << " %";
  if (!result.odometry_calibration_given) {
    out << " (reuse for this robot: --odometry-calibration " << Num(c[0], 6) << "," << Num(c[1], 6) << ","
        << Num(c[2], 6);
    if (covariance) {
      for (int i = 0; i < 3; ++i) out << "," << Num(std::sqrt(std::max(0.0, (*covariance)(i, i))), 3);
    }
    out << ")";
  }
  return out.str();
}

std::string FormatBuildSummary(const MapBuildResult& result) {
  std::ostringstream out;
  out << "map: " << result.map.markers.size() << " markers in " << result.components.size() << " component(s), "
      << result.frames << " frames, " << result.observations << " observations used\n";
  for (const ComponentSummary& c : result.components) {
    out << "  component " << c.component << ": " << c.markers << " markers, " << c.frames << " frames ("
        << c.trajectory_poses << " poses in its trajectory), gauge: " << c.gauge << "\n";
  }
  for (const CameraReprojection& r : result.reprojection) {
    out << "  reprojection " << r.camera << ": RMS " << Num(r.rms_px) << " px over " << r.observations
        << " observations\n";
  }
  out << "outliers rejected: " << result.outliers.size() << "\n";
  AppendOutlierTallies(result.outliers, out);
  const size_t shown = std::min<size_t>(result.outliers.size(), 10);
  for (size_t i = 0; i < shown; ++i) {
    const RejectedObservation& o = result.outliers[i];
    out << "  " << o.key.ToString() << " at t = " << Num(o.stamp_s, 12) << " s (" << o.camera << "): " << o.reason;
    if (o.rms_px > 0.0) out << ", " << Num(o.rms_px) << " px";
    out << "\n";
  }
  if (shown < result.outliers.size()) out << "  ... and " << result.outliers.size() - shown << " more\n";
  out << "unmapped codes: " << result.unmapped.size() << "\n";
  for (const UnmappedMarker& u : result.unmapped) out << "  " << u.key.ToString() << ": " << u.reason << "\n";
  out << "time: init " << Num(result.init_time_s, 3) << " s, solve " << Num(result.solver_time_s, 3)
      << " s, covariance " << Num(result.covariance_time_s, 3) << " s\n";
  out << "solver: " << Num(result.solver_time_s) << " s, " << result.iterations << " iterations, cost "
      << Num(result.initial_cost, 8) << " -> " << Num(result.final_cost, 8) << ", "
      << result.termination << "\n";
  out << "covariance: " << (result.covariance_computed ? "computed" : "not computed") << "\n";
  if (result.odometry_calibration) out << FormatOdometryCalibration(result) << "\n";
  for (const std::string& note : result.notes) out << "note: " << note << "\n";
  return out.str();
}

}  // namespace waymark
