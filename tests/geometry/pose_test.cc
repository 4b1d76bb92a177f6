// Tests of geometry/pose.h: SE3d / SE2d composition and inverse, the right-perturbation
// product map (BoxPlus / BoxMinus), SO(3) Exp / Log near 0 and near pi, yaw, WrapAngle.
#include "geometry/pose.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

namespace waymark {
namespace {

// A random rotation (uniform quaternion) and a translation in [-5, 5]^3.
SE3d RandomSE3(std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  std::uniform_real_distribution<double> u(-5.0, 5.0);
  const Eigen::Quaterniond q(n(rng), n(rng), n(rng), n(rng));
  return SE3d(q, Eigen::Vector3d(u(rng), u(rng), u(rng)));
}

void ExpectSE3Near(const SE3d& a, const SE3d& b, double tol) {
  EXPECT_LE((a.matrix() - b.matrix()).cwiseAbs().maxCoeff(), tol) << "\n"
                                                                  << a.matrix() << "\nvs\n"
                                                                  << b.matrix();
}

// Rodrigues' formula, written independently of ExpSO3.
Eigen::Matrix3d Rodrigues(const Eigen::Vector3d& w) {
  const double angle = w.norm();
  if (angle == 0.0) return Eigen::Matrix3d::Identity();
  const Eigen::Matrix3d K = Hat(Eigen::Vector3d(w / angle));
  return Eigen::Matrix3d::Identity() + std::sin(angle) * K + (1.0 - std::cos(angle)) * K * K;
}

TEST(GeometryTest, HatIsTheCrossProduct) {
  const Eigen::Vector3d a(0.3, -1.2, 2.0), b(-0.7, 0.4, 1.1);
  EXPECT_LE((Hat(a) * b - a.cross(b)).norm(), 1e-15);
  EXPECT_LE((Hat(a) + Hat(a).transpose()).norm(), 0.0);
}

TEST(GeometryTest, ComposeFollowsAdjacentSubscripts) {
  // Robot at (1, 2, 0) facing +y (yaw 90 deg); camera 0.5 m ahead of the robot.
  const SE3d T_world_robot = SE3d::FromXYZYaw(1.0, 2.0, 0.0, M_PI / 2.0);
  const SE3d T_robot_camera(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.5, 0.0, 0.0));
  const SE3d T_world_camera = T_world_robot * T_robot_camera;
  EXPECT_LE((T_world_camera.translation() - Eigen::Vector3d(1.0, 2.5, 0.0)).norm(), 1e-15);
  // A point 1 m to the robot's left is at x = 0 in the world.
  EXPECT_LE((T_world_robot * Eigen::Vector3d(0.0, 1.0, 0.0) - Eigen::Vector3d(0.0, 2.0, 0.0)).norm(), 1e-15);
}

TEST(GeometryTest, ComposeIsAssociativeAndInverseUndoes) {
  std::mt19937 rng(1);
  for (int i = 0; i < 100; ++i) {
    const SE3d T_a_b = RandomSE3(rng), T_b_c = RandomSE3(rng), T_c_d = RandomSE3(rng);
    const Eigen::Vector3d p_d(0.3 * i, -1.0, 2.0);
    ExpectSE3Near((T_a_b * T_b_c) * T_c_d, T_a_b * (T_b_c * T_c_d), 1e-12);
    EXPECT_LE(((T_a_b * T_b_c) * p_d - T_a_b * (T_b_c * p_d)).norm(), 1e-12);
    ExpectSE3Near(T_a_b * T_a_b.inverse(), SE3d::Identity(), 1e-14);
    ExpectSE3Near(T_a_b.inverse() * T_a_b, SE3d::Identity(), 1e-14);
    EXPECT_LE((T_a_b.inverse() * (T_a_b * p_d) - p_d).norm(), 1e-12);
    ExpectSE3Near((T_a_b * T_b_c).inverse(), T_b_c.inverse() * T_a_b.inverse(), 1e-12);
    ExpectSE3Near(SE3d::FromMatrix(T_a_b.matrix()), T_a_b, 1e-14);
    EXPECT_LE((T_a_b.matrix().inverse() - T_a_b.inverse().matrix()).cwiseAbs().maxCoeff(), 1e-12);
  }
}

TEST(GeometryTest, ConstructorsNormalizeTheRotation) {
  const SE3d T(Eigen::Quaterniond(2.0, 0.0, 0.0, 0.0), Eigen::Vector3d(1.0, 2.0, 3.0));
  EXPECT_NEAR(T.rotation().norm(), 1.0, 1e-15);
  EXPECT_TRUE(T.IsFinite());
  EXPECT_FALSE(SE3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(std::nan(""), 0.0, 0.0)).IsFinite());
}

TEST(GeometryTest, BoxPlusIsARightPerturbationInTheBodyFrame) {
  const SE3d T_world_robot = SE3d::FromXYZYaw(1.0, 2.0, 0.5, M_PI / 2.0);
  Vector6d delta = Vector6d::Zero();
  delta(3) = 1.0;  // 1 m along the body x axis = world +y here
  const SE3d moved = T_world_robot.BoxPlus(delta);
  EXPECT_LE((moved.translation() - Eigen::Vector3d(1.0, 3.0, 0.5)).norm(), 1e-15);
  EXPECT_LE(RotationAngleBetween(moved, T_world_robot), 1e-15);
  delta.setZero();
  delta(0) = 0.1;  // rotation about the body x axis = world +y
  const SE3d rolled = T_world_robot.BoxPlus(delta);
  const Eigen::Matrix3d expected =
      T_world_robot.rotation_matrix() * Rodrigues(Eigen::Vector3d(0.1, 0.0, 0.0));
  EXPECT_LE((rolled.rotation_matrix() - expected).norm(), 1e-14);
  EXPECT_LE((rolled.translation() - T_world_robot.translation()).norm(), 1e-15);
}

TEST(GeometryTest, BoxPlusBoxMinusRoundTrip) {
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int i = 0; i < 200; ++i) {
    const SE3d T = RandomSE3(rng), other = RandomSE3(rng);
    Vector6d delta;
    for (int k = 0; k < 6; ++k) delta(k) = 1.5 * u(rng);  // |dr| < pi
    const Vector6d back = T.BoxMinus(T.BoxPlus(delta));
    EXPECT_LE((back - delta).norm(), 1e-12) << delta.transpose() << "\n" << back.transpose();
    ExpectSE3Near(T.BoxPlus(T.BoxMinus(other)), other, 1e-12);
    EXPECT_LE(T.BoxMinus(T).norm(), 1e-15);
    EXPECT_NEAR(T.BoxMinus(other).head<3>().norm(), RotationAngleBetween(T, other), 1e-12);
  }
}

TEST(GeometryTest, ExpMatchesRodriguesAndLogInvertsIt) {
  std::mt19937 rng(3);
  std::normal_distribution<double> n(0.0, 1.0);
  for (double angle : {0.0, 1e-15, 1e-12, 1e-9, 1e-6, 1e-3, 0.5, 2.0, 3.0}) {
    for (int i = 0; i < 20; ++i) {
      const Eigen::Vector3d w = Eigen::Vector3d(n(rng), n(rng), n(rng)).normalized() * angle;
      const Eigen::Quaterniond q = ExpSO3(w);
      EXPECT_NEAR(q.norm(), 1.0, 1e-15);
      EXPECT_LE((q.toRotationMatrix() - Rodrigues(w)).norm(), 1e-15 + 1e-15 * angle);
      // Relative accuracy of Log holds all the way down to tiny angles.
      EXPECT_LE((LogSO3(q) - w).norm(), 1e-14 * std::max(angle, 1e-300) + 1e-300) << "angle " << angle;
    }
  }
}

TEST(GeometryTest, LogNearPiStaysInRangeAndRepresentsTheRotation) {
  std::mt19937 rng(4);
  std::normal_distribution<double> n(0.0, 1.0);
  for (double eps : {1e-3, 1e-6, 1e-9, 0.0}) {
    for (int i = 0; i < 20; ++i) {
      const Eigen::Vector3d axis = Eigen::Vector3d(n(rng), n(rng), n(rng)).normalized();
      const Eigen::Vector3d w = axis * (M_PI - eps);
      for (double sign : {1.0, -1.0}) {  // q and -q are the same rotation
        Eigen::Quaterniond q = ExpSO3(w);
        q.coeffs() *= sign;
        const Eigen::Vector3d log = LogSO3(q);
        EXPECT_LE(log.norm(), M_PI + 1e-15);
        EXPECT_NEAR(log.norm(), M_PI - eps, 1e-12);
        EXPECT_LE((ExpSO3(log).toRotationMatrix() - Rodrigues(w)).norm(), 1e-12);
        if (eps > 0.0) {
          EXPECT_LE((log - w).norm(), 1e-9);  // unique below pi
        } else {
          EXPECT_LE(std::min((log - w).norm(), (log + w).norm()), 1e-9);  // +-axis at pi
        }
      }
    }
  }
  // Beyond pi, Log returns the shorter rotation about the opposite axis.
  const Eigen::Vector3d w(0.0, 0.0, M_PI + 0.25);
  EXPECT_LE((LogSO3(ExpSO3(w)) - Eigen::Vector3d(0.0, 0.0, -(M_PI - 0.25))).norm(), 1e-14);
}

TEST(GeometryTest, YawIsTheHeadingOfTheXAxis) {
  for (double yaw : {-3.0, -M_PI / 2.0, -0.1, 0.0, 0.7, M_PI / 2.0, 3.1}) {
    EXPECT_NEAR(SE3d::FromXYZYaw(1.0, 2.0, 3.0, yaw).yaw(), yaw, 1e-15);
    // A small roll about the robot's own x axis leaves the x axis, hence the yaw, unchanged.
    const SE3d rolled =
        SE3d::FromXYZYaw(0.0, 0.0, 0.0, yaw) * SE3d::Exp((Vector6d() << 0.3, 0, 0, 0, 0, 0).finished());
    EXPECT_NEAR(rolled.yaw(), yaw, 1e-14);
  }
  EXPECT_NEAR(SE3d::FromXYZYaw(0.0, 0.0, 0.0, M_PI).yaw(), M_PI, 1e-15);
}

TEST(GeometryTest, WrapAngleRange) {
  EXPECT_DOUBLE_EQ(WrapAngle(0.0), 0.0);
  EXPECT_DOUBLE_EQ(WrapAngle(M_PI), M_PI);
  EXPECT_DOUBLE_EQ(WrapAngle(-M_PI), M_PI);
  EXPECT_DOUBLE_EQ(WrapAngle(3.0 * M_PI), M_PI);
  EXPECT_NEAR(WrapAngle(2.0 * M_PI), 0.0, 1e-15);
  EXPECT_NEAR(WrapAngle(-1.5 * M_PI), 0.5 * M_PI, 1e-15);
  EXPECT_NEAR(WrapAngle(1.5 * M_PI), -0.5 * M_PI, 1e-15);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-100.0, 100.0);
  for (int i = 0; i < 1000; ++i) {
    const double a = u(rng), w = WrapAngle(a);
    EXPECT_GT(w, -M_PI);
    EXPECT_LE(w, M_PI);
    EXPECT_NEAR(std::cos(w), std::cos(a), 1e-12);
    EXPECT_NEAR(std::sin(w), std::sin(a), 1e-12);
  }
}

TEST(GeometryTest, SE2ComposeInverseAgreeWithSE3) {
  std::mt19937 rng(6);
  std::uniform_real_distribution<double> u(-4.0, 4.0);
  for (int i = 0; i < 100; ++i) {
    const SE2d T_a_b(u(rng), u(rng), u(rng)), T_b_c(u(rng), u(rng), u(rng));
    const SE2d T_a_c = T_a_b * T_b_c;
    ExpectSE3Near(T_a_c.ToSE3(), T_a_b.ToSE3() * T_b_c.ToSE3(), 1e-12);
    ExpectSE3Near(T_a_b.inverse().ToSE3(), T_a_b.ToSE3().inverse(), 1e-12);
    const SE2d identity = T_a_b * T_a_b.inverse();
    EXPECT_NEAR(identity.x(), 0.0, 1e-12);
    EXPECT_NEAR(identity.y(), 0.0, 1e-12);
    EXPECT_NEAR(identity.theta(), 0.0, 1e-12);
    const Eigen::Vector2d p_c(u(rng), u(rng));
    EXPECT_LE((T_a_c * p_c - T_a_b * (T_b_c * p_c)).norm(), 1e-12);
    EXPECT_GT(T_a_c.theta(), -M_PI);
    EXPECT_LE(T_a_c.theta(), M_PI);
  }
}

TEST(GeometryTest, SE2FromSE3AndBack) {
  const SE3d T = SE3d::FromXYZYaw(1.5, -2.0, 0.3, 2.5);
  const SE2d T2 = SE2d::FromSE3(T);
  EXPECT_DOUBLE_EQ(T2.x(), 1.5);
  EXPECT_DOUBLE_EQ(T2.y(), -2.0);
  EXPECT_NEAR(T2.theta(), 2.5, 1e-15);
  ExpectSE3Near(T2.ToSE3(0.3), T, 1e-15);
  // Roll and pitch are dropped; the heading of the x axis is kept.
  const SE3d tilted = T * SE3d::Exp((Vector6d() << 0.2, 0.1, 0.0, 0.0, 0.0, 0.0).finished());
  const Eigen::Vector3d x_axis = tilted.rotation_matrix().col(0);
  EXPECT_NEAR(SE2d::FromSE3(tilted).theta(), std::atan2(x_axis.y(), x_axis.x()), 1e-15);
  EXPECT_DOUBLE_EQ(SE2d::FromSE3(tilted).ToSE3(7.0).translation().z(), 7.0);
}

TEST(GeometryTest, SE2BoxMinusWrapsAndInvertsExp) {
  const SE2d a(1.0, 2.0, M_PI - 0.1), b(1.0, 2.0, -M_PI + 0.1);
  EXPECT_NEAR(a.BoxMinus(b).z(), 0.2, 1e-12);  // across the +-pi seam, the short way
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  for (int i = 0; i < 100; ++i) {
    const SE2d T(u(rng), u(rng), u(rng));
    const Eigen::Vector3d delta(u(rng), u(rng), u(rng));
    const SE2d moved = T * SE2d::Exp(delta);
    EXPECT_LE((T.BoxMinus(moved) - delta).norm(), 1e-12);
  }
}

}  // namespace
}  // namespace waymark
