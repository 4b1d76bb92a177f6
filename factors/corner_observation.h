// The constant part of a marker-corner reprojection residual, shared by the three
// reprojection factors (they differ only in how they build T_camera_marker).
//
//   r = (1 / sigma_px) [ project(K, d, T_camera_marker * c_i) - z_i ]_{i = 0..3}   (8 residuals)
//
// c_i: the four corners in the marker frame, docs/design.md order (top-left, top-right, bottom-right,
//      bottom-left), from MarkerCorners(size_m);
// z_i: the detected corners in pixels, same order; residual layout [u0 v0 u1 v1 u2 v2 u3 v3];
// project: geometry/camera.h ProjectPoint with the camera's model, K = [fx fy cx cy], d = distortion.
// Whitening: the corner noise is isotropic, so the square-root information is I / sigma_px.
//
// Near and behind the camera the pinhole model is undefined (z_camera <= 0) or explodes, and a
// residual that fails there (Residuals returning false) makes every trial step that moves one
// corner behind its camera fail to evaluate: on a badly initialized survey Ceres then spends its
// iterations on failed steps. A zero residual with true (COLMAP's choice) would instead reward the
// wrong solution. So below the depth z_s = kPenaltyDepthM the normalized coordinates are continued
// by their first-order expansion in z about z_s (C^1 at z_s, finite everywhere):
//   z >= z_s:  n = (X, Y) / z
//   z <  z_s:  n = (X, Y) / z_s * (2 - z / z_s)
// and projected by the model as the point (n, 1). The pixel error keeps growing the further a
// corner moves behind the camera, so the cost stays high there and smooth; no real observation
// lies within 10 cm of its camera's plane (z_s that large also keeps n, and the distortion
// polynomial evaluated at it, moderate a little behind the camera: the Jacobians stay accurate). Residuals
// returns false only for a non-finite depth (residuals untouched).
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <string>

#include "factors/pose_block.h"
#include "factors/sqrt_information.h"
#include "geometry/camera.h"
#include "geometry/types.h"

namespace waymark {

// Depth below which the projection is continued linearly (header comment).
inline constexpr double kPenaltyDepthM = 0.1;

class CornerObservation {
 public:
  // Throws std::invalid_argument on a malformed camera, a size_m or sigma_px that is not finite
  // and > 0, or a non-finite corner.
  CornerObservation(const CameraInfo& camera, double size_m, const std::array<Eigen::Vector2d, 4>& corners_px,
                    double sigma_px)
      : model_(camera.model),
        intrinsics_(CheckedIntrinsics(camera)),
        distortion_(CheckedDistortion(camera)),
        corners_marker_(MarkerCorners(CheckedSize(camera, size_m))),
        corners_px_(CheckedCorners(camera, corners_px)),
        inverse_sigma_px_(InverseSigma(sigma_px, Where(camera))) {}

  // Writes the 8 whitened residuals for the marker seen from the camera at T_camera_marker.
  // Returns false (residuals untouched) only when a corner's depth is not finite.
  template <typename T>
  bool Residuals(const SE3T<T>& T_camera_marker, T* residuals) const {
    T intrinsics[4];
    T distortion[5];
    for (int i = 0; i < 4; ++i) intrinsics[i] = T(intrinsics_[i]);
    for (int i = 0; i < 5; ++i) distortion[i] = T(distortion_[i]);
    T px[4][2];
    for (int i = 0; i < 4; ++i) {
      Vector3T<T> corner_camera = T_camera_marker * corners_marker_[i].template cast<T>();
      if (corner_camera.z() < T(kPenaltyDepthM)) {  // the continuation of the header comment
        const T scale = (T(2.0) - corner_camera.z() / T(kPenaltyDepthM)) / T(kPenaltyDepthM);
        corner_camera = Vector3T<T>(corner_camera.x() * scale, corner_camera.y() * scale, T(1.0));
      }
      if (!ProjectPoint<T>(model_, intrinsics, distortion, corner_camera.data(), px[i])) return false;
    }
    for (int i = 0; i < 4; ++i) {
      residuals[2 * i] = (px[i][0] - T(corners_px_[i].x())) * T(inverse_sigma_px_);
      residuals[2 * i + 1] = (px[i][1] - T(corners_px_[i].y())) * T(inverse_sigma_px_);
    }
    return true;
  }

 private:
  static std::string Where(const CameraInfo& camera) {
    return "corner reprojection (camera " + camera.name + ")";
  }
  static std::array<double, 4> CheckedIntrinsics(const CameraInfo& camera) {
    const std::array<double, 4>& k = camera.intrinsics;
    if (!std::all_of(k.begin(), k.end(), [](double v) { return std::isfinite(v); }) || !(k[0] > 0.0) ||
        !(k[1] > 0.0)) {
      throw std::invalid_argument(Where(camera) + ": intrinsics must be finite with fx, fy > 0");
    }
    return k;
  }
  static std::array<double, 5> CheckedDistortion(const CameraInfo& camera) {
    const size_t expected = CameraInfo::DistortionSize(camera.model);
    if (camera.distortion.size() != expected) {
      throw std::invalid_argument(Where(camera) + ": expected " + std::to_string(expected) +
                                  " distortion coefficients, got " +
                                  std::to_string(camera.distortion.size()));
    }
    std::array<double, 5> d{};  // unused trailing entries stay zero
    for (size_t i = 0; i < expected; ++i) {
      if (!std::isfinite(camera.distortion[i])) {
        throw std::invalid_argument(Where(camera) + ": non-finite distortion coefficient");
      }
      d[i] = camera.distortion[i];
    }
    return d;
  }
  static double CheckedSize(const CameraInfo& camera, double size_m) {
    if (!(std::isfinite(size_m) && size_m > 0.0)) {
      throw std::invalid_argument(Where(camera) + ": size_m must be finite and > 0, got " +
                                  FormatDouble(size_m));
    }
    return size_m;
  }
  static std::array<Eigen::Vector2d, 4> CheckedCorners(const CameraInfo& camera,
                                                       const std::array<Eigen::Vector2d, 4>& corners_px) {
    for (const Eigen::Vector2d& corner : corners_px) {
      if (!corner.allFinite()) throw std::invalid_argument(Where(camera) + ": non-finite corner");
    }
    return corners_px;
  }

  const CameraModel model_;
  const std::array<double, 4> intrinsics_;  // fx fy cx cy
  const std::array<double, 5> distortion_;  // radtan k1 k2 p1 p2 k3; equidistant k1 k2 k3 k4 0
  const std::array<Eigen::Vector3d, 4> corners_marker_;
  const std::array<Eigen::Vector2d, 4> corners_px_;
  const double inverse_sigma_px_;
};

}  // namespace waymark
