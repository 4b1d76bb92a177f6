// Parameter-block layouts shared by every Waymark factor, and the scalar-templated
// geometry the factors evaluate on Ceres Jets. factors/README.md explains the choices.
//
// SE(3) pose block, kSE3BlockSize = 7 doubles, one block per pose:
//   [qx qy qz qw tx ty tz]  holding T_a_b (p_a = R(q) p_b + t),
// quaternion in Eigen's storage order (x, y, z, w) as docs/design.md requires; never ceres/rotation.h's
// (w, x, y, z) helpers. Its manifold is SE3Manifold = ProductManifold<EigenQuaternionManifold,
// EuclideanManifold<3>>. Blocks must hold unit quaternions (the manifold keeps them unit).
//
// SE(2) robot block, kSE2BlockSize = 3 doubles: [x y theta] holding T_world_robot of a planar
// robot, Euclidean (no manifold). theta is unbounded in the block; every residual wraps it.
// It is lifted to 3-D at z = 0: T_world_robot = (Rz(theta), [x, y, 0]); the camera extrinsic
// T_robot_camera carries the camera's fixed height and tilt.
//
// Residuals and covariances given to factors follow geometry/pose.h: tangent order [r, t], right
// perturbation in the body frame, T = T_hat * Exp(delta). Ceres' manifold steps differently
// (left, half-angle rotation, world-frame translation):
//   Plus([q, t], [m_r, m_t]) = ([cos|m_r|, sin|m_r| m_r/|m_r|] (x) q,  t + m_t),
// i.e. rotation vector 2 m_r applied on the left. The step does not change the optimum, only
// covariances read back from ceres::Covariance in the manifold's tangent: convert them with
// ManifoldToBodyTangentJacobian, delta = J m, J = blockdiag(2 R^T, R^T), Sigma = J Sigma_m J^T.
#pragma once

#include <ceres/manifold.h>
#include <ceres/product_manifold.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>

#include "geometry/pose.h"

namespace waymark {

inline constexpr int kSE3BlockSize = 7;
inline constexpr int kSE2BlockSize = 3;

// The manifold of every SE(3) pose block.
using SE3Manifold = ceres::ProductManifold<ceres::EigenQuaternionManifold, ceres::EuclideanManifold<3>>;

// Writes T into a 7-block [qx qy qz qw tx ty tz] (unit quaternion).
inline void SE3ToBlock(const SE3d& T, double* block) {
  const Eigen::Quaterniond q = T.rotation().normalized();
  block[0] = q.x();
  block[1] = q.y();
  block[2] = q.z();
  block[3] = q.w();
  for (int i = 0; i < 3; ++i) block[4 + i] = T.translation()[i];
}

inline SE3d SE3FromBlock(const double* block) {
  const Eigen::Quaterniond q(block[3], block[0], block[1], block[2]);  // (w, x, y, z) constructor
  return SE3d(q, Eigen::Vector3d(block[4], block[5], block[6]));
}

inline void SE2ToBlock(const SE2d& T, double* block) {
  block[0] = T.x();
  block[1] = T.y();
  block[2] = T.theta();
}

inline SE2d SE2FromBlock(const double* block) { return SE2d(block[0], block[1], block[2]); }

// d(delta_body)/d(m_manifold) at T (see the header comment): blockdiag(2 R^T, R^T).
inline Matrix6d ManifoldToBodyTangentJacobian(const SE3d& T) {
  const Eigen::Matrix3d R_t = T.rotation_matrix().transpose();
  Matrix6d J = Matrix6d::Zero();
  J.topLeftCorner<3, 3>() = 2.0 * R_t;
  J.bottomRightCorner<3, 3>() = R_t;
  return J;
}

template <typename T>
using Vector2T = Eigen::Matrix<T, 2, 1>;
template <typename T>
using Vector3T = Eigen::Matrix<T, 3, 1>;

// A rigid transform on any scalar (double or ceres::Jet): p_a = q * p_b + t.
template <typename T>
struct SE3T {
  Eigen::Quaternion<T> q;
  Vector3T<T> t;

  Vector3T<T> operator*(const Vector3T<T>& p_b) const { return q * p_b + t; }
  SE3T operator*(const SE3T& other) const { return {q * other.q, q * other.t + t}; }
  SE3T inverse() const {
    const Eigen::Quaternion<T> q_inv = q.conjugate();
    return {q_inv, -(q_inv * t)};
  }
};

// Views a 7-block as a transform (copies; blocks are small).
template <typename T>
SE3T<T> SE3TFromBlock(const T* block) {
  return {Eigen::Quaternion<T>(block[3], block[0], block[1], block[2]),
          Vector3T<T>(block[4], block[5], block[6])};
}

// A constant transform cast to the scalar T.
template <typename T>
SE3T<T> SE3TFromSE3(const SE3d& T_a_b) {
  return {T_a_b.rotation().template cast<T>(), T_a_b.translation().template cast<T>()};
}

// Lifts an SE(2) block [x y theta] to 3-D at z = 0: (Rz(theta), [x, y, 0]).
template <typename T>
SE3T<T> SE3TFromSE2Block(const T* block) {
  using std::cos;
  using std::sin;
  const T half_theta = T(0.5) * block[2];
  return {Eigen::Quaternion<T>(cos(half_theta), T(0), T(0), sin(half_theta)),
          Vector3T<T>(block[0], block[1], T(0))};
}

// Wraps an angle to (-pi, pi], smoothly differentiable (derivative 1) away from +-pi.
template <typename T>
T WrapAngleT(const T& angle_rad) {
  using std::atan2;
  using std::cos;
  using std::sin;
  return atan2(sin(angle_rad), cos(angle_rad));
}

// SO(3) logarithm (rotation vector, angle in [0, pi]) of a quaternion, as LogSO3 in
// geometry/pose.h. Invariant to the quaternion's scale. Below |v| = 1e-8 it uses the series
// 2 atan2(|v|, w) / |v| = 2 / w + O(|v|^2), so Jets stay finite at the identity.
template <typename T>
Vector3T<T> LogSO3T(const Eigen::Quaternion<T>& q_in) {
  using std::atan2;
  using std::sqrt;
  Eigen::Quaternion<T> q = q_in;
  if (q.w() < T(0)) q.coeffs() = -q.coeffs();  // shortest rotation
  const Vector3T<T> v = q.vec();
  const T sin_half_squared = v.squaredNorm();
  if (sin_half_squared > T(1e-16)) {
    const T sin_half = sqrt(sin_half_squared);
    return v * (T(2) * atan2(sin_half, q.w()) / sin_half);
  }
  return v * (T(2) / q.w());
}

// geometry/pose.h's SE3d::BoxMinus on any scalar: the delta with T_a * Exp(delta) = T_b,
//   delta = [Log(q_a^-1 q_b), R_a^T (t_b - t_a)].
template <typename T>
Eigen::Matrix<T, 6, 1> BoxMinusT(const SE3T<T>& T_a, const SE3T<T>& T_b) {
  const Eigen::Quaternion<T> q_a_inv = T_a.q.conjugate();
  Eigen::Matrix<T, 6, 1> delta;
  delta.template head<3>() = LogSO3T<T>(q_a_inv * T_b.q);
  delta.template tail<3>() = q_a_inv * (T_b.t - T_a.t);
  return delta;
}

}  // namespace waymark
