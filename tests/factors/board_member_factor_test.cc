// factors/board_member_factor.h: a code's residual on its board's pose equals the plain residual
// at T_world_board * T_board_marker (values and, through the chain rule, Jacobians), checked by
// ceres::GradientChecker with the solver's manifolds at ten random states.
#include "factors/board_member_factor.h"

#include <gtest/gtest.h>

#include <memory>
#include <random>

#include "factors/marker_reprojection_factor.h"
#include "factors/pose_prior_se3_factor.h"
#include "tests/factors/factor_test_util.h"

namespace waymark {
namespace {

constexpr double kSizeM = 0.16;

TEST(BoardMemberCost, EqualsThePlainResidualAtTheComposedPose) {
  const CameraInfo camera = testing::TestCamera(CameraModel::kPinholeRadtan);
  std::mt19937 rng(3);
  const SE3d T_world_robot = testing::RandomSE3(rng, 2.0);
  const SE3d T_camera_marker = testing::RandomVisibleMarker(rng);
  const SE3d T_world_marker = T_world_robot * camera.T_robot_camera * T_camera_marker;
  const SE3d T_board_marker = testing::RandomSE3(rng, 0.3);
  const SE3d T_world_board = T_world_marker * T_board_marker.inverse();
  std::array<Eigen::Vector2d, 4> corners_px;
  ASSERT_TRUE(testing::ProjectCorners(camera, T_camera_marker, kSizeM, &corners_px));
  corners_px[1].x() += 2.0;  // one hand-made error: residual u1 = 2 px / sigma
  double robot[7], board[7], marker[7];
  SE3ToBlock(T_world_robot, robot);
  SE3ToBlock(T_world_board, board);
  SE3ToBlock(T_world_marker, marker);
  const std::unique_ptr<ceres::CostFunction> plain(
      MarkerReprojectionFactor::Create(camera, kSizeM, corners_px, 0.5));
  const BoardMemberCost on_board(MarkerReprojectionFactor::Create(camera, kSizeM, corners_px, 0.5),
                                 T_board_marker);
  EXPECT_EQ(on_board.num_residuals(), 8);
  ASSERT_EQ(on_board.parameter_block_sizes(), plain->parameter_block_sizes());
  double expected[8], residuals[8];
  std::fill(residuals, residuals + 8, testing::kNaN);
  const double* plain_blocks[2] = {robot, marker};
  const double* board_blocks[2] = {robot, board};
  ASSERT_TRUE(plain->Evaluate(plain_blocks, expected, nullptr));
  ASSERT_TRUE(on_board.Evaluate(board_blocks, residuals, nullptr));
  for (int i = 0; i < 8; ++i) EXPECT_NEAR(residuals[i], expected[i], 1e-9) << i;
  EXPECT_NEAR(residuals[2], -4.0, 1e-6);  // projected - observed = -2 px, sigma 0.5
  // The robot block's Jacobian is the plain one; only the last block goes through the board.
  double j_robot_plain[8 * 7], j_marker[8 * 7], j_robot[8 * 7], j_board[8 * 7];
  double* plain_jacobians[2] = {j_robot_plain, j_marker};
  double* board_jacobians[2] = {j_robot, j_board};
  ASSERT_TRUE(plain->Evaluate(plain_blocks, expected, plain_jacobians));
  ASSERT_TRUE(on_board.Evaluate(board_blocks, residuals, board_jacobians));
  for (int i = 0; i < 56; ++i) EXPECT_NEAR(j_robot[i], j_robot_plain[i], 1e-9);
  // Only the board's Jacobian asked for.
  double* only_board[2] = {nullptr, j_board};
  EXPECT_TRUE(on_board.Evaluate(board_blocks, residuals, only_board));
}

TEST(BoardMemberCost, GradientCheckTenRandomStates) {
  const CameraInfo camera = testing::TestCamera(CameraModel::kPinholeEquidistant);
  const SE3Manifold se3;
  std::mt19937 rng(21);
  for (int trial = 0; trial < 10; ++trial) {
    const SE3d T_world_robot = testing::RandomSE3(rng, 5.0);
    const SE3d T_camera_marker = testing::RandomVisibleMarker(rng);
    const SE3d T_board_marker = testing::RandomSE3(rng, 0.5);
    const SE3d T_world_board =
        T_world_robot * camera.T_robot_camera * T_camera_marker * T_board_marker.inverse();
    std::array<Eigen::Vector2d, 4> corners_px;
    ASSERT_TRUE(testing::ProjectCorners(camera, T_camera_marker, kSizeM, &corners_px));
    for (auto& c : corners_px) c += testing::RandomVector(rng, 1.0).head<2>();
    double robot[7], board[7];
    SE3ToBlock(T_world_robot, robot);
    SE3ToBlock(T_world_board, board);
    const BoardMemberCost cost(MarkerReprojectionFactor::Create(camera, kSizeM, corners_px, 0.5),
                               T_board_marker);
    testing::ExpectGradientsMatch(cost, {&se3, &se3}, {robot, board}, 1e-6, "reprojection on a board");
    // A one-block residual (a pose prior on the code) on the board.
    Vector6d sigmas;
    sigmas << 0.01, 0.02, 0.03, 0.1, 0.2, 0.3;
    const BoardMemberCost prior(
        PosePriorSE3Factor::Create(testing::RandomSE3(rng, 3.0), Matrix6d(sigmas.cwiseAbs2().asDiagonal())),
        T_board_marker);
    testing::ExpectGradientsMatch(prior, {&se3}, {board}, 1e-6, "prior on a board");
  }
}

}  // namespace
}  // namespace waymark
