#include "online/ekf_state.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <stdexcept>
#include <string>

namespace waymark {

int StateDim(MotionModel motion) { return motion == MotionModel::kPlanar ? 3 : 4; }

Eigen::VectorXd PoseToStateVector(const SE3d& T_world_robot, MotionModel motion) {
  Eigen::VectorXd x(StateDim(motion));
  const Eigen::Vector3d& t = T_world_robot.translation();
  if (motion == MotionModel::kPlanar) {
    x << t.x(), t.y(), T_world_robot.yaw();
  } else {
    x << t.x(), t.y(), t.z(), T_world_robot.yaw();
  }
  return x;
}

Eigen::Matrix3d LevelRotation(const Eigen::Matrix3d& R_world_robot) {
  const double yaw_rad = std::atan2(R_world_robot(1, 0), R_world_robot(0, 0));
  return Eigen::AngleAxisd(-yaw_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix() * R_world_robot;
}

Eigen::RowVector3d YawJacobianWorld(const Eigen::Matrix3d& R) {
  const double n = R(0, 0) * R(0, 0) + R(1, 0) * R(1, 0);
  return Eigen::RowVector3d(-R(0, 0) * R(2, 0) / n, -R(1, 0) * R(2, 0) / n, 1.0);
}

EkfState::EkfState(MotionModel motion)
    : motion_(motion),
      mean_(Eigen::VectorXd::Zero(StateDim(motion))),
      covariance_(Eigen::MatrixXd::Identity(StateDim(motion), StateDim(motion))),
      cross_factor_(StateDim(motion), 0) {}

void EkfState::SetLevel(const Eigen::Matrix3d& R_level) {
  if (motion_ == MotionModel::kFree && R_level.allFinite()) R_level_ = LevelRotation(R_level);
}

SE3d EkfState::T_world_robot() const {
  const double yaw_rad = mean_(yaw_index());
  const Eigen::Matrix3d R_yaw = Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  if (motion_ == MotionModel::kPlanar) return SE3d(R_yaw, Eigen::Vector3d(mean_(0), mean_(1), 0.0));
  return SE3d(Eigen::Matrix3d(R_yaw * R_level_), Eigen::Vector3d(mean_.head<3>()));
}

Eigen::VectorXd EkfState::BoxMinus(const Eigen::VectorXd& mean_a, const Eigen::VectorXd& mean_b,
                                   int yaw_index) {
  // Eigen checks sizes only in debug builds: a state and a pose vector of other sizes read past
  // one of them (found by AddressSanitizer in a test's NEES).
  if (mean_a.size() != mean_b.size() || yaw_index < 0 || yaw_index >= mean_a.size()) {
    throw std::invalid_argument("EkfState::BoxMinus: states of sizes " + std::to_string(mean_a.size()) +
                                " and " + std::to_string(mean_b.size()) + ", yaw index " +
                                std::to_string(yaw_index));
  }
  Eigen::VectorXd delta = mean_b - mean_a;
  delta(yaw_index) = WrapAngle(delta(yaw_index));
  return delta;
}

Eigen::VectorXd EkfState::BoxPlus(const Eigen::VectorXd& mean, const Eigen::VectorXd& delta, int yaw_index) {
  Eigen::VectorXd out = mean + delta;
  out(yaw_index) = WrapAngle(out(yaw_index));
  return out;
}

StepStatus EkfState::WriteCovariance(const Eigen::MatrixXd& covariance, std::vector<CrossEntry> cross,
                                     Eigen::MatrixXd cross_factor) {
  if (covariance.rows() != dim() || covariance.cols() != dim()) return StepStatus::kInvalidInput;
  if (cross_factor.rows() != dim()) return StepStatus::kInvalidInput;
  if (!covariance.allFinite() || !cross_factor.allFinite()) return StepStatus::kNonFiniteCovariance;
  for (const CrossEntry& entry : cross) {
    if (entry.cross.rows() != dim()) return StepStatus::kInvalidInput;
    if (!entry.cross.allFinite()) return StepStatus::kNonFiniteCovariance;
  }
  covariance_ = 0.5 * (covariance + covariance.transpose());
  cross_ = std::move(cross);
  cross_factor_ = std::move(cross_factor);
  return StepStatus::kOk;
}

StepStatus EkfState::Reset(const Eigen::VectorXd& mean, const Eigen::MatrixXd& covariance) {
  if (mean.size() != dim() || !mean.allFinite()) return StepStatus::kInvalidInput;
  const StepStatus status = WriteCovariance(covariance, {}, Eigen::MatrixXd(dim(), 0));
  if (status != StepStatus::kOk) return status;
  mean_ = BoxPlus(mean, Eigen::VectorXd::Zero(dim()), yaw_index());
  return StepStatus::kOk;
}

StepStatus EkfState::Reset(const Eigen::VectorXd& mean, const Eigen::MatrixXd& covariance,
                           const MarkerKey& key, const CrossCovariance& cross) {
  if (mean.size() != dim() || !mean.allFinite()) return StepStatus::kInvalidInput;
  const StepStatus status =
      WriteCovariance(covariance, {CrossEntry{key, cross, ++updates_}}, Eigen::MatrixXd(dim(), 0));
  if (status != StepStatus::kOk) return status;
  mean_ = BoxPlus(mean, Eigen::VectorXd::Zero(dim()), yaw_index());
  return StepStatus::kOk;
}

StepStatus EkfState::Reset(const Eigen::VectorXd& mean, const Eigen::MatrixXd& covariance,
                           const MarkerKey& key, const CrossCovariance& cross,
                           const Matrix6d& marker_covariance, const CovarianceFactor& factor) {
  if (factor.cols() == 0) return Reset(mean, covariance, key, cross);
  if (mean.size() != dim() || !mean.allFinite() || cross.rows() != dim()) return StepStatus::kInvalidInput;
  const Eigen::LLT<Matrix6d> llt(marker_covariance);
  if (llt.info() != Eigen::Success || !factor.allFinite()) return StepStatus::kInvalidInput;
  const Eigen::MatrixXd A = llt.solve(Eigen::MatrixXd(cross.transpose())).transpose();  // cross Sigma_m^-1
  const Matrix6d D = marker_covariance - factor * factor.transpose();
  const StepStatus status =
      WriteCovariance(covariance, {CrossEntry{key, CrossCovariance(A * D), ++updates_}}, A * factor);
  if (status != StepStatus::kOk) return status;
  mean_ = BoxPlus(mean, Eigen::VectorXd::Zero(dim()), yaw_index());
  return StepStatus::kOk;
}

CrossCovariance EkfState::Cross(const MarkerKey& key) const {
  for (const CrossEntry& entry : cross_) {
    if (entry.key == key) return entry.cross;
  }
  return CrossCovariance::Zero(dim(), 6);
}

StepStatus EkfState::Propagate(const Eigen::VectorXd& mean_new, const Eigen::MatrixXd& F,
                               const Eigen::MatrixXd& G, const Eigen::MatrixXd& Qu) {
  if (mean_new.size() != dim() || !mean_new.allFinite()) return StepStatus::kInvalidInput;
  std::vector<CrossEntry> cross = cross_;
  for (CrossEntry& entry : cross) entry.cross = F * entry.cross;
  const StepStatus status = WriteCovariance(F * covariance_ * F.transpose() + G * Qu * G.transpose(),
                                            std::move(cross), F * cross_factor_);
  if (status != StepStatus::kOk) return status;
  mean_ = BoxPlus(mean_new, Eigen::VectorXd::Zero(dim()), yaw_index());
  return StepStatus::kOk;
}

struct EkfState::Gain {
  Eigen::MatrixXd PHt;  // P H^T (+ C_m H_m^T + C_xi A_m^T)
  Eigen::MatrixXd S;    // symmetrized
  Eigen::LLT<Eigen::MatrixXd> llt;
  Matrix6d D_m;         // Sigma_m - F_m F_m^T
  Eigen::MatrixXd A_m;  // H_m F_m (no columns without a factor)
};

std::optional<EkfState::Gain> EkfState::ComputeGain(const Linearization& lin) const {
  Gain gain;
  gain.PHt = covariance_ * lin.H.transpose();
  gain.S = lin.H * gain.PHt + lin.R;
  if (lin.consider) {
    const ConsideredMarker& marker = *lin.consider;
    const Eigen::MatrixXd& H_m = marker.H_marker;
    gain.D_m = marker.covariance - marker.factor * marker.factor.transpose();
    gain.A_m = H_m * marker.factor;
    Eigen::MatrixXd C_Hmt = Cross(marker.key) * H_m.transpose();
    if (gain.A_m.cols() > 0 && cross_factor_.cols() == gain.A_m.cols())
      C_Hmt += cross_factor_ * gain.A_m.transpose();
    const Eigen::MatrixXd H_C_Hmt = lin.H * C_Hmt;
    gain.PHt += C_Hmt;
    gain.S +=
        H_C_Hmt + H_C_Hmt.transpose() + H_m * gain.D_m * H_m.transpose() + gain.A_m * gain.A_m.transpose();
  }
  gain.S = 0.5 * (gain.S + gain.S.transpose());
  gain.llt.compute(gain.S);
  if (gain.llt.info() != Eigen::Success) return std::nullopt;
  return gain;
}

std::vector<EkfState::CrossEntry> EkfState::UpdatedCross(const Eigen::MatrixXd& K, const Linearization& lin,
                                                         const Gain& gain,
                                                         Eigen::MatrixXd* cross_factor) const {
  std::vector<CrossEntry> cross = cross_;
  for (CrossEntry& entry : cross) entry.cross -= K * (lin.H * entry.cross);
  *cross_factor = cross_factor_;
  if (lin.consider && gain.A_m.cols() > 0 && cross_factor->cols() == 0) {
    *cross_factor = Eigen::MatrixXd::Zero(dim(), gain.A_m.cols());
  }
  if (cross_factor->cols() > 0) {
    Eigen::MatrixXd innovation_cross = lin.H * *cross_factor;  // d y / d xi, state part
    if (lin.consider && gain.A_m.cols() > 0) innovation_cross += gain.A_m;
    *cross_factor -= K * innovation_cross;
  }
  if (!lin.consider) return cross;
  const Eigen::MatrixXd K_Hm_Sigma = K * lin.consider->H_marker * gain.D_m;
  auto it = std::find_if(cross.begin(), cross.end(),
                         [&](const CrossEntry& entry) { return entry.key == lin.consider->key; });
  if (it == cross.end()) {
    cross.push_back({lin.consider->key, CrossCovariance::Zero(dim(), 6), 0});
    it = cross.end() - 1;
  }
  it->cross -= K_Hm_Sigma;
  it->last_used = updates_ + 1;
  if (cross.size() > max_considered_) {  // forget the marker seen longest ago
    cross.erase(std::min_element(cross.begin(), cross.end(), [](const CrossEntry& a, const CrossEntry& b) {
      return a.last_used < b.last_used;
    }));
  }
  return cross;
}

UpdateResult EkfState::Update(const Eigen::VectorXd& innovation, const Eigen::MatrixXd& H,
                              const Eigen::MatrixXd& R, std::optional<double> nis_gate) {
  const Linearization lin{innovation, H, R, std::nullopt};
  return UpdateIterated([&lin](const EkfState&) { return lin; }, nis_gate, 1);
}

UpdateResult EkfState::UpdateIterated(const MeasurementFunction& linearize, std::optional<double> nis_gate,
                                      int max_iterations) {
  UpdateResult result;
  const Eigen::VectorXd x0 = mean_;
  EkfState iterate = *this;
  std::optional<Linearization> lin = linearize(iterate);
  if (!lin) {
    result.status = StepStatus::kInvalidInput;
    return result;
  }
  result.innovation = lin->innovation;
  std::optional<Gain> gain;
  Eigen::MatrixXd K;
  for (int i = 0; i < std::max(max_iterations, 1); ++i) {
    if (!lin->innovation.allFinite() || !lin->H.allFinite() || !lin->R.allFinite() ||
        (lin->consider && (!lin->consider->H_marker.allFinite() || !lin->consider->covariance.allFinite() ||
                           !lin->consider->factor.allFinite() ||
                           (lin->consider->factor.cols() > 0 && cross_factor_.cols() > 0 &&
                            lin->consider->factor.cols() != cross_factor_.cols())))) {
      result.status = StepStatus::kInvalidInput;
      return result;
    }
    gain = ComputeGain(*lin);
    if (!gain) {
      result.status = StepStatus::kNotPositiveDefinite;
      return result;
    }
    if (i == 0) {
      result.nis = lin->innovation.dot(gain->llt.solve(lin->innovation));
      if (nis_gate && result.nis > *nis_gate) {
        result.gated = true;
        return result;
      }
    }
    K = gain->llt.solve(gain->PHt.transpose()).transpose();  // (P H^T + C_m H_m^T) S^-1
    const Eigen::VectorXd dx = BoxMinus(x0, iterate.mean_, yaw_index());
    const Eigen::VectorXd x_next = BoxPlus(x0, K * (lin->innovation + lin->H * dx), yaw_index());
    const double step = BoxMinus(iterate.mean_, x_next, yaw_index()).norm();
    iterate.mean_ = x_next;
    if (step < 1e-9 || i + 1 >= max_iterations) break;
    std::optional<Linearization> next = linearize(iterate);
    if (!next) break;  // h undefined at the new iterate: keep the last complete step
    lin = std::move(next);
    gain.reset();
  }
  if (!gain) {  // the last linearization was not factored yet
    gain = ComputeGain(*lin);
    if (!gain) {
      result.status = StepStatus::kNotPositiveDefinite;
      return result;
    }
    K = gain->llt.solve(gain->PHt.transpose()).transpose();
  }
  Eigen::MatrixXd P_new;
  if (lin->consider) {
    P_new = covariance_ - K * gain->S * K.transpose();
  } else {  // Joseph form
    const Eigen::MatrixXd I_KH = Eigen::MatrixXd::Identity(dim(), dim()) - K * lin->H;
    P_new = I_KH * covariance_ * I_KH.transpose() + K * lin->R * K.transpose();
  }
  Eigen::MatrixXd cross_factor;
  std::vector<CrossEntry> cross = UpdatedCross(K, *lin, *gain, &cross_factor);
  result.status = WriteCovariance(P_new, std::move(cross), std::move(cross_factor));
  if (result.status != StepStatus::kOk) return result;
  ++updates_;
  mean_ = iterate.mean_;
  result.accepted = true;
  return result;
}

}  // namespace waymark
