#include "geometry/robot_pnp.h"

#include <algorithm>
#include <cmath>
#include <optional>

#include "geometry/types.h"

namespace waymark {
namespace {

using Residuals8 = Eigen::Matrix<double, 8, 1>;
using Jacobian86 = Eigen::Matrix<double, 8, 6>;

// Whitened residuals of one view for T_world_robot and dr/d[dr, dt] (right perturbation of
// T_world_robot); false if a corner does not project.
bool PnpResiduals(const PnpView& view, const SE3d& T_world_robot, Residuals8* r, Jacobian86* J) {
  const SE3d& T_robot_camera = view.camera->info().T_robot_camera;
  const SE3d T_robot_marker = T_world_robot.inverse() * view.T_world_marker;
  const SE3d T_camera_robot = T_robot_camera.inverse();
  const Eigen::Matrix3d R_camera_robot = T_camera_robot.rotation_matrix();
  const std::array<Eigen::Vector3d, 4> corners_marker = MarkerCorners(view.size_m);
  for (int k = 0; k < 4; ++k) {
    const Eigen::Vector3d p_robot = T_robot_marker * corners_marker[k];
    Eigen::Matrix<double, 2, 3> J_px_p;
    const std::optional<Eigen::Vector2d> px = view.camera->Project(T_camera_robot * p_robot, &J_px_p);
    if (!px) return false;
    r->segment<2>(2 * k) = (*px - (*view.corners_px)[k]) / view.sigma_px;
    J->block<2, 3>(2 * k, 0) = J_px_p * R_camera_robot * Hat(p_robot) / view.sigma_px;
    J->block<2, 3>(2 * k, 3) = -J_px_p * R_camera_robot / view.sigma_px;
  }
  return true;
}

struct PnpNormal {
  Matrix6d H = Matrix6d::Zero();
  Vector6d g = Vector6d::Zero();
  double robust_cost = 0.0;
  bool ok = true;  // every view projects
};

PnpNormal LinearizePnp(const std::vector<const PnpView*>& views, const SE3d& T, double cauchy_scale) {
  const double c2 = cauchy_scale * cauchy_scale;
  PnpNormal n;
  Residuals8 r;
  Jacobian86 J;
  for (const PnpView* view : views) {
    if (!PnpResiduals(*view, T, &r, &J)) {
      n.ok = false;
      return n;
    }
    const double s = r.squaredNorm();
    const double w = 1.0 / (1.0 + s / c2);
    n.H += w * J.transpose() * J;
    n.g += w * J.transpose() * r;
    n.robust_cost += c2 * std::log1p(s / c2);
  }
  return n;
}

// The free directions of the right perturbation [dr, dt]: all six, or dr_z, dt_x, dt_y.
Eigen::Matrix<double, 6, Eigen::Dynamic> FreeDirections(bool planar) {
  if (!planar) return Matrix6d::Identity();
  Eigen::Matrix<double, 6, 3> S = Eigen::Matrix<double, 6, 3>::Zero();
  S(2, 0) = S(3, 1) = S(4, 2) = 1.0;
  return S;
}

}  // namespace

SE3d RefineRobotPose(const std::vector<PnpView>& views, const SE3d& start, bool planar, double cauchy_scale,
                     int max_iterations) {
  const auto flatten = [planar](const SE3d& T) { return planar ? SE2d::FromSE3(T).ToSE3() : T; };
  SE3d T = flatten(start);
  std::vector<const PnpView*> active;
  Residuals8 r;
  Jacobian86 J;
  for (const PnpView& view : views) {
    if (PnpResiduals(view, T, &r, &J)) active.push_back(&view);
  }
  if (active.empty()) return T;
  const Eigen::Matrix<double, 6, Eigen::Dynamic> S = FreeDirections(planar);
  PnpNormal n = LinearizePnp(active, T, cauchy_scale);
  double lambda = 1e-4;
  for (int iteration = 0; iteration < max_iterations; ++iteration) {
    const Eigen::MatrixXd H = S.transpose() * n.H * S;
    Eigen::MatrixXd A = H;
    A.diagonal() += lambda * H.diagonal() + Eigen::VectorXd::Constant(H.rows(), 1e-12);
    const Vector6d delta = S * A.ldlt().solve(-S.transpose() * n.g);
    const SE3d T_new = flatten(T.BoxPlus(delta));
    const PnpNormal n_new = LinearizePnp(active, T_new, cauchy_scale);
    if (delta.allFinite() && n_new.ok && n_new.robust_cost < n.robust_cost) {
      const double decrease = n.robust_cost - n_new.robust_cost;
      T = T_new;
      n = n_new;
      lambda = std::max(lambda * 0.1, 1e-10);
      if (decrease < 1e-10 * (1.0 + n.robust_cost) || delta.norm() < 1e-12) break;
    } else {
      lambda *= 10.0;
      if (lambda > 1e8) break;
    }
  }
  return T.IsFinite() ? T : flatten(start);
}

std::vector<std::optional<double>> RobotPnpErrors(const std::vector<PnpView>& views,
                                                  const SE3d& T_world_robot, Matrix6d* information) {
  std::vector<std::optional<double>> errors;
  errors.reserve(views.size());
  Matrix6d H = Matrix6d::Zero();
  Residuals8 r;
  Jacobian86 J;
  for (const PnpView& view : views) {
    if (!PnpResiduals(view, T_world_robot, &r, &J)) {
      errors.emplace_back();
      continue;
    }
    errors.emplace_back(r.squaredNorm());
    H += J.transpose() * J;
  }
  if (information != nullptr) *information = H;
  return errors;
}

}  // namespace waymark
