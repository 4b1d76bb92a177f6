#include "online/localizer.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <stdexcept>
#include <utility>

#include "geometry/robot_pnp.h"
#include "geometry/square_marker.h"
#include "online/chi_square.h"
#include "online/marker_measurement.h"
#include "util/check.h"

namespace waymark {

LocalizerOptions::~LocalizerOptions() = default;

bool LocalizerOptions::Check(std::string* why) const {
  WAYMARK_CHECK_OPTION(odometry.Check(why), nullptr);
  WAYMARK_CHECK_OPTION(!start_pose || start_pose->IsFinite(), "localizer options: start_pose must be finite");
  WAYMARK_CHECK_OPTION(gate_probability > 0.0 && gate_probability < 1.0,
                       "localizer options: gate_probability must be in (0, 1)");
  WAYMARK_CHECK_OPTION(IsFinitePositive(default_pixel_sigma_px),
                       "localizer options: default_pixel_sigma_px must be finite and > 0");
  WAYMARK_CHECK_OPTION(loose_noise.size() == StateDim(motion), "localizer options: loose_noise must have " +
                                                                   std::to_string(StateDim(motion)) +
                                                                   " variances for this motion model");
  WAYMARK_CHECK_OPTION(loose_noise.allFinite() && (loose_noise.array() > 0.0).all(),
                       "localizer options: loose_noise must be finite and > 0");
  WAYMARK_CHECK_OPTION(
      lost_after_rejected_frames >= 1 && relocalize_after_agreeing >= 1,
      "localizer options: lost_after_rejected_frames and relocalize_after_agreeing must be >= 1");
  WAYMARK_CHECK_OPTION(
      agree_trans_m > 0.0 && agree_rot_rad > 0.0 && max_position_sigma_m > 0.0,
      "localizer options: agree_trans_m, agree_rot_rad and max_position_sigma_m must be > 0");
  WAYMARK_CHECK_OPTION(clear_max_rms_sigmas > 0.0 && clear_max_range_sizes > 0.0,
                       "localizer options: clear_max_rms_sigmas and clear_max_range_sizes must be > 0");
  WAYMARK_CHECK_OPTION(tight_iterations >= 1, "localizer options: tight_iterations must be >= 1");
  WAYMARK_CHECK_OPTION(
      IsFiniteAtLeast(camera_mount_sigma_rad, 0.0) && IsFiniteAtLeast(camera_mount_sigma_m, 0.0),
      "localizer options: camera_mount_sigma_rad and camera_mount_sigma_m must be finite and >= 0");
  WAYMARK_CHECK_OPTION(
      IsFiniteAtLeast(without_odometry.speed_mps, 0.0) && IsFiniteAtLeast(without_odometry.turn_radps, 0.0),
      "localizer options: without_odometry speed and turn rate must be finite and >= 0");
  WAYMARK_CHECK_OPTION(IsFiniteAtLeast(without_odometry.fit_dominance, 0.0),
                       "localizer options: without_odometry fit_dominance must be finite and >= 0");
  WAYMARK_CHECK_OPTION(max_considered_markers >= 1, "localizer options: max_considered_markers must be >= 1");
  std::string nested_why;
  WAYMARK_CHECK_OPTION(marker_pose.Check(&nested_why), "localizer options: " + nested_why);
  WAYMARK_CHECK_OPTION(visibility.Check(&nested_why), "localizer options: " + nested_why);
  return true;
}

Localizer::Localizer(LocalizerOptions options, MarkerMap map, const std::vector<CameraInfo>& cameras)
    : options_(std::move(options)),
      map_(std::move(map)),
      state_(options_.motion),
      negative_(options_.visibility),
      code_index_(map_) {
  std::string why;
  if (!options_.Check(&why)) throw std::invalid_argument(why);
  state_.set_max_considered(static_cast<size_t>(options_.max_considered_markers));
  for (const CameraInfo& info : cameras) {
    if (!cameras_.emplace(info.name, Camera(info)).second) {
      throw std::invalid_argument("localizer: camera `" + info.name + "` given twice");
    }
  }
  gate_loose_ = ChiSquareQuantile(options_.gate_probability, state_.dim());
  gate_tight_ = ChiSquareQuantile(options_.gate_probability, 8);
}

StepStatus Localizer::Accept(double stamp_s) {
  StepStatus status = StepStatus::kOk;
  if (!std::isfinite(stamp_s))
    status = StepStatus::kInvalidInput;
  else if (last_stamp_s_ && stamp_s < *last_stamp_s_)
    status = StepStatus::kTimeWentBackwards;
  if (status != StepStatus::kOk) {
    ++counters_.rejected_inputs;
    return status;
  }
  last_stamp_s_ = stamp_s;
  return status;
}

void Localizer::SetLost(LostReason reason) {
  if (HasTrack()) {
    ++counters_.times_lost;
    switch (reason) {
      case LostReason::kGatedFrames:
        ++counters_.lost_by_gated_frames;
        break;
      case LostReason::kUncertainty:
        ++counters_.lost_by_uncertainty;
        break;
      case LostReason::kMissedCodes:
        ++counters_.lost_by_missed_codes;
        break;
      case LostReason::kNumerical:
        ++counters_.lost_by_numerical_failure;
        break;
    }
  }
  tracking_ = TrackingStatus::kLost;
  rejected_frames_in_a_row_ = 0;
}

void Localizer::CheckUncertainty() {
  if (!HasTrack()) return;
  const int n = state_.dim() - 1;
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(state_.covariance().topLeftCorner(n, n),
                                                             Eigen::EigenvaluesOnly);
  if (!(eigen.eigenvalues().maxCoeff() <= options_.max_position_sigma_m * options_.max_position_sigma_m))
    SetLost(LostReason::kUncertainty);
}

StepStatus Localizer::ApplyPrediction(const MotionPrediction& prediction, const SE3d& increment) {
  for (Hypothesis& hypothesis : hypotheses_) hypothesis.T_world_robot = hypothesis.T_world_robot * increment;
  if (tracking_ == TrackingStatus::kUninitialized) return StepStatus::kOk;
  const StepStatus status = state_.Propagate(prediction.mean, prediction.F, prediction.G, prediction.Qu);
  if (status != StepStatus::kOk) {
    SetLost(LostReason::kNumerical);
    return status;
  }
  state_.SetLevel(prediction.R_world_robot);  // free only; kOdometry put the odometry's attitude there
  CheckUncertainty();
  return status;
}

StepStatus Localizer::AddOdometry(double stamp_s, const SE3d& T_odom_robot) {
  if (!T_odom_robot.IsFinite()) {
    ++counters_.rejected_inputs;
    return StepStatus::kInvalidInput;
  }
  const StepStatus time_status = Accept(stamp_s);
  if (time_status != StepStatus::kOk) return time_status;
  had_motion_input_ = true;
  const std::optional<SE3d> previous = last_T_odom_robot_;
  const std::optional<double> previous_s = last_odometry_stamp_s_;
  last_T_odom_robot_ = T_odom_robot;
  last_odometry_stamp_s_ = stamp_s;
  if (!first_T_odom_robot_) first_T_odom_robot_ = T_odom_robot;
  if (!previous) return StepStatus::kOk;
  const SE3d increment = previous->inverse() * T_odom_robot;
  const double dt_s = stamp_s - *previous_s;  // >= 0: Accept refused older stamps
  if (options_.motion == MotionModel::kPlanar) {
    const SE2d increment_2d = SE2d::FromSE3(increment);
    return ApplyPrediction(PredictPlanarIncrement(state_.mean(), increment_2d, options_.odometry, dt_s),
                           increment_2d.ToSE3());
  }
  MotionPrediction prediction =
      PredictFreeIncrement(state_.mean(), state_.R_level(), increment, options_.odometry, dt_s);
  odometry_tilt_.Propagate(increment, options_.odometry, dt_s);
  if (options_.attitude_source == AttitudeSource::kOdometry)
    prediction.R_world_robot = odometry_tilt_.Level(T_odom_robot.rotation_matrix());
  return ApplyPrediction(prediction, increment);
}

StepStatus Localizer::AddVelocity(double stamp_s, double v_mps, double omega_radps) {
  if (options_.motion != MotionModel::kPlanar || !std::isfinite(v_mps) || !std::isfinite(omega_radps)) {
    ++counters_.rejected_inputs;
    return StepStatus::kInvalidInput;
  }
  const std::optional<double> previous_s = last_stamp_s_;
  const StepStatus time_status = Accept(stamp_s);
  if (time_status == StepStatus::kOk) had_motion_input_ = true;
  if (time_status != StepStatus::kOk || !previous_s) return time_status;
  const double dt_s = stamp_s - *previous_s;
  const double d = v_mps * dt_s, a = omega_radps * dt_s;
  const SE3d increment = SE2d(d * std::cos(0.5 * a), d * std::sin(0.5 * a), a).ToSE3();
  return ApplyPrediction(PredictUnicycle(state_.mean(), v_mps, omega_radps, dt_s, options_.odometry),
                         increment);
}

}  // namespace waymark

namespace waymark {

namespace {

// True when every predicted corner lies within the image grown by half its size on each side.
bool NearImage(const CameraInfo& info, const Vector8d& px) {
  const double margin_x = 0.5 * info.width, margin_y = 0.5 * info.height;
  for (int j = 0; j < 4; ++j) {
    const double u = px(2 * j), v = px(2 * j + 1);
    if (!(u >= -margin_x && u <= info.width + margin_x && v >= -margin_y && v <= info.height + margin_y))
      return false;
  }
  return true;
}

}  // namespace

SE3d Localizer::CodeHypothesis(const Camera& camera, const MapMarker& marker, const CodeSighting& sighting,
                               size_t i) const {
  return marker.T_world_marker * sighting.T_camera_marker[i].inverse() *
         camera.info().T_robot_camera.inverse();
}

std::optional<CodeRobotPose> Localizer::PlanarPoseFromCorners(const Camera& camera, const MapMarker& marker,
                                                              const CodeSighting& sighting, size_t i) const {
  if (options_.motion != MotionModel::kPlanar || i >= sighting.T_camera_marker.size()) return std::nullopt;
  constexpr int kMaxIterations = 20;
  constexpr double kGateChi2 = 40.0;  // 8 - 3 = 5 dof: far beyond any honest fit
  EkfState probe(options_.motion);
  const int dim = probe.dim();
  const Eigen::MatrixXd unit = Eigen::MatrixXd::Identity(dim, dim);
  Eigen::VectorXd mean = PoseToStateVector(CodeHypothesis(camera, marker, sighting, i), options_.motion);
  const Vector8d z = StackCorners(sighting.observation.corners_px);
  // Stops when the step is negligible, keeping the linearization (probe, prediction, normal)
  // at the mean it was taken at: the pose, P and C_m below all come from that one point.
  std::optional<CornerPrediction> prediction;
  Eigen::LDLT<Eigen::MatrixXd> normal;
  bool converged = false;
  for (int iteration = 0; iteration < kMaxIterations && !converged; ++iteration) {
    if (probe.Reset(mean, unit) != StepStatus::kOk) return std::nullopt;
    prediction = PredictCorners(probe, camera, marker);
    if (!prediction) return std::nullopt;
    normal.compute(prediction->H.transpose() * prediction->H);
    if (normal.info() != Eigen::Success) return std::nullopt;
    const Eigen::VectorXd step = normal.solve(prediction->H.transpose() * (z - prediction->px));
    if (!step.allFinite()) return std::nullopt;
    converged = step.head(dim - 1).norm() < 1e-6 && std::abs(step(dim - 1)) < 1e-7;
    if (!converged) mean = EkfState::BoxPlus(mean, step, probe.yaw_index());
  }
  if (!converged) return std::nullopt;
  const double sigma_px = camera.info().pixel_sigma.value_or(options_.default_pixel_sigma_px);
  const Vector8d residual = z - prediction->px;
  const Matrix8d R = CornerNoise(sigma_px, *prediction, marker.covariance);
  if (!(residual.dot(R.ldlt().solve(residual)) <= kGateChi2)) return std::nullopt;
  const Eigen::MatrixXd A = normal.solve(prediction->H.transpose());  // (H^T H)^-1 H^T, dim x 8
  CodeRobotPose pose;
  pose.T_world_robot = probe.T_world_robot();
  pose.covariance = sigma_px * sigma_px * A * A.transpose();
  pose.cross_marker = CrossCovariance::Zero(dim, 6);
  if (marker.covariance) {
    const Eigen::MatrixXd AJ = A * prediction->J_marker;
    pose.covariance += AJ * *marker.covariance * AJ.transpose();
    pose.cross_marker = -AJ * *marker.covariance;
  }
  if (!pose.covariance.allFinite()) return std::nullopt;
  return pose;
}

SE3d Localizer::RestartPose(const Camera& camera, const MapMarker& marker, const CodeSighting& sighting,
                            size_t i) const {
  const std::optional<CodeRobotPose> fitted = PlanarPoseFromCorners(camera, marker, sighting, i);
  return fitted ? fitted->T_world_robot : CodeHypothesis(camera, marker, sighting, i);
}

bool Localizer::PlanarResolvesAmbiguity(const Camera& camera, const MapMarker& marker,
                                        const CodeSighting& sighting) const {
  if (options_.motion != MotionModel::kPlanar || sighting.T_camera_marker.size() < 2) return false;
  const std::optional<CodeRobotPose> a = PlanarPoseFromCorners(camera, marker, sighting, 0);
  const std::optional<CodeRobotPose> b = PlanarPoseFromCorners(camera, marker, sighting, 1);
  if (!a || !b) return false;
  const auto [trans_m, rot_rad] = Distance(a->T_world_robot, b->T_world_robot);
  return trans_m < 1e-3 && rot_rad < 1e-3;
}

std::vector<ExpectedCode> Localizer::PredictCodesInView(
    const std::string& camera, const std::optional<VisibilityOptions>& visibility) const {
  const auto it = cameras_.find(camera);
  if (it == cameras_.end() || !HasTrack()) return {};
  return PredictExpectedCodes(state_, it->second, map_, code_index_, visibility.value_or(options_.visibility),
                              component_);
}

FrameResult Localizer::AddFrame(const CameraFrame& frame) {
  FrameResult result;
  const std::optional<double> previous_s = last_stamp_s_;
  const auto camera_it = cameras_.find(frame.camera);
  if (camera_it == cameras_.end()) {
    ++counters_.rejected_inputs;
    result.status = StepStatus::kUnknownCamera;
  } else {
    result.status = Accept(frame.stamp_s);
  }
  result.tracking = tracking_;
  if (result.status != StepStatus::kOk) return result;
  ++counters_.frames;
  if (options_.mode == CorrectionMode::kSingleFrame) {
    FitSingleFrame(camera_it->second, frame, &result);
    result.tracking = tracking_;
    return result;
  }
  if (!had_motion_input_ && HasTrack() && previous_s) PredictWithoutOdometry(frame.stamp_s - *previous_s);
  // Without odometry the tight mode corrects with the frame's robust PnP (header comment).
  const bool frame_fit = !had_motion_input_ && options_.mode == CorrectionMode::kTightCorners;
  if (frame_fit && tracking_ == TrackingStatus::kUninitialized) {
    // The first start without odometry: from all of the frame's codes at once, when one of the
    // codes it keeps is unambiguous (a single code seen head-on may flip) or it keeps two.
    const std::optional<FrameFit> fit = FitFrame(camera_it->second, frame);
    int kept = 0;
    bool unambiguous = false;
    if (fit) {
      for (size_t v = 0; v < fit->inliers.size(); ++v) {
        kept += fit->inliers[v];
        unambiguous = unambiguous || (fit->inliers[v] && fit->unambiguous[v]);
      }
    }
    if (fit && (unambiguous || kept >= 2) && StartFromFit(*fit, frame, &result)) {
      result.tracking = tracking_;
      return result;
    }
  }
  const bool had_track = HasTrack();
  const SE3d T_world_robot_predicted = state_.T_world_robot();
  std::vector<ExpectedCode> expected;
  // Codes expected in view and not seen say the robot is elsewhere only when a motion input
  // predicted where it is; a random walk predicts nothing of the kind (header comment).
  const bool test_visibility = options_.visibility.enabled && had_motion_input_;
  if (had_track && test_visibility) {
    const Camera& camera = camera_it->second;
    const Eigen::Vector3d camera_world =
        (T_world_robot_predicted * camera.info().T_robot_camera).translation();
    const std::vector<size_t>& near =
        near_codes_[frame.camera].Around(code_index_, camera, camera_world, options_.visibility);
    expected =
        PredictExpectedCodes(state_, camera, map_, code_index_, options_.visibility, component_, &near);
  }
  const bool learn =
      tracking_ == TrackingStatus::kTracking && negative_.llr() < options_.visibility.learn_below_llr;
  const long initializations = counters_.initializations;
  gated_.clear();
  int accepted = 0;
  if (frame_fit && had_track) {
    CorrectWithFrameFit(camera_it->second, frame, &result);
  } else {
    for (const CodeSighting& sighting : frame.sightings)
      result.corrections.push_back(ProcessSighting(camera_it->second, sighting));
  }
  for (const CorrectionResult& correction : result.corrections) {
    if (correction.status != StepStatus::kOk && result.status == StepStatus::kOk)
      result.status = correction.status;
    accepted += correction.outcome == CorrectionOutcome::kAccepted;
  }
  if (had_track && accepted > 0)
    predicted_before_correction_.push_back({frame.stamp_s, T_world_robot_predicted});
  if (HasTrack() && counters_.initializations == initializations) {
    const double llr = test_visibility ? TestExpectedCodes(frame, expected, result, learn) : 0.0;
    FinishFrame(accepted, llr);
  }
  gated_.clear();
  result.tracking = tracking_;
  return result;
}

bool FitDominates(const Eigen::MatrixXd& prior, const Eigen::MatrixXd& fit_covariance, double max_ratio) {
  if (!(max_ratio > 0.0)) return false;
  const Eigen::LLT<Eigen::MatrixXd> llt(prior);
  if (llt.info() != Eigen::Success) return false;
  // Generalized eigenvalues of (R, P): those of L^-1 R L^-T with P = L L^T.
  const Eigen::MatrixXd L_inv = llt.matrixL().solve(Eigen::MatrixXd::Identity(prior.rows(), prior.cols()));
  const Eigen::MatrixXd relative = L_inv * fit_covariance * L_inv.transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(0.5 * (relative + relative.transpose()),
                                                             Eigen::EigenvaluesOnly);
  return eigen.info() == Eigen::Success && eigen.eigenvalues().maxCoeff() <= max_ratio;
}

void Localizer::PredictWithoutOdometry(double dt_s) {
  if (!(dt_s > 0.0)) return;
  const int dim = state_.dim();
  Eigen::VectorXd sigma = Eigen::VectorXd::Constant(dim, options_.without_odometry.speed_mps * dt_s);
  sigma(state_.yaw_index()) = options_.without_odometry.turn_radps * dt_s;
  const Eigen::MatrixXd unit = Eigen::MatrixXd::Identity(dim, dim);
  if (state_.Propagate(state_.mean(), unit, unit, sigma.array().square().matrix().asDiagonal()) !=
      StepStatus::kOk) {
    SetLost(LostReason::kNumerical);
    return;
  }
  CheckUncertainty();
}

std::vector<PnpView> Localizer::FrameViews(const Camera& camera, const CameraFrame& frame) const {
  const double sigma_px = camera.info().pixel_sigma.value_or(options_.default_pixel_sigma_px);
  std::vector<PnpView> views;
  for (const CodeSighting& sighting : frame.sightings) {
    const MapMarker* marker = map_.Find(sighting.observation.key);
    if (marker == nullptr || !marker->has_pose) continue;
    views.push_back(
        {&camera, &sighting.observation.corners_px, sigma_px, marker->size_m, marker->T_world_marker});
  }
  return views;
}

namespace {

// Robust PnP of one frame: the Cauchy scale in whitened units of a whole code (8 residuals),
// and the iterations of Levenberg-Marquardt.
constexpr double kFrameCauchyScale = 4.0;
constexpr int kFrameFitIterations = 30;

}  // namespace

std::optional<Localizer::FrameFit> Localizer::FitFrame(const Camera& camera, const CameraFrame& frame) const {
  FrameFit fit;
  fit.views = FrameViews(camera, frame);
  const bool planar = options_.motion == MotionModel::kPlanar;
  // Starts: each code's single-image robot poses (both solutions of an ambiguous one), at most
  // kMaxStarts of them, and the current pose when there is a track.
  constexpr size_t kMaxStarts = 16;
  std::vector<SE3d> starts;
  if (HasTrack()) starts.push_back(state_.T_world_robot());
  for (const CodeSighting& sighting : frame.sightings) {
    const MapMarker* marker = map_.Find(sighting.observation.key);
    if (marker == nullptr || !marker->has_pose) continue;
    CodeSighting storage;
    const CodeSighting& solved = Solved(camera, *marker, sighting, &storage);
    fit.unambiguous.push_back(!solved.ambiguous || PlanarResolvesAmbiguity(camera, *marker, solved));
    for (size_t i = 0; i < solved.T_camera_marker.size() && starts.size() < kMaxStarts; ++i)
      starts.push_back(RestartPose(camera, *marker, solved, i));
  }
  // The fit that keeps the most codes inside the gate, then the smallest error over them.
  int best_count = 0;
  double best_error = std::numeric_limits<double>::infinity();
  for (const SE3d& start : starts) {
    const SE3d fitted = RefineRobotPose(fit.views, start, planar, kFrameCauchyScale, kFrameFitIterations);
    const std::vector<std::optional<double>> errors = RobotPnpErrors(fit.views, fitted, nullptr);
    std::vector<bool> inliers(fit.views.size(), false);
    int count = 0;
    double error = 0.0;
    for (size_t v = 0; v < fit.views.size(); ++v) {
      inliers[v] = errors[v] && *errors[v] <= gate_tight_;
      count += inliers[v];
      if (inliers[v]) error += *errors[v];
    }
    // With a track, the state's prior joins the fit's error (the negative log-posterior): an
    // ambiguous code's two solutions fit its corners about alike, and the one the track
    // expects wins unless the other fits clearly better.
    if (HasTrack() && count > 0) {
      const Eigen::VectorXd d =
          EkfState::BoxMinus(state_.mean(), PoseToStateVector(fitted, options_.motion), state_.yaw_index());
      error += d.dot(state_.covariance().ldlt().solve(d));
    }
    if (count > best_count || (count == best_count && count > 0 && error < best_error)) {
      fit.T_world_robot = fitted;
      fit.inliers = inliers;
      best_count = count;
      best_error = error;
    }
  }
  if (best_count == 0) return std::nullopt;
  // The covariance from the codes inside the gate, in the state's error coordinates, given
  // the fit's roll and pitch (the state holds them fixed; for planar robots they and z are 0):
  // with world errors [phi, dt_w] = [R dr, R dt] of the right perturbation [dr, dt], the
  // information is I_w = A I A^T (A = diag(R, R)), and the state's [dt_w (x, y[, z]), phi_z]
  // block of it is inverted. (The marginal, (A I^-1 A^T) of that block, would add the
  // uncertainty of a roll and pitch that SetLevel then takes as exact.)
  std::vector<PnpView> kept;
  for (size_t v = 0; v < fit.views.size(); ++v) {
    if (fit.inliers[v]) kept.push_back(fit.views[v]);
  }
  Matrix6d information;
  RobotPnpErrors(kept, fit.T_world_robot, &information);
  Matrix6d A = Matrix6d::Zero();
  A.topLeftCorner<3, 3>() = A.bottomRightCorner<3, 3>() = fit.T_world_robot.rotation_matrix();
  const Matrix6d information_world = A * information * A.transpose();
  const int dim = state_.dim();
  std::vector<int> index;  // state coordinate -> world error coordinate
  for (int i = 0; i < dim - 1; ++i) index.push_back(3 + i);
  index.push_back(2);
  Eigen::MatrixXd information_state(dim, dim);
  for (int i = 0; i < dim; ++i) {
    for (int j = 0; j < dim; ++j) information_state(i, j) = information_world(index[i], index[j]);
  }
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(information_state);
  if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) return std::nullopt;
  fit.covariance = ldlt.solve(Eigen::MatrixXd::Identity(dim, dim));
  if (!fit.covariance.allFinite() || Eigen::LLT<Eigen::MatrixXd>(fit.covariance).info() != Eigen::Success)
    return std::nullopt;
  return fit;
}

void Localizer::ReportFrameCodes(
    const CameraFrame& frame, FrameResult* result,
    const std::function<void(const CodeSighting&, const MapMarker&, size_t, CorrectionResult*)>& report) {
  size_t v = 0;  // index of the known codes, as in FrameViews
  for (const CodeSighting& sighting : frame.sightings) {
    CorrectionResult correction;
    correction.key = sighting.observation.key;
    const MapMarker* marker = map_.Find(sighting.observation.key);
    if (marker == nullptr || !marker->has_pose) {
      ++counters_.unknown_markers;
      correction.outcome = CorrectionOutcome::kUnknownMarker;
    } else {
      report(sighting, *marker, v++, &correction);
    }
    result->corrections.push_back(correction);
  }
}

bool Localizer::StartFromFit(const FrameFit& fit, const CameraFrame& frame, FrameResult* result) {
  if (state_.Reset(PoseToStateVector(fit.T_world_robot, options_.motion), fit.covariance) != StepStatus::kOk)
    return false;
  state_.SetLevel(fit.T_world_robot.rotation_matrix());
  const bool started = tracking_ == TrackingStatus::kUninitialized;
  tracking_ = TrackingStatus::kTracking;
  rejected_frames_in_a_row_ = 0;
  hypotheses_.clear();
  ReportFrameCodes(frame, result,
                   [&](const CodeSighting&, const MapMarker& marker, size_t v, CorrectionResult* correction) {
                     const bool inlier = fit.inliers[v];
                     correction->outcome = !inlier   ? CorrectionOutcome::kGated
                                           : started ? CorrectionOutcome::kInitialized
                                                     : CorrectionOutcome::kAccepted;
                     counters_.accepted += inlier && !started;
                     counters_.gated += !inlier;
                     if (inlier) component_ = marker.component;
                   });
  if (started) {
    ++counters_.initializations;
    negative_.Restart();
  }
  return true;
}

void Localizer::CorrectWithFrameFit(const Camera& camera, const CameraFrame& frame, FrameResult* result) {
  const std::optional<FrameFit> fit = FitFrame(camera, frame);
  UpdateResult update;
  if (fit) {
    const int dim = state_.dim();
    const Eigen::VectorXd innovation = EkfState::BoxMinus(
        state_.mean(), PoseToStateVector(fit->T_world_robot, options_.motion), state_.yaw_index());
    Eigen::MatrixXd R = fit->covariance;
    if (cameras_.size() > 1) {
      const double lever_m = camera.info().T_robot_camera.translation().norm();
      const double sigma_rad = options_.camera_mount_sigma_rad, sigma_m = options_.camera_mount_sigma_m;
      R.diagonal().head(dim - 1).array() += sigma_m * sigma_m + sigma_rad * sigma_rad * lever_m * lever_m;
      R(dim - 1, dim - 1) += sigma_rad * sigma_rad;
    }
    const Eigen::MatrixXd prior = state_.covariance();
    update = state_.Update(innovation, Eigen::MatrixXd::Identity(dim, dim), R, gate_loose_);
    // A fit that pins the pose far better than the random walk's prior in every direction is
    // taken as it is (header comment, "the fit dominates"): the prior's weight there is below
    // the error of the random walk's own mean (it predicts no motion while the camera moves).
    if (update.accepted && FitDominates(prior, R, options_.without_odometry.fit_dominance) &&
        state_.Reset(PoseToStateVector(fit->T_world_robot, options_.motion), R) == StepStatus::kOk) {
      ++counters_.frame_fits_taken;
    }
    if (update.accepted) state_.SetLevel(fit->T_world_robot.rotation_matrix());
  }
  ReportFrameCodes(
      frame, result,
      [&](const CodeSighting& sighting, const MapMarker& marker, size_t v, CorrectionResult* correction) {
        const bool used = fit && update.accepted && fit->inliers[v];
        correction->status = update.status;
        correction->nis = update.nis;
        correction->gate = gate_loose_;
        correction->innovation = update.innovation;
        correction->outcome = used ? CorrectionOutcome::kAccepted : CorrectionOutcome::kGated;
        counters_.accepted += used;
        counters_.gated += !used;
        if (used) {
          component_ = marker.component;
        } else {
          CodeSighting storage;
          gated_.push_back({&camera, &marker, Solved(camera, marker, sighting, &storage)});
        }
      });
}

void Localizer::FitSingleFrame(const Camera& camera, const CameraFrame& frame, FrameResult* result) {
  const std::optional<FrameFit> fit = FitFrame(camera, frame);
  if (fit && StartFromFit(*fit, frame, result)) return;
  ReportFrameCodes(frame, result,
                   [&](const CodeSighting&, const MapMarker&, size_t, CorrectionResult* correction) {
                     correction->outcome = CorrectionOutcome::kGated;
                     ++counters_.gated;
                   });
  // No pose for this frame; the next frame with codes has one again (no relocalization here).
  if (HasTrack()) tracking_ = TrackingStatus::kLost;
}

double Localizer::TestExpectedCodes(const CameraFrame& frame, const std::vector<ExpectedCode>& expected,
                                    const FrameResult& result, bool learn) {
  std::vector<ExpectedOutcome> outcomes(expected.size(), ExpectedOutcome::kMissed);
  int unexpected_hits = 0;
  for (const CorrectionResult& correction : result.corrections) {
    if (correction.outcome != CorrectionOutcome::kAccepted) continue;
    const auto it = std::find_if(expected.begin(), expected.end(), [&](const ExpectedCode& code) {
      return code.marker->key == correction.key;
    });
    if (it == expected.end())
      ++unexpected_hits;
    else
      outcomes[it - expected.begin()] = ExpectedOutcome::kHit;
  }
  for (size_t i = 0; i < expected.size(); ++i) {
    if (outcomes[i] == ExpectedOutcome::kHit) continue;
    for (const CodeSighting& sighting : frame.sightings) {
      if (CoversExpected(expected[i], sighting.observation.corners_px))
        outcomes[i] = ExpectedOutcome::kOccupied;
    }
    counters_.expected_missed += outcomes[i] == ExpectedOutcome::kMissed;
  }
  counters_.expected_codes += static_cast<long>(expected.size());
  return negative_.AddFrame(frame.stamp_s, frame.camera, expected, outcomes, unexpected_hits,
                            !frame.sightings.empty(), learn);
}

void Localizer::FinishFrame(int accepted, double llr) {
  const VisibilityOptions& visibility = options_.visibility;
  if (accepted > 0 && llr < visibility.suspect_llr) {
    if (tracking_ == TrackingStatus::kSuspect) ++counters_.suspect_cleared;
    tracking_ = TrackingStatus::kTracking;
    rejected_frames_in_a_row_ = 0;
    hypotheses_.clear();
    return;
  }
  if (accepted == 0 && !gated_.empty()) {
    bool contradicted = false;
    for (const GatedSighting& g : gated_)
      contradicted = contradicted || Contradicts(*g.camera, *g.marker, g.sighting);
    if (contradicted && tracking_ == TrackingStatus::kTracking) {
      tracking_ = TrackingStatus::kSuspect;
      ++counters_.times_suspect;
    }
    for (const GatedSighting& g : gated_) {
      if (OfferHypothesis(*g.camera, *g.marker, g.sighting)) return;  // restarted
    }
    if (++rejected_frames_in_a_row_ >= options_.lost_after_rejected_frames) {
      SetLost(LostReason::kGatedFrames);
      return;
    }
  }
  if (llr >= visibility.lost_llr) {
    SetLost(LostReason::kMissedCodes);
  } else if (llr >= visibility.suspect_llr && tracking_ == TrackingStatus::kTracking) {
    tracking_ = TrackingStatus::kSuspect;
    ++counters_.times_suspect;
    ++counters_.suspect_by_missed_codes;
  }
}

namespace {

// A `square` detection's corners differ from a prediction by the pose's error times ~170 px/m
// ([Seki]'s lens, 2 m up); squares of a map stand metres apart, hundreds of pixels.
constexpr double kSquareGatePx = 100.0;

// The square of the map a detection with the id "*" is (geometry/square_marker.h): the only one in
// the map, or the one the tracked pose predicts (IdentifySquare). Leaves it "*" (unknown to the
// map, counted as such) when neither tells.
// T_world_robot: the tracked pose, null without a track.
void IdentifySquareObservation(const MarkerMap& map, const Camera* camera, const SE3d* T_world_robot,
                               MarkerObservation* observation) {
  if (observation->key.family != kFamilySquare || observation->key.id != kUnidentifiedSquareId) return;
  const MapMarker* only = nullptr;
  int squares = 0;
  for (const MapMarker& m : map.markers) {
    if (m.key.family == kFamilySquare && m.has_pose) {
      only = &m;
      ++squares;
    }
  }
  if (squares == 1) {
    observation->key.id = only->key.id;
    observation->corners_px = SolidFirstToMarkerOrder(observation->corners_px, TapeOf(*only).solid_side);
    return;
  }
  if (camera == nullptr || T_world_robot == nullptr) return;
  const std::optional<SquareMatch> match = IdentifySquare(
      map, *camera, *T_world_robot * camera->info().T_robot_camera, observation->corners_px, kSquareGatePx);
  if (!match) return;
  observation->key.id = map.markers[match->index].key.id;
  observation->corners_px = match->corners_px;
}

}  // namespace

FrameResult Localizer::AddDetections(const DetectionFrame& detections) {
  CameraFrame frame;
  frame.stamp_s = detections.stamp_s;
  frame.camera = detections.camera;
  frame.sightings.reserve(detections.markers.size());
  const auto camera_it = cameras_.find(detections.camera);
  const Camera* camera = camera_it == cameras_.end() ? nullptr : &camera_it->second;
  // A plain pose and a pointer, not std::optional<SE3d>: GCC 12 warns (-Wmaybe-uninitialized,
  // falsely) about the optional's payload once IdentifySquareObservation is inlined.
  // Before the first start the start pose (moved with the odometry) stands in for the track.
  const bool tracked = HasTrack();
  const bool prior = !tracked && counters_.initializations == 0 && options_.start_pose.has_value();
  SE3d T_world_robot;
  if (tracked) {
    T_world_robot = state_.T_world_robot();
  } else if (prior) {
    T_world_robot = *options_.start_pose;
    if (first_T_odom_robot_ && last_T_odom_robot_) {
      T_world_robot = T_world_robot * (first_T_odom_robot_->inverse() * *last_T_odom_robot_);
    }
  }
  for (const MarkerObservation& observation : detections.markers) {
    CodeSighting sighting;
    sighting.observation = observation;
    IdentifySquareObservation(map_, camera, tracked || prior ? &T_world_robot : nullptr,
                              &sighting.observation);
    sighting.solved = !map_.Find(sighting.observation.key);  // nothing to solve for an unknown code
    frame.sightings.push_back(std::move(sighting));
  }
  return AddFrame(frame);
}

const CodeSighting& Localizer::Solved(const Camera& camera, const MapMarker& marker,
                                      const CodeSighting& sighting, CodeSighting* storage) const {
  if (sighting.solved) return sighting;
  *storage = MakeCodeSighting(camera, sighting.observation, marker.size_m, options_.marker_pose);
  return *storage;
}

CorrectionResult Localizer::ProcessSighting(const Camera& camera, const CodeSighting& sighting) {
  CorrectionResult result;
  result.key = sighting.observation.key;
  const MapMarker* marker = map_.Find(sighting.observation.key);
  if (!marker) {
    ++counters_.unknown_markers;
    result.outcome = CorrectionOutcome::kUnknownMarker;
    return result;
  }
  CodeSighting storage;
  if (tracking_ == TrackingStatus::kUninitialized) {
    const CodeSighting& solved = Solved(camera, *marker, sighting, &storage);
    const bool usable = !solved.ambiguous || PlanarResolvesAmbiguity(camera, *marker, solved);
    result.outcome = usable && Initialize(camera, *marker, solved) ? CorrectionOutcome::kInitialized
                                                                   : CorrectionOutcome::kNotUsable;
  } else if (tracking_ == TrackingStatus::kLost) {
    result.outcome = OfferHypothesis(camera, *marker, Solved(camera, *marker, sighting, &storage))
                         ? CorrectionOutcome::kInitialized
                         : CorrectionOutcome::kHypothesis;
  } else if (options_.mode == CorrectionMode::kLoosePose) {
    result = CorrectLoose(camera, *marker, Solved(camera, *marker, sighting, &storage));
  } else {
    result = CorrectTight(camera, *marker, sighting);
    if (result.outcome == CorrectionOutcome::kAccepted &&
        options_.attitude_source == AttitudeSource::kMarker) {
      const CodeSighting& solved = Solved(camera, *marker, sighting, &storage);
      if (!solved.T_camera_marker.empty() && !solved.ambiguous)
        state_.SetLevel(CodeHypothesis(camera, *marker, solved, 0).rotation_matrix());
    }
  }
  if (result.outcome == CorrectionOutcome::kGated) {
    gated_.push_back({&camera, marker, Solved(camera, *marker, sighting, &storage)});
  }
  if (result.outcome == CorrectionOutcome::kAccepted) component_ = marker->component;
  if ((result.outcome == CorrectionOutcome::kAccepted || result.outcome == CorrectionOutcome::kInitialized) &&
      options_.motion == MotionModel::kFree && options_.attitude_source == AttitudeSource::kOdometry)
    UpdateOdometryTilt(camera, *marker, Solved(camera, *marker, sighting, &storage));
  counters_.not_usable += result.outcome == CorrectionOutcome::kNotUsable;
  return result;
}

void Localizer::UpdateOdometryTilt(const Camera& camera, const MapMarker& marker,
                                   const CodeSighting& sighting) {
  if (options_.motion != MotionModel::kFree || options_.attitude_source != AttitudeSource::kOdometry ||
      !last_T_odom_robot_ || sighting.ambiguous || sighting.T_camera_marker.empty() || !sighting.covariance)
    return;
  const Eigen::Matrix3d R_odom_robot = last_T_odom_robot_->rotation_matrix();
  if (odometry_tilt_.Update(R_odom_robot, CodeHypothesis(camera, marker, sighting, 0).rotation_matrix(),
                            CodeAttitudeCovariance(marker, *sighting.covariance)))
    state_.SetLevel(odometry_tilt_.Level(R_odom_robot));
}

void Localizer::FinishCorrection(const UpdateResult& update, CorrectionResult* result) {
  result->status = update.status;
  result->nis = update.nis;
  result->innovation = update.innovation;
  if (update.accepted) {
    result->outcome = CorrectionOutcome::kAccepted;
    ++counters_.accepted;
  } else if (update.gated) {
    result->outcome = CorrectionOutcome::kGated;
    ++counters_.gated;
  } else {
    result->outcome = CorrectionOutcome::kNotUsable;
    if (update.status == StepStatus::kNonFiniteCovariance) SetLost(LostReason::kNumerical);
  }
}

CorrectionResult Localizer::CorrectTight(const Camera& camera, const MapMarker& marker,
                                         const CodeSighting& sighting) {
  CorrectionResult result;
  result.key = marker.key;
  result.gate = gate_tight_;
  const std::optional<CornerPrediction> prediction = PredictCorners(state_, camera, marker);
  if (!prediction || !NearImage(camera.info(), prediction->px)) {
    // The filter says this code cannot be in view (behind the camera, outside the valid field
    // of view, or far outside the image) while it was seen: evidence against the state, gated
    // like a large NIS. (Far outside, the linearization is meaningless anyway.)
    result.outcome = CorrectionOutcome::kGated;
    result.nis = std::numeric_limits<double>::infinity();
    ++counters_.gated;
    return result;
  }
  const double sigma_px = camera.info().pixel_sigma.value_or(options_.default_pixel_sigma_px);
  const Vector8d z = StackCorners(sighting.observation.corners_px);
  const MapUncertainty map_uncertainty =
      marker.covariance ? options_.map_uncertainty : MapUncertainty::kIgnore;
  // Free model: the roll and pitch error (the odometry tilt's) enters R (OdometryTilt::WorldCovariance).
  std::optional<Eigen::Matrix3d> attitude_covariance;
  if (options_.motion == MotionModel::kFree && options_.attitude_source == AttitudeSource::kOdometry &&
      last_T_odom_robot_)
    attitude_covariance = odometry_tilt_.WorldCovariance(state_.T_world_robot().rotation_matrix(),
                                                         last_T_odom_robot_->rotation_matrix());
  const MeasurementFunction linearize = [&](const EkfState& at) -> std::optional<Linearization> {
    const std::optional<CornerPrediction> p = PredictCorners(at, camera, marker);
    if (!p || !NearImage(camera.info(), p->px)) return std::nullopt;
    Linearization lin{
        z - p->px, p->H,
        CornerNoise(sigma_px, *p,
                    map_uncertainty == MapUncertainty::kInNoise ? marker.covariance : std::nullopt,
                    attitude_covariance),
        std::nullopt};
    if (map_uncertainty == MapUncertainty::kConsider)
      lin.consider = ConsideredMarker{marker.key, p->J_marker, *marker.covariance,
                                      marker.covariance_factor.value_or(CovarianceFactor(6, 0))};
    return lin;
  };
  FinishCorrection(state_.UpdateIterated(linearize, gate_tight_, options_.tight_iterations), &result);
  return result;
}

CorrectionResult Localizer::CorrectLoose(const Camera& camera, const MapMarker& marker,
                                         const CodeSighting& sighting) {
  CorrectionResult result;
  result.key = marker.key;
  result.gate = gate_loose_;
  if (sighting.T_camera_marker.empty()) return result;  // kNotUsable
  // With an ambiguous code, take the solution nearest to the prediction.
  const size_t candidates = sighting.ambiguous ? sighting.T_camera_marker.size() : 1;
  SE3d T_world_robot_code = CodeHypothesis(camera, marker, sighting, 0);
  for (size_t i = 1; i < candidates; ++i) {
    const SE3d candidate = CodeHypothesis(camera, marker, sighting, i);
    if (LooseInnovation(state_, candidate).norm() < LooseInnovation(state_, T_world_robot_code).norm()) {
      T_world_robot_code = candidate;
    }
  }
  const int dim = state_.dim();
  const Eigen::MatrixXd R = options_.loose_noise.asDiagonal();
  FinishCorrection(state_.Update(LooseInnovation(state_, T_world_robot_code),
                                 Eigen::MatrixXd::Identity(dim, dim), R, gate_loose_),
                   &result);
  if (result.outcome == CorrectionOutcome::kAccepted && options_.attitude_source == AttitudeSource::kMarker) {
    state_.SetLevel(T_world_robot_code.rotation_matrix());
  }
  return result;
}

bool Localizer::Initialize(const Camera& camera, const MapMarker& marker, const CodeSighting& sighting,
                           size_t i) {
  if (i >= sighting.T_camera_marker.size() || !sighting.covariance) return false;
  std::optional<CodeRobotPose> fitted;
  if (options_.motion == MotionModel::kPlanar) {
    fitted = PlanarPoseFromCorners(camera, marker, sighting, i);
    if (!fitted) return false;  // a corner behind the camera, no convergence, or a bad fit
  }
  const CodeRobotPose code =
      fitted ? *fitted
             : RobotPoseFromCode(marker, sighting.T_camera_marker[i], *sighting.covariance,
                                 camera.info().T_robot_camera, options_.motion);
  if (!code.T_world_robot.IsFinite() || !code.covariance.allFinite() ||
      Eigen::LLT<Eigen::MatrixXd>(code.covariance).info() != Eigen::Success) {
    return false;
  }
  const Eigen::VectorXd mean = PoseToStateVector(code.T_world_robot, options_.motion);
  const bool consider = options_.map_uncertainty == MapUncertainty::kConsider && marker.covariance;
  const StepStatus status =
      consider ? state_.Reset(mean, code.covariance, marker.key, code.cross_marker, *marker.covariance,
                              marker.covariance_factor.value_or(CovarianceFactor(6, 0)))
               : state_.Reset(mean, code.covariance);
  if (status != StepStatus::kOk) return false;
  state_.SetLevel(code.T_world_robot.rotation_matrix());
  tracking_ = TrackingStatus::kTracking;
  ++counters_.initializations;
  rejected_frames_in_a_row_ = 0;
  hypotheses_.clear();
  negative_.Restart();
  component_ = marker.component;
  return true;
}

StepStatus Localizer::InitializeAt(double stamp_s, const SE3d& T_world_robot,
                                   const Eigen::MatrixXd& covariance) {
  const int dim = state_.dim();
  if (covariance.rows() != dim || covariance.cols() != dim || !covariance.allFinite() ||
      !T_world_robot.IsFinite() || Eigen::LLT<Eigen::MatrixXd>(covariance).info() != Eigen::Success) {
    ++counters_.rejected_inputs;
    return StepStatus::kInvalidInput;
  }
  if (const StepStatus status = Accept(stamp_s); status != StepStatus::kOk) return status;
  const StepStatus status = state_.Reset(PoseToStateVector(T_world_robot, options_.motion), covariance);
  if (status != StepStatus::kOk) return status;
  state_.SetLevel(T_world_robot.rotation_matrix());
  tracking_ = TrackingStatus::kTracking;
  ++counters_.initializations;
  rejected_frames_in_a_row_ = 0;
  hypotheses_.clear();
  negative_.Restart();
  component_.reset();
  return StepStatus::kOk;
}

std::pair<double, double> Localizer::Distance(const SE3d& a, const SE3d& b) const {
  const int yaw_index = state_.yaw_index();
  const Eigen::VectorXd delta = EkfState::BoxMinus(PoseToStateVector(a, options_.motion),
                                                   PoseToStateVector(b, options_.motion), yaw_index);
  return {delta.head(yaw_index).norm(), std::abs(delta(yaw_index))};
}

bool Localizer::IsClear(const Camera& camera, const MapMarker& marker, const CodeSighting& sighting) const {
  if (sighting.ambiguous || sighting.T_camera_marker.empty() || !sighting.covariance) return false;
  const double sigma_px = camera.info().pixel_sigma.value_or(options_.default_pixel_sigma_px);
  return sighting.rms_px <= options_.clear_max_rms_sigmas * sigma_px &&
         sighting.T_camera_marker[0].translation().norm() <= options_.clear_max_range_sizes * marker.size_m;
}

bool Localizer::Contradicts(const Camera& camera, const MapMarker& marker,
                            const CodeSighting& sighting) const {
  if (sighting.T_camera_marker.empty()) return false;  // no pose: no evidence either way
  const int yaw_index = state_.yaw_index();
  const Eigen::MatrixXd& P = state_.covariance();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(P.topLeftCorner(yaw_index, yaw_index),
                                                             Eigen::EigenvaluesOnly);
  const double sigma_m = std::sqrt(std::max(0.0, eigen.eigenvalues().maxCoeff()));
  const double sigma_rad = std::sqrt(std::max(0.0, P(yaw_index, yaw_index)));
  const size_t candidates = sighting.ambiguous ? sighting.T_camera_marker.size() : 1;
  for (size_t i = 0; i < candidates; ++i) {
    const auto [trans_m, rot_rad] =
        Distance(state_.T_world_robot(), RestartPose(camera, marker, sighting, i));
    if (trans_m <= options_.agree_trans_m + 3.0 * sigma_m &&
        rot_rad <= options_.agree_rot_rad + 3.0 * sigma_rad)
      return false;
  }
  return true;
}

bool Localizer::OfferHypothesis(const Camera& camera, const MapMarker& marker, const CodeSighting& sighting) {
  if (sighting.T_camera_marker.empty()) return false;
  const bool clear = IsClear(camera, marker, sighting);
  // Codes expected and not seen already doubt the track: the contradicting code needs no second sighting.
  const bool doubted =
      tracking_ == TrackingStatus::kLost || negative_.llr() >= options_.visibility.suspect_llr;
  const int needed = !clear ? options_.relocalize_after_agreeing : doubted ? 1 : 2;
  const size_t candidates = sighting.ambiguous ? sighting.T_camera_marker.size() : 1;
  std::vector<Hypothesis> chained;
  size_t best = 0;
  for (size_t i = 0; i < candidates; ++i) {
    Hypothesis hypothesis{RestartPose(camera, marker, sighting, i), 1};
    for (const Hypothesis& previous : hypotheses_) {
      const auto [trans_m, rot_rad] = Distance(previous.T_world_robot, hypothesis.T_world_robot);
      if (trans_m < options_.agree_trans_m && rot_rad < options_.agree_rot_rad)
        hypothesis.agreeing = std::max(hypothesis.agreeing, previous.agreeing + 1);
    }
    if (chained.empty() || hypothesis.agreeing > chained[best].agreeing) best = i;
    chained.push_back(hypothesis);
  }
  hypotheses_ = std::move(chained);
  // An ambiguous code restarts only from a solution some earlier sighting confirmed.
  const bool confirmed = !sighting.ambiguous || hypotheses_[best].agreeing > 1;
  return tracking_ != TrackingStatus::kTracking && confirmed && hypotheses_[best].agreeing >= needed &&
         Initialize(camera, marker, sighting, best);
}

PoseOutput Localizer::Output() const {
  PoseOutput output;
  output.stamp_s = last_stamp_s_.value_or(0.0);
  output.tracking = tracking_;
  if (tracking_ == TrackingStatus::kTracking) {
    output.T_world_robot = state_.T_world_robot();
    output.covariance = state_.covariance();
  }
  return output;
}

}  // namespace waymark
