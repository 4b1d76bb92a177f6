// Tests of the block layout and the scalar-templated geometry of factors/pose_block.h (against
// geometry/pose.h), of the manifold-to-body tangent conversion, and of SqrtInformation.
#include "factors/pose_block.h"

#include <ceres/jet.h>
#include <gtest/gtest.h>

#include <random>
#include <stdexcept>

#include "factors/sqrt_information.h"
#include "tests/factors/factor_test_util.h"

namespace waymark {
namespace {

TEST(PoseBlock, SE3RoundTripAndLayout) {
  const SE3d T(Eigen::Quaterniond(0.5, -0.5, 0.5, 0.5), Eigen::Vector3d(1, 2, 3));
  double block[7];
  SE3ToBlock(T, block);
  // [qx qy qz qw tx ty tz]
  EXPECT_DOUBLE_EQ(block[0], -0.5);
  EXPECT_DOUBLE_EQ(block[1], 0.5);
  EXPECT_DOUBLE_EQ(block[2], 0.5);
  EXPECT_DOUBLE_EQ(block[3], 0.5);
  EXPECT_DOUBLE_EQ(block[6], 3.0);
  const SE3d back = SE3FromBlock(block);
  EXPECT_LT(back.BoxMinus(T).norm(), 1e-15);
  const SE3T<double> T_generic = SE3TFromBlock(block);
  const Eigen::Vector3d p(0.3, -0.7, 1.1);
  EXPECT_LT((T_generic * p - T * p).norm(), 1e-15);
}

TEST(PoseBlock, SE2LiftMatchesGeometry) {
  const SE2d T_2d(1.5, -2.0, 2.5);
  double block[3];
  SE2ToBlock(T_2d, block);
  const SE3T<double> lifted = SE3TFromSE2Block(block);
  const SE3d expected = T_2d.ToSE3();
  EXPECT_LT(SE3d(lifted.q, lifted.t).BoxMinus(expected).norm(), 1e-15);
  block[2] += 2 * M_PI;  // an unwrapped angle lifts to the same rotation
  const SE3T<double> wrapped = SE3TFromSE2Block(block);
  EXPECT_LT(SE3d(wrapped.q, wrapped.t).BoxMinus(expected).norm(), 1e-14);
}

TEST(PoseBlock, TemplatedLogAndBoxMinusMatchGeometry) {
  std::mt19937 rng(3);
  for (int trial = 0; trial < 100; ++trial) {
    const SE3d T_a = testing::RandomSE3(rng, 3.0);
    // Small, moderate and near-pi relative rotations.
    const double scale = trial % 3 == 0 ? 1e-9 : (trial % 3 == 1 ? 0.5 : 3.1);
    const Eigen::Vector3d axis = testing::RandomVector(rng, 1.0).normalized();
    const SE3d T_b = T_a.BoxPlus((Vector6d() << axis * scale, testing::RandomVector(rng, 2.0)).finished());
    const Vector6d expected = T_a.BoxMinus(T_b);
    const Vector6d actual = BoxMinusT(SE3TFromSE3<double>(T_a), SE3TFromSE3<double>(T_b));
    EXPECT_LT((actual - expected).norm(), 1e-12) << "trial " << trial;
    // Scale invariance of the logarithm (a non-unit quaternion gives the same rotation vector).
    Eigen::Quaterniond q_scaled = T_b.rotation();
    q_scaled.coeffs() *= 1.7;
    EXPECT_LT((LogSO3T(q_scaled) - LogSO3(T_b.rotation())).norm(), 1e-12);
  }
}

TEST(PoseBlock, LogJetsAreFiniteAndCorrectAtTheIdentity) {
  // d Log(q) / d q_vec at the identity is 2 I; the series branch must give it, not NaN.
  using Jet = ceres::Jet<double, 4>;
  const Eigen::Quaternion<Jet> q(Jet(1.0, 3), Jet(0.0, 0), Jet(0.0, 1), Jet(0.0, 2));
  const Vector3T<Jet> log = LogSO3T(q);
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(log[i].a, 0.0);
    for (int j = 0; j < 4; ++j) EXPECT_DOUBLE_EQ(log[i].v[j], i == j ? 2.0 : 0.0) << i << "," << j;
  }
}

TEST(PoseBlock, WrapAngle) {
  EXPECT_NEAR(WrapAngleT(3 * M_PI / 2), -M_PI / 2, 1e-15);
  EXPECT_NEAR(WrapAngleT(-7.0), WrapAngle(-7.0), 1e-15);
  EXPECT_NEAR(WrapAngleT(0.25), 0.25, 1e-16);
}

// Ceres' manifold steps left and half-angle; ManifoldToBodyTangentJacobian must map its tangent
// onto geometry.h's right perturbation: T (+)_manifold m ~= T.BoxPlus(J m) to first order.
TEST(PoseBlock, ManifoldToBodyTangentJacobianMatchesTheManifold) {
  const SE3Manifold manifold;
  std::mt19937 rng(5);
  for (int trial = 0; trial < 10; ++trial) {
    const SE3d T = testing::RandomSE3(rng, 4.0);
    double block[7], stepped[7];
    SE3ToBlock(T, block);
    const Vector6d m =
        (Vector6d() << testing::RandomVector(rng, 1.0), testing::RandomVector(rng, 1.0)).finished() * 1e-6;
    ASSERT_TRUE(manifold.Plus(block, m.data(), stepped));
    const Vector6d delta_body = T.BoxMinus(SE3FromBlock(stepped));
    const Vector6d predicted = ManifoldToBodyTangentJacobian(T) * m;
    EXPECT_LT((delta_body - predicted).norm(), 1e-11 + 1e-4 * predicted.norm()) << "trial " << trial;
    EXPECT_GT(predicted.norm(), 1e-7);
  }
}

TEST(SqrtInformation, WhitensWithTheFullCovariance) {
  Eigen::Matrix3d A;
  A << 2.0, 0.3, -0.1, 0.3, 1.0, 0.2, -0.1, 0.2, 0.5;
  const Eigen::Matrix3d covariance = A * A.transpose();  // strongly non-diagonal
  const Eigen::Matrix3d S = SqrtInformation<3>(covariance, "test");
  EXPECT_TRUE(S.isLowerTriangular(1e-15));
  const Eigen::Vector3d r(0.7, -1.2, 0.4);
  const double expected = r.dot(covariance.ldlt().solve(r));
  EXPECT_NEAR((S * r).squaredNorm(), expected, 1e-10 * expected);
  // S^T S is the information matrix.
  EXPECT_LT((S.transpose() * S * covariance - Eigen::Matrix3d::Identity()).norm(), 1e-10);
}

TEST(SqrtInformation, RejectsBadCovariances) {
  Eigen::Matrix2d not_positive;
  not_positive << 1.0, 2.0, 2.0, 1.0;
  EXPECT_THROW(SqrtInformation<2>(not_positive, "x"), std::invalid_argument);
  Eigen::Matrix2d asymmetric;
  asymmetric << 1.0, 0.5, 0.0, 1.0;
  EXPECT_THROW(SqrtInformation<2>(asymmetric, "x"), std::invalid_argument);
  EXPECT_THROW(SqrtInformation<2>(Eigen::Matrix2d::Zero(), "x"), std::invalid_argument);
  Eigen::Matrix2d nan = Eigen::Matrix2d::Identity();
  nan(1, 1) = testing::kNaN;
  EXPECT_THROW(SqrtInformation<2>(nan, "x"), std::invalid_argument);
  try {
    SqrtInformation<2>(not_positive, "odometry SE(2) factor");
    ADD_FAILURE() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "odometry SE(2) factor: covariance is not positive definite");
  }
  EXPECT_THROW(InverseSigma(0.0, "x"), std::invalid_argument);
  EXPECT_THROW(InverseSigma(testing::kNaN, "x"), std::invalid_argument);
  EXPECT_DOUBLE_EQ(InverseSigma(0.25, "x"), 4.0);
}

}  // namespace
}  // namespace waymark
