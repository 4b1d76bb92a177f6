// The global problem of a map build (mapping/map_builder.h, stage 3): every placed frame and
// marker of a survey as Ceres parameter blocks, the corner observations (factors/), odometry
// (plain or calibrated), priors and the gauge; one solve, per-observation errors, the
// re-placement of outlying markers, and the covariances from one factorization of H.
#pragma once

#include <ceres/ceres.h>

#include <array>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "factors/calibrated_odometry_factor.h"
#include "factors/pose_block.h"
#include "mapping/initializer.h"
#include "mapping/map_builder.h"
#include "mapping/map_covariance.h"
#include "mapping/residuals.h"
#include "mapping/survey.h"

namespace waymark {

// The global problem over the placed frames and markers of a survey.
class GlobalProblem {
 public:
  GlobalProblem(const Survey& survey, const Initialization& init, const MapBuildOptions& options);
  // The blocks point into blocks_: not copyable.
  GlobalProblem(const GlobalProblem&) = delete;
  GlobalProblem& operator=(const GlobalProblem&) = delete;

  // One solve over the observations in `active` (indices), with or without the robust loss.
  ceres::Solver::Summary Solve(const std::vector<int>& active, bool robust, std::vector<std::string>* gauges);
  // Whitened squared norm of an observation at the current values (+inf behind the camera).
  double SquaredError(int o) const;
  // Marker covariances in map.json's convention and, with factor_rank > 0, the markers' rows of
  // the joint covariance factor (mapping/map_covariance.h), both from one factorization of H
  // (mapping/marginal_covariance.h); false when H is not positive definite (a free gauge).
  // With the odometry calibration estimated, its covariance goes to *calibration_covariance;
  // each estimated camera mount's (body tangent [r, t], geometry/pose.h) to *mount_covariance.
  bool Covariances(int factor_rank, std::vector<std::optional<Matrix6d>>* covariance,
                   std::vector<std::optional<CovarianceFactor>>* factors,
                   std::optional<Eigen::Matrix3d>* calibration_covariance,
                   std::map<std::string, Matrix6d>* mount_covariance,
                   std::vector<std::optional<Matrix6d>>* board_covariance = nullptr) const;
  // The odometry calibration of the problem, nullopt when it has no calibrated odometry link.
  std::optional<Eigen::Vector3d> Calibration() const {
    if (!problem_->HasParameterBlock(calibration_)) return std::nullopt;
    return Eigen::Vector3d(calibration_[0], calibration_[1], calibration_[2]);
  }
  bool CalibrationEstimated() const {
    return problem_->HasParameterBlock(calibration_) && !problem_->IsParameterBlockConstant(calibration_);
  }

  // Re-places the codes with an observation above the outlier gate by consensus over their
  // views at the current frame poses (mapping/initializer.h), and moves the codes whose other
  // planar-flip branch fits better there (OtherFlipBranch); returns how many moved.
  size_t ReplaceOutlyingMarkers(const std::vector<int>& active, const std::map<std::string, Camera>& cameras);

  // The odometry's mean squared whitened residual per degree of freedom at the current values,
  // in units of the odometry noise the survey states (1 when the statement is right; a
  // variance component estimate, biased low since the poses absorb part of each residual).
  double OdometryVarianceFactor() const;
  // Scales every odometry link's covariance by `scale` from the next Solve on.
  void SetOdometryVarianceScale(double scale) { odometry_variance_scale_ = scale; }
  double OdometryVarianceScale() const { return odometry_variance_scale_; }

  // The estimated mounts (T_robot_camera) of the cameras with a T_robot_camera_sigma that
  // observe something in the problem, by camera name.
  std::map<std::string, SE3d> Mounts() const;
  // Each frame's deviation of a camera off its mount (cameras with frame_wiggle_sigma), by
  // camera name, over the frames in the problem.
  std::map<std::string, std::vector<SE3d>> Wiggles() const;

  bool FramePlaced(int f) const { return init_.T_world_robot[f].has_value(); }
  SE3d Robot(int f) const { return RobotFromBlock(survey_.motion, robot_[f]); }
  SE3d Marker(int m) const { return SE3FromBlock(marker_[m].data()); }
  // A rigid board's pose (mapping/boards.h); its codes' Marker() is Board(b) * T_board_marker.
  bool BoardPlaced(int b) const { return board_placed_[b]; }
  SE3d Board(int b) const { return SE3FromBlock(board_[b].data()); }

 private:
  void AddPriorsAndGauge(const std::set<int>& markers_used, std::vector<std::string>* gauges);
  void AddOdometry();
  // Whether an odometry link joins two frames of the problem (else the frames are eliminated
  // first by a Schur complement).
  bool FramesJoined() const;
  // Whether a frame's camera deviation (frame_wiggle_sigma) is in the problem.
  bool HasWiggle() const;
  void AddCalibratedOdometry(const OdometryLink& link);
  // Rigid boards (mapping/boards.h): initial board poses; the pose block of a code (its board's
  // for a code on a board); a residual whose last block is code m's pose, on its board's block
  // through factors/board_member_factor.h when it is on a board; the codes' poses from their
  // boards' after a solve.
  void InitBoards();
  bool OnBoard(int m) const {
    return survey_.markers[m].board >= 0 && board_placed_[survey_.markers[m].board];
  }
  PoseBlock* CodeBlock(int m) { return OnBoard(m) ? &board_[survey_.markers[m].board] : &marker_[m]; }
  const PoseBlock* CodeBlock(int m) const {
    return OnBoard(m) ? &board_[survey_.markers[m].board] : &marker_[m];
  }
  void AddOnCode(ceres::CostFunction* cost, ceres::LossFunction* loss, std::vector<double*> blocks, int m);
  void SyncBoardCodes();

  const Survey& survey_;
  const Initialization& init_;
  const MapBuildOptions& options_;
  // A run of pose blocks inside blocks_.
  struct BlockRange {
    PoseBlock* first = nullptr;
    size_t count = 0;
    PoseBlock& operator[](size_t i) const { return first[i]; }
    size_t size() const { return count; }
    PoseBlock* begin() const { return first; }
    PoseBlock* end() const { return first + count; }
  };
  // Every parameter block of the problem lives in this one buffer, allocated once, in a fixed
  // order: frames, codes, boards, mounts, each frame's camera wiggles, the odometry calibration.
  // Ceres orders the blocks of an elimination group by their addresses (ParameterBlockOrdering
  // holds std::set<double*>), and the Schur solves eliminate and factor in that order: with the
  // blocks spread over the heap, where the allocator put them (which depends on the threads'
  // timing) decided the rounding of the solve, and two builds of one survey differed in their
  // last bits (docs/mapping.md, "Determinism").
  std::vector<PoseBlock> blocks_;
  BlockRange robot_, marker_;
  BlockRange board_;  // per Survey::boards
  std::vector<bool> board_placed_;
  // Cameras whose mount is a block: estimated (T_robot_camera_sigma), or held constant with a
  // per-frame wiggle around it (frame_wiggle_sigma only).
  std::map<std::string, PoseBlock*> mount_;
  // Each frame's deviation of a wiggling camera: blocks_ holds one per frame and such camera,
  // frame-major (wiggle_slot_ gives the camera's place), identity until a solve moves it.
  BlockRange wiggle_blocks_;
  std::map<std::string, size_t> wiggle_slot_;
  PoseBlock& Wiggle(int frame, const std::string& camera) const {
    return wiggle_blocks_[frame * wiggle_slot_.size() + wiggle_slot_.at(camera)];
  }
  double* calibration_ = nullptr;  // kOdometryCalibrationSize values at the start of a block
  double odometry_variance_scale_ = 1.0;
  std::vector<ceres::ResidualBlockId> odometry_residuals_;
  std::unique_ptr<ceres::Problem> problem_;
  std::vector<const double*> covariance_markers_;
};

}  // namespace waymark
