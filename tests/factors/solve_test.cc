// End-to-end solves with the factors on synthetic truth (fixed seeds): five markers on a wall,
// a short trajectory, corners with 0.5 px noise, odometry drawn from the covariance the helper
// builds, initial values perturbed by up to ~17 cm / ~10 deg. Asserts the rotation and translation
// errors of markers and robot poses after the solve, in degrees and metres.
//  - Free: SE(3) robot, radtan camera, one anchor marker held constant (the gauge).
//  - Planar: SE(2) robot, equidistant camera at 0.3 m tilted up, no anchor: payload-style
//    x, y position priors on three markers and a yaw prior fix the gauge.
#include <ceres/ceres.h>
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>
#include <type_traits>
#include <vector>

#include "factors/marker_reprojection_factor.h"
#include "factors/odometry_covariance.h"
#include "factors/odometry_se2_factor.h"
#include "factors/odometry_se3_factor.h"
#include "factors/planar_marker_reprojection_factor.h"
#include "factors/pose_block.h"
#include "factors/position_prior_factor.h"
#include "factors/yaw_prior_factor.h"
#include "tests/factors/factor_test_util.h"

namespace waymark {
namespace {

constexpr double kSizeM = 0.2;
constexpr double kSigmaPx = 0.5;
constexpr double kDeg = M_PI / 180.0;
constexpr int kNumMarkers = 5;
constexpr int kNumPoses = 20;

// Five markers on the wall x = 3 m, facing -x (towards the robot), upright, slightly tilted.
std::vector<SE3d> WallMarkers(std::mt19937& rng) {
  Eigen::Matrix3d R_facing;  // marker x = world -y, y = world z, z = world -x
  R_facing << 0, 0, -1, -1, 0, 0, 0, 1, 0;
  std::vector<SE3d> markers;
  for (int i = 0; i < kNumMarkers; ++i) {
    const Eigen::Vector3d t_world(3.0, -1.0 + 0.5 * i, 0.35 + 0.1 * (i % 3));
    markers.emplace_back(Eigen::Quaterniond(R_facing) * ExpSO3(testing::RandomVector(rng, 0.15)), t_world);
  }
  return markers;
}

// A detection as the sim would emit it: every corner in front, inside the image, face towards
// the camera within 70 degrees; corners with Gaussian noise.
struct Observation {
  int pose;
  int marker;
  std::array<Eigen::Vector2d, 4> corners_px;
};

std::vector<Observation> Observe(const CameraInfo& camera, const std::vector<SE3d>& T_world_robots,
                                 const std::vector<SE3d>& T_world_markers, std::mt19937& rng) {
  std::normal_distribution<double> noise(0.0, kSigmaPx);
  std::vector<Observation> observations;
  for (int k = 0; k < static_cast<int>(T_world_robots.size()); ++k) {
    const SE3d T_camera_world = (T_world_robots[k] * camera.T_robot_camera).inverse();
    for (int m = 0; m < static_cast<int>(T_world_markers.size()); ++m) {
      const SE3d T_camera_marker = T_camera_world * T_world_markers[m];
      const Eigen::Vector3d normal_camera = T_camera_marker.rotation() * Eigen::Vector3d::UnitZ();
      if (normal_camera.dot(-T_camera_marker.translation().normalized()) < std::cos(70 * kDeg)) continue;
      Observation observation{k, m, {}};
      if (!testing::ProjectCorners(camera, T_camera_marker, kSizeM, &observation.corners_px)) continue;
      bool inside = true;
      for (Eigen::Vector2d& corner : observation.corners_px) {
        inside = inside && camera.InImage(corner);
        corner += Eigen::Vector2d(noise(rng), noise(rng));
      }
      if (inside) observations.push_back(observation);
    }
  }
  return observations;
}

// Largest rotation (deg) and translation (m) error over a set of estimates.
struct MaxError {
  double rotation_deg = 0.0;
  double translation_m = 0.0;
  void Add(const SE3d& estimate, const SE3d& truth) {
    rotation_deg = std::max(rotation_deg, RotationAngleBetween(estimate, truth) / kDeg);
    translation_m = std::max(translation_m, (estimate.translation() - truth.translation()).norm());
  }
};

// Normalized estimation error squared of an SE(3) block, e^T Sigma^-1 e with e = est.BoxMinus(truth)
// (truth = est * Exp(e)) and Sigma the block's covariance from ceres::Covariance, converted from
// the manifold's tangent to geometry.h's by ManifoldToBodyTangentJacobian. Its mean is 6 when the
// whitening of every factor matches the noise and the conversion is right.
double NeesSE3(ceres::Covariance& covariance, const double* block, const SE3d& truth) {
  Eigen::Matrix<double, 6, 6, Eigen::RowMajor> covariance_manifold;
  EXPECT_TRUE(covariance.GetCovarianceBlockInTangentSpace(block, block, covariance_manifold.data()));
  const SE3d estimate = SE3FromBlock(block);
  const Matrix6d J = ManifoldToBodyTangentJacobian(estimate);
  const Matrix6d covariance_body = J * covariance_manifold * J.transpose();
  const Vector6d error = estimate.BoxMinus(truth);
  return error.dot(covariance_body.ldlt().solve(error));
}

// The same for an SE(2) block [x y theta], whose tangent is the block itself.
double NeesSE2(ceres::Covariance& covariance, const double* block, const SE2d& truth) {
  Eigen::Matrix<double, 3, 3, Eigen::RowMajor> covariance_block;
  EXPECT_TRUE(covariance.GetCovarianceBlock(block, block, covariance_block.data()));
  const Eigen::Vector3d error(truth.x() - block[0], truth.y() - block[1],
                              WrapAngle(truth.theta() - block[2]));
  return error.dot(covariance_block.ldlt().solve(error));
}

std::unique_ptr<ceres::Covariance> ComputeCovariance(ceres::Problem* problem,
                                                     const std::vector<const double*>& blocks) {
  ceres::Covariance::Options options;
  options.algorithm_type = ceres::DENSE_SVD;
  auto covariance = std::make_unique<ceres::Covariance>(options);
  std::vector<std::pair<const double*, const double*>> pairs;
  for (const double* block : blocks) pairs.emplace_back(block, block);
  EXPECT_TRUE(covariance->Compute(pairs, problem));
  return covariance;
}

// Mean NEES per degree of freedom over markers first_marker.. (the others are constant) and all
// robot poses, from one ceres::Covariance of the solved problem.
template <typename RobotBlock, typename RobotTruth>
double MeanNeesPerDof(ceres::Problem* problem, const std::vector<std::array<double, 7>>& marker_blocks,
                      const std::vector<SE3d>& T_world_markers, const std::vector<RobotBlock>& robot_blocks,
                      const std::vector<RobotTruth>& T_world_robots, int first_marker) {
  std::vector<const double*> blocks;
  for (size_t m = first_marker; m < marker_blocks.size(); ++m) blocks.push_back(marker_blocks[m].data());
  for (const RobotBlock& block : robot_blocks) blocks.push_back(block.data());
  const std::unique_ptr<ceres::Covariance> covariance = ComputeCovariance(problem, blocks);
  double nees_sum = 0.0, dof = 0.0;
  for (size_t m = first_marker; m < marker_blocks.size(); ++m) {
    nees_sum += NeesSE3(*covariance, marker_blocks[m].data(), T_world_markers[m]);
    dof += 6.0;
  }
  for (size_t k = 0; k < robot_blocks.size(); ++k) {
    if constexpr (std::is_same_v<RobotTruth, SE2d>) {
      nees_sum += NeesSE2(*covariance, robot_blocks[k].data(), T_world_robots[k]);
      dof += 3.0;
    } else {
      nees_sum += NeesSE3(*covariance, robot_blocks[k].data(), T_world_robots[k]);
      dof += 6.0;
    }
  }
  return nees_sum / dof;
}

ceres::Solver::Summary Solve(ceres::Problem* problem) {
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::SPARSE_SCHUR;
  options.max_num_iterations = 100;
  options.function_tolerance = 1e-12;
  options.num_threads = 1;
  ceres::Solver::Summary summary;
  ceres::Solve(options, problem, &summary);
  return summary;
}

// A drone-like path: 1.5 m forward and 1.2 m sideways at varying height, heading, roll and pitch.
std::vector<SE3d> DronePath() {
  std::vector<SE3d> T_world_robots;
  for (int k = 0; k < kNumPoses; ++k) {
    const double s = k / (kNumPoses - 1.0);
    const Eigen::Vector3d t(1.5 * s, 0.6 - 1.2 * s, 0.2 * std::sin(3 * s));
    const double yaw_rad = 0.7 * std::atan2(-t.y(), 3.0 - t.x());  // roughly towards the wall's middle
    const Eigen::Vector3d rotation_vector(0.05 * std::sin(5 * s), 0.08 * std::cos(4 * s), yaw_rad);
    T_world_robots.emplace_back(ExpSO3(rotation_vector), t);
  }
  return T_world_robots;
}

// A planar robot weaving towards the wall while turning from +23 to -23 degrees.
std::vector<SE2d> PlanarPath() {
  std::vector<SE2d> T_world_robots;
  for (int k = 0; k < kNumPoses; ++k) {
    const double s = k / (kNumPoses - 1.0);
    T_world_robots.emplace_back(0.8 + 1.2 * s, 0.8 - 1.6 * s + 0.3 * std::sin(4 * s), 0.4 - 0.8 * s);
  }
  return T_world_robots;
}

// Odometry between consecutive poses: the true increment with noise drawn from the covariance
// OdometryCovarianceSE3 gives for odometry_sigma {0.02, 0.02}.
void AddOdometrySE3(const std::vector<SE3d>& T_world_robots, std::vector<std::array<double, 7>>* robot_blocks,
                    std::mt19937& rng, ceres::Problem* problem) {
  std::normal_distribution<double> unit(0.0, 1.0);
  for (size_t k = 0; k + 1 < T_world_robots.size(); ++k) {
    const SE3d T_a_b = T_world_robots[k].inverse() * T_world_robots[k + 1];
    const Matrix6d covariance = OdometryCovarianceSE3(OdometrySigma{0.02, 0.02}, T_a_b);
    Vector6d noise;
    for (int i = 0; i < 6; ++i) noise[i] = std::sqrt(covariance(i, i)) * unit(rng);
    problem->AddResidualBlock(OdometrySE3Factor::Create(T_a_b.BoxPlus(-noise), covariance), nullptr,
                              (*robot_blocks)[k].data(), (*robot_blocks)[k + 1].data());
  }
}

// The same in SE(2).
void AddOdometrySE2(const std::vector<SE2d>& T_world_robots, std::vector<std::array<double, 3>>* robot_blocks,
                    std::mt19937& rng, ceres::Problem* problem) {
  std::normal_distribution<double> unit(0.0, 1.0);
  for (size_t k = 0; k + 1 < T_world_robots.size(); ++k) {
    const SE2d T_a_b = T_world_robots[k].inverse() * T_world_robots[k + 1];
    const Eigen::Matrix3d covariance = OdometryCovarianceSE2(OdometrySigma{0.02, 0.02}, T_a_b);
    const SE2d noisy =
        T_a_b * SE2d(std::sqrt(covariance(0, 0)) * unit(rng), std::sqrt(covariance(1, 1)) * unit(rng),
                     std::sqrt(covariance(2, 2)) * unit(rng));
    problem->AddResidualBlock(OdometrySE2Factor::Create(noisy, covariance), nullptr,
                              (*robot_blocks)[k].data(), (*robot_blocks)[k + 1].data());
  }
}

// Payload coordinates (x, y of markers 0, 2, 4, printed to 1 cm, so 5 mm noise) and a printed
// yaw on marker 2 (0.5 deg off, sigma 1 deg).
void AddPayloadPriors(const std::vector<SE3d>& T_world_markers,
                      std::vector<std::array<double, 7>>* marker_blocks, std::mt19937& rng,
                      ceres::Problem* problem) {
  std::normal_distribution<double> payload_noise(0.0, 0.005);
  for (int m : {0, 2, 4}) {
    const Eigen::Vector2d p_world =
        T_world_markers[m].translation().head<2>() + Eigen::Vector2d(payload_noise(rng), payload_noise(rng));
    problem->AddResidualBlock(PositionPriorXYFactor::Create(p_world, 0.005), nullptr,
                              (*marker_blocks)[m].data());
  }
  problem->AddResidualBlock(YawPriorFactor::Create(T_world_markers[2].yaw() + 0.5 * kDeg, 1.0 * kDeg),
                            nullptr, (*marker_blocks)[2].data());
}

// Prints the figures of a solve and its NEES for the record (the test log).
void Report(const char* name, size_t num_observations, const ceres::Solver::Summary& summary,
            const MaxError& marker_error, const MaxError& robot_error, double mean_nees_per_dof) {
  std::printf(
      "%s: %zu observations, cost %.3g -> %.3g in %d iterations; max marker error %.3f deg %.4f m, "
      "max robot error %.3f deg %.4f m; mean NEES per degree of freedom %.3f\n",
      name, num_observations, summary.initial_cost, summary.final_cost,
      static_cast<int>(summary.iterations.size()), marker_error.rotation_deg, marker_error.translation_m,
      robot_error.rotation_deg, robot_error.translation_m, mean_nees_per_dof);
}

// Expected 1 for a consistent estimate; the blocks are correlated, so one run varies widely
// (0.25-2.1 over 16 seeds tried while writing the test). A whitening off by a factor 2 would
// move it by 4x.
void ExpectConsistentNees(double mean_nees_per_dof) {
  EXPECT_GT(mean_nees_per_dof, 0.1);
  EXPECT_LT(mean_nees_per_dof, 3.0);
}

TEST(Solve, FreeRobotWithOneAnchor) {
  std::mt19937 rng(2026);
  const CameraInfo camera = testing::TestCamera(CameraModel::kPinholeRadtan);
  const std::vector<SE3d> T_world_markers = WallMarkers(rng);
  const std::vector<SE3d> T_world_robots = DronePath();
  const std::vector<Observation> observations = Observe(camera, T_world_robots, T_world_markers, rng);
  ASSERT_GE(observations.size(), 50u);

  std::vector<std::array<double, 7>> robot_blocks(kNumPoses), marker_blocks(kNumMarkers);
  const auto perturbation = [&rng] {
    return (Vector6d() << testing::RandomVector(rng, 0.1), testing::RandomVector(rng, 0.1)).finished();
  };
  for (int k = 0; k < kNumPoses; ++k)
    SE3ToBlock(T_world_robots[k].BoxPlus(perturbation()), robot_blocks[k].data());
  for (int m = 0; m < kNumMarkers; ++m)
    SE3ToBlock(T_world_markers[m].BoxPlus(perturbation()), marker_blocks[m].data());
  SE3ToBlock(T_world_markers[0], marker_blocks[0].data());

  ceres::Problem problem;
  for (const Observation& o : observations) {
    problem.AddResidualBlock(MarkerReprojectionFactor::Create(camera, kSizeM, o.corners_px, kSigmaPx),
                             nullptr, robot_blocks[o.pose].data(), marker_blocks[o.marker].data());
  }
  AddOdometrySE3(T_world_robots, &robot_blocks, rng, &problem);
  for (auto* blocks : {&robot_blocks, &marker_blocks}) {
    for (auto& block : *blocks) problem.SetManifold(block.data(), new SE3Manifold);
  }
  // The gauge: marker 0 is an anchor (known pose, as in markers.json), held constant. Without it
  // the whole scene could move rigidly at no cost.
  problem.SetParameterBlockConstant(marker_blocks[0].data());

  const ceres::Solver::Summary summary = Solve(&problem);
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.FullReport();
  MaxError marker_error, robot_error;
  for (int m = 0; m < kNumMarkers; ++m)
    marker_error.Add(SE3FromBlock(marker_blocks[m].data()), T_world_markers[m]);
  for (int k = 0; k < kNumPoses; ++k)
    robot_error.Add(SE3FromBlock(robot_blocks[k].data()), T_world_robots[k]);
  // The bounds hold for 16 seeds tried while writing the test (worst: markers 1.9 deg, 5.4 cm;
  // robot 1.5 deg, 7.6 cm): one 20 cm anchor seen from 2-3 m leaves the scene's rotation about
  // it weakly determined, and the NEES below shows these errors are the ones the covariance
  // predicts, not a bias. The initial values were off by up to 10 deg and 17 cm.
  EXPECT_LT(marker_error.rotation_deg, 2.5);
  EXPECT_LT(marker_error.translation_m, 0.07);
  EXPECT_LT(robot_error.rotation_deg, 2.0);
  EXPECT_LT(robot_error.translation_m, 0.10);

  const double mean_nees_per_dof = MeanNeesPerDof(&problem, marker_blocks, T_world_markers, robot_blocks,
                                                  T_world_robots, /*first_marker=*/1);
  Report("free", observations.size(), summary, marker_error, robot_error, mean_nees_per_dof);
  ExpectConsistentNees(mean_nees_per_dof);
}

TEST(Solve, PlanarRobotWithPayloadPriors) {
  std::mt19937 rng(2027);
  const CameraInfo camera = testing::TestCamera(CameraModel::kPinholeEquidistant);
  const std::vector<SE3d> T_world_markers = WallMarkers(rng);
  const std::vector<SE2d> T_world_robots_2d = PlanarPath();
  std::vector<SE3d> T_world_robots;
  for (const SE2d& T_world_robot : T_world_robots_2d) T_world_robots.push_back(T_world_robot.ToSE3());
  const std::vector<Observation> observations = Observe(camera, T_world_robots, T_world_markers, rng);
  ASSERT_GE(observations.size(), 50u);

  std::vector<std::array<double, 3>> robot_blocks(kNumPoses);
  std::vector<std::array<double, 7>> marker_blocks(kNumMarkers);
  std::uniform_real_distribution<double> u(-0.1, 0.1);
  for (int k = 0; k < kNumPoses; ++k) {
    SE2ToBlock(T_world_robots_2d[k] * SE2d(u(rng), u(rng), u(rng)), robot_blocks[k].data());
  }
  for (int m = 0; m < kNumMarkers; ++m) {
    const Vector6d perturbation =
        (Vector6d() << testing::RandomVector(rng, 0.1), testing::RandomVector(rng, 0.1)).finished();
    SE3ToBlock(T_world_markers[m].BoxPlus(perturbation), marker_blocks[m].data());
  }

  ceres::Problem problem;
  for (const Observation& o : observations) {
    problem.AddResidualBlock(PlanarMarkerReprojectionFactor::Create(camera, kSizeM, o.corners_px, kSigmaPx),
                             nullptr, robot_blocks[o.pose].data(), marker_blocks[o.marker].data());
  }
  AddOdometrySE2(T_world_robots_2d, &robot_blocks, rng, &problem);
  for (auto& block : marker_blocks) problem.SetManifold(block.data(), new SE3Manifold);
  // The gauge of a planar survey: the floor fixes z, roll and pitch; the payload priors fix x, y
  // and the heading.
  AddPayloadPriors(T_world_markers, &marker_blocks, rng, &problem);

  const ceres::Solver::Summary summary = Solve(&problem);
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.FullReport();
  MaxError marker_error, robot_error;
  for (int m = 0; m < kNumMarkers; ++m)
    marker_error.Add(SE3FromBlock(marker_blocks[m].data()), T_world_markers[m]);
  for (int k = 0; k < kNumPoses; ++k)
    robot_error.Add(SE2FromBlock(robot_blocks[k].data()).ToSE3(), T_world_robots[k]);
  // 16 seeds tried while writing the test: worst markers 1.4 deg, 0.9 cm; robot 0.33 deg, 1.4 cm.
  EXPECT_LT(marker_error.rotation_deg, 2.0);
  EXPECT_LT(marker_error.translation_m, 0.015);
  EXPECT_LT(robot_error.rotation_deg, 0.5);
  EXPECT_LT(robot_error.translation_m, 0.02);

  const double mean_nees_per_dof = MeanNeesPerDof(&problem, marker_blocks, T_world_markers, robot_blocks,
                                                  T_world_robots_2d, /*first_marker=*/0);
  Report("planar", observations.size(), summary, marker_error, robot_error, mean_nees_per_dof);
  ExpectConsistentNees(mean_nees_per_dof);
}

}  // namespace
}  // namespace waymark
