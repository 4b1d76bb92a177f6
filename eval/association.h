// Timestamp association of two trajectories, exactly as evo does it
// (evo/core/sync.py: associate_trajectories and matching_time_indices):
//
//   - the SHORTER trajectory is iterated; when both have the same number of poses the
//     estimate is iterated (evo passes (reference, estimate) and only swaps when the second
//     one is strictly longer);
//   - each of its stamps t_s is matched to the pose of the other trajectory whose stamp t_l
//     minimizes |t_l - t_s| (the FIRST such pose on ties, like numpy.argmin);
//   - the pair is kept when |t_l - t_s| <= max_dt_s (inclusive, evaluated in double
//     precision exactly as numpy does).
//
// Consequences worth knowing (and tested): a pose of the longer trajectory may be used by
// several pairs; a stamp of the shorter one with no neighbour within max_dt_s is dropped;
// pairs come out in the order of the shorter trajectory.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "geometry/types.h"

namespace waymark::eval {

inline constexpr double kDefaultMaxDtS = 0.01;  // evo's default --t_max_diff

struct StampPair {
  size_t gt_index = 0;
  size_t est_index = 0;
};

// Index pairs (into gt and est) in evo's order. Empty when nothing associates.
// Uses binary search when the searched trajectory is sorted by stamp (same result as the
// linear argmin), and a linear scan otherwise.
std::vector<StampPair> AssociateByStamp(const Trajectory& gt, const Trajectory& est, double max_dt_s);

// The two trajectories reduced to the associated pairs, element i of each forming pair i.
struct AssociatedTrajectories {
  Trajectory gt;
  Trajectory est;
  std::vector<StampPair> pairs;
};

// Throws std::runtime_error when no pair associates; the message gives both sizes, the
// stamp ranges and suggests a larger --max-dt. `est_name` names the estimate in it.
AssociatedTrajectories Associate(const Trajectory& gt, const Trajectory& est, double max_dt_s,
                                 const std::string& est_name = "estimate");

}  // namespace waymark::eval
