// EKF localization of a planar robot against a map of point landmarks from range-bearing
// observations (range_bearing.jsonl; mapping/range_bearing_map.h builds such maps).
//
// State x = [x, y, theta] = T_world_robot, covariance P (3 x 3, the same order).
// Predict with an odometry increment M = (t_M, theta_M) in the robot frame:
//   x' = [t + R(theta) t_M, theta + theta_M]
//   F  = d x'/d x = [[1, 0, -(R(theta) t_M)_y], [0, 1, (R(theta) t_M)_x], [0, 0, 1]]
//   G  = d x'/d M = blockdiag(R(theta), 1)
//   P' = F P F^T + G Q G^T,  Q = diag(q_t (d + d0), q_t (d + d0), q_r (|theta_M| + c_d d + th0)), d = |t_M|
//   (the random walk of mapping/range_bearing_map.h, d0 = 1 mm, th0 = 1 mrad).
// Update with a landmark l (map position, 2-D; its map covariance Sigma_l when present):
//   d = l - t, q = |d|^2, h(x) = [sqrt(q), wrap(atan2(d_y, d_x) - theta)]
//   H = [[-d_x/sqrt(q), -d_y/sqrt(q), 0], [d_y/q, -d_x/q, -1]],  H_l = -H[:, 0:2]
//   y = [range - h_0, wrap(bearing - h_1)],  S = H P H^T + R + H_l Sigma_l H_l^T,
//   R = diag(sigma_range(range)^2, sigma_bearing^2)
//   gate: y^T S^-1 y <= gate_chi2 (2 dof), else the observation is a gross outlier (counted);
//   K = P H^T S^-1 (LLT), x += K y, P = (I - K H) P (I - K H)^T + K R' K^T (Joseph), symmetrized.
// A landmark absent from the map (an unknown or misread code) is rejected and counted.
// Lost: the position's largest standard deviation exceeds lost_sigma_m, or lost_rejections
// observations in a row failed the gate (then P is inflated to reacquire_sigma_m /
// reacquire_sigma_rad so that the gate can accept again); the track is regained after
// regain_updates accepted updates in a row with the position's sigma below lost_sigma_m. No pose
// is output while lost.
#pragma once

#include <Eigen/Core>
#include <map>
#include <optional>
#include <string>

#include "geometry/pose.h"
#include "geometry/types.h"

namespace waymark {

// Why a noise model is unusable ("" when fine).
std::string CheckRangeBearingNoise(const RangeBearingNoise& noise);

struct RangeBearingLocalizerOptions {
  RangeBearingNoise noise;
  double gate_chi2 = 13.8155;  // 2 dof, 99.9 %
  double lost_sigma_m = 0.5;
  int lost_rejections = 10;
  double reacquire_sigma_m = 1.0;
  double reacquire_sigma_rad = 0.3;
  int regain_updates = 3;
  bool Check(std::string* why) const;
};

enum class RangeBearingUpdate { kAccepted, kUnknownLandmark, kGated, kDegenerate };

class RangeBearingLocalizer {
 public:
  // Throws std::invalid_argument for bad options or a covariance that is not SPD.
  RangeBearingLocalizer(const MarkerMap& map, const RangeBearingLocalizerOptions& options, const SE2d& T_world_start,
                        const Eigen::Matrix3d& start_covariance);

  void Predict(const SE2d& T_a_b);
  RangeBearingUpdate Update(const RangeBearingObservation& observation);

  SE2d pose() const { return SE2d(x_[0], x_[1], x_[2]); }
  const Eigen::Matrix3d& covariance() const { return P_; }
  bool lost() const { return lost_; }
  // Counts: accepted, unknown, gated, degenerate, became lost, regained.
  const std::map<std::string, long>& counts() const { return counts_; }

  // Exposed for the Jacobian tests.
  static Eigen::Matrix3d PredictJacobian(const Eigen::Vector3d& x, const SE2d& T_a_b);
  static Eigen::Vector2d Measure(const Eigen::Vector3d& x, const Eigen::Vector2d& l_world);
  static Eigen::Matrix<double, 2, 3> MeasureJacobian(const Eigen::Vector3d& x, const Eigen::Vector2d& l_world);

 private:
  void CheckLost();

  RangeBearingLocalizerOptions options_;
  std::map<MarkerKey, std::pair<Eigen::Vector2d, std::optional<Eigen::Matrix2d>>> landmarks_;
  Eigen::Vector3d x_;
  Eigen::Matrix3d P_;
  bool lost_ = false;
  int rejections_in_row_ = 0;
  int accepted_in_row_ = 0;
  std::map<std::string, long> counts_;
};

}  // namespace waymark
