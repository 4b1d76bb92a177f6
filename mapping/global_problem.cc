#include "mapping/global_problem.h"

#include <ceres/covariance.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "factors/board_member_factor.h"
#include "factors/odometry_se2_factor.h"
#include "factors/odometry_se3_factor.h"
#include "factors/pose_prior_se3_factor.h"
#include "factors/position_prior_factor.h"
#include "factors/yaw_prior_factor.h"
#include "geometry/board.h"
#include "mapping/boards.h"
#include "mapping/marginal_covariance.h"
#include "mapping/residuals.h"
#include "mapping/serial_blas.h"
#include "util/format.h"

namespace waymark {
namespace {

// Levenberg-Marquardt's first trust region (see GlobalProblem::Solve).
constexpr double kInitialTrustRegionRadius = 1e12;

// Forwards Ceres iterations to the progress callback.
class ProgressCallback : public ceres::IterationCallback {
 public:
  ProgressCallback(const std::function<void(const std::string&)>& progress, std::string stage)
      : progress_(progress), stage_(std::move(stage)) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& s) override {
    progress_(stage_ + ": iteration " + std::to_string(s.iteration) + ", cost " +
              FormatSignificant(s.cost, 8));
    return ceres::SOLVER_CONTINUE;
  }

 private:
  const std::function<void(const std::string&)>& progress_;
  std::string stage_;
};

// A diagonal covariance from sigmas [rotation rad, translation m] (body tangent [r, t]).
Matrix6d SigmasToCovariance(const std::array<double, 2>& sigma) {
  Vector6d variances;
  variances << sigma[0] * sigma[0], sigma[0] * sigma[0], sigma[0] * sigma[0], sigma[1] * sigma[1],
      sigma[1] * sigma[1], sigma[1] * sigma[1];
  return variances.asDiagonal();
}

PoseBlock IdentityBlock() {
  PoseBlock block;
  SE3ToBlock(SE3d(), block.data());
  return block;
}

}  // namespace

GlobalProblem::GlobalProblem(const Survey& survey, const Initialization& init, const MapBuildOptions& options)
    : survey_(survey), init_(init), options_(options) {
  std::vector<std::string> mounted;
  for (const auto& [name, camera] : survey.cameras) {
    if (camera.T_robot_camera_sigma || camera.frame_wiggle_sigma) mounted.push_back(name);
    if (camera.frame_wiggle_sigma) wiggle_slot_.emplace(name, wiggle_slot_.size());
  }
  const size_t frames = survey.frames.size(), markers = survey.markers.size(), boards = survey.boards.size();
  const size_t wiggles = frames * wiggle_slot_.size();
  // Never resized after this: the blocks' addresses are fixed.
  blocks_.assign(frames + markers + boards + mounted.size() + wiggles + 1, IdentityBlock());
  PoseBlock* next = blocks_.data();
  const auto take = [&next](size_t count) {
    const BlockRange range{next, count};
    next += count;
    return range;
  };
  robot_ = take(frames);
  marker_ = take(markers);
  board_ = take(boards);
  for (const std::string& name : mounted) mount_[name] = take(1).first;
  wiggle_blocks_ = take(wiggles);
  calibration_ = take(1).first->data();
  static_assert(kOdometryCalibrationSize <= kSE3BlockSize, "the calibration fits in a block");

  for (size_t f = 0; f < robot_.size(); ++f) {
    if (init.T_world_robot[f]) RobotToBlock(survey.motion, *init.T_world_robot[f], &robot_[f]);
  }
  for (size_t m = 0; m < marker_.size(); ++m) {
    if (init.T_world_marker[m]) SE3ToBlock(*init.T_world_marker[m], marker_[m].data());
  }
  InitBoards();
  for (const std::string& name : mounted)
    SE3ToBlock(survey.cameras.at(name).T_robot_camera, mount_[name]->data());
  const Eigen::Vector3d c = options.odometry_calibration.value_or(init.odometry_calibration);
  for (int i = 0; i < kOdometryCalibrationSize; ++i) calibration_[i] = c[i];
}

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
    if (markers_used.insert(obs.marker).second && !problem_->HasParameterBlock(CodeBlock(obs.marker)->data()))
      AddMarkerBlock(problem_.get(), CodeBlock(obs.marker));
    const CameraInfo& camera = survey_.cameras.at(obs.camera);
    const double size_m = survey_.markers[obs.marker].size_m;
    const auto mount = mount_.find(obs.camera);
    if (mount == mount_.end()) {
      AddOnCode(CornerCost(survey_.motion, camera, size_m, obs.corners_px, CornerBlocks::kRobotMarker), loss,
                {robot_[obs.frame].data(), marker_[obs.marker].data()}, obs.marker);
      continue;
    }
    if (!problem_->HasParameterBlock(mount->second->data())) {
      AddMarkerBlock(problem_.get(), mount->second);
      if (camera.T_robot_camera_sigma) {
        // The camera file's mount is the prior's mean, its T_robot_camera_sigma the prior's
        // spread (rotation and translation in the camera's body frame).
        problem_->AddResidualBlock(
            PosePriorSE3Factor::Create(camera.T_robot_camera,
                                       SigmasToCovariance(*camera.T_robot_camera_sigma)),
            nullptr, mount->second->data());
      } else {
        problem_->SetParameterBlockConstant(mount->second->data());  // held; only the wiggle moves
      }
    }
    if (!camera.frame_wiggle_sigma) {
      AddOnCode(CornerCost(survey_.motion, camera, size_m, obs.corners_px, CornerBlocks::kRobotMountMarker),
                loss, {robot_[obs.frame].data(), mount->second->data(), marker_[obs.marker].data()},
                obs.marker);
      continue;
    }
    PoseBlock& wiggle = Wiggle(obs.frame, obs.camera);
    if (!problem_->HasParameterBlock(wiggle.data())) {
      AddMarkerBlock(problem_.get(), &wiggle);
      problem_->AddResidualBlock(
          PosePriorSE3Factor::Create(SE3d(), SigmasToCovariance(*camera.frame_wiggle_sigma)), nullptr,
          wiggle.data());
    }
    AddOnCode(
        CornerCost(survey_.motion, camera, size_m, obs.corners_px, CornerBlocks::kRobotMountWiggleMarker),
        loss, {robot_[obs.frame].data(), mount->second->data(), wiggle.data(), marker_[obs.marker].data()},
        obs.marker);
  }
  if (loss != nullptr && active.empty()) delete loss;
  AddOdometry();
  AddPriorsAndGauge(markers_used, gauges);
  covariance_markers_.clear();
  std::set<const double*> listed;
  for (int m : markers_used) {
    const double* block = CodeBlock(m)->data();
    if (!problem_->IsParameterBlockConstant(block) && listed.insert(block).second)
      covariance_markers_.push_back(block);
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
  // iterations -> 8 + 3, maps equal within 11 um on the accuracy scenarios). A relative cost change of 1e-6
  // ends the robust solves, which only decide the outliers. The final solve runs to 1e-10: stopping it at
  // 1e-6 moves the maps by up to 0.08 mm now for one iteration, and left sparse-code maps up to
  // 50 % worse with the default radius (corridor d = 4 m seed 3: 45 -> 69 mm).
  ceres::Solver::Options solver_options;
  solver_options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  solver_options.sparse_linear_algebra_library_type = ceres::SUITE_SPARSE;
  solver_options.initial_trust_region_radius = kInitialTrustRegionRadius;
  solver_options.max_num_iterations = options_.max_iterations;
  solver_options.num_threads = options_.num_threads;
  // Without odometry between the frames in the problem (a survey without odometry: TagSLAM's
  // multi-camera rigs and hand-held cameras), no residual joins two frames: the frames are an
  // independent set, eliminated first (SPARSE_SCHUR), and the reduced system holds only the
  // codes. TagSLAM test6 (1 478 frames, 35 codes, 61 619 observations, 23 robust iterations):
  // the linear solver took 0.50 of the Jacobian evaluation time with Cholesky of the normal
  // equations, 0.21 with this (16.0 of 32.1 s, then 10.5 of 49.7 s on a busier machine); the
  // map is the same within 1e-15 m.
  // The blocks in `first` are an independent set (no residual joins two of them): eliminated
  // first by a Schur complement, the rest form the reduced system.
  const auto eliminate_first = [&](const std::set<const double*>& first) {
    auto ordering = std::make_shared<ceres::ParameterBlockOrdering>();
    std::vector<double*> blocks;
    problem_->GetParameterBlocks(&blocks);
    for (double* block : blocks) ordering->AddElementToGroup(block, first.count(block) > 0 ? 0 : 1);
    solver_options.linear_solver_type = ceres::SPARSE_SCHUR;
    solver_options.linear_solver_ordering = ordering;
    // One thread: Ceres' Schur eliminator adds each eliminated block's contribution to the
    // reduced system under a lock, in whatever order the threads reach it, so with two threads
    // the sums (and the map) differed in their last bits from run to run (TagSLAM test6: every
    // one of the 1 478 poses and 35 codes). The map must be the same at any load
    // (docs/mapping.md, "Determinism"); the cost is in wall time only (test6: 37-39 s of CPU
    // time either way), as the second thread sped up the Jacobians.
    solver_options.num_threads = 1;
  };
  if (HasWiggle()) {
    // Each frame's camera deviations touch only that frame and camera's residuals: they are
    // the independent set; frames, codes and mounts form the reduced system.
    std::set<const double*> wiggles;
    for (const PoseBlock& block : wiggle_blocks_) wiggles.insert(block.data());
    eliminate_first(wiggles);
  } else if (!FramesJoined()) {
    std::set<const double*> frames;
    for (const PoseBlock& block : robot_) frames.insert(block.data());
    eliminate_first(frames);
  }
  solver_options.function_tolerance = robust ? 1e-6 : 1e-10;
  solver_options.parameter_tolerance = robust ? 1e-8 : 1e-10;
  std::unique_ptr<ProgressCallback> callback;
  if (options_.progress) {
    callback = std::make_unique<ProgressCallback>(options_.progress, robust ? "robust solve" : "final solve");
    solver_options.callbacks.push_back(callback.get());
  }
  ceres::Solver::Summary summary;
  {
    const ScopedSerialLinearAlgebra serial;  // the same result at any load
    ceres::Solve(solver_options, problem_.get(), &summary);
  }
  SyncBoardCodes();
  return summary;
}

void GlobalProblem::InitBoards() {
  board_placed_.assign(survey_.boards.size(), false);
  for (size_t b = 0; b < survey_.boards.size(); ++b) {
    const std::optional<SE3d> T = InitialBoardPose(survey_, init_, static_cast<int>(b));
    if (!T) continue;
    SE3ToBlock(survey_.boards[b].fixed_pose.value_or(*T), board_[b].data());
    board_placed_[b] = true;
  }
  SyncBoardCodes();
}

void GlobalProblem::SyncBoardCodes() {
  for (size_t m = 0; m < survey_.markers.size(); ++m) {
    if (OnBoard(static_cast<int>(m)))
      SE3ToBlock(Board(survey_.markers[m].board) * survey_.markers[m].T_board_marker, marker_[m].data());
  }
}

void GlobalProblem::AddOnCode(ceres::CostFunction* cost, ceres::LossFunction* loss,
                              std::vector<double*> blocks, int m) {
  if (OnBoard(m)) {
    cost = new BoardMemberCost(cost, survey_.markers[m].T_board_marker);
    blocks.back() = board_[survey_.markers[m].board].data();
  }
  problem_->AddResidualBlock(cost, loss, blocks);
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
    if ((marker.known && marker.known->fixed) || OnBoard(m)) continue;  // a board moves as a whole
    const std::optional<SE3d> T =
        MarkerByConsensus(survey_, cameras, init_.views, T_world_robot, m, options_.initializer.cauchy_scale);
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
    if (!init_.T_world_marker[m] || outlying.count(code) > 0 || fixed || OnBoard(code)) continue;
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
bool GlobalProblem::FramesJoined() const {
  for (const OdometryLink& link : survey_.odometry_links) {
    if (FramePlaced(link.frame_a) && FramePlaced(link.frame_b)) return true;
  }
  return false;
}

double GlobalProblem::OdometryVarianceFactor() const {
  double sum = 0.0;
  size_t count = 0;
  for (const ceres::ResidualBlockId id : odometry_residuals_) {
    const int size = problem_->GetCostFunctionForResidualBlock(id)->num_residuals();
    std::vector<double> residuals(size);
    double cost = 0.0;
    if (!problem_->EvaluateResidualBlock(id, false, &cost, residuals.data(), nullptr)) continue;
    for (double r : residuals) sum += r * r;
    count += size;
  }
  // In units of the variances the odometry links were built with (not the scaled ones).
  return count == 0 ? 1.0 : odometry_variance_scale_ * sum / static_cast<double>(count);
}

void GlobalProblem::AddOdometry() {
  odometry_residuals_.clear();
  for (const OdometryLink& link : survey_.odometry_links) {
    if (!FramePlaced(link.frame_a) || !FramePlaced(link.frame_b)) continue;
    for (int f : {link.frame_a, link.frame_b}) {
      if (!problem_->HasParameterBlock(robot_[f].data()))
        AddRobotBlock(problem_.get(), survey_.motion, &robot_[f]);
    }
    const double scale = odometry_variance_scale_;
    if (options_.calibrate_odometry) {
      AddCalibratedOdometry(link);
    } else if (survey_.motion == MotionModel::kPlanar) {
      odometry_residuals_.push_back(problem_->AddResidualBlock(
          OdometrySE2Factor::Create(SE2d::FromSE3(link.T_a_b), scale * link.covariance_se2), nullptr,
          robot_[link.frame_a].data(), robot_[link.frame_b].data()));
    } else {
      odometry_residuals_.push_back(
          problem_->AddResidualBlock(OdometrySE3Factor::Create(link.T_a_b, scale * link.covariance_se3),
                                     nullptr, robot_[link.frame_a].data(), robot_[link.frame_b].data()));
    }
  }
}

void GlobalProblem::AddCalibratedOdometry(const OdometryLink& link) {
  if (!problem_->HasParameterBlock(calibration_)) {
    problem_->AddParameterBlock(calibration_, kOdometryCalibrationSize);
    problem_->AddResidualBlock(
        OdometryCalibrationPrior::Create(options_.odometry_calibration.value_or(Eigen::Vector3d::Zero()),
                                         options_.odometry_calibration_sigma.value_or(
                                             Eigen::Vector3d::Constant(options_.calibration_sigma))),
        nullptr, calibration_);
    if (options_.odometry_calibration && !options_.odometry_calibration_sigma) {
      problem_->SetParameterBlockConstant(calibration_);
    }
  }
  const double scale = odometry_variance_scale_;
  ceres::CostFunction* cost =
      survey_.motion == MotionModel::kPlanar
          ? CalibratedOdometrySE2Factor::Create(SE2d::FromSE3(link.T_a_b), scale * link.covariance_se2)
          : CalibratedOdometrySE3Factor::Create(link.T_a_b, scale * link.covariance_se3);
  odometry_residuals_.push_back(problem_->AddResidualBlock(cost, nullptr, robot_[link.frame_a].data(),
                                                           robot_[link.frame_b].data(), calibration_));
}

void GlobalProblem::AddPriorsAndGauge(const std::set<int>& markers_used, std::vector<std::string>* gauges) {
  gauges->assign(init_.components, "");
  std::vector<int> anchors(init_.components, 0), payloads(init_.components, 0),
      payloads_z(init_.components, 0);
  std::set<int> boards_used;
  for (int m : markers_used) {
    const SurveyMarker& marker = survey_.markers[m];
    const int c = init_.marker_component[m];
    if (OnBoard(m)) {
      // The board's world information goes on the board's block, once (mapping/boards.h).
      if (!boards_used.insert(marker.board).second) continue;
      const SurveyBoard& board = survey_.boards[marker.board];
      double* block = board_[marker.board].data();
      if (board.fixed_pose) {
        SE3ToBlock(*board.fixed_pose, block);
        problem_->SetParameterBlockConstant(block);
        ++anchors[c];
      }
      for (const BoardPrior& prior : board.priors) {
        problem_->AddResidualBlock(PosePriorSE3Factor::Create(prior.T_world_board, prior.covariance), nullptr,
                                   block);
      }
      if (!board.priors.empty() && !board.fixed_pose) ++anchors[c];
      continue;
    }
    if (marker.known && marker.known->fixed) {
      SE3ToBlock(marker.known->T_world_marker, marker_[m].data());
      problem_->SetParameterBlockConstant(marker_[m].data());
      ++anchors[c];
    } else if (marker.known && marker.known->covariance) {
      problem_->AddResidualBlock(
          PosePriorSE3Factor::Create(marker.known->T_world_marker, *marker.known->covariance), nullptr,
          marker_[m].data());
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
      AddOnCode(
          PositionPriorFactor<3>::Create(Eigen::Vector3d(*p.x_m, *p.y_m, *p.z_m), options_.payload_sigma_m),
          nullptr, {marker_[m].data()}, m);
      ++payloads_z[c];
    } else {
      AddOnCode(PositionPriorFactor<2>::Create(Eigen::Vector2d(*p.x_m, *p.y_m), options_.payload_sigma_m),
                nullptr, {marker_[m].data()}, m);
    }
    if (p.yaw_rad) {
      AddOnCode(YawPriorFactor::Create(*p.yaw_rad, options_.payload_yaw_sigma_rad), nullptr,
                {marker_[m].data()}, m);
    }
    ++payloads[c];
  }
  for (int c = 0; c < init_.components; ++c) {
    int first = -1;
    for (size_t f = 0; f < survey_.frames.size() && first < 0; ++f) {
      if (init_.frame_component[f] == c && problem_->HasParameterBlock(robot_[f].data()))
        first = static_cast<int>(f);
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
        problem_->AddResidualBlock(PosePriorSE3Factor::Create(Robot(first), Matrix6d(variances.asDiagonal())),
                                   nullptr, robot_[first].data());
      }
    } else if (first >= 0) {
      problem_->SetParameterBlockConstant(robot_[first].data());
      (*gauges)[c] = "first frame held fixed";
    }
  }
}

std::map<std::string, SE3d> GlobalProblem::Mounts() const {
  std::map<std::string, SE3d> mounts;
  for (const auto& [name, block] : mount_) {
    if (problem_ && problem_->HasParameterBlock(block->data()) &&
        !problem_->IsParameterBlockConstant(block->data()))
      mounts[name] = SE3FromBlock(block->data());
  }
  return mounts;
}

bool GlobalProblem::HasWiggle() const {
  for (const PoseBlock& block : wiggle_blocks_) {
    if (problem_->HasParameterBlock(block.data())) return true;
  }
  return false;
}

std::map<std::string, std::vector<SE3d>> GlobalProblem::Wiggles() const {
  std::map<std::string, std::vector<SE3d>> wiggles;
  if (!problem_) return wiggles;
  for (size_t f = 0; f < survey_.frames.size(); ++f) {
    for (const auto& [name, slot] : wiggle_slot_) {
      const PoseBlock& block = Wiggle(static_cast<int>(f), name);
      if (problem_->HasParameterBlock(block.data())) wiggles[name].push_back(SE3FromBlock(block.data()));
    }
  }
  return wiggles;
}

double GlobalProblem::SquaredError(int o) const {
  const SurveyObservation& obs = survey_.observations[o];
  const CameraInfo& camera = survey_.cameras.at(obs.camera);
  const double size_m = survey_.markers[obs.marker].size_m;
  const auto mount = mount_.find(obs.camera);
  double residuals[8];
  double s = 0.0;
  std::unique_ptr<ceres::CostFunction> cost;
  bool evaluated = false;
  if (mount == mount_.end()) {
    cost.reset(CornerCost(survey_.motion, camera, size_m, obs.corners_px, CornerBlocks::kRobotMarker));
    const double* blocks[2] = {robot_[obs.frame].data(), marker_[obs.marker].data()};
    evaluated = cost->Evaluate(blocks, residuals, nullptr);
  } else if (camera.frame_wiggle_sigma) {
    // The frame's deviation counts in the gate (whitened by its prior): a view that only fits
    // by moving its camera far off the mount is not hidden by the wiggle.
    // Identity until a solve has moved it.
    const PoseBlock& W = Wiggle(obs.frame, obs.camera);
    cost.reset(
        CornerCost(survey_.motion, camera, size_m, obs.corners_px, CornerBlocks::kRobotMountWiggleMarker));
    const double* blocks[4] = {robot_[obs.frame].data(), mount->second->data(), W.data(),
                               marker_[obs.marker].data()};
    evaluated = cost->Evaluate(blocks, residuals, nullptr);
    const Vector6d delta = SE3d().BoxMinus(SE3FromBlock(W.data()));
    const std::array<double, 2>& sigma = *camera.frame_wiggle_sigma;
    s += delta.head<3>().squaredNorm() / (sigma[0] * sigma[0]) +
         delta.tail<3>().squaredNorm() / (sigma[1] * sigma[1]);
  } else {
    cost.reset(CornerCost(survey_.motion, camera, size_m, obs.corners_px, CornerBlocks::kRobotMountMarker));
    const double* blocks[3] = {robot_[obs.frame].data(), mount->second->data(), marker_[obs.marker].data()};
    evaluated = cost->Evaluate(blocks, residuals, nullptr);
  }
  if (!evaluated) return std::numeric_limits<double>::infinity();
  for (double r : residuals) s += r * r;
  return s;
}

bool GlobalProblem::Covariances(int factor_rank, std::vector<std::optional<Matrix6d>>* covariance,
                                std::vector<std::optional<CovarianceFactor>>* factors,
                                std::optional<Eigen::Matrix3d>* calibration_covariance,
                                std::map<std::string, Matrix6d>* mount_covariance,
                                std::vector<std::optional<Matrix6d>>* board_covariance) const {
  covariance->assign(survey_.markers.size(), std::nullopt);
  if (board_covariance != nullptr) board_covariance->assign(survey_.boards.size(), std::nullopt);
  factors->assign(survey_.markers.size(), std::nullopt);
  calibration_covariance->reset();
  mount_covariance->clear();
  MarginalCovarianceOptions marginal_options;
  marginal_options.num_threads = options_.num_threads;
  std::vector<const double*> marginal_blocks = covariance_markers_;  // markers first, mounts, then c
  std::vector<std::string> mounts;
  for (const auto& [name, block] : mount_) {
    if (problem_->HasParameterBlock(block->data()) && !problem_->IsParameterBlockConstant(block->data())) {
      marginal_blocks.push_back(block->data());
      mounts.push_back(name);
    }
  }
  if (CalibrationEstimated()) marginal_blocks.push_back(calibration_);
  const InformationFactor information(problem_.get(), marginal_blocks, marginal_options);
  if (information.size() == 0) return covariance_markers_.empty();
  if (!information.positive_definite()) return false;
  const std::vector<Eigen::MatrixXd> manifold = information.Marginals();  // marginal_blocks order
  if (CalibrationEstimated()) *calibration_covariance = Eigen::Matrix3d(manifold.back());
  for (size_t i = 0; i < mounts.size(); ++i) {
    const Matrix6d J = ManifoldToBodyTangentJacobian(SE3FromBlock(mount_.at(mounts[i])->data()));
    const Matrix6d body = J * Matrix6d(manifold[covariance_markers_.size() + i]) * J.transpose();
    (*mount_covariance)[mounts[i]] = 0.5 * (body + body.transpose());
  }
  std::map<const double*, size_t> index_of;
  for (size_t i = 0; i < covariance_markers_.size(); ++i) index_of[covariance_markers_[i]] = i;
  const size_t count = covariance_markers_.size();
  std::vector<SE3d> poses(count);  // of the blocks, in covariance_markers_ order
  std::vector<Matrix6d> marginals(count);
  std::vector<std::vector<size_t>> markers(count);  // the codes of each block (several on a board)
  for (size_t m = 0; m < survey_.markers.size(); ++m) {
    const int code = static_cast<int>(m);
    const auto it = index_of.find(CodeBlock(code)->data());
    if (it == index_of.end()) continue;
    const size_t i = it->second;
    if (markers[i].empty()) {
      poses[i] = OnBoard(code) ? Board(survey_.markers[m].board) : Marker(code);
      const Matrix6d J = ManifoldToBodyTangentJacobian(poses[i]);
      const Matrix6d body = J * Matrix6d(manifold[i]) * J.transpose();
      marginals[i] = 0.5 * (body + body.transpose());
      if (OnBoard(code) && board_covariance != nullptr)
        (*board_covariance)[survey_.markers[m].board] = marginals[i];
    }
    markers[i].push_back(m);
    (*covariance)[m] =
        OnBoard(code) ? MemberCovariance(marginals[i], survey_.markers[m].T_board_marker) : marginals[i];
  }
  if (factor_rank <= 0) return true;
  CovarianceFactorOptions factor_options;
  factor_options.rank = factor_rank;
  const auto rows =
      MarkerCovarianceFactors(information, covariance_markers_, poses, marginals, factor_options);
  for (size_t i = 0; rows && i < markers.size(); ++i) {
    for (size_t m : markers[i]) {
      (*factors)[m] =
          OnBoard(static_cast<int>(m))
              ? CovarianceFactor(BoardToMemberJacobian(survey_.markers[m].T_board_marker) * (*rows)[i])
              : (*rows)[i];
    }
  }
  return true;
}

}  // namespace waymark
