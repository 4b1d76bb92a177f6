// Marginal covariances by the selected inverse against ceres::Covariance (SPARSE_QR) on small
// problems with quaternion manifolds, constant blocks and a free gauge.
#include "mapping/marginal_covariance.h"

#include <ceres/ceres.h>
#include <ceres/covariance.h>
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <array>
#include <memory>
#include <random>

namespace waymark {
namespace {

// r = sum_b A_b x_b + c (raw parameters), with exact Jacobians; the manifolds make the problem
// nonlinear in the tangent.
class LinearCost : public ceres::CostFunction {
 public:
  LinearCost(std::vector<Eigen::MatrixXd> A, Eigen::VectorXd c) : A_(std::move(A)), c_(std::move(c)) {
    set_num_residuals(static_cast<int>(c_.size()));
    for (const Eigen::MatrixXd& a : A_)
      mutable_parameter_block_sizes()->push_back(static_cast<int>(a.cols()));
  }
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
    Eigen::Map<Eigen::VectorXd> r(residuals, c_.size());
    r = c_;
    for (size_t b = 0; b < A_.size(); ++b) {
      r += A_[b] * Eigen::Map<const Eigen::VectorXd>(parameters[b], A_[b].cols());
      if (jacobians != nullptr && jacobians[b] != nullptr) {
        Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
            jacobians[b], A_[b].rows(), A_[b].cols()) = A_[b];
      }
    }
    return true;
  }

 private:
  const std::vector<Eigen::MatrixXd> A_;
  const Eigen::VectorXd c_;
};

// A chain of blocks (alternately quaternions and 3-vectors) closed into a loop, plus "marker"
// blocks each tied to a few chain blocks; an absolute prior on block 0 unless free_gauge.
struct ChainProblem {
  std::vector<std::vector<double>> values;
  ceres::Problem problem;

  ChainProblem(int chain, int markers, bool free_gauge, std::uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> normal;
    const auto random = [&](int rows, int cols) {
      Eigen::MatrixXd m(rows, cols);
      for (int i = 0; i < m.size(); ++i) m(i) = normal(rng);
      return m;
    };
    const int blocks = chain + markers;
    values.resize(blocks);
    for (int b = 0; b < blocks; ++b) {
      const int size = b % 2 == 0 ? 4 : 3;
      Eigen::VectorXd v = random(size, 1);
      if (size == 4) v.normalize();
      values[b].assign(v.data(), v.data() + size);
      problem.AddParameterBlock(values[b].data(), size,
                                size == 4 ? new ceres::QuaternionManifold() : nullptr);
    }
    const auto size_of = [&](int b) { return static_cast<int>(values[b].size()); };
    for (int b = 0; b < chain; ++b) {
      const int next = (b + 1) % chain;
      AddCost({b, next}, {random(5, size_of(b)), random(5, size_of(next))}, random(5, 1));
    }
    for (int m = chain; m < blocks; ++m) {
      for (int k = 0; k < 3; ++k) {
        const int b = static_cast<int>(rng() % chain);
        AddCost({b, m}, {random(4, size_of(b)), random(4, size_of(m))}, random(4, 1));
      }
    }
    if (!free_gauge) AddCost({0}, {random(4, size_of(0))}, random(4, 1));
  }

  // Relative-only costs (r = x_b - x_a - c) leave the sum of the blocks free.
  void AddCost(const std::vector<int>& blocks, const std::vector<Eigen::MatrixXd>& A,
               const Eigen::VectorXd& c) {
    std::vector<double*> parameters;
    for (int b : blocks) parameters.push_back(values[b].data());
    problem.AddResidualBlock(new LinearCost(A, c), nullptr, parameters);
  }
};

std::vector<Eigen::MatrixXd> CeresCovariances(ceres::Problem* problem,
                                              const std::vector<const double*>& blocks) {
  ceres::Covariance::Options options;
  options.algorithm_type = ceres::SPARSE_QR;
  ceres::Covariance covariance(options);
  std::vector<std::pair<const double*, const double*>> pairs;
  for (const double* b : blocks) pairs.emplace_back(b, b);
  EXPECT_TRUE(covariance.Compute(pairs, problem));
  std::vector<Eigen::MatrixXd> out;
  for (const double* b : blocks) {
    const int size = problem->ParameterBlockTangentSize(b);
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> block(size, size);
    EXPECT_TRUE(covariance.GetCovarianceBlockInTangentSpace(b, b, block.data()));
    out.emplace_back(block);
  }
  return out;
}

TEST(MarginalCovarianceTest, MatchesCeresCovarianceOnEveryBlock) {
  ChainProblem chain(30, 12, false, 7);
  std::vector<const double*> blocks;
  for (const std::vector<double>& v : chain.values) blocks.push_back(v.data());
  std::vector<Eigen::MatrixXd> ours;
  ASSERT_TRUE(MarginalCovariances(&chain.problem, blocks, &ours));
  const std::vector<Eigen::MatrixXd> reference = CeresCovariances(&chain.problem, blocks);
  ASSERT_EQ(ours.size(), blocks.size());
  for (size_t b = 0; b < blocks.size(); ++b) {
    ASSERT_EQ(ours[b].rows(), reference[b].rows());
    EXPECT_LE((ours[b] - reference[b]).norm(), 1e-9 * reference[b].norm()) << "block " << b;
  }
}

TEST(MarginalCovarianceTest, ConstantBlocksAreConditionedOn) {
  ChainProblem chain(20, 6, true, 11);
  chain.problem.SetParameterBlockConstant(chain.values[3].data());
  std::vector<const double*> blocks = {chain.values[0].data(), chain.values[21].data(),
                                       chain.values[25].data()};
  std::vector<Eigen::MatrixXd> ours;
  ASSERT_TRUE(MarginalCovariances(&chain.problem, blocks, &ours));
  const std::vector<Eigen::MatrixXd> reference = CeresCovariances(&chain.problem, blocks);
  for (size_t b = 0; b < blocks.size(); ++b) {
    EXPECT_LE((ours[b] - reference[b]).norm(), 1e-9 * reference[b].norm()) << "block " << b;
  }
}

// H = J^T J formed densely from Ceres' Jacobian over the non-constant blocks, in the column order
// of InformationFactor (GetParameterBlocks order).
Eigen::MatrixXd DenseInformation(ceres::Problem* problem) {
  std::vector<double*> all;
  problem->GetParameterBlocks(&all);
  ceres::Problem::EvaluateOptions evaluate;
  for (double* block : all) {
    if (!problem->IsParameterBlockConstant(block)) evaluate.parameter_blocks.push_back(block);
  }
  ceres::CRSMatrix crs;
  EXPECT_TRUE(problem->Evaluate(evaluate, nullptr, nullptr, nullptr, &crs));
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(crs.num_rows, crs.num_cols);
  for (int r = 0; r < crs.num_rows; ++r) {
    for (int p = crs.rows[r]; p < crs.rows[r + 1]; ++p) J(r, crs.cols[p]) = crs.values[p];
  }
  return J.transpose() * J;
}

// One factorization serves both uses: its marginals are the diagonal blocks of the dense H^-1,
// and Solve(B) is H^-1 B for every column of B at once.
TEST(MarginalCovarianceTest, FactorSolvesAndMarginalsMatchTheDenseInverse) {
  ChainProblem chain(25, 10, false, 3);
  chain.problem.SetParameterBlockConstant(chain.values[5].data());
  const std::vector<const double*> blocks = {chain.values[1].data(), chain.values[26].data(),
                                             chain.values[30].data()};
  const InformationFactor factor(&chain.problem, blocks);
  ASSERT_TRUE(factor.positive_definite());
  const Eigen::MatrixXd H = DenseInformation(&chain.problem);
  ASSERT_EQ(factor.size(), H.rows());
  const Eigen::MatrixXd H_inverse = H.ldlt().solve(Eigen::MatrixXd::Identity(H.rows(), H.cols()));
  std::mt19937_64 rng(9);
  std::normal_distribution<double> normal;
  Eigen::MatrixXd B(H.rows(), 7);
  for (int i = 0; i < B.size(); ++i) B(i) = normal(rng);
  const Eigen::MatrixXd X = factor.Solve(B);
  EXPECT_LE((X - H_inverse * B).norm(), 1e-9 * (H_inverse * B).norm());
  const std::vector<Eigen::MatrixXd> marginals = factor.Marginals();
  ASSERT_EQ(marginals.size(), blocks.size());
  for (size_t b = 0; b < blocks.size(); ++b) {
    const int first = factor.FirstColumn(blocks[b]), size = factor.TangentSize(blocks[b]);
    const Eigen::MatrixXd reference = H_inverse.block(first, first, size, size);
    EXPECT_LE((marginals[b] - reference).norm(), 1e-9 * reference.norm()) << "block " << b;
  }
  EXPECT_THROW(factor.FirstColumn(chain.values[5].data()), std::runtime_error);  // constant
}

// The leverages of every residual row are the diagonal of the dense hat matrix J H^-1 J^T; they
// sum to the number of free parameters (quaternion blocks count 3), and a constant block's columns
// are conditioned on.
TEST(MarginalCovarianceTest, LeveragesMatchTheDenseHatMatrix) {
  ChainProblem chain(25, 10, false, 5);
  chain.problem.SetParameterBlockConstant(chain.values[4].data());
  const InformationFactor factor(&chain.problem, {});
  ASSERT_TRUE(factor.positive_definite());
  std::vector<double> residuals;
  ceres::CRSMatrix crs;
  ASSERT_TRUE(ResidualJacobian(&chain.problem, {}, 1, &residuals, &crs));
  ASSERT_EQ(crs.num_cols, factor.size());
  ASSERT_EQ(static_cast<int>(residuals.size()), crs.num_rows);
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(crs.num_rows, crs.num_cols);
  for (int r = 0; r < crs.num_rows; ++r) {
    for (int p = crs.rows[r]; p < crs.rows[r + 1]; ++p) J(r, crs.cols[p]) = crs.values[p];
  }
  const Eigen::MatrixXd H = J.transpose() * J;
  const Eigen::MatrixXd hat = J * H.ldlt().solve(J.transpose());
  const std::vector<double> leverage = factor.Leverages(crs);
  ASSERT_EQ(static_cast<int>(leverage.size()), crs.num_rows);
  double sum = 0.0;
  for (int r = 0; r < crs.num_rows; ++r) {
    EXPECT_NEAR(leverage[r], hat(r, r), 1e-9) << "row " << r;
    EXPECT_GE(leverage[r], -1e-12);
    EXPECT_LE(leverage[r], 1.0 + 1e-12);
    sum += leverage[r];
  }
  EXPECT_NEAR(sum, static_cast<double>(factor.size()), 1e-8);
  ceres::CRSMatrix wrong = crs;
  wrong.num_cols += 1;
  EXPECT_THROW(factor.Leverages(wrong), std::logic_error);
}

TEST(MarginalCovarianceTest, FreeGaugeIsReportedNotInverted) {
  // Pure differences: r = x_b - x_a - c leaves a common shift of every block free.
  std::vector<std::array<double, 3>> x(8, {0.0, 0.0, 0.0});
  ceres::Problem problem;
  for (size_t b = 0; b + 1 < x.size(); ++b) {
    Eigen::MatrixXd minus = -Eigen::MatrixXd::Identity(3, 3), plus = Eigen::MatrixXd::Identity(3, 3);
    problem.AddResidualBlock(new LinearCost({minus, plus}, Eigen::Vector3d(1.0, 0.0, 0.5)), nullptr,
                             x[b].data(), x[b + 1].data());
  }
  std::vector<Eigen::MatrixXd> covariance;
  EXPECT_FALSE(MarginalCovariances(&problem, {x[4].data()}, &covariance));
  EXPECT_TRUE(covariance.empty());
  EXPECT_FALSE(InformationFactor(&problem, {x[4].data()}).positive_definite());
  // Holding one block fixes the gauge: the chain's marginal grows by one unit per link.
  problem.SetParameterBlockConstant(x[0].data());
  ASSERT_TRUE(MarginalCovariances(&problem, {x[4].data()}, &covariance));
  EXPECT_NEAR(covariance[0](0, 0), 4.0, 1e-9);
  EXPECT_NEAR(covariance[0](0, 1), 0.0, 1e-9);
}

TEST(MarginalCovarianceTest, UnknownOrConstantBlockThrows) {
  std::array<double, 3> x{0.0, 0.0, 0.0}, y{0.0, 0.0, 0.0}, outside{0.0, 0.0, 0.0};
  ceres::Problem problem;
  problem.AddResidualBlock(new LinearCost({Eigen::MatrixXd::Identity(3, 3), Eigen::MatrixXd::Identity(3, 3)},
                                          Eigen::Vector3d::Zero()),
                           nullptr, x.data(), y.data());
  problem.SetParameterBlockConstant(y.data());
  std::vector<Eigen::MatrixXd> covariance;
  EXPECT_THROW(MarginalCovariances(&problem, {outside.data()}, &covariance), std::runtime_error);
  EXPECT_THROW(MarginalCovariances(&problem, {y.data()}, &covariance), std::runtime_error);
  ASSERT_TRUE(MarginalCovariances(&problem, {x.data()}, &covariance));
  EXPECT_TRUE(covariance[0].isApprox(Eigen::Matrix3d::Identity(), 1e-12));
}

}  // namespace
}  // namespace waymark
