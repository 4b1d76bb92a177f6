// Per-axis absolute errors of the ATE pairs (eval/trajectory_metrics.h) and their place in the
// reports (eval/report.h), on hand-computed poses.
#include <gtest/gtest.h>

#include <cmath>

#include "eval/report.h"
#include "eval/trajectory_eval.h"
#include "eval/trajectory_metrics.h"

namespace waymark::eval {
namespace {

constexpr double kDegToRad = M_PI / 180.0;

// Truth: three poses; estimate: each off by a known amount per axis and in yaw, with a roll
// that must not count as yaw.
void MakePairs(Trajectory* gt, Trajectory* est) {
  const double offsets[3][4] = {{0.01, -0.02, 0.03, 1.0}, {-0.03, 0.0, -0.01, -2.0}, {0.02, 0.04, 0.0, 3.0}};
  for (int i = 0; i < 3; ++i) {
    const double yaw_rad = 0.5 * i;  // truth heading
    const SE3d T_gt = SE3d::FromXYZYaw(i, 2.0 * i, 1.0, yaw_rad);
    const Eigen::Quaterniond q_est =
        Eigen::AngleAxisd(yaw_rad + offsets[i][3] * kDegToRad, Eigen::Vector3d::UnitZ()) *
        Eigen::AngleAxisd(0.05, Eigen::Vector3d::UnitX());
    const SE3d T_est(q_est,
                     T_gt.translation() + Eigen::Vector3d(offsets[i][0], offsets[i][1], offsets[i][2]));
    gt->push_back({0.1 * i, T_gt});
    est->push_back({0.1 * i, T_est});
  }
}

TEST(AxisErrorsTest, MeanAbsoluteErrorPerAxisAndYaw) {
  Trajectory gt, est;
  MakePairs(&gt, &est);
  const AxisErrors axes = ComputeAxisErrors(gt, est);
  EXPECT_NEAR(axes.x_m.mean, (0.01 + 0.03 + 0.02) / 3.0, 1e-12);
  EXPECT_NEAR(axes.y_m.mean, (0.02 + 0.0 + 0.04) / 3.0, 1e-12);
  EXPECT_NEAR(axes.z_m.mean, (0.03 + 0.01 + 0.0) / 3.0, 1e-12);
  EXPECT_NEAR(axes.yaw_deg.mean, 2.0, 1e-9);
  EXPECT_NEAR(axes.yaw_deg.max, 3.0, 1e-9);
  EXPECT_NEAR(axes.x_m.max, 0.03, 1e-12);
  EXPECT_EQ(axes.z_m.count, 3u);
  EXPECT_THROW(ComputeAxisErrors(gt, Trajectory()), std::invalid_argument);
}

TEST(AxisErrorsTest, AteCarriesTheAxesIntoEveryReport) {
  Trajectory gt, est;
  MakePairs(&gt, &est);
  TrajectoryEvalOptions options;
  options.align = AlignmentMode::kNone;
  const TrajectoryEvaluation evaluation = EvaluateTrajectory(gt, est, std::nullopt, options);
  EXPECT_NEAR(evaluation.ate.axes.y_m.mean, 0.02, 1e-12);
  EvalReportInput input;
  input.trajectory = &evaluation;
  const Json j = EvalReportToJson(input);
  ASSERT_TRUE(j["ate"].contains("axes"));
  EXPECT_NEAR(j["ate"]["axes"]["z_m"]["mean"].get<double>(), 0.04 / 3.0, 1e-12);
  EXPECT_NEAR(j["ate"]["axes"]["yaw_deg"]["mean"].get<double>(), 2.0, 1e-9);
  EXPECT_NE(EvalSummaryTable(input).find("|yaw| (deg)"), std::string::npos);
  EXPECT_NE(EvalReportToMarkdown(input).find("| abs. error x (m) | "), std::string::npos);
}

}  // namespace
}  // namespace waymark::eval
