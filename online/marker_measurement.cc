#include "online/marker_measurement.h"

namespace waymark {
namespace {

// Rows of a world-position Jacobian (3 x n) and a world-rotation Jacobian (3 x n) that make
// up the state: [x y (z)] and yaw.
Eigen::MatrixXd ToStateRows(const Eigen::Matrix<double, 3, 6>& d_position,
                            const Eigen::Matrix<double, 3, 6>& d_phi, const Eigen::Matrix3d& R_world_robot,
                            MotionModel motion) {
  const int dim = StateDim(motion);
  Eigen::MatrixXd J(dim, 6);
  J.topRows(dim - 1) = d_position.topRows(dim - 1);
  J.row(dim - 1) = YawJacobianWorld(R_world_robot) * d_phi;
  return J;
}

}  // namespace

CodeRobotPose RobotPoseFromCode(const MapMarker& marker, const SE3d& T_camera_marker,
                                const Matrix6d& covariance_camera_marker, const SE3d& T_robot_camera,
                                MotionModel motion) {
  const SE3d T_marker_robot = T_camera_marker.inverse() * T_robot_camera.inverse();
  CodeRobotPose out;
  out.T_world_robot = marker.T_world_marker * T_marker_robot;
  const Eigen::Matrix3d R_wm = marker.T_world_marker.rotation_matrix();
  const Eigen::Matrix3d R_wm_hat_t = R_wm * Hat(T_marker_robot.translation());
  const Eigen::Matrix3d R_wr = out.T_world_robot.rotation_matrix();

  Eigen::Matrix<double, 3, 6> d_position, d_phi;
  d_position << R_wm_hat_t, -R_wm;
  d_phi << -R_wm, Eigen::Matrix3d::Zero();
  const Eigen::MatrixXd J_code = ToStateRows(d_position, d_phi, R_wr, motion);
  out.covariance = J_code * covariance_camera_marker * J_code.transpose();
  out.cross_marker = CrossCovariance::Zero(StateDim(motion), 6);
  if (marker.covariance) {
    d_position << -R_wm_hat_t, R_wm;
    d_phi << R_wm, Eigen::Matrix3d::Zero();
    const Eigen::MatrixXd J_map = ToStateRows(d_position, d_phi, R_wr, motion);
    out.covariance += J_map * (*marker.covariance) * J_map.transpose();
    out.cross_marker = J_map * (*marker.covariance);
  }
  return out;
}

Eigen::Matrix3d CodeAttitudeCovariance(const MapMarker& marker, const Matrix6d& covariance_camera_marker) {
  const Eigen::Matrix3d R_wm = marker.T_world_marker.rotation_matrix();
  Eigen::Matrix3d sigma_rr = covariance_camera_marker.topLeftCorner<3, 3>();
  if (marker.covariance) sigma_rr += marker.covariance->topLeftCorner<3, 3>();
  return R_wm * sigma_rr * R_wm.transpose();
}

Eigen::VectorXd LooseInnovation(const EkfState& state, const SE3d& T_world_robot_measured) {
  return EkfState::BoxMinus(state.mean(), PoseToStateVector(T_world_robot_measured, state.motion()),
                            state.yaw_index());
}

std::optional<CornerPrediction> PredictCorners(const EkfState& state, const Camera& camera,
                                               const MapMarker& marker) {
  const SE3d T_world_robot = state.T_world_robot();
  const Eigen::Matrix3d R_wr_T = T_world_robot.rotation_matrix().transpose();
  const SE3d T_camera_robot = camera.info().T_robot_camera.inverse();
  const Eigen::Matrix3d R_cr = T_camera_robot.rotation_matrix();
  const Eigen::Matrix3d R_wm = marker.T_world_marker.rotation_matrix();
  const int dim = state.dim();
  const std::array<Eigen::Vector3d, 4> corners_marker = MarkerCorners(marker.size_m);

  CornerPrediction out;
  out.H.resize(8, dim);
  for (int j = 0; j < 4; ++j) {
    const Eigen::Vector3d corner_world = marker.T_world_marker * corners_marker[j];
    const Eigen::Vector3d offset_world = corner_world - T_world_robot.translation();
    const Eigen::Vector3d corner_camera = T_camera_robot * (R_wr_T * offset_world);
    Eigen::Matrix<double, 2, 3> J_p;
    const std::optional<Eigen::Vector2d> px = camera.Project(corner_camera, &J_p);
    if (!px) return std::nullopt;
    out.px.segment<2>(2 * j) = *px;
    const Eigen::Matrix<double, 2, 3> J_robot = J_p * R_cr;  // d px / d c_r
    out.H.block(2 * j, 0, 2, dim - 1) = -(J_robot * R_wr_T).leftCols(dim - 1);
    out.H.block<2, 1>(2 * j, dim - 1) =
        -J_robot * R_wr_T * Hat(Eigen::Vector3d::UnitZ().eval()) * offset_world;
    const Eigen::Matrix<double, 2, 3> J_world = J_robot * R_wr_T;  // d px / d c_w
    out.J_marker.block<2, 3>(2 * j, 0) = -J_world * R_wm * Hat(corners_marker[j]);
    out.J_marker.block<2, 3>(2 * j, 3) = J_world * R_wm;
    out.J_attitude.block<2, 3>(2 * j, 0) = J_world * Hat(offset_world);
  }
  return out;
}

Matrix8d CornerNoise(double sigma_px, const CornerPrediction& prediction,
                     const std::optional<Matrix6d>& covariance,
                     const std::optional<Eigen::Matrix3d>& attitude_covariance) {
  Matrix8d R = Matrix8d::Identity() * (sigma_px * sigma_px);
  if (covariance) R += prediction.J_marker * (*covariance) * prediction.J_marker.transpose();
  if (attitude_covariance)
    R += prediction.J_attitude * (*attitude_covariance) * prediction.J_attitude.transpose();
  return R;
}

Vector8d StackCorners(const std::array<Eigen::Vector2d, 4>& corners_px) {
  Vector8d z;
  for (int j = 0; j < 4; ++j) z.segment<2>(2 * j) = corners_px[j];
  return z;
}

}  // namespace waymark
