// plan/route.h and plan/route_io.h on hand-made survey poses.
#include "plan/route.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>

#include "io/util.h"
#include "plan/route_io.h"

namespace waymark::plan {
namespace {

using ::testing::HasSubstr;

const MarkerKey kCodeA{"qr", "A"}, kCodeB{"qr", "B"}, kCodeFar{"qr", "F"};

// Poses every 5 cm along the straight line from a to b (heading a -> b), seeing `codes`.
void Line(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const std::set<MarkerKey>& codes,
          std::vector<SurveyPose>* poses) {
  const double yaw = std::atan2((b - a).y(), (b - a).x());
  const int n = static_cast<int>(std::round((b - a).norm() / 0.05));
  for (int i = 0; i <= n; ++i) {
    SurveyPose p;
    p.stamp_s = poses->size() * 0.1;
    const Eigen::Vector2d q = a + (b - a) * i / n;
    p.x_y_yaw = Eigen::Vector3d(q.x(), q.y(), yaw);
    p.covariance = Eigen::Vector3d(1e-4, 1e-4, 1e-4).asDiagonal();
    p.codes = codes;
    poses->push_back(p);
  }
}

// A 5 m corridor seeing code A, then (carried away: a jump) a 2 m one 20 m off seeing F.
std::vector<SurveyPose> TwoParts() {
  std::vector<SurveyPose> poses;
  Line({0, 0}, {5, 0}, {kCodeA}, &poses);
  Line({20, 0}, {22, 0}, {kCodeFar}, &poses);
  return poses;
}

TEST(RouteTest, GraphThinsThePosesAndFindsTheParts) {
  const SurveyGraph graph = BuildSurveyGraph(TwoParts(), RouteOptions());
  EXPECT_EQ(graph.components, 2);
  EXPECT_EQ(graph.nodes.size(), 11u + 5u);  // every 0.5 m
  for (const RouteEdge& e : graph.edges) {
    EXPECT_LE((graph.nodes[e.a].position_world - graph.nodes[e.b].position_world).norm(), 2.0 + 1e-9);
  }
}

TEST(RouteTest, StraightRouteHasTheLengthAndTheCodes) {
  const SurveyGraph graph = BuildSurveyGraph(TwoParts(), RouteOptions());
  RouteGoal goal;
  goal.pose = Eigen::Vector3d(4.8, 0.1, 0.0);
  const Route route = PlanRoute(graph, {0.2, -0.1, 0.0}, goal, RouteOptions());
  EXPECT_NEAR(route.length_m, (Eigen::Vector2d(4.8, 0.1) - Eigen::Vector2d(0.2, -0.1)).norm(), 0.1);
  EXPECT_GE(route.cost, route.length_m);
  EXPECT_TRUE(route.goal_yaw_given);
  EXPECT_NEAR(route.waypoints.back().x_y_yaw.x(), 4.8, 1e-12);
  EXPECT_NEAR(route.waypoints.back().x_y_yaw.z(), 0.0, 1e-12);
  ASSERT_FALSE(route.segments.empty());
  EXPECT_EQ(route.segments[1].codes, std::vector<MarkerKey>{kCodeA});
  EXPECT_EQ(route.blind_m, 0.0);
}

TEST(RouteTest, OffTheGraphAndOtherPartsAreOneLineErrors) {
  const SurveyGraph graph = BuildSurveyGraph(TwoParts(), RouteOptions());
  RouteGoal goal;
  goal.pose = Eigen::Vector3d(4.0, 0.0, std::nan(""));
  try {
    PlanRoute(graph, {2.0, 3.0, 0.0}, goal, RouteOptions());
    FAIL() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_THAT(e.what(),
                HasSubstr("start (2.00, 3.00) is off the survey graph: the nearest survey pose is 3.00 m"));
  }
  goal.pose = Eigen::Vector3d(21.0, 0.0, std::nan(""));
  try {
    PlanRoute(graph, {1.0, 0.0, 0.0}, goal, RouteOptions());
    FAIL() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_THAT(e.what(), HasSubstr("goal (21.00, 0.00) is in another part of the survey than the start"));
  }
  goal.pose = Eigen::Vector3d(12.0, 0.0, std::nan(""));
  EXPECT_THROW(PlanRoute(graph, {1.0, 0.0, 0.0}, goal, RouteOptions()), std::invalid_argument);
  RouteGoal code_goal;
  code_goal.code = kCodeB;
  try {
    PlanRoute(graph, {1.0, 0.0, 0.0}, code_goal, RouteOptions());
    FAIL() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "code qr:B was never seen in the survey");
  }
  code_goal.code = kCodeFar;
  try {
    PlanRoute(graph, {1.0, 0.0, 0.0}, code_goal, RouteOptions());
    FAIL() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_THAT(e.what(), HasSubstr("code qr:F was seen only from another part of the survey"));
  }
  EXPECT_THROW(PlanRoute(SurveyGraph(), {0, 0, 0}, goal, RouteOptions()), std::invalid_argument);
}

TEST(RouteTest, ToCodeEndsWhereTheCodeWasSeen) {
  std::vector<SurveyPose> poses;
  Line({0, 0}, {3, 0}, {kCodeA}, &poses);
  Line({3, 0}, {3, 2}, {kCodeB}, &poses);
  const SurveyGraph graph = BuildSurveyGraph(poses, RouteOptions());
  RouteGoal goal;
  goal.code = kCodeB;
  const Route route = PlanRoute(graph, {0, 0, 0}, goal, RouteOptions());
  EXPECT_TRUE(route.goal_yaw_given);
  ASSERT_TRUE(route.goal_code);
  EXPECT_EQ(*route.goal_code, kCodeB);
  // The nearest node that saw B is at the corner (3, 0) or just after it.
  EXPECT_NEAR(route.waypoints.back().x_y_yaw.x(), 3.0, 1e-9);
  EXPECT_LE(route.waypoints.back().x_y_yaw.y(), 0.5 + 1e-9);
}

// Two ways from (0, 0) to (4, 0): straight with no code in view (4 m), or a 1 m detour out and
// back with codes all along (6 m). The uncertainty cost decides.
TEST(RouteTest, UncertaintyCostPrefersTheWayWithCodes) {
  std::vector<SurveyPose> poses;
  Line({0, 0}, {4, 0}, {}, &poses);
  Line({4, 0}, {4, 1}, {kCodeB}, &poses);
  Line({4, 1}, {0, 1}, {kCodeB}, &poses);
  Line({0, 1}, {0, 0}, {kCodeB}, &poses);
  // Codes only at the ends of the straight way, so that its middle is blind.
  poses.front().codes = {kCodeA};
  RouteOptions options;
  options.max_covisible_m = 0.0;  // only what the survey drove
  const SurveyGraph graph = BuildSurveyGraph(poses, options);
  RouteGoal goal;
  goal.pose = Eigen::Vector3d(4.0, 0.0, std::nan(""));
  options.uncertainty_cost_per_m = 0.0;
  const Route direct = PlanRoute(graph, {0, 0, 0}, goal, options);
  EXPECT_NEAR(direct.length_m, 4.0, 1e-6);
  EXPECT_GT(direct.blind_m, 3.0);
  options.uncertainty_cost_per_m = 1e4;
  const Route detour = PlanRoute(graph, {0, 0, 0}, goal, options);
  EXPECT_NEAR(detour.length_m, 6.0, 1e-6);
  EXPECT_LT(detour.blind_m, 1.0);
  // The blind way's predicted position sigma is larger than the seen one's.
  EXPECT_GT(direct.max_position_sigma_m, detour.max_position_sigma_m);
}

TEST(RouteTest, PredictedCovarianceGrowsWithoutCodes) {
  std::vector<SurveyPose> poses;
  Line({0, 0}, {6, 0}, {}, &poses);
  poses.front().codes = {kCodeA};
  const SurveyGraph graph = BuildSurveyGraph(poses, RouteOptions());
  RouteGoal goal;
  goal.pose = Eigen::Vector3d(6.0, 0.0, std::nan(""));
  const Route route = PlanRoute(graph, {0, 0, 0}, goal, RouteOptions());
  for (size_t i = 1; i < route.waypoints.size(); ++i) {
    EXPECT_GT(route.waypoints[i].covariance.trace(), route.waypoints[i - 1].covariance.trace());
  }
}

TEST(RouteTest, ViaLegsJoin) {
  const SurveyGraph graph = BuildSurveyGraph(TwoParts(), RouteOptions());
  RouteGoal a, b;
  a.pose = Eigen::Vector3d(4.0, 0.0, std::nan(""));
  b.pose = Eigen::Vector3d(1.0, 0.0, std::nan(""));
  const Route first = PlanRoute(graph, {0, 0, 0}, a, RouteOptions());
  const Route second = PlanRoute(graph, first.waypoints.back().x_y_yaw, b, RouteOptions());
  const Route both = JoinRoutes({first, second});
  EXPECT_EQ(both.waypoints.size(), first.waypoints.size() + second.waypoints.size() - 1);
  EXPECT_EQ(both.segments.size(), first.segments.size() + second.segments.size());
  EXPECT_NEAR(both.length_m, 7.0, 1e-6);
  EXPECT_GT(both.turn_rad, 3.0);  // turned back once
}

TEST(RouteIoTest, RoundTripAndErrors) {
  const SurveyGraph graph = BuildSurveyGraph(TwoParts(), RouteOptions());
  RouteGoal goal;
  goal.pose = Eigen::Vector3d(4.0, 0.0, 0.5);
  const Route route = PlanRoute(graph, {0, 0, 0}, goal, RouteOptions());
  const Route back = ParseRoute(FormatRoute(route), "route.json");
  ASSERT_EQ(back.waypoints.size(), route.waypoints.size());
  for (size_t i = 0; i < back.waypoints.size(); ++i) {
    EXPECT_EQ(back.waypoints[i].x_y_yaw, route.waypoints[i].x_y_yaw);
    EXPECT_EQ(back.waypoints[i].covariance, route.waypoints[i].covariance);
  }
  EXPECT_TRUE(back.goal_yaw_given);
  EXPECT_EQ(back.cost, route.cost);
  auto error = [](const std::string& text) {
    try {
      ParseRoute(text, "r.json");
    } catch (const FormatError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_THAT(error("{\"format\": \"waymark-map\", \"version\": 1}"),
              HasSubstr("r.json:1: format: expected \"waymark-route\""));
  EXPECT_THAT(error("{\"format\": \"waymark-route\", \"version\": 1,\n\"waypoints\": []}"),
              HasSubstr("r.json:2: waypoints: expected a non-empty array"));
  EXPECT_THAT(error("{\"format\": \"waymark-route\", \"version\": 1, \"waypoints\": [{\"x\": 1, \"y\": 2}]}"),
              HasSubstr("waypoints[0]"));
}

}  // namespace
}  // namespace waymark::plan
