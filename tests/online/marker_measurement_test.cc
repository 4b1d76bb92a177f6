#include "online/marker_measurement.h"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>

#include "tests/online/jacobian_check.h"
#include "tests/online/synthetic_corridor.h"

namespace waymark {
namespace {

using testing::NumericJacobian;

Eigen::VectorXd WrapLast(Eigen::VectorXd v) {
  v(v.size() - 1) = WrapAngle(v(v.size() - 1));
  return v;
}

MapMarker LeftWallMarker() {
  testing::CorridorConfig config;
  MapMarker marker = testing::CorridorMap(config).markers[2];  // x = 1.5 on the left wall
  return marker;
}

Matrix6d SomeMarkerCovariance() {
  Eigen::Matrix<double, 6, 6> A = Eigen::Matrix<double, 6, 6>::Random();
  return 1e-4 * (A * A.transpose() + Matrix6d::Identity());
}

TEST(MarkerMeasurementTest, YawJacobianWorldMatchesCentralDifferences) {
  const Eigen::Matrix3d R =
      (Eigen::AngleAxisd(2.5, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()) *
       Eigen::AngleAxisd(-0.4, Eigen::Vector3d::UnitX()))
          .toRotationMatrix();
  const auto yaw = [&](const Eigen::VectorXd& phi) -> Eigen::VectorXd {
    const Eigen::Matrix3d Rp = ExpSO3(phi).toRotationMatrix() * R;
    return Eigen::VectorXd::Constant(1, std::atan2(Rp(1, 0), Rp(0, 0)));
  };
  EXPECT_LT((YawJacobianWorld(R) - NumericJacobian(yaw, Eigen::Vector3d::Zero())).norm(), 1e-8);
}

// H of the tightly coupled update against central differences, planar and free.
TEST(MarkerMeasurementTest, CornerJacobiansMatchCentralDifferences) {
  const Camera camera(testing::SideCamera("left", true, 0.3));
  const MapMarker marker = LeftWallMarker();
  for (MotionModel motion : {MotionModel::kPlanar, MotionModel::kFree}) {
    EkfState state(motion);
    const Eigen::VectorXd x = motion == MotionModel::kPlanar
                                  ? Eigen::VectorXd(Eigen::Vector3d(1.4, 0.05, 0.1))
                                  : Eigen::VectorXd(Eigen::Vector4d(1.4, 0.05, 0.02, 0.1));
    state.SetLevel((Eigen::AngleAxisd(0.05, Eigen::Vector3d::UnitY()) *
                    Eigen::AngleAxisd(-0.03, Eigen::Vector3d::UnitX()))
                       .toRotationMatrix());
    ASSERT_EQ(state.Reset(x, Eigen::MatrixXd::Identity(x.size(), x.size())), StepStatus::kOk);
    const std::optional<CornerPrediction> prediction = PredictCorners(state, camera, marker);
    ASSERT_TRUE(prediction);
    for (int j = 0; j < 4; ++j) EXPECT_TRUE(camera.info().InImage(prediction->px.segment<2>(2 * j)));
    const auto h_x = [&](const Eigen::VectorXd& xx) -> Eigen::VectorXd {
      EkfState perturbed = state;
      EXPECT_EQ(perturbed.Reset(xx, state.covariance()), StepStatus::kOk);
      return PredictCorners(perturbed, camera, marker)->px;
    };
    const auto h_marker = [&](const Eigen::VectorXd& eps) -> Eigen::VectorXd {
      MapMarker perturbed = marker;
      perturbed.T_world_marker = marker.T_world_marker.BoxPlus(eps);
      return PredictCorners(state, camera, perturbed)->px;
    };
    const Eigen::MatrixXd H_numeric = NumericJacobian(h_x, x, 1e-6);
    EXPECT_LT((prediction->H - H_numeric).norm(), 1e-5 * H_numeric.norm()) << "motion " << int(motion);
    const Eigen::MatrixXd J_numeric = NumericJacobian(h_marker, Vector6d::Zero(), 1e-6);
    EXPECT_LT((prediction->J_marker - J_numeric).norm(), 1e-5 * J_numeric.norm());
  }
}

// The covariance of the robot pose a code implies: first-order propagation checked against
// central differences of the composition in both the single-image pose and the map pose.
TEST(MarkerMeasurementTest, RobotPoseFromCodeCovarianceMatchesCentralDifferences) {
  const CameraInfo info = testing::SideCamera("left", true, 0.3);
  MapMarker marker = LeftWallMarker();
  const SE3d T_world_robot = SE3d::FromXYZYaw(1.4, 0.05, 0.0, 0.1);
  const SE3d T_camera_marker = (T_world_robot * info.T_robot_camera).inverse() * marker.T_world_marker;
  for (MotionModel motion : {MotionModel::kPlanar, MotionModel::kFree}) {
    const Eigen::VectorXd x0 = PoseToStateVector(T_world_robot, motion);
    const auto f_code = [&](const Eigen::VectorXd& delta) -> Eigen::VectorXd {
      const SE3d T =
          marker.T_world_marker * T_camera_marker.BoxPlus(delta).inverse() * info.T_robot_camera.inverse();
      return PoseToStateVector(T, motion);
    };
    const auto f_map = [&](const Eigen::VectorXd& eps) -> Eigen::VectorXd {
      const SE3d T =
          marker.T_world_marker.BoxPlus(eps) * T_camera_marker.inverse() * info.T_robot_camera.inverse();
      return PoseToStateVector(T, motion);
    };
    const Eigen::MatrixXd J_code = NumericJacobian(f_code, Vector6d::Zero(), 1e-6, WrapLast);
    const Eigen::MatrixXd J_map = NumericJacobian(f_map, Vector6d::Zero(), 1e-6, WrapLast);
    const Matrix6d Sigma_code = SomeMarkerCovariance();
    marker.covariance = SomeMarkerCovariance();
    const CodeRobotPose code =
        RobotPoseFromCode(marker, T_camera_marker, Sigma_code, info.T_robot_camera, motion);
    EXPECT_LT((PoseToStateVector(code.T_world_robot, motion) - x0).norm(), 1e-12);
    const Eigen::MatrixXd expected =
        J_code * Sigma_code * J_code.transpose() + J_map * (*marker.covariance) * J_map.transpose();
    EXPECT_LT((code.covariance - expected).norm(), 1e-7 * expected.norm()) << "motion " << int(motion);
  }
}

TEST(MarkerMeasurementTest, MapCovarianceInflatesCornerNoise) {
  const Camera camera(testing::SideCamera("left", true, 0.3));
  const MapMarker marker = LeftWallMarker();
  EkfState state(MotionModel::kPlanar);
  ASSERT_EQ(state.Reset(Eigen::Vector3d(1.4, 0.0, 0.0), Eigen::Matrix3d::Identity() * 1e-4), StepStatus::kOk);
  const CornerPrediction prediction = *PredictCorners(state, camera, marker);
  const Matrix8d R_exact = CornerNoise(0.5, prediction, std::nullopt);
  EXPECT_EQ(R_exact, Matrix8d::Identity() * 0.25);
  Matrix6d Sigma = Matrix6d::Zero();
  Sigma.diagonal() << 1e-4, 1e-4, 1e-4, 4e-4, 4e-4, 4e-4;  // 0.6 deg, 2 cm
  const Matrix8d R_uncertain = CornerNoise(0.5, prediction, Sigma);
  // R_uncertain - R_exact is J Sigma J^T: positive semi-definite and large (a 2 cm error at 0.4 m is ~25 px).
  const Eigen::SelfAdjointEigenSolver<Matrix8d> eigen(R_uncertain - R_exact);
  EXPECT_GT(eigen.eigenvalues().minCoeff(), -1e-9);
  EXPECT_GT(eigen.eigenvalues().maxCoeff(), 100.0);
}

// J_attitude (d px / d phi, R_true = Exp(phi) R_world_robot) against central differences of
// the projection, and the attitude part of R.
TEST(MarkerMeasurementTest, AttitudeJacobianAndNoiseMatchCentralDifferences) {
  const Camera camera(testing::SideCamera("left", true, 0.3));
  const MapMarker marker = LeftWallMarker();
  EkfState state(MotionModel::kFree);
  state.SetLevel(
      (Eigen::AngleAxisd(0.05, Eigen::Vector3d::UnitY()) * Eigen::AngleAxisd(-0.03, Eigen::Vector3d::UnitX()))
          .toRotationMatrix());
  ASSERT_EQ(state.Reset(Eigen::Vector4d(1.4, 0.05, 0.02, 0.1), Eigen::Matrix4d::Identity()), StepStatus::kOk);
  const std::optional<CornerPrediction> prediction = PredictCorners(state, camera, marker);
  ASSERT_TRUE(prediction);
  const SE3d T_world_robot = state.T_world_robot();
  const SE3d T_camera_robot = camera.info().T_robot_camera.inverse();
  const auto h_phi = [&](const Eigen::VectorXd& phi) -> Eigen::VectorXd {
    const SE3d T_perturbed(Eigen::Quaterniond(ExpSO3(Eigen::Vector3d(phi)) * T_world_robot.rotation()),
                           T_world_robot.translation());
    Vector8d px;
    const std::array<Eigen::Vector3d, 4> corners = MarkerCorners(marker.size_m);
    for (int j = 0; j < 4; ++j) {
      px.segment<2>(2 * j) =
          *camera.Project(T_camera_robot * (T_perturbed.inverse() * (marker.T_world_marker * corners[j])));
    }
    return px;
  };
  const Eigen::MatrixXd J_numeric = NumericJacobian(h_phi, Eigen::Vector3d::Zero(), 1e-6);
  EXPECT_LT((prediction->J_attitude - J_numeric).norm(), 1e-5 * J_numeric.norm());
  const Eigen::Matrix3d attitude_covariance = Eigen::Vector3d(1e-6, 4e-6, 0.0).asDiagonal();
  const Matrix8d R = CornerNoise(0.5, *prediction, std::nullopt, attitude_covariance);
  const Matrix8d expected =
      0.25 * Matrix8d::Identity() + J_numeric * attitude_covariance * J_numeric.transpose();
  EXPECT_LT((R - expected).norm(), 1e-6 * expected.norm());
}

TEST(MarkerMeasurementTest, CodeAttitudeCovarianceIsTheRotationBlocksInTheWorldFrame) {
  MapMarker marker = LeftWallMarker();
  const Matrix6d code = SomeMarkerCovariance();
  const Eigen::Matrix3d R_wm = marker.T_world_marker.rotation_matrix();
  EXPECT_LT(
      (CodeAttitudeCovariance(marker, code) - R_wm * code.topLeftCorner<3, 3>() * R_wm.transpose()).norm(),
      1e-15);
  const Matrix6d map = SomeMarkerCovariance();
  marker.covariance = map;
  const Eigen::Matrix3d both = R_wm * (code + map).topLeftCorner<3, 3>() * R_wm.transpose();
  EXPECT_LT((CodeAttitudeCovariance(marker, code) - both).norm(), 1e-15);
}

}  // namespace
}  // namespace waymark
