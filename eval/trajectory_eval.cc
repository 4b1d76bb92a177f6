#include "eval/trajectory_eval.h"

#include <cmath>
#include <stdexcept>

#include "util/check.h"

namespace waymark::eval {

bool TrajectoryEvalOptions::Check(std::string* why) const {
  WAYMARK_CHECK_OPTION(IsFiniteAtLeast(max_dt_s, 0.0), "max-dt must be a finite number >= 0 s");
  WAYMARK_CHECK_OPTION(!rpe || rpe->Check(why), nullptr);
  return true;
}

TrajectoryEvaluation EvaluateTrajectory(const Trajectory& gt, const Trajectory& est,
                                        const std::optional<Trajectory>& predicted,
                                        const TrajectoryEvalOptions& options) {
  std::string why;
  if (!options.Check(&why)) throw std::invalid_argument(why);
  TrajectoryEvaluation evaluation;
  evaluation.options = options;
  evaluation.gt_poses = gt.size();
  evaluation.est_poses = est.size();

  AssociatedTrajectories associated = Associate(gt, est, options.max_dt_s);
  const bool needs_fit = options.align != AlignmentMode::kNone || options.scale;
  if (options.align == AlignmentMode::kOrigin) {
    if (options.scale) throw std::invalid_argument("--scale does not apply to alignment origin");
    evaluation.alignment = AlignOrigin(associated.gt.front().T, associated.est.front().T);
  } else if (needs_fit) {
    evaluation.alignment =
        ComputeAlignment(options.align, options.scale, Positions(associated.est), Positions(associated.gt));
  }
  evaluation.gt_associated = std::move(associated.gt);
  evaluation.est_aligned = evaluation.alignment.Apply(associated.est);
  evaluation.ate = ComputeAte(evaluation.gt_associated, evaluation.est_aligned);
  if (options.rpe)
    evaluation.rpe = ComputeRpe(evaluation.gt_associated, evaluation.est_aligned, *options.rpe);

  if (predicted) {
    evaluation.predicted_poses = predicted->size();
    evaluation.pe_te = EvaluatePredicted(gt, *predicted, options, evaluation.alignment);
  }
  return evaluation;
}

PeTeResult EvaluatePredicted(const Trajectory& gt, const Trajectory& predicted,
                             const TrajectoryEvalOptions& options, const Sim3Alignment& alignment) {
  const AssociatedTrajectories instants = Associate(gt, predicted, options.max_dt_s, "predicted poses");
  return ComputePeTe(instants.gt, options.align_predicted ? alignment.Apply(instants.est) : instants.est);
}

}  // namespace waymark::eval
