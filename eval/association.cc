#include "eval/association.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace waymark::eval {
namespace {

bool IsSorted(const Trajectory& trajectory) {
  for (size_t i = 1; i < trajectory.size(); ++i) {
    if (trajectory[i].stamp_s < trajectory[i - 1].stamp_s) return false;
  }
  return true;
}

// numpy.argmin(|stamps - stamp|): the first index of the smallest difference.
size_t ArgMinLinear(const Trajectory& trajectory, double stamp_s) {
  size_t best = 0;
  double best_diff = std::abs(trajectory[0].stamp_s - stamp_s);
  for (size_t i = 1; i < trajectory.size(); ++i) {
    const double diff = std::abs(trajectory[i].stamp_s - stamp_s);
    if (diff < best_diff) {
      best = i;
      best_diff = diff;
    }
  }
  return best;
}

// Same result as ArgMinLinear for a trajectory sorted by stamp. |t_i - stamp| computed in
// floating point is non-increasing left of the first t_i >= stamp and non-decreasing from
// it on, so the first minimum is the leftmost of the equal values just left of that point,
// or that point itself.
size_t ArgMinSorted(const Trajectory& trajectory, double stamp_s) {
  const auto it = std::lower_bound(trajectory.begin(), trajectory.end(), stamp_s,
                                   [](const StampedSE3& p, double t) { return p.stamp_s < t; });
  const size_t right = static_cast<size_t>(it - trajectory.begin());
  if (right == 0) return 0;
  size_t left = right - 1;
  const double left_diff = std::abs(trajectory[left].stamp_s - stamp_s);
  while (left > 0 && std::abs(trajectory[left - 1].stamp_s - stamp_s) == left_diff) --left;
  if (right == trajectory.size()) return left;
  const double right_diff = std::abs(trajectory[right].stamp_s - stamp_s);
  return left_diff <= right_diff ? left : right;
}

}  // namespace

std::vector<StampPair> AssociateByStamp(const Trajectory& gt, const Trajectory& est, double max_dt_s) {
  std::vector<StampPair> pairs;
  if (gt.empty() || est.empty()) return pairs;
  const bool est_longer = est.size() > gt.size();
  const Trajectory& shorter = est_longer ? gt : est;
  const Trajectory& longer = est_longer ? est : gt;
  const bool sorted = IsSorted(longer);
  for (size_t i = 0; i < shorter.size(); ++i) {
    const double stamp_s = shorter[i].stamp_s;
    const size_t j = sorted ? ArgMinSorted(longer, stamp_s) : ArgMinLinear(longer, stamp_s);
    if (!(std::abs(longer[j].stamp_s - stamp_s) <= max_dt_s)) continue;
    pairs.push_back(est_longer ? StampPair{i, j} : StampPair{j, i});
  }
  return pairs;
}

AssociatedTrajectories Associate(const Trajectory& gt, const Trajectory& est, double max_dt_s,
                                 const std::string& est_name) {
  AssociatedTrajectories result;
  result.pairs = AssociateByStamp(gt, est, max_dt_s);
  if (result.pairs.empty()) {
    std::ostringstream why;
    why << "no pose pairs associated within max-dt " << max_dt_s << " s (ground truth: " << gt.size()
        << " poses";
    if (!gt.empty()) why << ", t = " << gt.front().stamp_s << " .. " << gt.back().stamp_s;
    why << "; " << est_name << ": " << est.size() << " poses";
    if (!est.empty()) why << ", t = " << est.front().stamp_s << " .. " << est.back().stamp_s;
    why << "); are the stamps on the same clock? Try a larger --max-dt";
    throw std::runtime_error(why.str());
  }
  result.gt.reserve(result.pairs.size());
  result.est.reserve(result.pairs.size());
  for (const StampPair& pair : result.pairs) {
    result.gt.push_back(gt[pair.gt_index]);
    result.est.push_back(est[pair.est_index]);
  }
  return result;
}

}  // namespace waymark::eval
