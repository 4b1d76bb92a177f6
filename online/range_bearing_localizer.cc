#include "online/range_bearing_localizer.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <tuple>

#include "util/check.h"

namespace waymark {
namespace {

constexpr double kLinkFloorM = 1e-3;
constexpr double kLinkFloorRad = 1e-3;

bool IsSpd(const Eigen::Matrix3d& P) {
  if (!P.allFinite() ||
      (P - P.transpose()).cwiseAbs().maxCoeff() > 1e-9 * std::max(1.0, P.cwiseAbs().maxCoeff()))
    return false;
  return Eigen::LLT<Eigen::Matrix3d>(P).info() == Eigen::Success;
}

}  // namespace

std::string CheckRangeBearingNoise(const RangeBearingNoise& n) {
  if (!IsFinitePositive(n.range_a_m)) return "range_a_m must be > 0";
  if (!IsFiniteAtLeast(n.range_b, 0.0)) return "range_b must be >= 0";
  if (!IsFinitePositive(n.bearing_rad)) return "bearing_rad must be > 0";
  if (!IsFinitePositive(n.odometry_q_t)) return "odometry_q_t must be > 0";
  if (!IsFinitePositive(n.odometry_q_r)) return "odometry_q_r must be > 0";
  if (!IsFiniteAtLeast(n.odometry_c_d, 0.0)) return "odometry_c_d must be >= 0";
  return "";
}

std::optional<RangeBearingMapUncertainty> ParseRangeBearingMapUncertainty(const std::string& name) {
  if (name == "estimate") return RangeBearingMapUncertainty::kEstimate;
  if (name == "consider") return RangeBearingMapUncertainty::kConsider;
  if (name == "in-noise") return RangeBearingMapUncertainty::kInNoise;
  if (name == "ignore") return RangeBearingMapUncertainty::kIgnore;
  return std::nullopt;
}

bool RangeBearingLocalizerOptions::Check(std::string* why) const {
  WAYMARK_CHECK_OPTION(CheckRangeBearingNoise(noise).empty(), "noise: " + CheckRangeBearingNoise(noise));
  WAYMARK_CHECK_OPTION(IsFinitePositive(gate_chi2), "gate_chi2 must be > 0");
  WAYMARK_CHECK_OPTION(IsFinitePositive(variance_factor), "variance_factor must be > 0");
  WAYMARK_CHECK_OPTION(IsFinitePositive(lost_sigma_m), "lost_sigma_m must be > 0");
  WAYMARK_CHECK_OPTION(lost_rejections >= 1, "lost_rejections must be >= 1");
  WAYMARK_CHECK_OPTION(IsFinitePositive(reacquire_sigma_m) && IsFinitePositive(reacquire_sigma_rad),
                       "reacquire sigmas must be > 0");
  WAYMARK_CHECK_OPTION(regain_updates >= 1, "regain_updates must be >= 1");
  WAYMARK_CHECK_OPTION(calibration_sigma.allFinite() && (calibration_sigma.array() >= 0.0).all(),
                       "calibration_sigma must be finite and >= 0");
  WAYMARK_CHECK_OPTION(sensor_bias_sigma.allFinite() && (sensor_bias_sigma.array() >= 0.0).all(),
                       "sensor_bias_sigma must be finite and >= 0");
  WAYMARK_CHECK_OPTION(IsFiniteAtLeast(bearing_scale_sigma, 0.0), "bearing_scale_sigma must be >= 0");
  WAYMARK_CHECK_OPTION(IsFiniteAtLeast(depth_share_sigma, 0.0), "depth_share_sigma must be >= 0");
  WAYMARK_CHECK_OPTION(IsFiniteAtLeast(range_scale_state_sigma, 0.0), "range_scale_state_sigma must be >= 0");
  WAYMARK_CHECK_OPTION(calibration_mean.allFinite() && sensor_bias_mean.allFinite() &&
                           std::isfinite(bearing_scale_mean) && std::isfinite(depth_share_mean) &&
                           std::isfinite(range_scale_mean),
                       "the calibration's and the sensor's means must be finite");
  WAYMARK_CHECK_OPTION(calibration_time_s.allFinite() && (calibration_time_s.array() >= 0.0).all(),
                       "calibration_time_s must be finite and >= 0");
  WAYMARK_CHECK_OPTION(
      IsFiniteAtLeast(turn_fluctuation_sigma, 0.0) && IsFiniteAtLeast(turn_fluctuation_time_s, 0.0),
      "turn_fluctuation_sigma and turn_fluctuation_time_s must be finite and >= 0");
  WAYMARK_CHECK_OPTION(max_landmark_states >= 1, "max_landmark_states must be >= 1");
  WAYMARK_CHECK_OPTION(update_iterations >= 1 && update_iterations <= 100 && relocalization_iterations >= 1 &&
                           relocalization_iterations <= 100,
                       "update_iterations and relocalization_iterations must be in 1..100");
  return true;
}

Eigen::Vector3d ConvertOdometryCalibration(const Eigen::Vector3d& c) {
  return Eigen::Vector3d(-c[0] / (1.0 + c[1]), -c[1] / (1.0 + c[1]), -c[2] / (1.0 + c[2]));
}

Eigen::Vector3d ConvertOdometryCalibrationSigma(const Eigen::Vector3d& c, const Eigen::Vector3d& sigma) {
  return Eigen::Vector3d(sigma[0] / std::abs(1.0 + c[1]), sigma[1] / ((1.0 + c[1]) * (1.0 + c[1])),
                         sigma[2] / ((1.0 + c[2]) * (1.0 + c[2])));
}

void SensorPriorFromMap(const RangeBearingSensorModel& model, RangeBearingLocalizerOptions* options) {
  const RangeBearingSensorValues& mean = model.prior_mean;
  const RangeBearingSensorValues& sigma = model.prior_sigma;
  options->calibration_mean = ConvertOdometryCalibration(mean.odometry_calibration);
  options->calibration_sigma =
      ConvertOdometryCalibrationSigma(mean.odometry_calibration, sigma.odometry_calibration);
  options->sensor_bias_mean = Eigen::Vector2d(mean.range_offset_m, mean.bearing_offset_rad);
  options->sensor_bias_sigma = Eigen::Vector2d(sigma.range_offset_m, sigma.bearing_offset_rad);
  options->bearing_scale_mean = mean.bearing_scale;
  options->bearing_scale_sigma = sigma.bearing_scale;
  options->depth_share_mean = model.depth_ranges ? mean.depth_share : 0.0;
  options->depth_share_sigma = model.depth_ranges ? sigma.depth_share : 0.0;
  options->range_scale_mean = model.depth_ranges ? mean.range_scale : 0.0;
  options->range_scale_state_sigma = model.depth_ranges ? sigma.range_scale : 0.0;
}

RangeBearingLocalizer::RangeBearingLocalizer(const MarkerMap& map,
                                             const RangeBearingLocalizerOptions& options,
                                             const SE2d& T_world_start,
                                             const Eigen::Matrix3d& start_covariance)
    : options_(options) {
  std::string why;
  if (!options.Check(&why)) throw std::invalid_argument("range-bearing localizer: " + why);
  if (!IsSpd(start_covariance))
    throw std::invalid_argument(
        "range-bearing localizer: the start covariance is not symmetric positive definite");
  for (const MapMarker& marker : map.markers) {
    if (marker.is_point && marker.position_covariance && marker.covariance_factor)
      k_ = std::max(k_, static_cast<int>(marker.covariance_factor->cols()));
  }
  if (!Augmented()) k_ = 0;
  for (const MapMarker& marker : map.markers) {
    if (!marker.is_point) continue;
    Landmark landmark;
    landmark.l_map = marker.T_world_marker.translation().head<2>();
    landmark.F = Eigen::Matrix<double, 2, Eigen::Dynamic>::Zero(2, k_);
    if (marker.position_covariance) {
      landmark.sigma = marker.position_covariance->topLeftCorner<2, 2>();
      landmark.D = *landmark.sigma;
      if (k_ > 0 && marker.covariance_factor) {
        // A point's position factor: the translation rows of covariance_factor (map_io.h).
        const CovarianceFactor& F = *marker.covariance_factor;
        landmark.F.leftCols(F.cols()) = F.middleRows<2>(3);
        landmark.D = *landmark.sigma - landmark.F * landmark.F.transpose();
        // Round-off of the factor: keep D symmetric positive semi-definite.
        const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eigen(0.5 *
                                                                   (landmark.D + landmark.D.transpose()));
        landmark.D = eigen.eigenvectors() * eigen.eigenvalues().cwiseMax(0.0).asDiagonal() *
                     eigen.eigenvectors().transpose();
      }
    }
    landmarks_[marker.key] = landmark;
  }
  x_ = Eigen::VectorXd::Zero(kStateSize + k_);
  x_.head<3>() << T_world_start.x(), T_world_start.y(), T_world_start.theta();
  x_.segment<3>(3) = options.calibration_mean;
  x_.segment<2>(6) = options.sensor_bias_mean;
  x_[9] = options.bearing_scale_mean;
  x_[10] = options.depth_share_mean;
  x_[11] = options.range_scale_mean;
  P_ = Eigen::MatrixXd::Zero(kStateSize + k_, kStateSize + k_);
  P_.topLeftCorner<3, 3>() = start_covariance;
  P_.block<3, 3>(3, 3) = options.calibration_sigma.cwiseAbs2().asDiagonal();
  P_.block<2, 2>(6, 6) = options.sensor_bias_sigma.cwiseAbs2().asDiagonal();
  P_(8, 8) = options.noise.range_scale_sigma * options.noise.range_scale_sigma;
  P_(9, 9) = options.bearing_scale_sigma * options.bearing_scale_sigma;
  P_(10, 10) = options.depth_share_sigma * options.depth_share_sigma;
  P_(11, 11) = options.range_scale_state_sigma * options.range_scale_state_sigma;
  if (options.turn_fluctuation_sigma > 0.0 && options.turn_fluctuation_time_s > 0.0)
    P_(12, 12) = options.turn_fluctuation_sigma * options.turn_fluctuation_sigma;
  P_.bottomRightCorner(k_, k_).setIdentity();
}

std::optional<Eigen::Vector2d> RangeBearingLocalizer::LandmarkPosition(const MarkerKey& key) const {
  const auto it = landmarks_.find(key);
  if (it == landmarks_.end()) return std::nullopt;
  const auto slot = slots_.find(key);
  return LandmarkIn(it->second, slot != slots_.end() ? slot->second.index : -1, x_);
}

Eigen::Vector2d RangeBearingLocalizer::LandmarkIn(const Landmark& landmark, int slot,
                                                  const Eigen::VectorXd& state) const {
  Eigen::Vector2d l = landmark.l_map;
  if (options_.map_uncertainty != RangeBearingMapUncertainty::kEstimate) return l;
  if (k_ > 0) l += landmark.F * state.segment(kStateSize, k_);
  if (slot >= 0) l += state.segment<2>(slot);
  return l;
}

void RangeBearingLocalizer::DropSlot(const MarkerKey& key) {
  const int index = slots_.at(key).index, n = static_cast<int>(x_.size());
  const int tail = n - index - 2;
  // Marginalizing a Gaussian: drop its rows and columns.
  x_.segment(index, tail) = x_.tail(tail).eval();
  P_.middleRows(index, tail) = P_.bottomRows(tail).eval();
  P_.middleCols(index, tail) = P_.rightCols(tail).eval();
  x_.conservativeResize(n - 2);
  P_.conservativeResize(n - 2, n - 2);
  slots_.erase(key);
  for (auto& [other, slot] : slots_) {
    if (slot.index > index) slot.index -= 2;
  }
  ++counts_["landmark states dropped"];
}

int RangeBearingLocalizer::SlotOf(const MarkerKey& key, const Landmark& landmark) {
  if (!landmark.sigma) return -1;
  if (const auto it = slots_.find(key); it != slots_.end()) {
    it->second.last_used = updates_;
    return it->second.index;
  }
  if (static_cast<int>(slots_.size()) >= options_.max_landmark_states) {
    const auto oldest = std::min_element(slots_.begin(), slots_.end(), [](const auto& a, const auto& b) {
      return a.second.last_used < b.second.last_used;
    });
    DropSlot(oldest->first);
  }
  const int n = static_cast<int>(x_.size());
  x_.conservativeResize(n + 2);
  x_.tail<2>().setZero();
  P_.conservativeResize(n + 2, n + 2);
  P_.rightCols<2>().setZero();
  P_.bottomRows<2>().setZero();
  P_.bottomRightCorner<2, 2>() = landmark.D;
  slots_[key] = {n, updates_};
  return n;
}

std::pair<double, double> RangeBearingLocalizer::GaussMarkovStep(double sigma, double tau_s, double dt_s) {
  if (!(tau_s > 0.0)) return {1.0, 0.0};
  const double phi = std::exp(-std::max(0.0, dt_s) / tau_s);
  return {phi, sigma * sigma * (1.0 - phi * phi)};
}

RangeBearingLocalizer::Vector6 RangeBearingLocalizer::PredictState(const Vector6& x, const SE2d& T_a_b,
                                                                   double phi,
                                                                   const Eigen::Vector3d& calibration_phi,
                                                                   const Eigen::Vector3d& calibration_mean,
                                                                   double turn_phi) {
  const Eigen::Vector2d t_C = (1.0 + x[5]) * T_a_b.translation();
  const double theta_C = (1.0 + x[4] + x[12]) * T_a_b.theta() + x[3] * T_a_b.translation().norm();
  Vector6 next = x;
  next.head<2>() += Eigen::Rotation2Dd(x[2]) * t_C;
  next[2] = WrapAngle(x[2] + theta_C);
  next.segment<3>(3) = calibration_mean + calibration_phi.cwiseProduct(x.segment<3>(3) - calibration_mean);
  next[8] = phi * x[8];
  next[12] = turn_phi * x[12];
  return next;
}

RangeBearingLocalizer::Matrix6 RangeBearingLocalizer::PredictJacobian(const Vector6& x, const SE2d& T_a_b,
                                                                      double phi,
                                                                      const Eigen::Vector3d& calibration_phi,
                                                                      double turn_phi) {
  const Eigen::Matrix2d R = Eigen::Rotation2Dd(x[2]).toRotationMatrix();
  const Eigen::Vector2d rotated = R * ((1.0 + x[5]) * T_a_b.translation());
  Matrix6 F = Matrix6::Identity();
  F(0, 2) = -rotated.y();
  F(1, 2) = rotated.x();
  F.block<2, 1>(0, 5) = R * T_a_b.translation();
  F(2, 3) = T_a_b.translation().norm();
  F(2, 4) = T_a_b.theta();
  F(8, 8) = phi;
  for (int i = 0; i < 3; ++i) F(3 + i, 3 + i) = calibration_phi[i];
  F(2, 12) = T_a_b.theta();
  F(12, 12) = turn_phi;
  return F;
}

Eigen::Vector2d RangeBearingLocalizer::MeasureState(const Vector6& x, const Eigen::Vector2d& l_world) {
  const Eigen::Vector2d h = Measure(x.head<3>(), l_world);
  const Eigen::Vector2d d = l_world - x.head<2>();
  const double depth = std::cos(x[2]) * d.x() + std::sin(x[2]) * d.y();  // p_x
  const double read = h[0] + x[10] * (depth - h[0]);                     // (1 - c) r + c p_x
  return Eigen::Vector2d((1.0 + x[8] + x[11]) * read + x[6], WrapAngle((1.0 + x[9]) * h[1] + x[7]));
}

Eigen::Matrix<double, 2, RangeBearingLocalizer::kStateSize> RangeBearingLocalizer::MeasureStateJacobian(
    const Vector6& x, const Eigen::Vector2d& l_world) {
  Eigen::Matrix<double, 2, kStateSize> H = Eigen::Matrix<double, 2, kStateSize>::Zero();
  H.leftCols<3>() = MeasureJacobian(x.head<3>(), l_world);
  const Eigen::Vector2d d = l_world - x.head<2>();
  const double c = std::cos(x[2]), s = std::sin(x[2]);
  const double r = d.norm(), depth = c * d.x() + s * d.y(), lateral = -s * d.x() + c * d.y();
  // d p_x / d [x, y, theta] = [-cos theta, -sin theta, p_y].
  const Eigen::RowVector3d d_depth(-c, -s, lateral);
  const double scale = 1.0 + x[8] + x[11];
  H.block<1, 3>(0, 0) = scale * ((1.0 - x[10]) * H.block<1, 3>(0, 0) + x[10] * d_depth);
  H.block<1, 3>(1, 0) *= 1.0 + x[9];
  H(0, 6) = 1.0;
  H(1, 7) = 1.0;
  H(0, 8) = r + x[10] * (depth - r);
  H(1, 9) = Measure(x.head<3>(), l_world)[1];
  H(0, 10) = scale * (depth - r);
  H(0, 11) = H(0, 8);
  return H;
}

Eigen::Matrix2d RangeBearingLocalizer::MeasureLandmarkJacobian(const Vector6& x,
                                                               const Eigen::Vector2d& l_world) {
  return -MeasureStateJacobian(x, l_world).leftCols<2>();
}

Eigen::Vector2d RangeBearingLocalizer::Measure(const Eigen::Vector3d& x, const Eigen::Vector2d& l_world) {
  const Eigen::Vector2d d = l_world - x.head<2>();
  return Eigen::Vector2d(d.norm(), WrapAngle(std::atan2(d.y(), d.x()) - x[2]));
}

Eigen::Matrix<double, 2, 3> RangeBearingLocalizer::MeasureJacobian(const Eigen::Vector3d& x,
                                                                   const Eigen::Vector2d& l_world) {
  const Eigen::Vector2d d = l_world - x.head<2>();
  const double q = d.squaredNorm(), r = std::sqrt(q);
  Eigen::Matrix<double, 2, 3> H;
  H << -d.x() / r, -d.y() / r, 0.0, d.y() / q, -d.x() / q, -1.0;
  return H;
}

void RangeBearingLocalizer::Predict(const SE2d& T_a_b, double dt_s) {
  const RangeBearingNoise& n = options_.noise;
  const double phi = n.range_scale_sigma > 0.0 ? std::exp(-std::max(0.0, dt_s) / n.range_scale_time_s) : 1.0;
  Eigen::Vector3d calibration_phi, calibration_q;
  for (int i = 0; i < 3; ++i) {
    std::tie(calibration_phi[i], calibration_q[i]) =
        GaussMarkovStep(options_.calibration_sigma[i], options_.calibration_time_s[i], dt_s);
  }
  const bool fluctuates = options_.turn_fluctuation_sigma > 0.0 && options_.turn_fluctuation_time_s > 0.0;
  const auto [turn_phi, turn_q] =
      fluctuates ? GaussMarkovStep(options_.turn_fluctuation_sigma, options_.turn_fluctuation_time_s, dt_s)
                 : std::make_pair(1.0, 0.0);
  const Vector6 x = x_.head<kStateSize>();
  const Matrix6 F = PredictJacobian(x, T_a_b, phi, calibration_phi, turn_phi);
  const double c = std::cos(x[2]), s = std::sin(x[2]);
  Eigen::Matrix<double, kStateSize, 3> G = Eigen::Matrix<double, kStateSize, 3>::Zero();
  G.topLeftCorner<2, 2>() << c, -s, s, c;
  G(2, 2) = 1.0;
  const double d = T_a_b.translation().norm();
  const double var_t = n.odometry_q_t * (d + kLinkFloorM);
  const double var_r = n.odometry_q_r * (std::abs(T_a_b.theta()) + n.odometry_c_d * d + kLinkFloorRad);
  const Eigen::Matrix3d Q = Eigen::Vector3d(var_t, var_t, var_r).asDiagonal();
  x_.head<kStateSize>() = PredictState(x, T_a_b, phi, calibration_phi, options_.calibration_mean, turn_phi);
  // F_aug = blockdiag(F, I): the robot's rows and columns only.
  const Matrix6 P_xx = P_.topLeftCorner<kStateSize, kStateSize>();
  Matrix6 next = F * P_xx * F.transpose() + G * Q * G.transpose();
  next(8, 8) += n.range_scale_sigma * n.range_scale_sigma * (1.0 - phi * phi);
  for (int i = 0; i < 3; ++i) next(3 + i, 3 + i) += calibration_q[i];
  next(12, 12) += turn_q;
  P_.topLeftCorner<kStateSize, kStateSize>() = 0.5 * (next + next.transpose());
  const int rest = static_cast<int>(x_.size()) - kStateSize;
  if (rest > 0) {
    const Eigen::MatrixXd P_xm = F * P_.topRightCorner(kStateSize, rest);
    P_.topRightCorner(kStateSize, rest) = P_xm;
    P_.bottomLeftCorner(rest, kStateSize) = P_xm.transpose();
  }
  CheckLost();
}

RangeBearingUpdate RangeBearingLocalizer::Update(const RangeBearingObservation& observation) {
  const auto it = landmarks_.find(observation.key);
  if (it == landmarks_.end()) {
    ++counts_["unknown landmark"];
    return RangeBearingUpdate::kUnknownLandmark;
  }
  ++updates_;
  const Landmark& landmark = it->second;
  const Vector6 x = x_.head<kStateSize>();
  const Eigen::Vector2d l = *LandmarkPosition(observation.key);
  if ((l - x.head<2>()).norm() < 1e-3) {
    ++counts_["degenerate"];
    return RangeBearingUpdate::kDegenerate;
  }
  const double range_m = observation.elevation_rad
                             ? observation.range_m * std::cos(*observation.elevation_rad)
                             : observation.range_m;
  const RangeBearingNoise& n = options_.noise;
  double var_range = 0.0;
  if (observation.sigma_range_m) {
    var_range = *observation.sigma_range_m * *observation.sigma_range_m;
  } else {
    // The range variance less its part common to the frame (the state's s_range).
    const double total = n.range_a_m + n.range_b * range_m, common = n.range_scale_sigma * range_m;
    var_range = std::max(total * total - common * common, n.range_a_m * n.range_a_m);
  }
  const double sigma_bearing = observation.sigma_bearing_rad.value_or(n.bearing_rad);
  const int slot = Augmented() ? SlotOf(observation.key, landmark) : -1;
  const int size = static_cast<int>(x_.size());
  // The measurement linearized at robot state `xr` with the landmark at `l_at`: its Jacobian
  // over the whole state, its noise (with the map's error in it for kInNoise) and the
  // innovation z - h.
  struct Linearized {
    Eigen::MatrixXd H;
    Eigen::Matrix2d R;
    Eigen::Vector2d y;
  };
  const auto linearize = [&](const Vector6& xr, const Eigen::Vector2d& l_at) {
    Linearized out;
    out.R = Eigen::Vector2d(var_range, sigma_bearing * sigma_bearing).asDiagonal();
    const Eigen::Matrix<double, 2, kStateSize> H_x = MeasureStateJacobian(xr, l_at);
    const Eigen::Matrix2d H_l = -H_x.leftCols<2>();
    if (options_.map_uncertainty == RangeBearingMapUncertainty::kInNoise && landmark.sigma)
      out.R += H_l * *landmark.sigma * H_l.transpose();
    out.H = Eigen::MatrixXd::Zero(2, size);
    out.H.leftCols<kStateSize>() = H_x;
    if (k_ > 0) out.H.middleCols(kStateSize, k_) = H_l * landmark.F;
    if (slot >= 0) out.H.middleCols<2>(slot) = H_l;
    const Eigen::Vector2d predicted = MeasureState(xr, l_at);
    out.y = Eigen::Vector2d(range_m - predicted[0], WrapAngle(observation.bearing_rad - predicted[1]));
    return out;
  };
  const Linearized first = linearize(x, l);
  const Eigen::MatrixXd& H = first.H;
  const Eigen::Vector2d& y = first.y;
  const Eigen::MatrixXd HP = H * P_;  // 2 x size
  const Eigen::Matrix2d S = HP * H.transpose() + first.R;
  const Eigen::LLT<Eigen::Matrix2d> llt(S);
  if (llt.info() != Eigen::Success) {
    ++counts_["degenerate"];
    return RangeBearingUpdate::kDegenerate;
  }
  const double chi2 = y.dot(llt.solve(y));
  if (chi2 > options_.gate_chi2) {
    ++counts_["gated"];
    accepted_in_row_ = 0;
    if (++rejections_in_row_ >= options_.lost_rejections) {
      // Lost: widen P so that the gate can accept the next sightings again.
      const double sm = options_.reacquire_sigma_m, sr = options_.reacquire_sigma_rad;
      P_.topLeftCorner<3, 3>() += Eigen::Vector3d(sm * sm, sm * sm, sr * sr).asDiagonal().toDenseMatrix();
      rejections_in_row_ = 0;
      if (!lost_) ++counts_["became lost"];
      lost_ = true;
    }
    return RangeBearingUpdate::kGated;
  }
  Eigen::MatrixXd K = llt.solve(HP).transpose();  // size x 2
  // Schmidt: the map's error is considered, not estimated.
  if (options_.map_uncertainty == RangeBearingMapUncertainty::kConsider)
    K.bottomRows(size - kStateSize).setZero();
  Eigen::MatrixXd HP_i = HP;
  Eigen::Matrix2d S_i = S;
  const Eigen::VectorXd x_prior = x_;
  Eigen::VectorXd x_i = x_prior + K * y;
  x_i[2] = WrapAngle(x_i[2]);
  // The iterated update (Gauss-Newton on the prior and this sighting): relinearize h at the
  // updated state, y_i = z - h(x_i) - H_i (x_prior - x_i), x = x_prior + K_i y_i.
  const int iterations = lost_ ? options_.relocalization_iterations : options_.update_iterations;
  for (int iteration = 1; iteration < iterations; ++iteration) {
    const Vector6 xr = x_i.head<kStateSize>();
    const Eigen::Vector2d l_i = LandmarkIn(landmark, slot, x_i);
    if ((l_i - xr.head<2>()).norm() < 1e-3) break;
    const Linearized at = linearize(xr, l_i);
    Eigen::VectorXd dx = x_prior - x_i;
    dx[2] = WrapAngle(dx[2]);
    const Eigen::Vector2d y_i = at.y - at.H * dx;
    const Eigen::MatrixXd HP_next = at.H * P_;
    const Eigen::Matrix2d S_next = HP_next * at.H.transpose() + at.R;
    const Eigen::LLT<Eigen::Matrix2d> llt_i(S_next);
    if (llt_i.info() != Eigen::Success) break;
    K = llt_i.solve(HP_next).transpose();
    if (options_.map_uncertainty == RangeBearingMapUncertainty::kConsider)
      K.bottomRows(size - kStateSize).setZero();
    HP_i = HP_next;
    S_i = S_next;
    Eigen::VectorXd x_next = x_prior + K * y_i;
    x_next[2] = WrapAngle(x_next[2]);
    Eigen::VectorXd step = x_next - x_i;
    step[2] = WrapAngle(step[2]);
    x_i = x_next;
    if (step.head<3>().norm() < 1e-9) break;
  }
  x_ = x_i;
  // Joseph form (I - K H) P (I - K H)^T + K R K^T, expanded: right for any gain.
  const Eigen::MatrixXd KHP = K * HP_i;
  P_ += -KHP - KHP.transpose() + K * S_i * K.transpose();
  P_ = 0.5 * (P_ + P_.transpose()).eval();
  ++counts_["accepted"];
  accepted_nis_sum_ += chi2;
  ++accepted_nis_count_;
  rejections_in_row_ = 0;
  ++accepted_in_row_;
  CheckLost();
  return RangeBearingUpdate::kAccepted;
}

void RangeBearingLocalizer::CheckLost() {
  const double sigma_m = std::sqrt(std::max(
      0.0,
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(P_.topLeftCorner<2, 2>()).eigenvalues().maxCoeff()));
  if (!lost_ && sigma_m > options_.lost_sigma_m) {
    lost_ = true;
    accepted_in_row_ = 0;
    ++counts_["became lost"];
  } else if (lost_ && sigma_m <= options_.lost_sigma_m && accepted_in_row_ >= options_.regain_updates) {
    lost_ = false;
    ++counts_["regained"];
  }
}

}  // namespace waymark
