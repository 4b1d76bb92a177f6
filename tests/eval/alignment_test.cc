// Umeyama alignment recovers known Sim(3), SE(3) and SE(2) transforms exactly, and refuses
// degenerate point sets.
#include "eval/alignment.h"

#include <gtest/gtest.h>

#include <random>

namespace waymark::eval {
namespace {

std::vector<Eigen::Vector3d> RandomPoints(std::mt19937* rng, int n) {
  std::uniform_real_distribution<double> u(-5.0, 5.0);
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < n; ++i) points.emplace_back(u(*rng), u(*rng), u(*rng));
  return points;
}

Eigen::Matrix3d RandomRotation(std::mt19937* rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  return ExpSO3(Eigen::Vector3d(n(*rng), n(*rng), n(*rng))).toRotationMatrix();
}

std::vector<Eigen::Vector3d> Transform(const std::vector<Eigen::Vector3d>& points, const Sim3Alignment& a) {
  std::vector<Eigen::Vector3d> out;
  for (const Eigen::Vector3d& p : points) out.push_back(a.Apply(p));
  return out;
}

TEST(AlignmentTest, UmeyamaRecoversSim3) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 10; ++trial) {
    Sim3Alignment truth;
    truth.R_gt_est = RandomRotation(&rng);
    truth.t_gt_est = Eigen::Vector3d(3.0, -2.0, 0.5) * trial;
    truth.scale = 0.3 + 0.4 * trial;
    const std::vector<Eigen::Vector3d> src = RandomPoints(&rng, 20);
    const Sim3Alignment fit = UmeyamaSim3(src, Transform(src, truth), /*with_scale=*/true);
    EXPECT_LT((fit.R_gt_est - truth.R_gt_est).norm(), 1e-9);
    EXPECT_LT((fit.t_gt_est - truth.t_gt_est).norm(), 1e-9);
    EXPECT_NEAR(fit.scale, truth.scale, 1e-9);
  }
}

TEST(AlignmentTest, UmeyamaRecoversSE3WithoutScale) {
  std::mt19937 rng(8);
  Sim3Alignment truth;
  truth.R_gt_est = RandomRotation(&rng);
  truth.t_gt_est = Eigen::Vector3d(-1.0, 4.0, 2.0);
  const std::vector<Eigen::Vector3d> src = RandomPoints(&rng, 4);
  const Sim3Alignment fit = ComputeAlignment(AlignmentMode::kSE3, false, src, Transform(src, truth));
  EXPECT_LT((fit.R_gt_est - truth.R_gt_est).norm(), 1e-9);
  EXPECT_LT((fit.t_gt_est - truth.t_gt_est).norm(), 1e-9);
  EXPECT_EQ(fit.scale, 1.0);
  EXPECT_NEAR(fit.R_gt_est.determinant(), 1.0, 1e-12);
}

TEST(AlignmentTest, PlanarPointsGiveAProperRotation) {
  // Points on the plane z = 0 leave one singular value at zero: the reflection through the
  // plane fits as well as the rotation; the S matrix must pick det(R) = +1.
  const std::vector<Eigen::Vector3d> src = {{0, 0, 0}, {1, 0, 0}, {0, 2, 0}, {3, 1, 0}};
  Sim3Alignment truth;
  truth.R_gt_est = Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  truth.t_gt_est = Eigen::Vector3d(1, 2, 3);
  const Sim3Alignment fit = UmeyamaSim3(src, Transform(src, truth), false);
  EXPECT_NEAR(fit.R_gt_est.determinant(), 1.0, 1e-12);
  EXPECT_LT((fit.R_gt_est - truth.R_gt_est).norm(), 1e-9);
}

TEST(AlignmentTest, SE2RecoversYawAndPlanarTranslationAndKeepsHeights) {
  std::mt19937 rng(9);
  const std::vector<Eigen::Vector3d> src = RandomPoints(&rng, 10);
  Sim3Alignment truth;
  truth.R_gt_est = Eigen::AngleAxisd(-2.5, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  truth.t_gt_est = Eigen::Vector3d(7.0, -3.0, 0.0);
  std::vector<Eigen::Vector3d> dst = Transform(src, truth);
  // A height offset is not part of the SE(2) model: it stays in the residual.
  for (Eigen::Vector3d& p : dst) p.z() += 0.25;
  const Sim3Alignment fit = ComputeAlignment(AlignmentMode::kSE2, false, src, dst);
  EXPECT_LT((fit.R_gt_est - truth.R_gt_est).norm(), 1e-9);
  EXPECT_LT((fit.t_gt_est - truth.t_gt_est).norm(), 1e-9);
  EXPECT_EQ(fit.t_gt_est.z(), 0.0);
  EXPECT_NEAR((fit.Apply(src[3]) - dst[3]).norm(), 0.25, 1e-9);
}

TEST(AlignmentTest, SE2WithScale) {
  const std::vector<Eigen::Vector3d> src = {{0, 0, 0}, {1, 0, 0.5}, {0, 2, 1}, {3, 1, 0}};
  Sim3Alignment truth;
  truth.R_gt_est = Eigen::AngleAxisd(1.2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  truth.t_gt_est = Eigen::Vector3d(-1, 5, 0);
  truth.scale = 2.5;
  const Sim3Alignment fit = UmeyamaSE2(src, Transform(src, truth), true);
  EXPECT_NEAR(fit.scale, 2.5, 1e-9);
  EXPECT_LT((fit.R_gt_est - truth.R_gt_est).norm(), 1e-9);
  EXPECT_LT((fit.t_gt_est - truth.t_gt_est).norm(), 1e-9);
}

TEST(AlignmentTest, NoneWithScaleAppliesOnlyTheScale) {
  std::mt19937 rng(10);
  const std::vector<Eigen::Vector3d> src = RandomPoints(&rng, 8);
  Sim3Alignment truth;
  truth.R_gt_est = RandomRotation(&rng);
  truth.scale = 3.0;
  const Sim3Alignment fit = ComputeAlignment(AlignmentMode::kNone, true, src, Transform(src, truth));
  EXPECT_NEAR(fit.scale, 3.0, 1e-9);
  EXPECT_TRUE(fit.R_gt_est.isIdentity(0.0));
  EXPECT_TRUE(fit.t_gt_est.isZero(0.0));
  const Sim3Alignment none = ComputeAlignment(AlignmentMode::kNone, false, src, Transform(src, truth));
  EXPECT_EQ(none.scale, 1.0);
}

TEST(AlignmentTest, PosesAreRotatedAndTranslated) {
  Sim3Alignment a;
  a.R_gt_est = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  a.t_gt_est = Eigen::Vector3d(1, 0, 0);
  a.scale = 2.0;
  const SE3d T = a.Apply(SE3d::FromXYZYaw(1.0, 0.0, 0.0, 0.1));
  // p = 2 * Rz(90) (1, 0, 0) + (1, 0, 0) = (1, 2, 0); yaw 0.1 + pi/2.
  EXPECT_LT((T.translation() - Eigen::Vector3d(1, 2, 0)).norm(), 1e-12);
  EXPECT_NEAR(T.yaw(), 0.1 + M_PI / 2, 1e-12);
}

TEST(AlignmentTest, DegenerateSetsThrow) {
  const std::vector<Eigen::Vector3d> line = {{0, 0, 0}, {1, 1, 1}, {2, 2, 2}, {3, 3, 3}};
  EXPECT_THROW(UmeyamaSim3(line, line, false), DegenerateAlignmentError);
  const std::vector<Eigen::Vector3d> same = {{1, 1, 1}, {1, 1, 1}, {1, 1, 1}};
  EXPECT_THROW(UmeyamaSE2(same, same, false), DegenerateAlignmentError);
  // Two distinct points fix an SE(2) alignment (rank 1 = dim - 1 is enough in the plane).
  const std::vector<Eigen::Vector3d> two = {{0, 0, 0}, {1, 0, 0}};
  EXPECT_NO_THROW(UmeyamaSE2(two, two, false));
  EXPECT_THROW(UmeyamaSim3({{0, 0, 0}}, {{0, 0, 0}}, false), std::invalid_argument);
  EXPECT_THROW(UmeyamaSim3(two, line, false), std::invalid_argument);
  EXPECT_THROW(ParseAlignmentMode("sim3"), std::invalid_argument);
  EXPECT_EQ(ParseAlignmentMode("se2"), AlignmentMode::kSE2);
}

}  // namespace
}  // namespace waymark::eval

namespace waymark::eval {
namespace {

// --align origin: the first estimated pose is moved exactly onto the first true pose, and the
// same rigid motion carries every later pose (evo's --align_origin).
TEST(AlignOriginTest, MovesTheFirstPoseOntoTheTruthAndKeepsRelativeMotion) {
  const SE3d T_gt_first = SE3d::FromXYZYaw(2.0, -1.0, 0.0, 0.7);
  const SE3d T_est_first = SE3d::FromXYZYaw(0.0, 0.0, 0.0, 0.0);
  const Sim3Alignment alignment = AlignOrigin(T_gt_first, T_est_first);
  const SE3d moved_first = alignment.Apply(T_est_first);
  EXPECT_LT((moved_first.translation() - T_gt_first.translation()).norm(), 1e-12);
  EXPECT_LT(RotationAngleBetween(moved_first, T_gt_first), 1e-12);
  // A pose 1 m ahead of the estimate's origin lands 1 m ahead of the true start, along yaw 0.7.
  const SE3d moved_ahead = alignment.Apply(SE3d::FromXYZYaw(1.0, 0.0, 0.0, 0.0));
  EXPECT_NEAR(moved_ahead.translation().x(), 2.0 + std::cos(0.7), 1e-12);
  EXPECT_NEAR(moved_ahead.translation().y(), -1.0 + std::sin(0.7), 1e-12);
  EXPECT_NEAR(moved_ahead.yaw(), 0.7, 1e-12);
  EXPECT_EQ(ParseAlignmentMode("origin"), AlignmentMode::kOrigin);
  EXPECT_THROW(ComputeAlignment(AlignmentMode::kOrigin, false, {}, {}), std::invalid_argument);
}

}  // namespace
}  // namespace waymark::eval
