// Aligning an estimate to ground truth before measuring its error.
//
// An alignment is a similarity transform from the estimate's world frame into the
// ground truth's world frame:
//   p_gt = s * R_gt_est * p_est + t_gt_est,        R_world_robot' = R_gt_est * R_world_robot
// (the scale s applies to positions only, as in evo's PosePath3D.scale then .transform).
//
// Modes:
//   kSE3  Umeyama (1991) on the associated positions: R, t (and s with `with_scale`) minimize
//         sum_i || p_gt_i - (s R p_est_i + t) ||^2.
//           mu_x, mu_y   means of the estimate / ground-truth points
//           Sigma_xy     = (1/n) sum (y_i - mu_y)(x_i - mu_x)^T = U D V^T
//           S            = diag(1, .., 1, -1) if det(U) det(V) < 0 else I
//           R = U S V^T,  s = tr(D S) / sigma_x^2 (or 1),  t = mu_y - s R mu_x
//         Equal to evo's `-a` (and `-as` with scale).
//   kSE2  For planar robots: a rotation about world z and an x, y translation, found by the
//         same Umeyama equations on the (x, y) coordinates only. No z offset: both frames
//         are taken to share the floor plane z = 0 (world z up), so a height error stays an
//         error. With `with_scale`, s (from the 2-D fit) scales x, y and z alike.
//   kNone Identity. With `with_scale` only the scale of the SE3 Umeyama fit is applied,
//         about the origin (evo's `-s` without `-a`).
//   kOrigin The first associated estimate pose is moved onto the first ground-truth pose:
//         T_gt_est = T_gt_robot(0) * T_est_robot(0)^-1 (evo's `--align_origin`). This is the
//         honest alignment for dead reckoning, which knows its start pose and nothing after.
//         Needs poses, not positions: see AlignOrigin. No scale.
//
// Degenerate point sets (rank of Sigma_xy below dim - 1, e.g. all points equal, or on a line
// for kSE3) throw DegenerateAlignmentError, as evo refuses them too.
#pragma once

#include <Eigen/Core>
#include <stdexcept>
#include <string>
#include <vector>

#include "geometry/types.h"

namespace waymark::eval {

class DegenerateAlignmentError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

enum class AlignmentMode { kNone, kSE3, kSE2, kOrigin };

// "none", "se3", "se2", "origin"; ParseAlignmentMode throws std::invalid_argument otherwise.
const char* AlignmentModeName(AlignmentMode mode);
AlignmentMode ParseAlignmentMode(const std::string& name);

// p_gt = scale * R_gt_est * p_est + t_gt_est.
struct Sim3Alignment {
  Eigen::Matrix3d R_gt_est = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t_gt_est = Eigen::Vector3d::Zero();
  double scale = 1.0;

  Eigen::Vector3d Apply(const Eigen::Vector3d& p_est) const { return scale * (R_gt_est * p_est) + t_gt_est; }
  // T_gt_robot from T_est_robot: rotation R_gt_est * R, translation Apply(t).
  SE3d Apply(const SE3d& T_est_robot) const;
  Trajectory Apply(const Trajectory& trajectory_est) const;
};

// Umeyama fit of dst ~ s R src + t in 3-D (see the header comment). src and dst have the
// same size. Throws std::invalid_argument on size mismatch or fewer than 2 points, and
// DegenerateAlignmentError on a degenerate configuration.
Sim3Alignment UmeyamaSim3(const std::vector<Eigen::Vector3d>& src, const std::vector<Eigen::Vector3d>& dst,
                          bool with_scale);

// Rotation about z and x, y translation (and scale) from the x, y coordinates only.
Sim3Alignment UmeyamaSE2(const std::vector<Eigen::Vector3d>& src, const std::vector<Eigen::Vector3d>& dst,
                         bool with_scale);

// T_gt_est = T_gt_robot * T_est_robot^-1 from one associated pair (kOrigin).
Sim3Alignment AlignOrigin(const SE3d& T_gt_robot, const SE3d& T_est_robot);

// Dispatches on the mode; `src` are the estimate's positions, `dst` the ground truth's.
// kOrigin needs poses: it throws std::invalid_argument here (use AlignOrigin).
Sim3Alignment ComputeAlignment(AlignmentMode mode, bool with_scale, const std::vector<Eigen::Vector3d>& src,
                               const std::vector<Eigen::Vector3d>& dst);

// Positions of a trajectory, in order.
std::vector<Eigen::Vector3d> Positions(const Trajectory& trajectory);

}  // namespace waymark::eval
