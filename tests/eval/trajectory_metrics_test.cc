// ATE, RPE and PE/TE on small cases worked out by hand (the numbers are in the comments),
// through the same pipeline as `waymark eval` (association, alignment, metrics).
#include <gtest/gtest.h>

#include <cmath>

#include "eval/trajectory_eval.h"

namespace waymark::eval {
namespace {

constexpr double kDeg = M_PI / 180.0;

SE3d Pose(double x, double y, double z, double yaw_rad) { return SE3d::FromXYZYaw(x, y, z, yaw_rad); }

// The hand-computed ATE case. Ground truth: the corners of a 4 m x 2 m rectangle,
//   A (0,0,0), B (4,0,0), C (4,2,0), D (0,2,0)  at t = 0, 1, 2, 3, yaw 0, 90, 180, 270 deg.
// Estimate: p_est = R0 (p_gt + e) + t0 with R0 = Rz(30 deg) Rx(10 deg), t0 = (10, 20, 0.5), and
//   e_A = (0.3, 0, 0.4), e_B = (-0.3, 0, -0.4), e_C = (0, 0, 0.4), e_D = (0, 0, -0.4);
//   R_est = R0 R_gt Exp(w_i), |w_i| = 1, 2, 3, 4 deg; stamps t + 0.004 s, and one more estimate
//   pose at t = 10 s that associates with nothing.
// Association (est is longer, gt is iterated): A..D pair with the first four estimate poses.
// Umeyama: centred gt x_i = (-2,-1,0), (2,-1,0), (2,1,0), (-2,1,0); the e_i sum to zero, so
//   Sigma = (1/4) sum x_i (x_i + e_i)^T = diag(16 - 1.2, 4, 0) / 4 (the off-diagonal sums
//   sum x e_z, sum y e_x, sum y e_z are all 0): symmetric positive semi-definite, hence the
//   fitted rotation is R0^T exactly, the translation undoes t0, and the aligned estimate is
//   p_gt + e. Translation errors |e_i| = 0.5, 0.5, 0.4, 0.4 m:
//   rmse = sqrt((0.25 + 0.25 + 0.16 + 0.16) / 4) = sqrt(0.205) = 0.452769256906871
//   mean = median = 0.45, std = 0.05, min 0.4, max 0.5, sse 0.82, pairs 4.
// Rotation errors |w_i| = 1, 2, 3, 4 deg: rmse = sqrt(30 / 4) = 2.738612787525831,
//   mean = median = 2.5, std = sqrt((2.25 + 0.25 + 0.25 + 2.25) / 4) = 1.118033988749895.
struct HandCase {
  Trajectory gt, est;
};

Eigen::Matrix3d HandR0() {
  return (Eigen::AngleAxisd(30 * kDeg, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(10 * kDeg, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

HandCase MakeHandAteCase() {
  const SE3d T0(HandR0(), Eigen::Vector3d(10, 20, 0.5));
  const std::vector<Eigen::Vector3d> p = {{0, 0, 0}, {4, 0, 0}, {4, 2, 0}, {0, 2, 0}};
  const std::vector<Eigen::Vector3d> e = {{0.3, 0, 0.4}, {-0.3, 0, -0.4}, {0, 0, 0.4}, {0, 0, -0.4}};
  const std::vector<Eigen::Vector3d> axes = {Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(),
                                             Eigen::Vector3d::UnitZ(), Eigen::Vector3d(1, 1, 0).normalized()};
  HandCase c;
  for (int i = 0; i < 4; ++i) {
    const SE3d T_gt = Pose(p[i].x(), p[i].y(), p[i].z(), 90 * kDeg * i);
    const SE3d T_err(ExpSO3(axes[i] * (i + 1) * kDeg), Eigen::Vector3d::Zero());
    c.gt.push_back({static_cast<double>(i), T_gt});
    const SE3d T_est = T0 * SE3d(T_gt.rotation(), p[i] + e[i]) * T_err;
    c.est.push_back({i + 0.004, T_est});
  }
  c.est.push_back({10.0, T0});
  return c;
}

TEST(TrajectoryMetricsTest, HandComputedAteWithSE3Alignment) {
  const HandCase c = MakeHandAteCase();
  TrajectoryEvalOptions options;  // --align se3, --max-dt 0.01 (evo_ape -a)
  const TrajectoryEvaluation e = EvaluateTrajectory(c.gt, c.est, std::nullopt, options);
  const ErrorStats& t = e.ate.translation_m;
  EXPECT_EQ(t.count, 4u);
  EXPECT_NEAR(t.rmse, 0.452769256906871, 1e-12);
  EXPECT_NEAR(t.mean, 0.45, 1e-12);
  EXPECT_NEAR(t.median, 0.45, 1e-12);
  EXPECT_NEAR(t.std, 0.05, 1e-12);
  EXPECT_NEAR(t.min, 0.4, 1e-12);
  EXPECT_NEAR(t.max, 0.5, 1e-12);
  EXPECT_NEAR(t.sse, 0.82, 1e-12);
  const ErrorStats& r = e.ate.rotation_deg;
  EXPECT_NEAR(r.rmse, 2.738612787525831, 1e-9);
  EXPECT_NEAR(r.mean, 2.5, 1e-9);
  EXPECT_NEAR(r.median, 2.5, 1e-9);
  EXPECT_NEAR(r.std, 1.118033988749895, 1e-9);
  EXPECT_NEAR(r.min, 1.0, 1e-9);
  EXPECT_NEAR(r.max, 4.0, 1e-9);
  EXPECT_EQ(e.est_poses, 5u);
  EXPECT_EQ(e.gt_poses, 4u);
  EXPECT_LT((e.alignment.R_gt_est - HandR0().transpose()).norm(), 1e-12);
  EXPECT_LT((e.alignment.t_gt_est + HandR0().transpose() * Eigen::Vector3d(10, 20, 0.5)).norm(), 1e-12);
}

TEST(TrajectoryMetricsTest, WithoutAlignmentTheOffsetIsTheError) {
  // est = gt shifted by (3, 4, 0): ATE without alignment is 5 m for every pair, 0 with it.
  Trajectory gt, est;
  for (int i = 0; i < 10; ++i) {
    gt.push_back({0.1 * i, Pose(i, std::sin(i), 0, 0.2 * i)});
    est.push_back({0.1 * i, Pose(i + 3.0, std::sin(i) + 4.0, 0, 0.2 * i)});
  }
  TrajectoryEvalOptions options;
  options.align = AlignmentMode::kNone;
  EXPECT_NEAR(EvaluateTrajectory(gt, est, std::nullopt, options).ate.translation_m.rmse, 5.0, 1e-12);
  options.align = AlignmentMode::kSE2;
  EXPECT_NEAR(EvaluateTrajectory(gt, est, std::nullopt, options).ate.translation_m.max, 0.0, 1e-9);
}

// Hand RPE case (align none, delta 1 frame):
//   gt:  (0,0) yaw 0;  (1,0) yaw 90;    (1,1.5) yaw 90
//   est: (0,0) yaw 0;  (1.1,0) yaw 90;  (1.1,1.0) yaw 100
// Pair (0,1): Q = T_gt0^-1 T_gt1 = ((1,0), 90), P = ((1.1,0), 90),
//   E = Q^-1 P = (Rz(-90) (0.1, 0), 0) = ((0,-0.1), 0): 0.1 m, 0 deg.
// Pair (1,2): Q = (Rz(-90) (0, 1.5), 0) = ((1.5,0), 0), P = ((1.0,0), 10 deg),
//   E = ((-0.5, 0), 10 deg): 0.5 m, 10 deg.
// Translation rmse sqrt((0.01 + 0.25)/2) = sqrt(0.13) = 0.360555127546399, mean 0.3;
// rotation rmse sqrt(100/2) = 7.071067811865476, mean 5.
Trajectory RpeGt() {
  return {{0, Pose(0, 0, 0, 0)}, {1, Pose(1, 0, 0, 90 * kDeg)}, {2, Pose(1, 1.5, 0, 90 * kDeg)}};
}
Trajectory RpeEst() {
  return {{0, Pose(0, 0, 0, 0)}, {1, Pose(1.1, 0, 0, 90 * kDeg)}, {2, Pose(1.1, 1.0, 0, 100 * kDeg)}};
}

TEST(TrajectoryMetricsTest, HandComputedRpeInFrames) {
  const RpeResult rpe = ComputeRpe(RpeGt(), RpeEst(), {1.0, RpeUnit::kFrames});
  ASSERT_EQ(rpe.index_pairs.size(), 2u);
  EXPECT_NEAR(rpe.translation_errors_m[0], 0.1, 1e-12);
  EXPECT_NEAR(rpe.translation_errors_m[1], 0.5, 1e-12);
  EXPECT_NEAR(rpe.translation_m.rmse, 0.360555127546399, 1e-12);
  EXPECT_NEAR(rpe.translation_m.mean, 0.3, 1e-12);
  EXPECT_NEAR(rpe.rotation_deg.rmse, 7.071067811865476, 1e-9);
  EXPECT_NEAR(rpe.rotation_deg.mean, 5.0, 1e-9);
  EXPECT_NEAR(rpe.rotation_errors_deg[0], 0.0, 1e-9);
}

TEST(TrajectoryMetricsTest, HandComputedRpeInMetresFollowsEvo) {
  // Estimate path: 1.1 m then 1.0 m. Delta 1 m keeps index 1 (1.1 >= 1) and index 2 (1.0 >= 1),
  // never index 0 (evo's rule): one pair (1,2) with 0.5 m, 10 deg.
  const RpeResult rpe = ComputeRpe(RpeGt(), RpeEst(), {1.0, RpeUnit::kMetres});
  ASSERT_EQ(rpe.index_pairs.size(), 1u);
  EXPECT_EQ(rpe.index_pairs[0], std::make_pair(size_t{1}, size_t{2}));
  EXPECT_NEAR(rpe.translation_m.mean, 0.5, 1e-12);
  EXPECT_NEAR(rpe.rotation_deg.mean, 10.0, 1e-9);
  // Delta 1.05 m: index 1 kept, then only 1.0 m remain: no pair, an error.
  EXPECT_THROW(ComputeRpe(RpeGt(), RpeEst(), {1.05, RpeUnit::kMetres}), std::runtime_error);
}

TEST(TrajectoryMetricsTest, RpeFramePairsAndOptions) {
  Trajectory five;
  for (int i = 0; i < 5; ++i) five.push_back({1.0 * i, Pose(i, 0, 0, 0)});
  const auto pairs = RpeIndexPairs(five, {2.0, RpeUnit::kFrames});
  ASSERT_EQ(pairs.size(), 2u);
  EXPECT_EQ(pairs[0], std::make_pair(size_t{0}, size_t{2}));
  EXPECT_EQ(pairs[1], std::make_pair(size_t{2}, size_t{4}));
  std::string why;
  EXPECT_FALSE((RpeOptions{1.5, RpeUnit::kFrames}).Check(&why));
  EXPECT_FALSE((RpeOptions{0.0, RpeUnit::kMetres}).Check(&why));
  EXPECT_THROW(ComputeRpe(five, five, {1.5, RpeUnit::kFrames}), std::invalid_argument);
  EXPECT_THROW(ParseRpeUnit("km"), std::invalid_argument);
}

// Hand PE/TE case: ground truth x = t, y = 0, yaw = 0.1 t, every 0.1 s. Predicted poses just
// before three corrections:
//   t = 2.003 -> gt t = 2.0 (2, 0, 0, yaw 0.2): pred (2.3, 0.4, 0.5), yaw 0.2 + 5 deg
//                PE = hypot(0.3, 0.4) = 0.5, 3-D = sqrt(0.5) = 0.7071, TE = 5 deg
//   t = 5.0   -> gt (5, 0, 0, yaw 0.5): pred (5, -0.1, 0), yaw 0.5 - 3 deg: PE 0.1, TE 3 deg
//   t = 7.998 -> gt t = 8.0 (8, 0, 0, yaw 0.8): pred (8, 0, 0), yaw 0.8 + 361 deg: PE 0, TE 1 deg
// PE mean 0.2 m, rmse sqrt(0.26 / 3) = 0.294392028877595; TE mean 3 deg, median 3 deg.
TEST(TrajectoryMetricsTest, HandComputedPeTe) {
  Trajectory gt;
  for (int i = 0; i <= 100; ++i) gt.push_back({0.1 * i, Pose(0.1 * i, 0, 0, 0.01 * i)});
  const Trajectory predicted = {{2.003, Pose(2.3, 0.4, 0.5, 0.2 + 5 * kDeg)},
                                {5.0, Pose(5, -0.1, 0, 0.5 - 3 * kDeg)},
                                {7.998, Pose(8, 0, 0, 0.8 + 361 * kDeg)}};
  TrajectoryEvalOptions options;
  options.align = AlignmentMode::kNone;  // the ground truth is a straight line: SE(3) would be degenerate
  const TrajectoryEvaluation e = EvaluateTrajectory(gt, gt, predicted, options);
  ASSERT_TRUE(e.pe_te.has_value());
  EXPECT_EQ(e.pe_te->position_m.count, 3u);
  EXPECT_NEAR(e.pe_te->position_m.mean, 0.2, 1e-9);
  EXPECT_NEAR(e.pe_te->position_m.rmse, 0.294392028877595, 1e-9);
  EXPECT_NEAR(e.pe_te->position_3d_m.max, std::sqrt(0.5), 1e-9);
  EXPECT_NEAR(e.pe_te->heading_deg.mean, 3.0, 1e-9);
  EXPECT_NEAR(e.pe_te->heading_deg.median, 3.0, 1e-9);
  EXPECT_NEAR(e.pe_te->heading_deg.min, 1.0, 1e-9);
}

TEST(TrajectoryMetricsTest, PeTeIsUnalignedUnlessAsked) {
  // The estimate and the predicted poses live in a frame shifted by 1 m in x. Unaligned, PE
  // sees the shift; with align_predicted the estimate's alignment removes it.
  Trajectory gt, est;
  for (int i = 0; i <= 50; ++i) {
    gt.push_back({0.1 * i, Pose(0.1 * i, std::sin(0.3 * i), 0, 0.05 * i)});
    est.push_back({0.1 * i, Pose(0.1 * i + 1.0, std::sin(0.3 * i), 0, 0.05 * i)});
  }
  const Trajectory predicted = {{1.0, est[10].T}, {3.0, est[30].T}};
  TrajectoryEvalOptions options;
  EXPECT_NEAR(EvaluateTrajectory(gt, est, predicted, options).pe_te->position_m.mean, 1.0, 1e-9);
  options.align_predicted = true;
  EXPECT_NEAR(EvaluateTrajectory(gt, est, predicted, options).pe_te->position_m.mean, 0.0, 1e-9);
  // Predicted poses that associate with nothing are an error naming them.
  try {
    EvaluateTrajectory(gt, est, Trajectory{{99.0, SE3d()}}, options);
    FAIL();
  } catch (const std::runtime_error& error) {
    EXPECT_NE(std::string(error.what()).find("predicted poses"), std::string::npos) << error.what();
  }
}

}  // namespace
}  // namespace waymark::eval
