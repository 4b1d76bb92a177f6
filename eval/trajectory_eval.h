// The whole trajectory evaluation, in evo's order:
//   1. associate estimate and ground truth by stamp (eval/association.h, --max-dt);
//   2. fit the alignment on the associated positions (eval/alignment.h, --align, --scale)
//      and apply it to the estimate: T_gt_robot = align(T_est_robot);
//   3. ATE on the associated, aligned pairs; RPE (if asked) on the same pairs;
//   4. PE / TE (if a predicted trajectory is given): predicted poses associated to the
//      ground truth the same way, with NO alignment (the localizer's map frame is the world
//      frame) unless `align_predicted` is set, in which case the alignment of step 2 is used.
#pragma once

#include <optional>

#include "eval/alignment.h"
#include "eval/association.h"
#include "eval/trajectory_metrics.h"
#include "geometry/types.h"

namespace waymark::eval {

struct TrajectoryEvalOptions {
  AlignmentMode align = AlignmentMode::kSE3;
  bool scale = false;
  double max_dt_s = kDefaultMaxDtS;
  std::optional<RpeOptions> rpe;
  bool align_predicted = false;
  bool Check(std::string* why) const;
};

struct TrajectoryEvaluation {
  TrajectoryEvalOptions options;
  size_t gt_poses = 0;
  size_t est_poses = 0;
  Sim3Alignment alignment;   // estimate world -> ground-truth world
  Trajectory gt_associated;  // the ground-truth pose of each pair
  Trajectory est_aligned;    // the estimate's pose of each pair, aligned
  AteResult ate;
  std::optional<RpeResult> rpe;
  size_t predicted_poses = 0;
  std::optional<PeTeResult> pe_te;
};

// PE / TE of step 4 alone: `predicted` associated to `gt` with options.max_dt_s, moved by
// `alignment` only when options.align_predicted. Throws std::runtime_error when no predicted
// pose associates.
PeTeResult EvaluatePredicted(const Trajectory& gt, const Trajectory& predicted,
                             const TrajectoryEvalOptions& options, const Sim3Alignment& alignment);

// Throws std::invalid_argument for bad options, std::runtime_error when nothing associates,
// the alignment is degenerate or the RPE delta leaves no pair.
TrajectoryEvaluation EvaluateTrajectory(const Trajectory& gt, const Trajectory& est,
                                        const std::optional<Trajectory>& predicted,
                                        const TrajectoryEvalOptions& options);

}  // namespace waymark::eval
