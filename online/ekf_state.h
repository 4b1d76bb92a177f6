// The localizer's state: the robot pose in the map's world frame, its covariance, and the
// only code that writes that covariance (OpenVINS' StateHelper idea, reduced to one pose).
//
// Mean and error state, by motion model (DatasetConfig::motion):
//   planar (3): x = [x, y, theta];      T_world_robot = (Rz(theta), [x, y, 0])
//   free   (4): x = [x, y, z, yaw];     T_world_robot = (Rz(yaw) * R_level, [x, y, z])
// R_level = Ry(pitch) * Rx(roll) (ZYX Euler: R = Rz(yaw) Ry(pitch) Rx(roll)) is NOT estimated.
// Roll and pitch of a drone are observable from gravity, so a gravity-aligned odometry (VIO,
// IMU attitude) keeps them to a fraction of a degree while yaw and position drift; the free
// model therefore takes R_level from outside: from the latest T_odom_robot when the odometry is
// gravity aligned (AttitudeSource::kOdometry), or else from the latest single-code pose
// (AttitudeSource::kMarker, see localizer.h). Its error is not part of P.
//
// Error state delta (same order as x), additive in the world frame:
//   x_true = x_hat [+] delta:  position += delta_position,  yaw = wrap(yaw + delta_yaw).
// P = E[delta delta^T]. BoxMinus(a, b) = b [-] a is the inverse (yaw difference wrapped).
//
// Covariance writes (all through WriteCovariance, which symmetrizes and refuses non-finite P):
//   Reset:     P = P0
//   Propagate: x = f(x, u),  P = F P F^T + G Qu G^T   (F = df/dx, G = df/du)
//   Update:    y = z [-] h(x),  S = H P H^T + R,  K = P H^T S^-1 (from the LLT of S),
//              NIS = y^T S^-1 y, gated when NIS > gate,
//              x = x [+] K y,   P = (I - K H) P (I - K H)^T + K R K^T   (Joseph form)
//   UpdateIterated: the iterated EKF form of Update (see below)
//
// Schmidt ("consider") treatment of the map's uncertainty. A map marker m has an error
// eps_m ~ N(0, Sigma_m) (its 6x6 map covariance, right perturbation) that is the same at every
// sighting. It is not estimated (the marker's mean stays the map's) but its correlation with
// the state is kept: C_m = E[delta eps_m^T] (dim x 6), markers independent of each other, for
// the `max_considered` markers seen last (older ones are dropped: C_m -> 0).
//   Propagate: C_m = F C_m
//   Update with a considered marker m (measurement Jacobians H on delta, H_m on eps_m):
//     S = H P H^T + H C_m H_m^T + H_m C_m^T H^T + H_m Sigma_m H_m^T + R
//     K = (P H^T + C_m H_m^T) S^-1                      (gain of the state only)
//     P = P - K S K^T,   C_j = C_j - K (H C_j + [j = m] H_m Sigma_m)   for every kept j
// Without the C_m the filter would take the same marker error as new information at every
// sighting and grow overconfident (NEES ~2x with a learned map: docs/online.md).
//
// Correlated markers (map.json `covariance_factor`, mapping/map_covariance.h). Markers of a
// learned map share the survey's drift: eps_m = F_m xi + eta_m with xi ~ N(0, I_k) common to all
// markers and eta_m ~ N(0, D_m), D_m = Sigma_m - F_m F_m^T, independent. xi is k more consider
// parameters, kept for good (never dropped): C_xi = E[delta xi^T] (dim x k). With A_m = H_m F_m:
//   Propagate: C_xi = F C_xi
//   Update:  S = H P H^T + R + [H C_m H_m^T + H_m D_m H_m^T + H C_xi A_m^T + (both transposed)] + A_m A_m^T
//            K = (P H^T + C_m H_m^T + C_xi A_m^T) S^-1,   P = P - K S K^T
//            C_xi = C_xi - K (H C_xi + A_m),   C_j = C_j - K (H C_j + [j = m] H_m D_m)
// (C_m and Sigma_m of the per-marker part above become D_m's). Without a factor, k = 0 and D_m = Sigma_m.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <optional>
#include <vector>

#include "geometry/pose.h"
#include "geometry/types.h"
#include "online/status.h"

namespace waymark {

// 3 for planar, 4 for free.
int StateDim(MotionModel motion);

// The state vector of a pose: [x, y, yaw] or [x, y, z, yaw] (roll and pitch dropped).
Eigen::VectorXd PoseToStateVector(const SE3d& T_world_robot, MotionModel motion);

// R_level = Rz(yaw)^T R: the roll-and-pitch part of a rotation (ZYX Euler).
Eigen::Matrix3d LevelRotation(const Eigen::Matrix3d& R_world_robot);

// d yaw / d phi for a world-frame (left) rotation perturbation R' = Exp(phi) R, yaw = atan2(R10, R00):
//   [-R00 R20, -R10 R20, R00^2 + R10^2] / (R00^2 + R10^2)     (1x3; [0, 0, 1] when level)
Eigen::RowVector3d YawJacobianWorld(const Eigen::Matrix3d& R_world_robot);

// Result of one measurement update.
struct UpdateResult {
  StepStatus status = StepStatus::kOk;
  bool accepted = false;       // the update was applied
  bool gated = false;          // NIS above the gate: state untouched
  double nis = 0.0;            // y^T S^-1 y
  Eigen::VectorXd innovation;  // y
};

// C_m of the header comment: dim x 6, at most 4 rows (no heap allocation).
using CrossCovariance = Eigen::Matrix<double, Eigen::Dynamic, 6, 0, 4, 6>;

// A map marker whose error is considered (Schmidt) in an update.
struct ConsideredMarker {
  MarkerKey key;
  Eigen::MatrixXd H_marker;  // d h / d eps_m (rows of the measurement x 6)
  Matrix6d covariance;       // Sigma_m (the full marginal)
  CovarianceFactor factor;   // F_m; no columns when the map has none
};

// A measurement linearized at some mean: y = z [-] h(mean), H = dh/dx there, R its noise
// (without the considered marker's part, which `consider` adds).
struct Linearization {
  Eigen::VectorXd innovation;
  Eigen::MatrixXd H;
  Eigen::MatrixXd R;
  std::optional<ConsideredMarker> consider;
};

class EkfState;
// Linearizes a measurement at the given state; nullopt when h is undefined there.
using MeasurementFunction = std::function<std::optional<Linearization>(const EkfState& at)>;

class EkfState {
 public:
  explicit EkfState(MotionModel motion);

  MotionModel motion() const { return motion_; }
  int dim() const { return static_cast<int>(mean_.size()); }
  int yaw_index() const { return dim() - 1; }
  const Eigen::VectorXd& mean() const { return mean_; }
  const Eigen::MatrixXd& covariance() const { return covariance_; }
  const Eigen::Matrix3d& R_level() const { return R_level_; }
  // Only meaningful for free motion; planar robots stay level.
  void SetLevel(const Eigen::Matrix3d& R_level);

  // T_world_robot of the mean (z = 0 and level for planar).
  SE3d T_world_robot() const;
  // delta with mean_b = mean_a [+] delta (yaw wrapped).
  static Eigen::VectorXd BoxMinus(const Eigen::VectorXd& mean_a, const Eigen::VectorXd& mean_b,
                                  int yaw_index);
  // mean [+] delta.
  static Eigen::VectorXd BoxPlus(const Eigen::VectorXd& mean, const Eigen::VectorXd& delta, int yaw_index);

  // Sets mean and covariance (initialization, relocalization); forgets every C_m.
  StepStatus Reset(const Eigen::VectorXd& mean, const Eigen::MatrixXd& covariance);
  // The same, with the cross-covariance of the state with one marker's map error (the
  // marker that initialized the state).
  StepStatus Reset(const Eigen::VectorXd& mean, const Eigen::MatrixXd& covariance, const MarkerKey& key,
                   const CrossCovariance& cross);
  // The same when the marker has a factor F_m: with cross = A Sigma_m (A = cross Sigma_m^-1),
  // C_m = A D_m and C_xi = A F_m. kInvalidInput when Sigma_m is not positive definite.
  StepStatus Reset(const Eigen::VectorXd& mean, const Eigen::MatrixXd& covariance, const MarkerKey& key,
                   const CrossCovariance& cross, const Matrix6d& marker_covariance,
                   const CovarianceFactor& factor);
  // C_m, zero when the marker is not kept.
  CrossCovariance Cross(const MarkerKey& key) const;
  size_t considered_markers() const { return cross_.size(); }
  // C_xi (dim x k); no columns until a marker with a factor was used.
  const Eigen::MatrixXd& cross_factor() const { return cross_factor_; }
  // How many markers keep their C_m (the most recently used; default 16, >= 1).
  void set_max_considered(size_t count) { max_considered_ = std::max<size_t>(count, 1); }
  // Prediction step; mean_new = f(mean, u) computed by the caller (online/motion_model.h).
  StepStatus Propagate(const Eigen::VectorXd& mean_new, const Eigen::MatrixXd& F, const Eigen::MatrixXd& G,
                       const Eigen::MatrixXd& Qu);
  // Correction step with innovation y = z [-] h(mean). Gated (no change) when NIS > nis_gate.
  UpdateResult Update(const Eigen::VectorXd& innovation, const Eigen::MatrixXd& H, const Eigen::MatrixXd& R,
                      std::optional<double> nis_gate);
  // Iterated EKF (Gauss-Newton on the MAP cost) for strongly non-linear h, e.g. pixels after
  // metres of dead reckoning. With x0, P0 the prior and x_i the current iterate:
  //   y_i = z [-] h(x_i),  H_i, R_i linearized at x_i,  S_i = H_i P0 H_i^T + R_i,
  //   x_{i+1} = x0 [+] K_i (y_i + H_i (x_i [-] x0)),  K_i = P0 H_i^T S_i^-1,
  // until |x_{i+1} [-] x_i| < 1e-9 or max_iterations; P from the last K_i, H_i, R_i (Joseph).
  // The gate uses the NIS at the prior (i = 0); max_iterations = 1 is the plain EKF update.
  UpdateResult UpdateIterated(const MeasurementFunction& linearize, std::optional<double> nis_gate,
                              int max_iterations);

 private:
  struct CrossEntry {
    MarkerKey key;
    CrossCovariance cross;
    long last_used = 0;
  };
  // The one writer of covariance_ and cross_: symmetrizes P, and keeps the old P and C_m
  // (returning an error) when the new ones are not finite.
  StepStatus WriteCovariance(const Eigen::MatrixXd& covariance, std::vector<CrossEntry> cross,
                             Eigen::MatrixXd cross_factor);
  // One iteration's S, P H^T + C_m H_m^T + C_xi A_m^T, D_m and A_m.
  struct Gain;
  std::optional<Gain> ComputeGain(const Linearization& lin) const;
  // The C_j and C_xi after the update with gain K.
  std::vector<CrossEntry> UpdatedCross(const Eigen::MatrixXd& K, const Linearization& lin, const Gain& gain,
                                       Eigen::MatrixXd* cross_factor) const;

  MotionModel motion_;
  Eigen::VectorXd mean_;
  Eigen::MatrixXd covariance_;
  std::vector<CrossEntry> cross_;
  Eigen::MatrixXd cross_factor_;  // C_xi
  size_t max_considered_ = 16;
  long updates_ = 0;
  Eigen::Matrix3d R_level_ = Eigen::Matrix3d::Identity();
};

}  // namespace waymark
