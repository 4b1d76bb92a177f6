// Single-code pose: T_camera_marker of one square code from its four corners in one image.
//
// Frames (docs/design.md): camera = OpenCV (x right, y down, z forward); marker = origin at the
// symbol centre, x right, y up, z out of the printed face. Corners in docs/design.md order,
// object points corner_marker = (-s/2, s/2, 0), (s/2, s/2, 0), (s/2, -s/2, 0), (-s/2, -s/2, 0).
//
// Method.
//  1. Each corner is unprojected to normalized coordinates with the full camera model.
//  2. Square planar PnP (IPPE, cv::solvePnPGeneric with SOLVEPNP_IPPE_SQUARE) on them gives
//     the two candidate poses of the planar ambiguity (a plane seen under perspective has
//     two local minima of the reprojection error, mirrored about the line of sight).
//  3. Each candidate is refined by Levenberg-Marquardt on the pixel reprojection error with
//     the distorted model, over the right perturbation T = T_hat * Exp([dr, dt]):
//       r_k = project(T_camera_marker * corner_marker_k) - corner_px_k          (8 residuals)
//       d(p_camera)/d(dr) = -R Hat(corner_marker),  d(p_camera)/d(dt) = R.
//  4. Solutions are sorted by RMS reprojection error, rms = sqrt(sum_k |r_k|^2 / 4) (px).
//     error_ratio = max(rms_second, floor) / max(rms_best, floor); the pose is ambiguous when
//     error_ratio < ambiguity_ratio (TagSLAM's test on the two IPPE solutions). The floor
//     keeps noiseless, exactly fitting corners from looking unambiguous.
//  5. Covariance of the best solution, tangent order [rx ry rz tx ty tz], right perturbation
//     of T_camera_marker:  Sigma = sigma_px^2 (J^T J)^-1, J = d r / d delta (8 x 6).
#pragma once

#include <Eigen/Core>
#include <array>
#include <optional>
#include <string>
#include <vector>

#include "geometry/camera.h"
#include "geometry/pose.h"

namespace waymark {

struct MarkerPoseOptions {
  // Corner noise (px) for the covariance; unset: the camera's pixel_sigma, else 1 px.
  std::optional<double> sigma_px;
  // Ambiguous when rms_second / rms_best (each floored at error_floor_px) is below this.
  double ambiguity_ratio = 3.0;
  double error_floor_px = 0.1;
  int max_iterations = 50;  // Levenberg-Marquardt iterations per solution
  // Quads whose undistorted area, in pixels of the focal length, is below this are degenerate.
  double min_area_px2 = 4.0;

  // False, with the reason, when a value is out of range.
  bool Check(std::string* why) const;
};

struct MarkerPoseSolution {
  SE3d T_camera_marker;
  double rms_px = 0.0;  // RMS reprojection error over the four corners
};

struct MarkerPoseEstimate {
  std::vector<MarkerPoseSolution> solutions;  // one or two, best (lowest rms_px) first
  double error_ratio = 0.0;                   // see the header comment; +inf with one solution
  bool ambiguous = false;
  Matrix6d covariance = Matrix6d::Zero();  // of solutions[0], [rx ry rz tx ty tz], right perturbation

  const MarkerPoseSolution& best() const { return solutions.front(); }
};

// Estimates T_camera_marker of a square code of edge `size_m` (m). Throws std::runtime_error
// for a non-finite corner or size, size_m <= 0, a corner outside the camera's field of view,
// a degenerate quad (collinear or repeated corners, area below min_area_px2), corners in
// mirrored order (the printed face seen from behind), invalid options, or when no candidate
// pose puts the code in front of the camera.
MarkerPoseEstimate EstimateMarkerPose(const std::array<Eigen::Vector2d, 4>& corners_px, double size_m,
                                      const Camera& camera, const MarkerPoseOptions& options = {});

// RMS reprojection error (px) of the code's corners for a given T_camera_marker; +inf if a
// corner does not project (behind the camera or outside the field of view).
double MarkerReprojectionRms(const std::array<Eigen::Vector2d, 4>& corners_px, double size_m,
                             const Camera& camera, const SE3d& T_camera_marker);

}  // namespace waymark
