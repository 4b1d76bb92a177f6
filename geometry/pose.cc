#include "geometry/pose.h"

#include <Eigen/LU>
#include <cmath>

namespace waymark {
namespace {

// V(phi) of the screw exponential (pose.h), with its series near phi = 0.
Eigen::Matrix3d ScrewV(const Eigen::Vector3d& phi) {
  const double theta = phi.norm();
  const Eigen::Matrix3d Phi = Hat(phi);
  double a = 0.0, b = 0.0;
  if (theta < 1e-5) {
    a = 0.5 - theta * theta / 24.0;
    b = 1.0 / 6.0 - theta * theta / 120.0;
  } else {
    a = (1.0 - std::cos(theta)) / (theta * theta);
    b = (theta - std::sin(theta)) / (theta * theta * theta);
  }
  return Eigen::Matrix3d::Identity() + a * Phi + b * Phi * Phi;
}

}  // namespace

SE3d ExpSE3Screw(const Vector6d& xi) {
  const Eigen::Vector3d phi = xi.head<3>();
  return SE3d(ExpSO3(phi), ScrewV(phi) * xi.tail<3>());
}

Vector6d LogSE3Screw(const SE3d& T) {
  Vector6d xi;
  xi.head<3>() = LogSO3(T.rotation());
  xi.tail<3>() = ScrewV(xi.head<3>()).partialPivLu().solve(T.translation());
  return xi;
}

SE3d InterpolateScrew(const SE3d& T_a, const SE3d& T_b, double s) {
  return T_a * ExpSE3Screw(s * LogSE3Screw(T_a.inverse() * T_b));
}

SE3d InterpolateProduct(const SE3d& T_a, const SE3d& T_b, double s) {
  const Eigen::Quaterniond q = T_a.rotation().slerp(s, T_b.rotation());
  return SE3d(q, (1.0 - s) * T_a.translation() + s * T_b.translation());
}

}  // namespace waymark
