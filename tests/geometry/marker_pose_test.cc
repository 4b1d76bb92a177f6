// Tests of geometry/marker_pose.h: exact recovery from noiseless corners (both camera models),
// Monte-Carlo agreement of the predicted covariance with the empirical one, the planar
// ambiguity flag, and every rejection of bad input.
#include "geometry/marker_pose.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <random>
#include <vector>

#include "tests/test_cameras.h"

namespace waymark {
namespace {

using Corners = std::array<Eigen::Vector2d, 4>;

// tagslam-test16 cam0 (radtan) and tagslam-test22 cam0 (fisheye), from /work/shared/data.
Camera RadtanCamera() { return Camera(testing::TagslamRadtanInfo()); }

Camera FisheyeCamera() { return Camera(testing::TagslamFisheyeInfo()); }

// A code at p_camera whose face looks back at the camera, then rotated about its own
// x axis by tilt_x, its y axis by tilt_y and its z axis by spin (radians).
SE3d CodePose(const Eigen::Vector3d& p_camera, double tilt_x, double tilt_y, double spin) {
  const Eigen::Matrix3d R_frontal = Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal();
  const Eigen::Matrix3d R = R_frontal *
                            Eigen::AngleAxisd(tilt_x, Eigen::Vector3d::UnitX()).toRotationMatrix() *
                            Eigen::AngleAxisd(tilt_y, Eigen::Vector3d::UnitY()).toRotationMatrix() *
                            Eigen::AngleAxisd(spin, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return SE3d(R, p_camera);
}

Corners ProjectCorners(const Camera& camera, const SE3d& T_camera_marker, double size_m) {
  Corners corners_px;
  const auto corners_marker = MarkerCorners(size_m);
  // The printed face is towards the camera: its normal points back along the line of sight.
  EXPECT_LT((T_camera_marker.rotation_matrix().col(2)).dot(T_camera_marker.translation()), 0.0);
  for (int k = 0; k < 4; ++k) {
    const auto px = camera.Project(T_camera_marker * corners_marker[k]);
    EXPECT_TRUE(px.has_value());
    EXPECT_TRUE(camera.info().InImage(*px)) << px->transpose();
    corners_px[k] = *px;
  }
  return corners_px;
}

Corners AddNoise(Corners corners_px, double sigma_px, std::mt19937& rng) {
  std::normal_distribution<double> noise(0.0, sigma_px);
  for (auto& c : corners_px) c += Eigen::Vector2d(noise(rng), noise(rng));
  return corners_px;
}

void ExpectExactRecovery(const Camera& camera, const SE3d& T_true, double size_m) {
  const MarkerPoseEstimate estimate =
      EstimateMarkerPose(ProjectCorners(camera, T_true, size_m), size_m, camera);
  ASSERT_FALSE(estimate.solutions.empty());
  const SE3d& T = estimate.best().T_camera_marker;
  EXPECT_LE(RotationAngleBetween(T, T_true), 1e-8) << T_true.translation().transpose();
  EXPECT_LE((T.translation() - T_true.translation()).norm(), 1e-9) << T_true.translation().transpose();
  EXPECT_LE(estimate.best().rms_px, 1e-7);
}

TEST(MarkerPoseTest, ExactRecoveryRadtan) {
  const Camera camera = RadtanCamera();
  ExpectExactRecovery(camera, CodePose({0.0, 0.0, 1.0}, 0.3, -0.2, 0.1), 0.16);
  ExpectExactRecovery(camera, CodePose({0.25, -0.2, 0.8}, -0.5, 0.4, 2.0), 0.10);
  ExpectExactRecovery(camera, CodePose({-0.2, 0.15, 0.6}, 0.9, 0.0, -1.0), 0.08);  // near the image corner
  ExpectExactRecovery(camera, CodePose({0.5, 0.0, 3.0}, 0.0, 1.0, 3.0), 0.20);
}

TEST(MarkerPoseTest, ExactRecoveryFisheye) {
  const Camera camera = FisheyeCamera();
  ExpectExactRecovery(camera, CodePose({0.0, 0.0, 0.8}, 0.3, -0.2, 0.1), 0.16);
  ExpectExactRecovery(camera, CodePose({0.6, -0.3, 0.5}, 0.3, -0.6, 2.0), 0.10);  // ~55 deg off-axis
  ExpectExactRecovery(camera, CodePose({-1.0, 0.6, 1.2}, 0.2, -0.7, -1.0), 0.42);
}

// Predicted covariance (at the noiseless corners) against the empirical covariance of
// estimates from noisy corners, in the right-perturbation tangent space of the truth.
void ExpectCovarianceMatchesMonteCarlo(const Camera& camera, const SE3d& T_true, double size_m,
                                       unsigned seed) {
  constexpr double kSigmaPx = 0.5;
  constexpr int kDraws = 1000;
  MarkerPoseOptions options;
  options.sigma_px = kSigmaPx;
  const Corners corners_px = ProjectCorners(camera, T_true, size_m);
  const Matrix6d predicted = EstimateMarkerPose(corners_px, size_m, camera, options).covariance;
  std::mt19937 rng(seed);
  std::vector<Vector6d> deltas;
  Vector6d mean = Vector6d::Zero();
  for (int i = 0; i < kDraws; ++i) {
    const MarkerPoseEstimate estimate =
        EstimateMarkerPose(AddNoise(corners_px, kSigmaPx, rng), size_m, camera, options);
    ASSERT_LE(RotationAngleBetween(estimate.best().T_camera_marker, T_true), 0.1)
        << "picked the mirrored pose";
    deltas.push_back(T_true.BoxMinus(estimate.best().T_camera_marker));
    mean += deltas.back() / kDraws;
  }
  Matrix6d empirical = Matrix6d::Zero();
  for (const Vector6d& d : deltas) empirical += (d - mean) * (d - mean).transpose() / (kDraws - 1);
  for (int k = 0; k < 6; ++k) {
    const double ratio = empirical(k, k) / predicted(k, k);
    EXPECT_GT(ratio, 0.8) << "axis " << k << " empirical " << empirical(k, k) << " predicted "
                          << predicted(k, k);
    EXPECT_LT(ratio, 1.25) << "axis " << k << " empirical " << empirical(k, k) << " predicted "
                           << predicted(k, k);
    // The mean error is small next to the spread (no gross bias).
    EXPECT_LT(std::abs(mean(k)), 0.2 * std::sqrt(predicted(k, k))) << "axis " << k;
  }
}

TEST(MarkerPoseTest, CovarianceMatchesMonteCarloRadtan) {
  ExpectCovarianceMatchesMonteCarlo(RadtanCamera(), CodePose({0.1, -0.05, 0.6}, 0.6, -0.3, 0.4), 0.16, 21);
}

TEST(MarkerPoseTest, CovarianceMatchesMonteCarloFisheye) {
  ExpectCovarianceMatchesMonteCarlo(FisheyeCamera(), CodePose({0.2, 0.1, 0.4}, -0.5, 0.4, 1.0), 0.16, 22);
}

TEST(MarkerPoseTest, CovarianceIsSymmetricPositiveDefiniteAndScalesWithSigmaSquared) {
  const Camera camera = RadtanCamera();
  const Corners corners_px = ProjectCorners(camera, CodePose({0.0, 0.1, 1.0}, 0.4, 0.2, 0.0), 0.16);
  MarkerPoseOptions options;
  options.sigma_px = 0.5;
  const Matrix6d c_half = EstimateMarkerPose(corners_px, 0.16, camera, options).covariance;
  options.sigma_px = 1.0;
  const Matrix6d c_one = EstimateMarkerPose(corners_px, 0.16, camera, options).covariance;
  EXPECT_LE((c_half - c_half.transpose()).norm(), 0.0);
  EXPECT_GT(Eigen::SelfAdjointEigenSolver<Matrix6d>(c_half).eigenvalues().minCoeff(), 0.0);
  EXPECT_LE((c_one - 4.0 * c_half).norm(), 1e-9 * c_one.norm());
  // Without options.sigma_px the camera's pixel_sigma is used.
  CameraInfo info = camera.info();
  info.pixel_sigma = 1.0;
  const Matrix6d c_camera = EstimateMarkerPose(corners_px, 0.16, Camera(info)).covariance;
  EXPECT_LE((c_camera - c_one).norm(), 1e-9 * c_one.norm());
}

TEST(MarkerPoseTest, SmallFarFrontalCodeIsAmbiguous) {
  const Camera camera = RadtanCamera();
  const SE3d T_true = CodePose({0.1, 0.05, 4.0}, 0.05, 0.03, 0.2);  // 5 cm code at 4 m: ~19 px
  const Corners corners_px = ProjectCorners(camera, T_true, 0.05);
  const MarkerPoseEstimate noiseless = EstimateMarkerPose(corners_px, 0.05, camera);
  ASSERT_EQ(noiseless.solutions.size(), 2u);
  EXPECT_TRUE(noiseless.ambiguous) << "ratio " << noiseless.error_ratio;
  std::mt19937 rng(31);
  const MarkerPoseEstimate noisy = EstimateMarkerPose(AddNoise(corners_px, 0.5, rng), 0.05, camera);
  EXPECT_TRUE(noisy.ambiguous) << "ratio " << noisy.error_ratio;
  EXPECT_LE(noisy.solutions[1].rms_px, 1.0);  // the mirrored pose also fits within the noise
}

TEST(MarkerPoseTest, CloseObliqueCodeIsNotAmbiguous) {
  const Camera camera = RadtanCamera();
  const SE3d T_true = CodePose({0.05, 0.0, 0.5}, 0.8, 0.0, 0.3);  // 16 cm code at 0.5 m, 46 deg tilt
  const Corners corners_px = ProjectCorners(camera, T_true, 0.16);
  std::mt19937 rng(32);
  for (const Corners& corners : {corners_px, AddNoise(corners_px, 0.5, rng)}) {
    const MarkerPoseEstimate estimate = EstimateMarkerPose(corners, 0.16, camera);
    ASSERT_EQ(estimate.solutions.size(), 2u);
    EXPECT_FALSE(estimate.ambiguous) << "ratio " << estimate.error_ratio;
    EXPECT_GT(estimate.solutions[1].rms_px, 5.0);
    EXPECT_LE(RotationAngleBetween(estimate.best().T_camera_marker, T_true), 0.02);
    // The second solution is the mirrored one: clearly another orientation.
    EXPECT_GT(RotationAngleBetween(estimate.solutions[1].T_camera_marker, T_true), 0.3);
  }
}

TEST(MarkerPoseTest, ReprojectionRmsIsPerCornerEuclidean) {
  const Camera camera = RadtanCamera();
  const SE3d T = CodePose({0.0, 0.0, 1.0}, 0.2, 0.1, 0.0);
  Corners corners_px = ProjectCorners(camera, T, 0.16);
  EXPECT_LE(MarkerReprojectionRms(corners_px, 0.16, camera, T), 1e-9);
  for (auto& c : corners_px) c += Eigen::Vector2d(3.0, 4.0);
  EXPECT_NEAR(MarkerReprojectionRms(corners_px, 0.16, camera, T), 5.0, 1e-9);
  const SE3d behind = CodePose({0.0, 0.0, -1.0}, 0.0, 0.0, 0.0);
  EXPECT_TRUE(std::isinf(MarkerReprojectionRms(corners_px, 0.16, camera, behind)));
}

TEST(MarkerPoseTest, BadInputIsRejectedWithAClearError) {
  using ::testing::HasSubstr;
  const Camera camera = RadtanCamera();
  const Corners good = ProjectCorners(camera, CodePose({0.0, 0.0, 1.0}, 0.2, 0.1, 0.0), 0.16);
  const auto expect_error = [&](const Corners& corners, double size_m, const MarkerPoseOptions& options,
                                const std::string& text, const Camera& cam) {
    try {
      EstimateMarkerPose(corners, size_m, cam, options);
      ADD_FAILURE() << "expected an error containing `" << text << "`";
    } catch (const std::runtime_error& e) {
      EXPECT_THAT(e.what(), HasSubstr(text));
    }
  };
  Corners bad = good;
  bad[2].x() = std::nan("");
  expect_error(bad, 0.16, {}, "corner 2 is not finite", camera);
  expect_error(good, 0.0, {}, "size_m", camera);
  expect_error(good, std::nan(""), {}, "size_m", camera);
  // Collinear along a line through the principal point (radial distortion keeps it a line).
  bad = {Eigen::Vector2d(641.176, 524.495), Eigen::Vector2d(691.176, 554.495),
         Eigen::Vector2d(741.176, 584.495), Eigen::Vector2d(791.176, 614.495)};
  expect_error(bad, 0.16, {}, "degenerate", camera);
  bad = {good[0], good[0], good[0], good[0]};
  expect_error(bad, 0.16, {}, "degenerate", camera);
  bad = {good[3], good[2], good[1], good[0]};
  expect_error(bad, 0.16, {}, "mirrored", camera);
  bad = {good[0], good[2], good[1], good[3]};
  expect_error(bad, 0.16, {}, "convex", camera);
  const Camera fisheye = FisheyeCamera();
  const Corners fisheye_good = ProjectCorners(fisheye, CodePose({0.0, 0.0, 1.0}, 0.2, 0.1, 0.0), 0.16);
  bad = fisheye_good;
  bad[1] = Eigen::Vector2d(0.0, 0.0);  // the image corner is beyond the fisheye's field of view
  expect_error(bad, 0.16, {}, "outside the field of view", fisheye);
  MarkerPoseOptions options;
  options.ambiguity_ratio = 0.5;
  expect_error(good, 0.16, options, "ambiguity_ratio", camera);
  options = {};
  options.sigma_px = -1.0;
  expect_error(good, 0.16, options, "sigma_px", camera);
  std::string why;
  EXPECT_TRUE(MarkerPoseOptions{}.Check(&why));
}

}  // namespace
}  // namespace waymark
