// Rigid transforms in 2-D and 3-D with Waymark's naming and perturbation conventions.
//
// Naming: a variable `T_a_b` of type SE3d maps a point from frame b into frame a,
//   p_a = T_a_b * p_b,   and only adjacent subscripts compose:
//   T_world_camera = T_world_robot * T_robot_camera.
//
// Quaternions are Eigen::Quaterniond (storage x, y, z, w, the order Ceres'
// EigenQuaternionManifold uses and the order files write as q_xyzw).
//
// Tangent space: 6-vectors are ordered [rotation, translation] = [rx ry rz tx ty tz],
// and perturbations are on the right, in the body frame:
//   T = T_hat * Exp(delta),   delta = [dr, dt].
// Exp here is the product map Exp([dr, dt]) = (exp(dr), dt): rotation and translation
// are perturbed independently, both in the body frame. This is the meaning of the
// `covariance` field of map.json (docs/design.md). It is NOT the tangent of Ceres'
// EigenQuaternionManifold (which perturbs the rotation on the left, by half the rotation
// vector) nor of a world-frame translation: a covariance from ceres::Covariance on a pose
// block is converted with factors/pose_block.h's ManifoldToBodyTangentJacobian.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>

namespace waymark {

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;

// Wraps an angle to (-pi, pi].
inline double WrapAngle(double angle_rad) {
  angle_rad = std::remainder(angle_rad, 2.0 * M_PI);
  if (angle_rad <= -M_PI) angle_rad += 2.0 * M_PI;
  return angle_rad;
}

// Skew-symmetric matrix: Hat(a) * b == a.cross(b).
template <typename T>
Eigen::Matrix<T, 3, 3> Hat(const Eigen::Matrix<T, 3, 1>& v) {
  Eigen::Matrix<T, 3, 3> m;
  m << T(0), -v.z(), v.y(), v.z(), T(0), -v.x(), -v.y(), v.x(), T(0);
  return m;
}

// SO(3) exponential of a rotation vector (axis * angle), exact near zero.
inline Eigen::Quaterniond ExpSO3(const Eigen::Vector3d& rotation_vector) {
  const double angle = rotation_vector.norm();
  if (angle < 1e-12) {
    Eigen::Quaterniond q(1.0, 0.5 * rotation_vector.x(), 0.5 * rotation_vector.y(),
                         0.5 * rotation_vector.z());
    return q.normalized();
  }
  return Eigen::Quaterniond(Eigen::AngleAxisd(angle, rotation_vector / angle));
}

// SO(3) logarithm: the rotation vector with angle in [0, pi].
inline Eigen::Vector3d LogSO3(const Eigen::Quaterniond& q_in) {
  Eigen::Quaterniond q = q_in.normalized();
  if (q.w() < 0.0) q.coeffs() = -q.coeffs();  // shortest rotation
  const Eigen::Vector3d v = q.vec();
  const double sin_half = v.norm();
  if (sin_half < 1e-12) return 2.0 * v;  // first order, w ~ 1
  const double angle = 2.0 * std::atan2(sin_half, q.w());
  return v * (angle / sin_half);
}

// A rigid transform in 3-D: p_a = q * p_b + t.
class SE3d {
 public:
  SE3d() : q_(Eigen::Quaterniond::Identity()), t_(Eigen::Vector3d::Zero()) {}
  SE3d(const Eigen::Quaterniond& q, const Eigen::Vector3d& t) : q_(q.normalized()), t_(t) {}
  SE3d(const Eigen::Matrix3d& R, const Eigen::Vector3d& t) : q_(Eigen::Quaterniond(R).normalized()), t_(t) {}

  static SE3d Identity() { return SE3d(); }
  // From a quaternion that is already unit norm to double precision (e.g. one read back from
  // a file Waymark wrote): kept bit for bit, so write/read round trips are exact. Callers
  // check the norm first (the constructors above renormalize, which can change the last bit).
  static SE3d FromUnitQuaternion(const Eigen::Quaterniond& q_unit, const Eigen::Vector3d& t) {
    SE3d T;
    T.q_ = q_unit;
    T.t_ = t;
    return T;
  }
  // From a 4x4 homogeneous matrix (the rotation block is re-orthonormalized).
  static SE3d FromMatrix(const Eigen::Matrix4d& m) {
    return SE3d(Eigen::Matrix3d(m.topLeftCorner<3, 3>()), Eigen::Vector3d(m.topRightCorner<3, 1>()));
  }
  // Planar pose (x, y, yaw) at height z.
  static SE3d FromXYZYaw(double x, double y, double z, double yaw_rad) {
    return SE3d(Eigen::Quaterniond(Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ())),
                Eigen::Vector3d(x, y, z));
  }
  // Product-map exponential (see the header comment): Exp([dr, dt]) = (exp(dr), dt).
  static SE3d Exp(const Vector6d& delta) { return SE3d(ExpSO3(delta.head<3>()), delta.tail<3>()); }

  const Eigen::Quaterniond& rotation() const { return q_; }
  const Eigen::Vector3d& translation() const { return t_; }
  Eigen::Matrix3d rotation_matrix() const { return q_.toRotationMatrix(); }
  Eigen::Matrix4d matrix() const {
    Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
    m.topLeftCorner<3, 3>() = rotation_matrix();
    m.topRightCorner<3, 1>() = t_;
    return m;
  }
  // Heading about world z of the x axis, atan2(R10, R00).
  double yaw() const {
    const Eigen::Matrix3d R = rotation_matrix();
    return std::atan2(R(1, 0), R(0, 0));
  }

  SE3d inverse() const {
    const Eigen::Quaterniond q_inv = q_.conjugate();
    return SE3d(q_inv, -(q_inv * t_));
  }
  SE3d operator*(const SE3d& other) const { return SE3d(q_ * other.q_, q_ * other.t_ + t_); }
  Eigen::Vector3d operator*(const Eigen::Vector3d& p) const { return q_ * p + t_; }

  // Right perturbation: this * Exp(delta).
  SE3d BoxPlus(const Vector6d& delta) const { return *this * Exp(delta); }
  // Inverse of BoxPlus: delta such that this.BoxPlus(delta) == other.
  //   dr = Log(q^-1 q_other), dt = q^-1 (t_other - t)   (product map in the body frame)
  Vector6d BoxMinus(const SE3d& other) const {
    Vector6d delta;
    delta.head<3>() = LogSO3(q_.conjugate() * other.q_);
    delta.tail<3>() = q_.conjugate() * (other.t_ - t_);
    return delta;
  }

  bool IsFinite() const { return q_.coeffs().allFinite() && t_.allFinite(); }

 private:
  Eigen::Quaterniond q_;
  Eigen::Vector3d t_;
};

// Angle of the relative rotation between two transforms, in radians.
inline double RotationAngleBetween(const SE3d& T_a, const SE3d& T_b) {
  return LogSO3(T_a.rotation().conjugate() * T_b.rotation()).norm();
}

// A rigid transform in the plane: p_a = R(theta) p_b + [x, y].
class SE2d {
 public:
  SE2d() = default;
  SE2d(double x, double y, double theta_rad) : x_(x), y_(y), theta_(WrapAngle(theta_rad)) {}

  // Drops z, roll and pitch: keeps x, y and the yaw of the x axis.
  static SE2d FromSE3(const SE3d& T) { return SE2d(T.translation().x(), T.translation().y(), T.yaw()); }
  // Lifts to 3-D at height z.
  SE3d ToSE3(double z = 0.0) const { return SE3d::FromXYZYaw(x_, y_, z, theta_); }
  // Exp of (dx, dy, dtheta) in the body frame, product map like SE3d::Exp.
  static SE2d Exp(const Eigen::Vector3d& delta) { return SE2d(delta.x(), delta.y(), delta.z()); }

  double x() const { return x_; }
  double y() const { return y_; }
  double theta() const { return theta_; }
  Eigen::Vector2d translation() const { return {x_, y_}; }
  Eigen::Matrix2d rotation_matrix() const {
    const double c = std::cos(theta_), s = std::sin(theta_);
    return (Eigen::Matrix2d() << c, -s, s, c).finished();
  }

  SE2d inverse() const {
    const Eigen::Vector2d t = -(rotation_matrix().transpose() * translation());
    return SE2d(t.x(), t.y(), -theta_);
  }
  SE2d operator*(const SE2d& other) const {
    const Eigen::Vector2d t = rotation_matrix() * other.translation() + translation();
    return SE2d(t.x(), t.y(), theta_ + other.theta_);
  }
  Eigen::Vector2d operator*(const Eigen::Vector2d& p) const { return rotation_matrix() * p + translation(); }

  // Right perturbation of the product map: [R^T (t_other - t), wrap(theta_other - theta)].
  Eigen::Vector3d BoxMinus(const SE2d& other) const {
    const Eigen::Vector2d dt = rotation_matrix().transpose() * (other.translation() - translation());
    return {dt.x(), dt.y(), WrapAngle(other.theta_ - theta_)};
  }

 private:
  double x_ = 0.0, y_ = 0.0, theta_ = 0.0;
};

// ---- SE(3) exponential, logarithm and interpolation (geometry/pose.cc) ----
//
// Two tangent maps, two meanings. The product map of ExpSO3 / BoxPlus above (rotation and
// translation perturbed separately) is the one of every covariance and every Ceres manifold. The
// screw map below moves along a constant twist: with the tangent [rotation, translation] =
// [phi, rho],
//   ExpSE3Screw(phi, rho) = (exp(phi), V(phi) rho),
//   V = I + (1 - cos th) / th^2 Phi + (th - sin th) / th^3 Phi^2,  Phi = Hat(phi), th = |phi|,
// exact for a body moving with constant linear and angular velocity in its own frame.
SE3d ExpSE3Screw(const Vector6d& xi);
Vector6d LogSE3Screw(const SE3d& T);

// The pose at fraction s of the way from T_a (s = 0) to T_b (s = 1) along the screw motion:
//   T_a * ExpSE3Screw(s * LogSE3Screw(T_a^-1 * T_b)).
// For odometry between two samples (a robot turning on an arc stays on the arc).
SE3d InterpolateScrew(const SE3d& T_a, const SE3d& T_b, double s);

// The same fraction with rotation and translation interpolated apart: slerp of the rotations,
// linear in the translations (the product map). For trajectories sampled densely enough that
// the difference from the screw does not matter, and where the path between samples is unknown.
SE3d InterpolateProduct(const SE3d& T_a, const SE3d& T_b, double s);

}  // namespace waymark
