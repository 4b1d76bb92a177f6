#include "online/ekf_state.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <random>
#include <stdexcept>

#include "online/motion_model.h"

namespace waymark {
namespace {

Eigen::Matrix3d SomeCovariance() {
  Eigen::Matrix3d P;
  P << 0.04, 0.01, 0.002, 0.01, 0.09, -0.003, 0.002, -0.003, 0.01;
  return P;
}

bool IsSymmetricPositiveDefinite(const Eigen::MatrixXd& P) {
  return (P - P.transpose()).norm() <= 1e-12 * P.norm() &&
         Eigen::LLT<Eigen::MatrixXd>(P).info() == Eigen::Success &&
         P.llt().matrixL().toDenseMatrix().diagonal().minCoeff() > 0.0;
}

TEST(EkfStateTest, ZeroInnovationKeepsMeanAndShrinksCovariance) {
  EkfState state(MotionModel::kPlanar);
  ASSERT_EQ(state.Reset(Eigen::Vector3d(1.0, 2.0, 0.5), SomeCovariance()), StepStatus::kOk);
  const Eigen::MatrixXd P_before = state.covariance();
  const UpdateResult result = state.Update(Eigen::Vector3d::Zero(), Eigen::Matrix3d::Identity(),
                                           Eigen::Matrix3d::Identity() * 0.01, 10.0);
  ASSERT_TRUE(result.accepted);
  EXPECT_EQ(result.nis, 0.0);
  EXPECT_LT((state.mean() - Eigen::Vector3d(1.0, 2.0, 0.5)).norm(), 1e-15);
  // P_before - P_after is positive definite: every direction became more certain.
  EXPECT_TRUE(IsSymmetricPositiveDefinite(P_before - state.covariance()));
  EXPECT_TRUE(IsSymmetricPositiveDefinite(state.covariance()));
}

TEST(EkfStateTest, GrossOutlierIsGatedAndChangesNothing) {
  EkfState state(MotionModel::kPlanar);
  ASSERT_EQ(state.Reset(Eigen::Vector3d(1.0, 2.0, 0.5), SomeCovariance()), StepStatus::kOk);
  const Eigen::MatrixXd P_before = state.covariance();
  const UpdateResult result = state.Update(Eigen::Vector3d(5.0, 0.0, 0.0), Eigen::Matrix3d::Identity(),
                                           Eigen::Matrix3d::Identity() * 0.01, 14.16);
  EXPECT_TRUE(result.gated);
  EXPECT_FALSE(result.accepted);
  EXPECT_GT(result.nis, 100.0);
  EXPECT_EQ(state.mean(), Eigen::Vector3d(1.0, 2.0, 0.5));
  EXPECT_EQ(state.covariance(), P_before);
}

TEST(EkfStateTest, YawIsWrappedByBoxPlusAndBoxMinus) {
  const Eigen::Vector3d a(0.0, 0.0, 3.1), b(0.0, 0.0, -3.1);
  const Eigen::VectorXd delta = EkfState::BoxMinus(a, b, 2);
  EXPECT_NEAR(delta(2), 2.0 * M_PI - 6.2, 1e-12);
  EXPECT_NEAR(EkfState::BoxPlus(a, delta, 2)(2), -3.1, 1e-12);
}

TEST(EkfStateTest, BoxMinusOfStatesOfDifferentSizesIsAnError) {
  const Eigen::VectorXd pose = Eigen::Vector3d(1.0, 2.0, 0.1);
  Eigen::VectorXd with_calibration(5);
  with_calibration << 1.0, 2.0, 0.1, 0.0, 0.0;
  EXPECT_THROW(EkfState::BoxMinus(with_calibration, pose, 2), std::invalid_argument);
  EXPECT_THROW(EkfState::BoxMinus(pose, pose, 3), std::invalid_argument);
  EXPECT_NEAR(EkfState::BoxMinus(with_calibration.head(3), pose, 2).norm(), 0.0, 1e-15);
}

TEST(EkfStateTest, NonFiniteCovarianceIsAnErrorAndKeepsTheOldOne) {
  EkfState state(MotionModel::kPlanar);
  ASSERT_EQ(state.Reset(Eigen::Vector3d::Zero(), SomeCovariance()), StepStatus::kOk);
  Eigen::Matrix3d F = Eigen::Matrix3d::Identity();
  F(0, 2) = std::numeric_limits<double>::infinity();
  EXPECT_EQ(
      state.Propagate(Eigen::Vector3d::Zero(), F, Eigen::Matrix3d::Identity(), Eigen::Matrix3d::Identity()),
      StepStatus::kNonFiniteCovariance);
  EXPECT_EQ(state.covariance(), SomeCovariance());
  Eigen::Matrix3d bad = SomeCovariance();
  bad(1, 1) = std::nan("");
  EXPECT_EQ(state.Reset(Eigen::Vector3d::Zero(), bad), StepStatus::kNonFiniteCovariance);
  // S not positive definite (negative measurement noise) is reported, not used.
  const UpdateResult result = state.Update(Eigen::Vector3d::Zero(), Eigen::Matrix3d::Identity(),
                                           -Eigen::Matrix3d::Identity(), std::nullopt);
  EXPECT_EQ(result.status, StepStatus::kNotPositiveDefinite);
  EXPECT_FALSE(result.accepted);
}

TEST(EkfStateTest, CovarianceStaysSymmetricPositiveDefiniteOverALongRun) {
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 1.0);
  EkfState state(MotionModel::kPlanar);
  ASSERT_EQ(state.Reset(Eigen::Vector3d::Zero(), Eigen::Matrix3d::Identity() * 1e-4), StepStatus::kOk);
  OdometryNoise odometry;
  Eigen::Matrix<double, 2, 3> H;  // a range-bearing-like rank-deficient measurement
  H << 1.0, 0.5, 0.0, 0.0, 0.2, 1.0;
  for (int k = 0; k < 100000; ++k) {
    const MotionPrediction p = PredictPlanarIncrement(state.mean(), SE2d(0.05, 0.0, 0.01), odometry);
    ASSERT_EQ(state.Propagate(p.mean, p.F, p.G, p.Qu), StepStatus::kOk);
    if (k % 10 == 0) {
      const Eigen::Vector2d y(1e-3 * noise(rng), 1e-3 * noise(rng));
      ASSERT_EQ(state.Update(y, H, Eigen::Matrix2d::Identity() * 1e-6, std::nullopt).status, StepStatus::kOk);
    }
    if (k % 997 == 0) {
      ASSERT_TRUE(IsSymmetricPositiveDefinite(state.covariance())) << "step " << k;
    }
  }
  EXPECT_TRUE(IsSymmetricPositiveDefinite(state.covariance()));
}

// For a linear h the iterated update converges in one step to the plain EKF update; for a
// non-linear h it reaches the MAP estimate (here: a range to the origin).
TEST(EkfStateTest, IteratedUpdateMatchesPlainUpdateForLinearMeasurements) {
  EkfState plain(MotionModel::kPlanar);
  ASSERT_EQ(plain.Reset(Eigen::Vector3d(1.0, 2.0, 0.5), SomeCovariance()), StepStatus::kOk);
  EkfState iterated = plain;
  Eigen::Matrix<double, 2, 3> H;
  H << 1.0, 0.5, 0.0, 0.0, 0.2, 1.0;
  const Eigen::Vector2d z(1.3, 0.9);
  const Eigen::Matrix2d R = Eigen::Matrix2d::Identity() * 0.01;
  const auto linearize = [&](const EkfState& at) -> std::optional<Linearization> {
    return Linearization{z - H * at.mean(), H, R, std::nullopt};
  };
  const UpdateResult a = plain.Update(z - H * plain.mean(), H, R, std::nullopt);
  const UpdateResult b = iterated.UpdateIterated(linearize, std::nullopt, 5);
  ASSERT_TRUE(a.accepted && b.accepted);
  EXPECT_NEAR(a.nis, b.nis, 1e-12);
  EXPECT_LT((plain.mean() - iterated.mean()).norm(), 1e-12);
  EXPECT_LT((plain.covariance() - iterated.covariance()).norm(), 1e-12);

  // Squared range r^2 = x^2 + y^2 measured as 1.0 from a prior at (3, 0.5) with a loose prior:
  // the iterated update lands on the unit circle, one linearization far from it.
  EkfState prior(MotionModel::kPlanar);
  ASSERT_EQ(prior.Reset(Eigen::Vector3d(3.0, 0.5, 0.0), Eigen::Matrix3d::Identity()), StepStatus::kOk);
  const auto range = [](const EkfState& at) -> std::optional<Linearization> {
    const Eigen::Vector2d p = at.mean().head<2>();
    Eigen::Matrix<double, 1, 3> J;
    J << 2.0 * p.x(), 2.0 * p.y(), 0.0;
    return Linearization{Eigen::VectorXd::Constant(1, 1.0 - p.squaredNorm()), J,
                         Eigen::MatrixXd::Constant(1, 1, 1e-6), std::nullopt};
  };
  EkfState once = prior, many = prior;
  ASSERT_TRUE(once.UpdateIterated(range, std::nullopt, 1).accepted);
  ASSERT_TRUE(many.UpdateIterated(range, std::nullopt, 20).accepted);
  EXPECT_GT(std::abs(once.mean().head<2>().norm() - 1.0), 0.05);
  EXPECT_LT(std::abs(many.mean().head<2>().norm() - 1.0), 1e-4);
}

// Schmidt (consider) updates on a linear model: the filter's P and C_m must equal the exact
// covariance of [its own error; the marker error], propagated alongside as
//   update:    [e; eps] <- [[I - K H, -K H_m], [0, I]] [e; eps] - K v
//   propagate: [e; eps] <- [[F, 0], [0, I]] [e; eps] + G u
// with K read from the filter's state before each update.
TEST(EkfStateTest, ConsiderUpdateCovarianceIsTheTrueErrorCovariance) {
  std::mt19937 rng(11);
  std::normal_distribution<double> normal(0.0, 1.0);
  const auto random = [&](int rows, int cols) {
    Eigen::MatrixXd M(rows, cols);
    for (int i = 0; i < M.size(); ++i) M(i) = normal(rng);
    return M;
  };
  Matrix6d Sigma = Matrix6d::Identity() * 1e-4;
  Sigma.topLeftCorner<3, 3>() *= 0.3;
  const MarkerKey key{kFamilyQr, "m"};
  EkfState state(MotionModel::kPlanar);
  const Eigen::Matrix3d P0 = SomeCovariance();
  CrossCovariance C0 = 0.1 * random(3, 6) * Sigma;  // some prior correlation
  ASSERT_EQ(state.Reset(Eigen::Vector3d::Zero(), P0, key, C0), StepStatus::kOk);
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(9, 9);  // covariance of [e; eps]
  J << P0, C0, C0.transpose(), Sigma;
  const Eigen::MatrixXd R = Eigen::MatrixXd::Identity(8, 8) * 0.25;
  for (int k = 0; k < 6; ++k) {
    const Eigen::MatrixXd H = random(8, 3), H_m = 10.0 * random(8, 6);
    const Linearization lin{Eigen::VectorXd::Zero(8), H, R, ConsideredMarker{key, H_m, Sigma, {}}};
    const Eigen::MatrixXd S =
        H * state.covariance() * H.transpose() + H * state.Cross(key) * H_m.transpose() +
        H_m * state.Cross(key).transpose() * H.transpose() + H_m * Sigma * H_m.transpose() + R;
    const Eigen::MatrixXd K = (state.covariance() * H.transpose() + state.Cross(key) * H_m.transpose()) *
                              S.llt().solve(Eigen::MatrixXd::Identity(8, 8));
    ASSERT_TRUE(state.UpdateIterated([&lin](const EkfState&) { return lin; }, std::nullopt, 3).accepted);
    Eigen::MatrixXd A = Eigen::MatrixXd::Identity(9, 9);
    A.topLeftCorner(3, 3) -= K * H;
    A.topRightCorner(3, 6) = -K * H_m;
    J = A * J * A.transpose();
    J.topLeftCorner(3, 3) += K * R * K.transpose();
    EXPECT_LT((state.covariance() - J.topLeftCorner(3, 3)).norm(), 1e-10 * J.norm()) << "update " << k;
    EXPECT_LT((Eigen::MatrixXd(state.Cross(key)) - J.topRightCorner(3, 6)).norm(), 1e-10 * J.norm());
    const Eigen::Matrix3d F = Eigen::Matrix3d::Identity() + 0.1 * random(3, 3);
    const Eigen::Matrix3d Q = Eigen::Matrix3d::Identity() * 1e-4;
    ASSERT_EQ(state.Propagate(state.mean(), F, Eigen::Matrix3d::Identity(), Q), StepStatus::kOk);
    Eigen::MatrixXd A_f = Eigen::MatrixXd::Identity(9, 9);
    A_f.topLeftCorner(3, 3) = F;
    J = A_f * J * A_f.transpose();
    J.topLeftCorner(3, 3) += Q;
    EXPECT_LT((state.covariance() - J.topLeftCorner(3, 3)).norm(), 1e-10 * J.norm());
  }
  EXPECT_EQ(state.considered_markers(), 1u);
  ASSERT_EQ(state.Reset(Eigen::Vector3d::Zero(), P0), StepStatus::kOk);  // forgets C_m
  EXPECT_EQ(state.considered_markers(), 0u);
  EXPECT_EQ(Eigen::MatrixXd(state.Cross(key)), Eigen::MatrixXd::Zero(3, 6));
}

// Markers with a joint covariance factor (eps_i = F_i xi + eta_i): the filter's P, and its
// correlation with every marker error, C_xi F_j^T + C_j, equal those of the Schmidt filter on
// the augmented vector [delta; eps_1 .. eps_M] with the full joint map covariance
// F F^T + blockdiag(D_i), propagated and updated in full (the marker rows get no gain).
TEST(EkfStateTest, ConsiderWithFactorMatchesAugmentedSchmidtFilter) {
  std::mt19937 rng(23);
  std::normal_distribution<double> normal(0.0, 1.0);
  const auto random = [&](int rows, int cols) {
    Eigen::MatrixXd M(rows, cols);
    for (int i = 0; i < M.size(); ++i) M(i) = normal(rng);
    return M;
  };
  constexpr int kMarkers = 3, kRank = 2, kDim = 3, kAug = kDim + 6 * kMarkers;
  const Eigen::MatrixXd F_all = 0.01 * random(6 * kMarkers, kRank);
  std::vector<Matrix6d> D(kMarkers), Sigma(kMarkers);
  Eigen::MatrixXd joint = F_all * F_all.transpose();
  for (int i = 0; i < kMarkers; ++i) {
    const Eigen::MatrixXd B = 0.003 * random(6, 6);
    D[i] = B * B.transpose() + Matrix6d::Identity() * 1e-6;
    joint.block<6, 6>(6 * i, 6 * i) += D[i];
    Sigma[i] = joint.block<6, 6>(6 * i, 6 * i);
  }
  const auto key = [](int i) { return MarkerKey{kFamilyQr, std::to_string(i)}; };
  EkfState state(MotionModel::kPlanar);
  state.set_max_considered(kMarkers);
  const Eigen::Matrix3d P0 = SomeCovariance();
  ASSERT_EQ(state.Reset(Eigen::Vector3d::Zero(), P0), StepStatus::kOk);
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(kAug, kAug);  // covariance of [delta; eps]
  J.topLeftCorner(kDim, kDim) = P0;
  J.bottomRightCorner(6 * kMarkers, 6 * kMarkers) = joint;
  const Eigen::MatrixXd R = Eigen::MatrixXd::Identity(8, 8) * 0.25;
  for (int step = 0; step < 9; ++step) {
    const int m = (step * 2) % kMarkers;
    const Eigen::MatrixXd H = random(8, kDim), H_m = 10.0 * random(8, 6);
    const CovarianceFactor F_m = F_all.middleRows(6 * m, 6);
    const Linearization lin{random(8, 1), H, R, ConsideredMarker{key(m), H_m, Sigma[m], F_m}};
    Eigen::MatrixXd H_aug = Eigen::MatrixXd::Zero(8, kAug);
    H_aug.leftCols(kDim) = H;
    H_aug.middleCols(kDim + 6 * m, 6) = H_m;
    const Eigen::MatrixXd S = H_aug * J * H_aug.transpose() + R;
    const Eigen::MatrixXd K = J.topRows(kDim) * H_aug.transpose() * S.inverse();
    const Eigen::VectorXd mean_expected = state.mean() + K * lin.innovation;
    ASSERT_TRUE(state.UpdateIterated([&lin](const EkfState&) { return lin; }, std::nullopt, 1).accepted);
    Eigen::MatrixXd A = Eigen::MatrixXd::Identity(kAug, kAug);
    A.topRows(kDim) -= K * H_aug;
    J = A * J * A.transpose();
    J.topLeftCorner(kDim, kDim) += K * R * K.transpose();
    EXPECT_LT((state.mean() - mean_expected).norm(), 1e-10 * mean_expected.norm()) << "update " << step;
    EXPECT_LT((state.covariance() - J.topLeftCorner(kDim, kDim)).norm(), 1e-9 * J.norm())
        << "update " << step;
    ASSERT_EQ(state.cross_factor().cols(), kRank);
    for (int i = 0; i < kMarkers; ++i) {
      const Eigen::MatrixXd cross = state.cross_factor() * F_all.middleRows(6 * i, 6).transpose() +
                                    Eigen::MatrixXd(state.Cross(key(i)));
      EXPECT_LT((cross - J.block(0, kDim + 6 * i, kDim, 6)).norm(), 1e-9 * J.norm()) << "update " << step;
    }
    const Eigen::Matrix3d F = Eigen::Matrix3d::Identity() + 0.1 * random(3, 3);
    const Eigen::Matrix3d Q = Eigen::Matrix3d::Identity() * 1e-4;
    ASSERT_EQ(state.Propagate(state.mean(), F, Eigen::Matrix3d::Identity(), Q), StepStatus::kOk);
    Eigen::MatrixXd A_f = Eigen::MatrixXd::Identity(kAug, kAug);
    A_f.topLeftCorner(kDim, kDim) = F;
    J = A_f * J * A_f.transpose();
    J.topLeftCorner(kDim, kDim) += Q;
  }
  // A factor with another number of columns than the map's so far is invalid input.
  const Linearization wrong_k{
      Eigen::VectorXd::Zero(8), random(8, kDim), R,
      ConsideredMarker{key(0), random(8, 6), Sigma[0], CovarianceFactor::Zero(6, kRank + 1)}};
  EXPECT_EQ(state.UpdateIterated([&](const EkfState&) { return wrong_k; }, std::nullopt, 1).status,
            StepStatus::kInvalidInput);
  ASSERT_EQ(state.Reset(Eigen::Vector3d::Zero(), P0), StepStatus::kOk);  // forgets C_xi
  EXPECT_EQ(state.cross_factor().cols(), 0);
}

// Initialization from a code whose map error has a factor: cross = A Sigma_m splits into
// C_m = A D_m and C_xi = A F_m.
TEST(EkfStateTest, ResetSplitsTheMarkerCrossCovariance) {
  std::mt19937 rng(5);
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::MatrixXd A(3, 6), B(6, 6), F(6, 2);
  for (int i = 0; i < A.size(); ++i) A(i) = normal(rng);
  for (int i = 0; i < B.size(); ++i) B(i) = 0.01 * normal(rng);
  for (int i = 0; i < F.size(); ++i) F(i) = 0.01 * normal(rng);
  const Matrix6d D = B * B.transpose() + Matrix6d::Identity() * 1e-6;
  const Matrix6d Sigma = D + F * F.transpose();
  const MarkerKey key{kFamilyQr, "a"};
  EkfState state(MotionModel::kPlanar);
  ASSERT_EQ(state.Reset(Eigen::Vector3d::Zero(), SomeCovariance(), key, CrossCovariance(A * Sigma), Sigma, F),
            StepStatus::kOk);
  EXPECT_LT((Eigen::MatrixXd(state.Cross(key)) - A * D).norm(), 1e-9 * (A * D).norm());
  EXPECT_LT((state.cross_factor() - A * F).norm(), 1e-9 * (A * F).norm());
  EXPECT_EQ(state.Reset(Eigen::Vector3d::Zero(), SomeCovariance(), key, CrossCovariance(A * Sigma),
                        Matrix6d::Zero(), F),
            StepStatus::kInvalidInput);
}

// Only the `max_considered` most recently used markers keep their C_m.
TEST(EkfStateTest, ConsideredMarkersAreCapped) {
  EkfState state(MotionModel::kPlanar);
  state.set_max_considered(2);
  ASSERT_EQ(state.Reset(Eigen::Vector3d::Zero(), SomeCovariance()), StepStatus::kOk);
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(2, 3);
  H(0, 0) = H(1, 1) = 1.0;
  Eigen::MatrixXd H_m = Eigen::MatrixXd::Zero(2, 6);
  H_m(0, 3) = H_m(1, 4) = 1.0;
  for (const char* id : {"a", "b", "c"}) {
    const Linearization lin{Eigen::Vector2d::Zero(), H, Eigen::Matrix2d::Identity() * 1e-4,
                            ConsideredMarker{{kFamilyQr, id}, H_m, Matrix6d::Identity() * 1e-4, {}}};
    ASSERT_TRUE(state.UpdateIterated([&lin](const EkfState&) { return lin; }, std::nullopt, 1).accepted);
  }
  EXPECT_EQ(state.considered_markers(), 2u);
  EXPECT_EQ(Eigen::MatrixXd(state.Cross({kFamilyQr, "a"})), Eigen::MatrixXd::Zero(3, 6));
  EXPECT_GT(state.Cross({kFamilyQr, "c"}).norm(), 0.0);
}

TEST(EkfStateTest, FreeStateKeepsLevelRotation) {
  EkfState state(MotionModel::kFree);
  ASSERT_EQ(state.dim(), 4);
  const Eigen::Matrix3d R =
      (Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitY()) *
       Eigen::AngleAxisd(-0.2, Eigen::Vector3d::UnitX()))
          .toRotationMatrix();
  state.SetLevel(R);  // the yaw part is removed
  ASSERT_EQ(state.Reset(Eigen::Vector4d(1.0, 2.0, 3.0, 0.7), Eigen::Matrix4d::Identity()), StepStatus::kOk);
  const SE3d T = state.T_world_robot();
  EXPECT_LT((T.rotation_matrix() - R).norm(), 1e-12);
  EXPECT_LT((T.translation() - Eigen::Vector3d(1.0, 2.0, 3.0)).norm(), 1e-15);
  EXPECT_LT((PoseToStateVector(T, MotionModel::kFree) - Eigen::Vector4d(1.0, 2.0, 3.0, 0.7)).norm(), 1e-12);
}

}  // namespace
}  // namespace waymark
