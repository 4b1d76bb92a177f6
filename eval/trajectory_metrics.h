// Trajectory error metrics against ground truth. All take trajectories that are already
// associated (element i of `gt` and of `est` form pair i; see eval/association.h) and,
// where alignment applies, already aligned (eval/alignment.h). Frames: both trajectories
// are T_world_robot in the ground truth's world frame.
//
// ATE (absolute trajectory error; evo's APE), per pair i:
//   e_t,i = || t_gt,i - t_est,i ||                        (m)   evo: APE translation part
//   e_r,i = angle( R_est,i^T R_gt,i )                      (deg) evo: APE rotation_angle_deg
// RPE (relative pose error; evo's RPE, consecutive pairs), for index pairs (i, j):
//   Q = T_gt,i^-1 T_gt,j,  P = T_est,i^-1 T_est,j,  E = Q^-1 P
//   e_t = || trans(E) ||  (m),   e_r = angle(rot(E))  (deg)
//   pairs by frames (delta N): i = 0, N, 2N, ..., pairs (i_k, i_k+1)
//   pairs by metres (delta d): walking the ESTIMATE, the path length is accumulated and an
//     index is kept (and the sum reset) each time it reaches >= d; pairs are consecutive kept
//     indices. As in evo, index 0 itself is never kept (its path is 0 < d).
// PE / TE ([Bach], eq. 15), at each correction instant k, of the pose
//   PREDICTED just before the correction (x^-_k, y^-_k, theta^-_k) against the truth:
//   PE_k = sqrt((x^-_k - x_k)^2 + (y^-_k - y_k)^2)  (m),   TE_k = |wrap(theta^-_k - theta_k)| (deg)
//   theta = yaw of the robot x axis about world z. Reported: their mean over the instants
//   (the paper's PE/TE for one run) with the other statistics; the 3-D position error too.
// Per-axis errors ([Kang]'s table), on the same pairs as the ATE, in the ground truth's world
//   frame: |x_est - x_gt|, |y_est - y_gt|, |z_est - z_gt| (m), |wrap(yaw_est - yaw_gt)| (deg),
//   yaw = atan2(R10, R00) (the heading of the robot x axis, as for TE). Reported: the mean
//   absolute error per axis with the other statistics.
#pragma once

#include <string>
#include <vector>

#include "eval/stats.h"
#include "geometry/types.h"

namespace waymark::eval {

// Absolute error per world axis and in yaw (see the header comment).
struct AxisErrors {
  ErrorStats x_m;
  ErrorStats y_m;
  ErrorStats z_m;
  ErrorStats yaw_deg;
};

// Per-axis errors of associated (and aligned) pairs. Throws like ComputeAte.
AxisErrors ComputeAxisErrors(const Trajectory& gt, const Trajectory& est);

struct AteResult {
  ErrorStats translation_m;
  ErrorStats rotation_deg;
  AxisErrors axes;               // per-axis absolute errors of the same pairs
  std::vector<double> stamps_s;  // of the ground-truth pose of each pair
  std::vector<double> translation_errors_m;
  std::vector<double> rotation_errors_deg;
};

// Throws std::invalid_argument if the sizes differ or are zero.
AteResult ComputeAte(const Trajectory& gt, const Trajectory& est);

enum class RpeUnit { kFrames, kMetres };
const char* RpeUnitName(RpeUnit unit);          // "frames", "m"
RpeUnit ParseRpeUnit(const std::string& name);  // throws std::invalid_argument

struct RpeOptions {
  double delta = 1.0;  // frames (a positive integer) or metres (> 0)
  RpeUnit unit = RpeUnit::kFrames;
  bool Check(std::string* why) const;
};

struct RpeResult {
  RpeOptions options;
  std::vector<std::pair<size_t, size_t>> index_pairs;
  ErrorStats translation_m;
  ErrorStats rotation_deg;
  std::vector<double> translation_errors_m;
  std::vector<double> rotation_errors_deg;
};

// evo's index pairs on a list of poses (consecutive pairs, see the header comment).
std::vector<std::pair<size_t, size_t>> RpeIndexPairs(const Trajectory& est, const RpeOptions& options);

// Throws std::invalid_argument for bad options or sizes, std::runtime_error when the delta
// leaves no pair (the message suggests a smaller delta).
RpeResult ComputeRpe(const Trajectory& gt, const Trajectory& est, const RpeOptions& options);

struct PeTeResult {
  ErrorStats position_m;     // planar PE, eq. 15
  ErrorStats position_3d_m;  // with z
  ErrorStats heading_deg;    // TE, eq. 15
  std::vector<double> stamps_s;
  std::vector<double> position_errors_m;
  std::vector<double> heading_errors_deg;
};

// `gt` and `predicted` associated (and aligned if asked). Throws like ComputeAte.
PeTeResult ComputePeTe(const Trajectory& gt, const Trajectory& predicted);

}  // namespace waymark::eval
