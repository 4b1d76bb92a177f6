// Odometry between-factors that also estimate the odometry's systematic errors.
//
// Wheel and visual odometry drift mostly through a few constant errors (Borenstein's UMBmark):
// unequal wheel radii bend straight runs into arcs (a heading change proportional to the
// distance), a wrong track width scales the measured turns, a wrong wheel radius or visual
// scale scales the distance. A per-increment noise model cannot absorb a constant bias (it
// accumulates linearly, the noise as a square root), so these three numbers are estimated with
// the map, in one block shared by every increment of a survey:
//   c = [k_rad_per_m, turn_scale, distance_scale]   (all 0 for a perfect odometry)
// The measured increment M = (t_M, theta_M) (SE(2); s = |t_M|) is corrected to
//   theta_C = (theta_M - k s) / (1 + turn_scale)
//   t_C     = R((theta_C - theta_M) / 2) t_M / (1 + distance_scale)
// (the chord of an arc points at half its heading change, hence the half-angle rotation), and
//   r = S BoxMinus(C, T_a_b)       exactly as factors/odometry_se2_factor.h with M -> C.
// SE(3) (free surveys): the heading correction rotates about the robot's z axis,
//   q_C = Rz((theta_C - theta_M)) q_M with theta_M the yaw of q_M,  t_C = t_M / (1 + distance_scale),
//   r = S BoxMinus(C, T_a_b)       as factors/odometry_se3_factor.h.
// Blocks: T_world_robot_a, T_world_robot_b (SE(2) [x y theta] or SE(3) 7-blocks), c (3, Euclidean).
// The calibration block needs a weak prior (OdometryCalibrationPrior) so that a survey that does
// not excite a parameter (no turn, no code) leaves it at 0 instead of making the problem singular.
#pragma once

#include <ceres/autodiff_cost_function.h>

#include <Eigen/Core>
#include <cmath>

#include "factors/pose_block.h"
#include "factors/sqrt_information.h"
#include "geometry/pose.h"

namespace waymark {

inline constexpr int kOdometryCalibrationSize = 3;

// A usable c: finite, and both scales above -1 (the corrections divide by 1 + scale).
inline constexpr const char* kOdometryCalibrationRule =
    "the odometry calibration must be three finite numbers k_rad_per_m, turn_scale, distance_scale with both "
    "scales above -1";
inline bool OdometryCalibrationValid(const Eigen::Vector3d& c) {
  return c.allFinite() && c[1] > -1.0 && c[2] > -1.0;
}
inline bool OdometryCalibrationSigmaValid(const Eigen::Vector3d& sigma) {
  return sigma.allFinite() && (sigma.array() > 0.0).all();
}

class CalibratedOdometrySE2Factor {
 public:
  // measurement_space: the translation error scaled back into the measurement's units, delta_t
  // (1 + distance_scale) (the noise is the measurement's: t_M = the true translation times
  // 1 + distance_scale, plus noise of `covariance`). Without it the translation error
  // is whitened in the corrected increment's units, so shrinking the whole map while the distance
  // scale grows lowers the cost: a free metric scale (e.g. a range sensor's scale estimated too)
  // is pulled short.
  CalibratedOdometrySE2Factor(const SE2d& T_a_b_measured, const Eigen::Matrix3d& covariance,
                              bool measurement_space = false)
      : M_(T_a_b_measured),
        distance_m_(T_a_b_measured.translation().norm()),
        sqrt_information_(SqrtInformation<3>(covariance, "calibrated odometry SE(2) factor")),
        measurement_space_(measurement_space) {}

  template <typename T>
  bool operator()(const T* const T_world_robot_a, const T* const T_world_robot_b, const T* const c,
                  T* residuals) const {
    using std::cos;
    using std::sin;
    const T theta_c = (T(M_.theta()) - c[0] * T(distance_m_)) / (T(1) + c[1]);
    const T half = T(0.5) * (theta_c - T(M_.theta()));
    const T inv_scale = T(1) / (T(1) + c[2]);
    const T tx_c = (cos(half) * T(M_.x()) - sin(half) * T(M_.y())) * inv_scale;
    const T ty_c = (sin(half) * T(M_.x()) + cos(half) * T(M_.y())) * inv_scale;
    // T_a_b in frame a, then BoxMinus(C, T_a_b) = [R(theta_C)^T (t_a_b - t_C), wrap(theta_a_b - theta_C)].
    const T dx_world = T_world_robot_b[0] - T_world_robot_a[0];
    const T dy_world = T_world_robot_b[1] - T_world_robot_a[1];
    const T cos_a = cos(T_world_robot_a[2]), sin_a = sin(T_world_robot_a[2]);
    const T dx_a = cos_a * dx_world + sin_a * dy_world - tx_c;
    const T dy_a = -sin_a * dx_world + cos_a * dy_world - ty_c;
    const T cos_c = cos(theta_c), sin_c = sin(theta_c);
    Eigen::Matrix<T, 3, 1> delta;
    delta << cos_c * dx_a + sin_c * dy_a, -sin_c * dx_a + cos_c * dy_a,
        WrapAngleT(T_world_robot_b[2] - T_world_robot_a[2] - theta_c);
    if (measurement_space_) {
      delta[0] *= T(1) + c[2];
      delta[1] *= T(1) + c[2];
    }
    Eigen::Map<Eigen::Matrix<T, 3, 1>> whitened(residuals);
    whitened = sqrt_information_.template cast<T>() * delta;
    return true;
  }

  static ceres::CostFunction* Create(const SE2d& T_a_b_measured, const Eigen::Matrix3d& covariance,
                                     bool measurement_space = false) {
    return new ceres::AutoDiffCostFunction<CalibratedOdometrySE2Factor, 3, kSE2BlockSize, kSE2BlockSize,
                                           kOdometryCalibrationSize>(
        new CalibratedOdometrySE2Factor(T_a_b_measured, covariance, measurement_space));
  }

 private:
  const SE2d M_;
  const double distance_m_;
  const Eigen::Matrix3d sqrt_information_;
  const bool measurement_space_;
};

class CalibratedOdometrySE3Factor {
 public:
  CalibratedOdometrySE3Factor(const SE3d& T_a_b_measured, const Matrix6d& covariance)
      : M_(T_a_b_measured),
        distance_m_(T_a_b_measured.translation().norm()),
        yaw_m_(T_a_b_measured.yaw()),
        sqrt_information_(SqrtInformation<6>(covariance, "calibrated odometry SE(3) factor")) {}

  template <typename T>
  bool operator()(const T* const T_world_robot_a, const T* const T_world_robot_b, const T* const c,
                  T* residuals) const {
    using std::cos;
    using std::sin;
    const T theta_c = (T(yaw_m_) - c[0] * T(distance_m_)) / (T(1) + c[1]);
    const T half = T(0.5) * (theta_c - T(yaw_m_));
    const Eigen::Quaternion<T> q_z(cos(half), T(0), T(0), sin(half));
    SE3T<T> C = SE3TFromSE3<T>(M_);
    C.q = q_z * C.q;
    C.t = C.t / (T(1) + c[2]);
    const SE3T<T> T_a_b = SE3TFromBlock(T_world_robot_a).inverse() * SE3TFromBlock(T_world_robot_b);
    Eigen::Map<Eigen::Matrix<T, 6, 1>> whitened(residuals);
    whitened = sqrt_information_.template cast<T>() * BoxMinusT(C, T_a_b);
    return true;
  }

  static ceres::CostFunction* Create(const SE3d& T_a_b_measured, const Matrix6d& covariance) {
    return new ceres::AutoDiffCostFunction<CalibratedOdometrySE3Factor, 6, kSE3BlockSize, kSE3BlockSize,
                                           kOdometryCalibrationSize>(
        new CalibratedOdometrySE3Factor(T_a_b_measured, covariance));
  }

 private:
  const SE3d M_;
  const double distance_m_;
  const double yaw_m_;
  const Matrix6d sqrt_information_;
};

// r = (c - mean) / sigma: by default a weak prior holding the calibration at 0 where the survey
// says nothing; with an earlier survey's estimate as mean and sigma, that survey's knowledge.
struct OdometryCalibrationPrior {
  OdometryCalibrationPrior(const Eigen::Vector3d& mean, const Eigen::Vector3d& sigma)
      : mean(mean), inverse_sigma(sigma.cwiseInverse()) {}
  template <typename T>
  bool operator()(const T* const c, T* residuals) const {
    for (int i = 0; i < 3; ++i) residuals[i] = (c[i] - T(mean[i])) * T(inverse_sigma[i]);
    return true;
  }
  static ceres::CostFunction* Create(const Eigen::Vector3d& sigma) {
    return Create(Eigen::Vector3d::Zero(), sigma);
  }
  static ceres::CostFunction* Create(const Eigen::Vector3d& mean, const Eigen::Vector3d& sigma) {
    return new ceres::AutoDiffCostFunction<OdometryCalibrationPrior, 3, kOdometryCalibrationSize>(
        new OdometryCalibrationPrior(mean, sigma));
  }
  const Eigen::Vector3d mean;
  const Eigen::Vector3d inverse_sigma;
};

}  // namespace waymark
