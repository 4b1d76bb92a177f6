// geometry/unicycle.h: straight runs, a full circle closes, the command holds until the next
// stamp, decreasing stamps are refused.
#include "geometry/unicycle.h"

#include <gtest/gtest.h>

#include <cmath>

namespace waymark {
namespace {

TEST(Unicycle, StraightAndArc) {
  const SE2d straight = IntegrateArc(SE2d(1.0, 2.0, M_PI / 2), 0.5, 0.0, 2.0);
  EXPECT_NEAR(straight.x(), 1.0, 1e-12);
  EXPECT_NEAR(straight.y(), 3.0, 1e-12);
  // A quarter circle of radius 2 turning left from the origin ends at (2, 2) facing +y.
  const SE2d quarter = IntegrateArc(SE2d(), 1.0, 0.5, M_PI);
  EXPECT_NEAR(quarter.x(), 2.0, 1e-12);
  EXPECT_NEAR(quarter.y(), 2.0, 1e-12);
  EXPECT_NEAR(quarter.theta(), M_PI / 2, 1e-12);
}

TEST(Unicycle, FullCircleInManyStepsCloses) {
  std::vector<VelocitySample> samples;
  const int n = 1000;
  for (int i = 0; i <= n; ++i) samples.push_back({i * 2 * M_PI / n, 0.3, 1.0});
  const Trajectory trajectory = IntegrateVelocities(samples, SE2d(1.0, -1.0, 0.2));
  ASSERT_EQ(trajectory.size(), samples.size());
  const SE2d end = SE2d::FromSE3(trajectory.back().T);
  EXPECT_NEAR(end.x(), 1.0, 1e-9);
  EXPECT_NEAR(end.y(), -1.0, 1e-9);
  EXPECT_NEAR(WrapAngle(end.theta() - 0.2), 0.0, 1e-9);
}

TEST(Unicycle, CommandHoldsUntilTheNextStamp) {
  // 1 m/s for 1 s, then 0 for 1 s, then the last command (2 m/s) is never integrated.
  const Trajectory trajectory = IntegrateVelocities({{0.0, 1.0, 0.0}, {1.0, 0.0, 0.0}, {2.0, 2.0, 0.0}});
  EXPECT_NEAR(trajectory[1].T.translation().x(), 1.0, 1e-12);
  EXPECT_NEAR(trajectory[2].T.translation().x(), 1.0, 1e-12);
  EXPECT_THROW(IntegrateVelocities({{1.0, 1.0, 0.0}, {0.5, 0.0, 0.0}}), std::invalid_argument);
}

}  // namespace
}  // namespace waymark
