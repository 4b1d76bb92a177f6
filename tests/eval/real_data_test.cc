// ATE and RPE on real data equal evo's figures. Set: /work/shared/data/tagslam/tagslam-test22
// (RealSense T265 visual odometry against TagSLAM's optimized trajectory, a peer's estimate used
// here as the reference). The expected numbers were produced by evo's own code
// (sync.associate_trajectories, PosePath3D.align, metrics.APE / metrics.RPE: the equivalent of
//   evo_ape tum reference/trajectory.tum odometry.tum -a [--t_max_diff 0.05]
//   evo_rpe tum reference/trajectory.tum odometry.tum -a --delta 1 --delta_unit m
// ), see tests/eval/evo_crosscheck.py; they are not outputs of this code.
#include <gtest/gtest.h>

#include <filesystem>

#include "eval/trajectory_eval.h"
#include "io/tum_io.h"

namespace waymark::eval {
namespace {

const std::filesystem::path kSet = std::filesystem::path(WAYMARK_SHARED_DATA) / "tagslam" / "tagslam-test22";

class RealDataTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!std::filesystem::exists(kSet / "odometry.tum")) {
      GTEST_SKIP() << "shared data set tagslam/tagslam-test22 not found at " << kSet << ": skipped";
    }
    odometry_ = ReadTum(kSet / "odometry.tum");
    reference_ = ReadTum(kSet / "reference" / "trajectory.tum");
  }
  Trajectory odometry_, reference_;
};

TEST_F(RealDataTest, DefaultMaxDtMatchesEvo) {
  TrajectoryEvalOptions options;
  options.rpe = RpeOptions{1.0, RpeUnit::kMetres};
  const TrajectoryEvaluation e = EvaluateTrajectory(reference_, odometry_, std::nullopt, options);
  EXPECT_EQ(e.ate.translation_m.count, 14u);
  EXPECT_NEAR(e.ate.translation_m.rmse, 0.1527924587090401, 1e-9);
  EXPECT_NEAR(e.ate.translation_m.mean, 0.1477941102013545, 1e-9);
  EXPECT_NEAR(e.ate.translation_m.max, 0.21588129514829243, 1e-9);
  EXPECT_NEAR(e.ate.rotation_deg.rmse, 5.529123403532987, 1e-7);
  ASSERT_TRUE(e.rpe.has_value());
  EXPECT_EQ(e.rpe->index_pairs.size(), 3u);
  EXPECT_NEAR(e.rpe->translation_m.rmse, 0.18581522625929772, 1e-9);
  EXPECT_NEAR(e.rpe->rotation_deg.mean, 3.304993034217673, 1e-7);
}

TEST_F(RealDataTest, LargerMaxDtMatchesEvo) {
  TrajectoryEvalOptions options;
  options.max_dt_s = 0.05;
  options.rpe = RpeOptions{1.0, RpeUnit::kMetres};
  const TrajectoryEvaluation e = EvaluateTrajectory(reference_, odometry_, std::nullopt, options);
  EXPECT_EQ(e.ate.translation_m.count, 68u);
  EXPECT_NEAR(e.ate.translation_m.rmse, 0.13799103581718114, 1e-9);
  EXPECT_NEAR(e.ate.translation_m.mean, 0.12047159617749992, 1e-9);
  EXPECT_NEAR(e.ate.translation_m.max, 0.2429266840535123, 1e-9);
  EXPECT_NEAR(e.ate.rotation_deg.mean, 3.0377328964575874, 1e-7);
  EXPECT_EQ(e.rpe->index_pairs.size(), 8u);
  EXPECT_NEAR(e.rpe->translation_m.mean, 0.08164975604489254, 1e-9);
  EXPECT_NEAR(e.rpe->rotation_deg.rmse, 3.0414517829620435, 1e-7);
}

}  // namespace
}  // namespace waymark::eval
