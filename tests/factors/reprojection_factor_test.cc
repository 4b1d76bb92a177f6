// Tests of the three marker-corner reprojection factors: hand-computed residuals, zero at the
// truth for both camera models, the penalty behind the camera, bad input, and Jacobians against
// ceres::GradientChecker under SE3Manifold at ten random states per factor and camera model.
#include <gtest/gtest.h>

#include <array>
#include <memory>
#include <random>
#include <stdexcept>
#include <vector>

#include "factors/extrinsic_marker_reprojection_factor.h"
#include "factors/marker_reprojection_factor.h"
#include "factors/planar_marker_reprojection_factor.h"
#include "factors/pose_block.h"
#include "tests/factors/factor_test_util.h"

namespace waymark {
namespace {

using testing::kNaN;

constexpr double kSizeM = 0.2;
constexpr double kSigmaPx = 0.5;

// Undistorted pinhole, f = 500 px, principal point (320, 240), camera at the robot origin looking
// along robot +x.
CameraInfo SimpleCamera() {
  CameraInfo camera;
  camera.name = "simple";
  camera.model = CameraModel::kPinholeRadtan;
  camera.width = 640;
  camera.height = 480;
  camera.intrinsics = {500.0, 500.0, 320.0, 240.0};
  camera.distortion = {0.0, 0.0, 0.0, 0.0, 0.0};
  camera.T_robot_camera = SE3d(testing::ForwardCameraRotation(0.0), Eigen::Vector3d::Zero());
  return camera;
}

// A 0.2 m marker 2 m ahead of the identity robot, facing it, upright: marker x = world -y,
// y = world z, z = world -x. In the camera its corners are (+-0.1, -+0.1, 2), so at f = 500 the
// corners are 25 px from the centre: TL (295, 215), TR (345, 215), BR (345, 265), BL (295, 265).
SE3d MarkerAheadOfIdentityRobot() {
  Eigen::Matrix3d R_world_marker;
  R_world_marker << 0, 0, -1, -1, 0, 0, 0, 1, 0;
  return SE3d(R_world_marker, Eigen::Vector3d(2.0, 0.0, 0.0));
}

// The hand-computed corners, with the top-left one moved by (+1, -2) px: the expected whitened
// residual is ((295 - 296) / 0.5, (215 - 213) / 0.5) = (-2, 4) there and zero elsewhere.
std::array<Eigen::Vector2d, 4> ObservedCorners() {
  return {Eigen::Vector2d(296, 213), Eigen::Vector2d(345, 215), Eigen::Vector2d(345, 265),
          Eigen::Vector2d(295, 265)};
}

void ExpectHandComputed(const std::array<double, 8>& residuals) {
  const std::array<double, 8> expected = {-2.0, 4.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
  for (int i = 0; i < 8; ++i) EXPECT_NEAR(residuals[i], expected[i], 1e-9) << "residual " << i;
}

TEST(MarkerReprojectionFactor, NominalHandComputed) {
  const std::unique_ptr<ceres::CostFunction> cost(
      MarkerReprojectionFactor::Create(SimpleCamera(), kSizeM, ObservedCorners(), kSigmaPx));
  double robot[7], marker[7];
  SE3ToBlock(SE3d(), robot);
  SE3ToBlock(MarkerAheadOfIdentityRobot(), marker);
  const double* parameters[] = {robot, marker};
  std::array<double, 8> residuals;
  residuals.fill(kNaN);
  ASSERT_TRUE(cost->Evaluate(parameters, residuals.data(), nullptr));
  ExpectHandComputed(residuals);
}

TEST(PlanarMarkerReprojectionFactor, NominalHandComputed) {
  // The same view from a robot at (0, -2) heading +y, camera 0.3 m up: rotate the scene by
  // +90 degrees about z and lift it by 0.3 m.
  CameraInfo camera = SimpleCamera();
  camera.T_robot_camera = SE3d(camera.T_robot_camera.rotation(), Eigen::Vector3d(0.0, 0.0, 0.3));
  const SE3d T_world_robot = SE2d(0.0, -2.0, M_PI / 2).ToSE3();
  const SE3d T_world_marker = T_world_robot *
                              SE3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, 0.3)) *
                              MarkerAheadOfIdentityRobot();
  const std::unique_ptr<ceres::CostFunction> cost(
      PlanarMarkerReprojectionFactor::Create(camera, kSizeM, ObservedCorners(), kSigmaPx));
  double robot[3] = {0.0, -2.0, M_PI / 2 + 2 * M_PI};  // an unwrapped angle is the same pose
  double marker[7];
  SE3ToBlock(T_world_marker, marker);
  const double* parameters[] = {robot, marker};
  std::array<double, 8> residuals;
  residuals.fill(kNaN);
  ASSERT_TRUE(cost->Evaluate(parameters, residuals.data(), nullptr));
  ExpectHandComputed(residuals);
}

TEST(ExtrinsicMarkerReprojectionFactor, NominalHandComputedUsesTheBlockNotTheYaml) {
  CameraInfo camera = SimpleCamera();
  const SE3d T_robot_camera = camera.T_robot_camera;
  camera.T_robot_camera = SE3d(ExpSO3(Eigen::Vector3d(0.3, 0.2, 0.1)), Eigen::Vector3d(1, 2, 3));  // ignored
  const std::unique_ptr<ceres::CostFunction> cost(
      ExtrinsicMarkerReprojectionFactor::Create(camera, kSizeM, ObservedCorners(), kSigmaPx));
  double robot[7], extrinsic[7], marker[7];
  SE3ToBlock(SE3d(), robot);
  SE3ToBlock(T_robot_camera, extrinsic);
  SE3ToBlock(MarkerAheadOfIdentityRobot(), marker);
  const double* parameters[] = {robot, extrinsic, marker};
  std::array<double, 8> residuals;
  residuals.fill(kNaN);
  ASSERT_TRUE(cost->Evaluate(parameters, residuals.data(), nullptr));
  ExpectHandComputed(residuals);
}

class ReprojectionByModel : public ::testing::TestWithParam<CameraModel> {};

// Random robot and a marker visible from its camera; corners projected exactly, or with noise.
struct Scene {
  SE3d T_world_robot;
  SE3d T_world_marker;
  std::array<Eigen::Vector2d, 4> corners_px;
};

Scene RandomScene(const CameraInfo& camera, const SE3d& T_world_robot, double noise_px, std::mt19937& rng) {
  Scene scene;
  scene.T_world_robot = T_world_robot;
  const SE3d T_camera_marker = testing::RandomVisibleMarker(rng);
  scene.T_world_marker = T_world_robot * camera.T_robot_camera * T_camera_marker;
  EXPECT_TRUE(testing::ProjectCorners(camera, T_camera_marker, kSizeM, &scene.corners_px));
  std::normal_distribution<double> noise(0.0, noise_px);
  for (Eigen::Vector2d& corner : scene.corners_px) corner += Eigen::Vector2d(noise(rng), noise(rng));
  return scene;
}

TEST_P(ReprojectionByModel, ZeroAtTheTruth) {
  const CameraInfo camera = testing::TestCamera(GetParam());
  std::mt19937 rng(11);
  for (int trial = 0; trial < 10; ++trial) {
    const SE2d T_world_robot_2d(rng() % 7 - 3.0, rng() % 5 - 2.0, (rng() % 628) / 100.0);
    const Scene scene = RandomScene(camera, T_world_robot_2d.ToSE3(), 0.0, rng);
    double robot_2d[3], robot[7], extrinsic[7], marker[7];
    SE2ToBlock(T_world_robot_2d, robot_2d);
    SE3ToBlock(scene.T_world_robot, robot);
    SE3ToBlock(camera.T_robot_camera, extrinsic);
    SE3ToBlock(scene.T_world_marker, marker);
    const std::unique_ptr<ceres::CostFunction> free_cost(
        MarkerReprojectionFactor::Create(camera, kSizeM, scene.corners_px, kSigmaPx));
    const std::unique_ptr<ceres::CostFunction> planar_cost(
        PlanarMarkerReprojectionFactor::Create(camera, kSizeM, scene.corners_px, kSigmaPx));
    const std::unique_ptr<ceres::CostFunction> extrinsic_cost(
        ExtrinsicMarkerReprojectionFactor::Create(camera, kSizeM, scene.corners_px, kSigmaPx));
    const double* free_parameters[] = {robot, marker};
    const double* planar_parameters[] = {robot_2d, marker};
    const std::unique_ptr<ceres::CostFunction> planar_extrinsic_cost(
        PlanarExtrinsicMarkerReprojectionFactor::Create(camera, kSizeM, scene.corners_px, kSigmaPx));
    const double* extrinsic_parameters[] = {robot, extrinsic, marker};
    const double* planar_extrinsic_parameters[] = {robot_2d, extrinsic, marker};
    for (auto [cost, parameters] :
         {std::pair{free_cost.get(), free_parameters}, std::pair{planar_cost.get(), planar_parameters},
          std::pair{extrinsic_cost.get(), extrinsic_parameters},
          std::pair{planar_extrinsic_cost.get(), planar_extrinsic_parameters}}) {
      Eigen::Matrix<double, 8, 1> residuals = Eigen::Matrix<double, 8, 1>::Constant(kNaN);
      ASSERT_TRUE(cost->Evaluate(parameters, residuals.data(), nullptr));
      EXPECT_LT(residuals.cwiseAbs().maxCoeff(), 1e-6) << "trial " << trial;
    }
  }
}

TEST_P(ReprojectionByModel, GradientCheckTenRandomStates) {
  const CameraInfo camera = testing::TestCamera(GetParam());
  const SE3Manifold se3;
  std::mt19937 rng(12);
  std::uniform_real_distribution<double> coordinate(-5.0, 5.0), angle(-M_PI, M_PI);
  for (int trial = 0; trial < 10; ++trial) {
    // Free robot: any orientation; planar robot: (x, y, theta) lifted at z = 0.
    const Scene scene = RandomScene(camera, testing::RandomSE3(rng, 5.0), 2.0, rng);
    double robot[7], extrinsic[7], marker[7];
    SE3ToBlock(scene.T_world_robot, robot);
    SE3ToBlock(camera.T_robot_camera, extrinsic);
    SE3ToBlock(scene.T_world_marker, marker);
    const std::unique_ptr<ceres::CostFunction> free_cost(
        MarkerReprojectionFactor::Create(camera, kSizeM, scene.corners_px, kSigmaPx));
    testing::ExpectGradientsMatch(*free_cost, {&se3, &se3}, {robot, marker}, 1e-6, "free");
    const std::unique_ptr<ceres::CostFunction> extrinsic_cost(
        ExtrinsicMarkerReprojectionFactor::Create(camera, kSizeM, scene.corners_px, kSigmaPx));
    testing::ExpectGradientsMatch(*extrinsic_cost, {&se3, &se3, &se3}, {robot, extrinsic, marker}, 1e-6,
                                  "extrinsic");

    const SE2d T_world_robot_2d(coordinate(rng), coordinate(rng), angle(rng));
    const Scene planar_scene = RandomScene(camera, T_world_robot_2d.ToSE3(), 2.0, rng);
    double robot_2d[3];
    SE2ToBlock(T_world_robot_2d, robot_2d);
    SE3ToBlock(planar_scene.T_world_marker, marker);
    const std::unique_ptr<ceres::CostFunction> planar_cost(
        PlanarMarkerReprojectionFactor::Create(camera, kSizeM, planar_scene.corners_px, kSigmaPx));
    testing::ExpectGradientsMatch(*planar_cost, {nullptr, &se3}, {robot_2d, marker}, 1e-6, "planar");
    const std::unique_ptr<ceres::CostFunction> planar_extrinsic_cost(
        PlanarExtrinsicMarkerReprojectionFactor::Create(camera, kSizeM, planar_scene.corners_px, kSigmaPx));
    testing::ExpectGradientsMatch(*planar_extrinsic_cost, {nullptr, &se3, &se3},
                                  {robot_2d, extrinsic, marker}, 1e-6, "planar extrinsic");
    // A frame's camera deviation off the mount (frame_wiggle_sigma): a small random pose.
    double wiggle[7];
    Vector6d small;
    small << 0.004, -0.006, 0.002, 0.005, -0.003, 0.008;
    SE3ToBlock(SE3d::Exp(small * (trial + 1) / 10.0), wiggle);
    const std::unique_ptr<ceres::CostFunction> planar_wiggle_cost(
        WiggleMarkerReprojectionFactor<true>::Create(camera, kSizeM, planar_scene.corners_px, kSigmaPx));
    testing::ExpectGradientsMatch(*planar_wiggle_cost, {nullptr, &se3, &se3, &se3},
                                  {robot_2d, extrinsic, wiggle, marker}, 1e-6, "planar wiggle");
    SE3ToBlock(scene.T_world_robot, robot);
    SE3ToBlock(scene.T_world_marker, marker);
    const std::unique_ptr<ceres::CostFunction> wiggle_cost(
        WiggleMarkerReprojectionFactor<false>::Create(camera, kSizeM, scene.corners_px, kSigmaPx));
    testing::ExpectGradientsMatch(*wiggle_cost, {&se3, &se3, &se3, &se3}, {robot, extrinsic, wiggle, marker},
                                  1e-6, "wiggle");
  }
}

// With the identity deviation the wiggle factor is the extrinsic one.
TEST(WiggleMarkerReprojectionFactor, IdentityWiggleEqualsTheExtrinsicFactor) {
  const CameraInfo camera = SimpleCamera();
  double robot[7], extrinsic[7], wiggle[7], marker[7];
  SE3ToBlock(SE3d(), robot);
  SE3ToBlock(camera.T_robot_camera, extrinsic);
  SE3ToBlock(SE3d(), wiggle);
  SE3ToBlock(MarkerAheadOfIdentityRobot(), marker);
  const std::unique_ptr<ceres::CostFunction> cost(
      WiggleMarkerReprojectionFactor<false>::Create(camera, kSizeM, ObservedCorners(), kSigmaPx));
  const double* parameters[] = {robot, extrinsic, wiggle, marker};
  std::array<double, 8> residuals;
  residuals.fill(kNaN);
  ASSERT_TRUE(cost->Evaluate(parameters, residuals.data(), nullptr));
  ExpectHandComputed(residuals);
}

// Squared norm of the factor's residuals with the marker at T_camera_marker (identity robot).
double SquaredResidual(const ceres::CostFunction& cost, const CameraInfo& camera,
                       const SE3d& T_camera_marker) {
  double robot[7], marker[7];
  SE3ToBlock(SE3d(), robot);
  SE3ToBlock(camera.T_robot_camera * T_camera_marker, marker);
  const double* parameters[] = {robot, marker};
  std::array<double, 8> residuals;
  residuals.fill(kNaN);
  EXPECT_TRUE(cost.Evaluate(parameters, residuals.data(), nullptr));
  double sum = 0.0;
  for (double r : residuals) {
    EXPECT_TRUE(std::isfinite(r));
    sum += r * r;
  }
  return sum;
}

// Behind the camera the projection is continued linearly (factors/corner_observation.h): the
// residuals stay finite, grow the further the marker moves behind, are continuous across the
// switch depth, and their Jacobians still match numeric differences there.
TEST_P(ReprojectionByModel, BehindTheCameraGivesAFiniteGrowingPenalty) {
  const CameraInfo camera = testing::TestCamera(GetParam());
  std::array<Eigen::Vector2d, 4> corners_px;  // the marker 2 m ahead, observed exactly
  ASSERT_TRUE(testing::ProjectCorners(
      camera, SE3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.05, 0.02, 2.0)), kSizeM, &corners_px));
  const std::unique_ptr<ceres::CostFunction> cost(
      MarkerReprojectionFactor::Create(camera, kSizeM, corners_px, kSigmaPx));
  const auto at_depth = [&](double z_m) {
    return SquaredResidual(*cost, camera,
                           SE3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.05, 0.02, z_m)));
  };
  EXPECT_LT(at_depth(2.0), 1e-12);
  // Whitened squared error of the marker 0.3 and 0.6 m behind: over 100 px per corner, growing.
  const double behind_near = at_depth(-0.3), behind_far = at_depth(-0.6);
  EXPECT_GT(behind_near, 8.0 * std::pow(100.0 / kSigmaPx, 2));
  EXPECT_GT(behind_far, behind_near);
  // A marker straddling the camera plane (corners at z = 0.05 -+ 0.1 m) is finite too, and the
  // residuals are continuous where a fronto-parallel marker's corners cross kPenaltyDepthM.
  const SE3d tilted_up(Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitY())),
                       Eigen::Vector3d(0.0, 0.0, 0.05));
  const double straddling = SquaredResidual(*cost, camera, tilted_up);
  EXPECT_TRUE(std::isfinite(straddling));
  const double above = at_depth(kPenaltyDepthM + 1e-9), below = at_depth(kPenaltyDepthM - 1e-9);
  EXPECT_NEAR(above, below, 1e-6 * above);
  // Gradients at states with corners behind the camera and straddling it.
  SE3Manifold se3;
  // (Generic rotations: at symmetric states some derivatives are exactly zero, where the
  // checker's relative error compares rounding noise.)
  const Eigen::Quaterniond generic(Eigen::AngleAxisd(0.3, Eigen::Vector3d(1.0, 2.0, 3.0).normalized()));
  for (const SE3d& T_camera_marker : {SE3d(generic, Eigen::Vector3d(0.05, 0.02, -0.3)),
                                      SE3d(generic * tilted_up.rotation(), tilted_up.translation())}) {
    double robot[7], marker[7];
    SE3ToBlock(SE3d(), robot);
    SE3ToBlock(camera.T_robot_camera * T_camera_marker, marker);
    testing::ExpectGradientsMatch(*cost, {&se3, &se3}, {robot, marker}, 1e-6, "behind the camera");
  }
  // A non-finite pose is still refused, residuals untouched.
  double robot[7], marker[7];
  SE3ToBlock(SE3d(), robot);
  SE3ToBlock(camera.T_robot_camera, marker);
  marker[6] = kNaN;
  const double* parameters[] = {robot, marker};
  std::array<double, 8> residuals;
  residuals.fill(kNaN);
  EXPECT_FALSE(cost->Evaluate(parameters, residuals.data(), nullptr));
}

INSTANTIATE_TEST_SUITE_P(BothModels, ReprojectionByModel,
                         ::testing::Values(CameraModel::kPinholeRadtan, CameraModel::kPinholeEquidistant),
                         [](const ::testing::TestParamInfo<CameraModel>& info) {
                           return info.param == CameraModel::kPinholeRadtan ? "Radtan" : "Equidistant";
                         });

TEST(MarkerReprojectionFactor, RejectsBadInput) {
  const CameraInfo camera = SimpleCamera();
  const std::array<Eigen::Vector2d, 4> corners = ObservedCorners();
  EXPECT_THROW(MarkerReprojectionFactor(camera, 0.0, corners, kSigmaPx), std::invalid_argument);
  EXPECT_THROW(MarkerReprojectionFactor(camera, kNaN, corners, kSigmaPx), std::invalid_argument);
  EXPECT_THROW(MarkerReprojectionFactor(camera, kSizeM, corners, 0.0), std::invalid_argument);
  EXPECT_THROW(MarkerReprojectionFactor(camera, kSizeM, corners, -1.0), std::invalid_argument);
  std::array<Eigen::Vector2d, 4> nan_corners = corners;
  nan_corners[2].y() = kNaN;
  EXPECT_THROW(MarkerReprojectionFactor(camera, kSizeM, nan_corners, kSigmaPx), std::invalid_argument);
  CameraInfo short_distortion = camera;
  short_distortion.distortion.pop_back();
  EXPECT_THROW(PlanarMarkerReprojectionFactor(short_distortion, kSizeM, corners, kSigmaPx),
               std::invalid_argument);
  CameraInfo equidistant_with_radtan = camera;
  equidistant_with_radtan.model = CameraModel::kPinholeEquidistant;  // needs 4 coefficients, has 5
  EXPECT_THROW(ExtrinsicMarkerReprojectionFactor(equidistant_with_radtan, kSizeM, corners, kSigmaPx),
               std::invalid_argument);
  CameraInfo zero_focal = camera;
  zero_focal.intrinsics[1] = 0.0;
  EXPECT_THROW(MarkerReprojectionFactor(zero_focal, kSizeM, corners, kSigmaPx), std::invalid_argument);
  try {
    MarkerReprojectionFactor(short_distortion, kSizeM, corners, kSigmaPx);
    ADD_FAILURE() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "corner reprojection (camera simple): expected 5 distortion coefficients, got 4");
  }
}

}  // namespace
}  // namespace waymark
