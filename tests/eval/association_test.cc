// Timestamp association against evo's rule (evo/core/sync.py), including the edge cases:
// duplicates, gaps, offset stamps, ties, the inclusive max-dt bound in double arithmetic.
#include "eval/association.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <stdexcept>
#include <string>

namespace waymark::eval {
namespace {

Trajectory FromStamps(const std::vector<double>& stamps_s) {
  Trajectory trajectory;
  for (const double t : stamps_s) trajectory.push_back({t, SE3d::Identity()});
  return trajectory;
}

// evo's matching_time_indices + associate_trajectories transliterated naively: the shorter
// list is iterated (the estimate when sizes are equal), numpy.argmin takes the first
// minimum, the bound is inclusive.
std::vector<StampPair> EvoReference(const Trajectory& gt, const Trajectory& est, double max_dt_s) {
  const bool est_longer = est.size() > gt.size();
  const Trajectory& shorter = est_longer ? gt : est;
  const Trajectory& longer = est_longer ? est : gt;
  std::vector<StampPair> pairs;
  for (size_t i = 0; i < shorter.size(); ++i) {
    size_t best = 0;
    for (size_t j = 1; j < longer.size(); ++j) {
      if (std::abs(longer[j].stamp_s - shorter[i].stamp_s) <
          std::abs(longer[best].stamp_s - shorter[i].stamp_s)) {
        best = j;
      }
    }
    if (std::abs(longer[best].stamp_s - shorter[i].stamp_s) <= max_dt_s) {
      pairs.push_back(est_longer ? StampPair{i, best} : StampPair{best, i});
    }
  }
  return pairs;
}

std::string ToString(const std::vector<StampPair>& pairs) {
  std::string out;
  for (const StampPair& p : pairs)
    out += "(" + std::to_string(p.gt_index) + "," + std::to_string(p.est_index) + ")";
  return out;
}

TEST(AssociationTest, GapsAndOffsetStampsIterateTheShorterTrajectory) {
  // est (5 poses) is longer than gt (4): gt is iterated.
  //   gt 0.0 -> est 0.004 (|dt| = 0.004 <= 0.01, kept)
  //   gt 1.0 -> est 1.02  (|dt| = 0.02, dropped: a gap in the estimate)
  //   gt 2.0 -> est 2.0   (kept; 2.001 is farther)
  //   gt 3.0 -> est 2.001 (|dt| = 0.999, dropped)
  const Trajectory gt = FromStamps({0.0, 1.0, 2.0, 3.0});
  const Trajectory est = FromStamps({0.004, 1.02, 2.0, 2.001, 5.0});
  EXPECT_EQ(ToString(AssociateByStamp(gt, est, 0.01)), "(0,0)(2,2)");
  EXPECT_EQ(ToString(AssociateByStamp(gt, est, 0.01)), ToString(EvoReference(gt, est, 0.01)));
}

TEST(AssociationTest, EqualSizesIterateTheEstimateAndMayReuseAGroundTruthPose) {
  // Same size: evo iterates its second argument (the estimate). Both est 0.0 and est 0.002
  // take gt 0.0; est 1.005 takes gt 1.0.
  const Trajectory gt = FromStamps({0.0, 1.0, 2.0});
  const Trajectory est = FromStamps({0.0, 0.002, 1.005});
  EXPECT_EQ(ToString(AssociateByStamp(gt, est, 0.01)), "(0,0)(0,1)(1,2)");
}

TEST(AssociationTest, DuplicateStampsTakeTheFirst) {
  // numpy.argmin returns the first of equal minima: est 1.0 -> gt index 0, not 1.
  const Trajectory gt = FromStamps({1.0, 1.0, 2.0});
  const Trajectory est = FromStamps({1.0, 2.0});
  EXPECT_EQ(ToString(AssociateByStamp(gt, est, 0.01)), "(0,0)(2,1)");
  // Beyond the last of a run of duplicates: the first of the run again.
  const Trajectory runs = FromStamps({1.0, 1.0, 1.0});
  EXPECT_EQ(ToString(AssociateByStamp(runs, FromStamps({1.005}), 0.01)), "(0,0)");
}

TEST(AssociationTest, ExactTieTakesTheEarlierPose) {
  // 0.5 is 0.5 s from both 0 and 1 (exact in binary): the earlier one wins.
  EXPECT_EQ(ToString(AssociateByStamp(FromStamps({0.0, 1.0}), FromStamps({0.5}), 0.6)), "(0,0)");
}

TEST(AssociationTest, BoundIsInclusiveInDoubleArithmetic) {
  // |0.01 - 0.0| = 0.01 exactly: kept. |1.01 - 1.0| = 0.010000000000000009 in doubles:
  // dropped, as numpy drops it.
  const Trajectory gt = FromStamps({0.0, 1.0});
  const Trajectory est = FromStamps({0.01, 1.01});
  EXPECT_EQ(ToString(AssociateByStamp(gt, est, 0.01)), "(0,0)");
}

TEST(AssociationTest, UnsortedInputFallsBackToTheLinearRule) {
  const Trajectory gt = FromStamps({3.0, 1.0, 2.0, 1.0});
  const Trajectory est = FromStamps({1.0, 2.003});
  EXPECT_EQ(ToString(AssociateByStamp(gt, est, 0.01)), "(1,0)(2,1)");
}

TEST(AssociationTest, RandomSortedStampsMatchTheReference) {
  std::mt19937 rng(42);
  std::uniform_real_distribution<double> step(0.0, 0.03);
  std::uniform_int_distribution<int> repeat(0, 4);
  for (int trial = 0; trial < 50; ++trial) {
    std::vector<double> a, b;
    double t = 0.0;
    for (int i = 0; i < 200; ++i) {
      t += repeat(rng) == 0 ? 0.0 : std::round(step(rng) * 1000.0) / 1000.0;  // duplicates, ms grid
      a.push_back(t);
    }
    t = 0.0005 * trial;
    for (int i = 0; i < 150 + trial; ++i) b.push_back(t += step(rng));
    for (const double max_dt : {0.0, 0.005, 0.01, 0.05}) {
      const Trajectory gt = FromStamps(a), est = FromStamps(b);
      ASSERT_EQ(ToString(AssociateByStamp(gt, est, max_dt)), ToString(EvoReference(gt, est, max_dt)));
      ASSERT_EQ(ToString(AssociateByStamp(est, gt, max_dt)), ToString(EvoReference(est, gt, max_dt)));
    }
  }
}

TEST(AssociationTest, NoPairIsAnErrorSuggestingMaxDt) {
  const Trajectory gt = FromStamps({0.0, 1.0});
  const Trajectory est = FromStamps({100.0, 101.0});
  try {
    Associate(gt, est, 0.01);
    FAIL() << "expected an error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("--max-dt"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("no pose pairs"), std::string::npos) << e.what();
  }
  EXPECT_THROW(Associate(Trajectory(), est, 0.01), std::runtime_error);
}

TEST(AssociationTest, AssociateReducesBothTrajectories) {
  Trajectory gt = FromStamps({0.0, 1.0, 2.0});
  Trajectory est = FromStamps({1.001, 2.002});
  est[1].T = SE3d::FromXYZYaw(1.0, 2.0, 3.0, 0.0);
  const AssociatedTrajectories a = Associate(gt, est, 0.01);
  ASSERT_EQ(a.gt.size(), 2u);
  ASSERT_EQ(a.est.size(), 2u);
  EXPECT_EQ(a.gt[0].stamp_s, 1.0);
  EXPECT_EQ(a.est[1].stamp_s, 2.002);
  EXPECT_EQ(a.est[1].T.translation().z(), 3.0);
}

}  // namespace
}  // namespace waymark::eval
