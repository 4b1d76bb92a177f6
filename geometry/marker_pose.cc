#include "geometry/marker_pose.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/calib3d.hpp>
#include <sstream>
#include <stdexcept>

#include "geometry/types.h"
#include "util/check.h"

namespace waymark {
namespace {

using Residuals8 = Eigen::Matrix<double, 8, 1>;
using Jacobian86 = Eigen::Matrix<double, 8, 6>;
using Corners2 = std::array<Eigen::Vector2d, 4>;

[[noreturn]] void Fail(const std::string& message) {
  throw std::runtime_error("EstimateMarkerPose: " + message);
}

std::string PointString(const Eigen::Vector2d& p) {
  std::ostringstream out;
  out << "(" << p.x() << ", " << p.y() << ")";
  return out.str();
}

// r_k = project(T_camera_marker * corner_marker_k) - corner_px_k and, if J is given,
// dr/d[dr, dt] for the right perturbation. False if a corner does not project.
bool ReprojectionResiduals(const Corners2& corners_px, const std::array<Eigen::Vector3d, 4>& corners_marker,
                           const Camera& camera, const SE3d& T_camera_marker, Residuals8* r, Jacobian86* J) {
  const Eigen::Matrix3d R = T_camera_marker.rotation_matrix();
  for (int k = 0; k < 4; ++k) {
    Eigen::Matrix<double, 2, 3> J_px_p;
    const std::optional<Eigen::Vector2d> px =
        camera.Project(T_camera_marker * corners_marker[k], J != nullptr ? &J_px_p : nullptr);
    if (!px) return false;
    r->segment<2>(2 * k) = *px - corners_px[k];
    if (J != nullptr) {
      J->block<2, 3>(2 * k, 0) = -J_px_p * R * Hat(corners_marker[k]);
      J->block<2, 3>(2 * k, 3) = J_px_p * R;
    }
  }
  return true;
}

double Rms(const Residuals8& r) { return std::sqrt(r.squaredNorm() / 4.0); }

// Levenberg-Marquardt on the reprojection error from T_start; nullopt if the start does
// not project.
std::optional<SE3d> RefinePose(const Corners2& corners_px,
                               const std::array<Eigen::Vector3d, 4>& corners_marker, const Camera& camera,
                               const SE3d& T_start, int max_iterations) {
  SE3d T = T_start;
  Residuals8 r;
  Jacobian86 J;
  if (!ReprojectionResiduals(corners_px, corners_marker, camera, T, &r, &J)) return std::nullopt;
  double cost = r.squaredNorm(), lambda = 1e-4;
  for (int iteration = 0; iteration < max_iterations && cost > 1e-26; ++iteration) {
    const Matrix6d H = J.transpose() * J;
    const Vector6d g = J.transpose() * r;
    Matrix6d A = H;
    A.diagonal() += lambda * H.diagonal();
    const Vector6d delta = A.ldlt().solve(-g);
    const SE3d T_new = T.BoxPlus(delta);
    Residuals8 r_new;
    Jacobian86 J_new;
    if (delta.allFinite() &&
        ReprojectionResiduals(corners_px, corners_marker, camera, T_new, &r_new, &J_new) &&
        r_new.squaredNorm() < cost) {
      const double decrease = cost - r_new.squaredNorm();
      T = T_new;
      r = r_new;
      J = J_new;
      cost = r.squaredNorm();
      lambda = std::max(lambda * 0.1, 1e-12);
      if (decrease <= 1e-14 * cost || delta.norm() < 1e-14) break;
    } else {
      lambda *= 10.0;
      if (lambda > 1e12) break;
    }
  }
  return T;
}

// Normalized (undistorted) coordinates of the corners, checked for a usable quad.
Corners2 NormalizedCorners(const Corners2& corners_px, const Camera& camera, double min_area_px2) {
  Corners2 corners_normalized;
  for (int k = 0; k < 4; ++k) {
    if (!corners_px[k].allFinite()) Fail("corner " + std::to_string(k) + " is not finite");
    const std::optional<Eigen::Vector3d> ray = camera.Unproject(corners_px[k]);
    if (!ray) {
      Fail("corner " + std::to_string(k) + " " + PointString(corners_px[k]) +
           " is outside the field of view of camera `" + camera.name() + "`");
    }
    corners_normalized[k] = ray->head<2>();
  }
  // Turn directions around the quad (positive: the upright face seen from the front) and area.
  int positive = 0, negative = 0;
  double twice_area = 0.0;
  for (int k = 0; k < 4; ++k) {
    const Eigen::Vector2d& a = corners_normalized[k];
    const Eigen::Vector2d& b = corners_normalized[(k + 1) % 4];
    const Eigen::Vector2d& c = corners_normalized[(k + 2) % 4];
    const Eigen::Vector2d ab = b - a, bc = c - b;
    const double turn = ab.x() * bc.y() - ab.y() * bc.x();
    (turn > 0.0 ? positive : negative) += 1;
    twice_area += a.x() * b.y() - b.x() * a.y();
  }
  const auto& k = camera.info().intrinsics;
  const double area_px2 = 0.5 * std::abs(twice_area) * k[0] * k[1];
  if (!(area_px2 >= min_area_px2)) {
    Fail("degenerate corners (area " + std::to_string(area_px2) + " px^2, expected at least " +
         std::to_string(min_area_px2) + ")");
  }
  if (negative == 4)
    Fail("corners are in mirrored order (expected top-left, top-right, bottom-right, bottom-left)");
  if (positive != 4) Fail("corners do not form a convex quadrilateral");
  return corners_normalized;
}

// IPPE candidates on normalized coordinates (camera matrix = identity, no distortion).
std::vector<SE3d> IppeCandidates(const Corners2& corners_normalized, double size_m) {
  std::vector<cv::Point3d> object_points;
  for (const Eigen::Vector3d& c : MarkerCorners(size_m)) object_points.emplace_back(c.x(), c.y(), c.z());
  std::vector<cv::Point2d> image_points;
  for (const Eigen::Vector2d& c : corners_normalized) image_points.emplace_back(c.x(), c.y());
  std::vector<cv::Mat> rvecs, tvecs;
  cv::solvePnPGeneric(object_points, image_points, cv::Matx33d::eye(), cv::noArray(), rvecs, tvecs, false,
                      cv::SOLVEPNP_IPPE_SQUARE);
  std::vector<SE3d> candidates;
  for (size_t i = 0; i < rvecs.size(); ++i) {
    cv::Matx33d R_cv;
    cv::Rodrigues(rvecs[i], R_cv);
    Eigen::Matrix3d R;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) R(r, c) = R_cv(r, c);
    }
    const cv::Vec3d t = tvecs[i];
    const SE3d T_camera_marker(R, Eigen::Vector3d(t[0], t[1], t[2]));
    if (T_camera_marker.IsFinite()) candidates.push_back(T_camera_marker);
  }
  return candidates;
}

double FlooredRatio(double rms_second, double rms_best, double floor_px) {
  return std::max(rms_second, floor_px) / std::max(rms_best, floor_px);
}

}  // namespace

bool MarkerPoseOptions::Check(std::string* why) const {
  WAYMARK_CHECK_OPTION(!sigma_px || IsFinitePositive(*sigma_px), "sigma_px: expected a number > 0");
  WAYMARK_CHECK_OPTION(IsFiniteAtLeast(ambiguity_ratio, 1.0), "ambiguity_ratio: expected >= 1");
  WAYMARK_CHECK_OPTION(IsFinitePositive(error_floor_px), "error_floor_px: expected > 0");
  WAYMARK_CHECK_OPTION(max_iterations >= 1, "max_iterations: expected >= 1");
  WAYMARK_CHECK_OPTION(IsFiniteAtLeast(min_area_px2, 0.0), "min_area_px2: expected >= 0");
  return true;
}

double MarkerReprojectionRms(const Corners2& corners_px, double size_m, const Camera& camera,
                             const SE3d& T_camera_marker) {
  Residuals8 r;
  if (!ReprojectionResiduals(corners_px, MarkerCorners(size_m), camera, T_camera_marker, &r, nullptr)) {
    return std::numeric_limits<double>::infinity();
  }
  return Rms(r);
}

MarkerPoseEstimate EstimateMarkerPose(const Corners2& corners_px, double size_m, const Camera& camera,
                                      const MarkerPoseOptions& options) {
  std::string why;
  if (!options.Check(&why)) Fail("options: " + why);
  if (!(std::isfinite(size_m) && size_m > 0.0))
    Fail("size_m: expected a number > 0, got " + std::to_string(size_m));
  const double sigma_px = options.sigma_px.value_or(camera.info().pixel_sigma.value_or(1.0));
  if (!(std::isfinite(sigma_px) && sigma_px > 0.0)) Fail("camera pixel_sigma: expected a number > 0");

  const Corners2 corners_normalized = NormalizedCorners(corners_px, camera, options.min_area_px2);
  const std::array<Eigen::Vector3d, 4> corners_marker = MarkerCorners(size_m);
  MarkerPoseEstimate estimate;
  for (const SE3d& T_start : IppeCandidates(corners_normalized, size_m)) {
    const std::optional<SE3d> T =
        RefinePose(corners_px, corners_marker, camera, T_start, options.max_iterations);
    if (!T) continue;
    estimate.solutions.push_back({*T, MarkerReprojectionRms(corners_px, size_m, camera, *T)});
  }
  if (estimate.solutions.empty()) Fail("no pose puts the code in front of camera `" + camera.name() + "`");
  std::sort(estimate.solutions.begin(), estimate.solutions.end(),
            [](const MarkerPoseSolution& a, const MarkerPoseSolution& b) { return a.rms_px < b.rms_px; });

  estimate.error_ratio =
      estimate.solutions.size() < 2
          ? std::numeric_limits<double>::infinity()
          : FlooredRatio(estimate.solutions[1].rms_px, estimate.solutions[0].rms_px, options.error_floor_px);
  estimate.ambiguous = estimate.error_ratio < options.ambiguity_ratio;

  Residuals8 r;
  Jacobian86 J;
  ReprojectionResiduals(corners_px, corners_marker, camera, estimate.best().T_camera_marker, &r, &J);
  const Eigen::LLT<Matrix6d> llt(J.transpose() * J);
  if (llt.info() != Eigen::Success) Fail("singular information matrix for the best pose");
  estimate.covariance = sigma_px * sigma_px * llt.solve(Matrix6d::Identity());
  estimate.covariance = 0.5 * (estimate.covariance + estimate.covariance.transpose()).eval();
  return estimate;
}

}  // namespace waymark
