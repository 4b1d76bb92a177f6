#include "mapping/map_covariance.h"

#include <ceres/ceres.h>
#include <ceres/covariance.h>
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <array>
#include <random>

#include "factors/odometry_se3_factor.h"
#include "factors/pose_block.h"
#include "factors/pose_prior_se3_factor.h"

namespace waymark {
namespace {

Eigen::MatrixXd RandomMatrix(int rows, int cols, std::mt19937* rng) {
  std::normal_distribution<double> normal;
  Eigen::MatrixXd M(rows, cols);
  for (int i = 0; i < M.size(); ++i) M(i) = normal(*rng);
  return M;
}

// A PSD matrix with a decaying spectrum: the top k eigenpairs are found to high accuracy.
TEST(MapCovarianceTest, TopEigenFactorFindsTheLargestEigenpairs) {
  std::mt19937 rng(3);
  const int n = 60, k = 5;
  const Eigen::HouseholderQR<Eigen::MatrixXd> qr(RandomMatrix(n, n, &rng));
  const Eigen::MatrixXd V = qr.householderQ();
  Eigen::VectorXd lambda(n);
  for (int i = 0; i < n; ++i) lambda(i) = std::pow(0.7, i);
  const Eigen::MatrixXd Sigma = V * lambda.asDiagonal() * V.transpose();
  CovarianceFactorOptions options;
  options.rank = k;
  const Eigen::MatrixXd F =
      TopEigenFactor([&](const Eigen::MatrixXd& X) { return Eigen::MatrixXd(Sigma * X); }, n, options);
  ASSERT_EQ(F.cols(), k);
  const Eigen::MatrixXd best = V.leftCols(k) * lambda.head(k).asDiagonal() * V.leftCols(k).transpose();
  EXPECT_LT((F * F.transpose() - best).norm(), 1e-6 * best.norm());
  // The rest is PSD: F F^T <= Sigma.
  EXPECT_GT(
      Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(Sigma - F * F.transpose()).eigenvalues().minCoeff(),
      -1e-9);
  options.rank = n + 10;  // capped at n: the whole matrix
  const Eigen::MatrixXd F_all =
      TopEigenFactor([&](const Eigen::MatrixXd& X) { return Eigen::MatrixXd(Sigma * X); }, n, options);
  EXPECT_EQ(F_all.cols(), n);
  EXPECT_LT((F_all * F_all.transpose() - Sigma).norm(), 1e-9 * Sigma.norm());
}

TEST(MapCovarianceTest, FitFactorToMarginalKeepsTheRestPositiveSemiDefinite) {
  std::mt19937 rng(4);
  const Eigen::MatrixXd B = RandomMatrix(6, 6, &rng);
  const Matrix6d marginal = B * B.transpose() + Matrix6d::Identity();
  CovarianceFactor inside = 0.1 * RandomMatrix(6, 3, &rng);
  const CovarianceFactor inside_before = inside;
  EXPECT_EQ(FitFactorToMarginal(marginal, &inside), 1.0);
  EXPECT_EQ(inside, inside_before);
  CovarianceFactor outside = 10.0 * RandomMatrix(6, 3, &rng);
  const double scale = FitFactorToMarginal(marginal, &outside);
  EXPECT_LT(scale, 1.0);
  const double min_eigenvalue =
      Eigen::SelfAdjointEigenSolver<Matrix6d>(marginal - outside * outside.transpose())
          .eigenvalues()
          .minCoeff();
  EXPECT_GT(min_eigenvalue, -1e-9);
  EXPECT_LT(min_eigenvalue, 1e-6);  // scaled just enough: touches the boundary
}

// Three poses in a chain (a prior on the first, relative poses between neighbours, a weak
// prior on the last): at full rank F F^T is the joint covariance ceres::Covariance gives,
// converted to the body tangent.
TEST(MapCovarianceTest, FullRankFactorIsTheJointCovariance) {
  std::mt19937 rng(5);
  std::normal_distribution<double> normal;
  const auto random_pose = [&]() {
    return SE3d(Eigen::Quaterniond(1.0, 0.1 * normal(rng), 0.1 * normal(rng), 0.1 * normal(rng)).normalized(),
                Eigen::Vector3d(normal(rng), normal(rng), normal(rng)));
  };
  std::array<std::array<double, kSE3BlockSize>, 3> blocks;
  std::vector<SE3d> poses;
  ceres::Problem problem;
  for (auto& block : blocks) {
    poses.push_back(random_pose());
    SE3ToBlock(poses.back(), block.data());
    problem.AddParameterBlock(block.data(), kSE3BlockSize, new SE3Manifold);
  }
  const Matrix6d prior = Matrix6d::Identity() * 1e-4;
  problem.AddResidualBlock(PosePriorSE3Factor::Create(random_pose(), prior), nullptr, blocks[0].data());
  problem.AddResidualBlock(PosePriorSE3Factor::Create(random_pose(), prior * 100.0), nullptr,
                           blocks[2].data());
  for (int i = 0; i < 2; ++i) {
    problem.AddResidualBlock(OdometrySE3Factor::Create(random_pose(), prior * (i + 1)), nullptr,
                             blocks[i].data(), blocks[i + 1].data());
  }
  std::vector<const double*> block_pointers = {blocks[0].data(), blocks[1].data(), blocks[2].data()};
  ceres::Covariance::Options covariance_options;
  ceres::Covariance covariance(covariance_options);
  ASSERT_TRUE(covariance.Compute(block_pointers, &problem));
  Eigen::Matrix<double, 18, 18, Eigen::RowMajor> manifold;
  ASSERT_TRUE(covariance.GetCovarianceMatrixInTangentSpace(block_pointers, manifold.data()));
  Eigen::Matrix<double, 18, 18> B = Eigen::Matrix<double, 18, 18>::Zero();
  std::vector<Matrix6d> marginals;
  for (int i = 0; i < 3; ++i) B.block<6, 6>(6 * i, 6 * i) = ManifoldToBodyTangentJacobian(poses[i]);
  const Eigen::Matrix<double, 18, 18> joint = B * manifold * B.transpose();
  for (int i = 0; i < 3; ++i) marginals.push_back(joint.block<6, 6>(6 * i, 6 * i));

  CovarianceFactorOptions options;
  options.rank = 18;
  const auto rows = MarkerCovarianceFactors(&problem, block_pointers, poses, marginals, options);
  ASSERT_TRUE(rows.has_value());
  ASSERT_EQ(rows->size(), 3u);
  Eigen::MatrixXd F(18, 18);
  for (int i = 0; i < 3; ++i) F.middleRows(6 * i, 6) = (*rows)[i];
  EXPECT_LT((F * F.transpose() - joint).norm(), 1e-6 * joint.norm());

  options.rank = 4;  // low rank: every marker's rest D_i is PSD
  const auto low = MarkerCovarianceFactors(&problem, block_pointers, poses, marginals, options);
  ASSERT_TRUE(low.has_value());
  for (int i = 0; i < 3; ++i) {
    ASSERT_EQ((*low)[i].cols(), 4);
    const Matrix6d rest = marginals[i] - (*low)[i] * (*low)[i].transpose();
    EXPECT_GT(Eigen::SelfAdjointEigenSolver<Matrix6d>(rest).eigenvalues().minCoeff(), -1e-12);
  }
  EXPECT_FALSE(MarkerCovarianceFactors(&problem, block_pointers, poses, {}, options).has_value());
}

// A free gauge (no prior): H is singular and no factor is returned.
TEST(MapCovarianceTest, FreeGaugeGivesNoFactor) {
  std::array<std::array<double, kSE3BlockSize>, 2> blocks;
  ceres::Problem problem;
  std::vector<SE3d> poses = {SE3d(), SE3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(1, 0, 0))};
  for (int i = 0; i < 2; ++i) {
    SE3ToBlock(poses[i], blocks[i].data());
    problem.AddParameterBlock(blocks[i].data(), kSE3BlockSize, new SE3Manifold);
  }
  problem.AddResidualBlock(OdometrySE3Factor::Create(poses[1], Matrix6d::Identity() * 1e-4), nullptr,
                           blocks[0].data(), blocks[1].data());
  const std::vector<Matrix6d> marginals(2, Matrix6d::Identity());
  EXPECT_FALSE(MarkerCovarianceFactors(&problem, {blocks[0].data(), blocks[1].data()}, poses, marginals, {})
                   .has_value());
}

}  // namespace
}  // namespace waymark
