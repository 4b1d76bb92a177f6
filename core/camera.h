// Camera models: project a point in the camera frame (OpenCV: x right, y down, z forward)
// to pixels, and back. Two models, both with OpenCV's conventions exactly:
//   pinhole-radtan      OpenCV plumb-bob, distortion [k1 k2 p1 p2 k3] (cv::projectPoints)
//   pinhole-equidistant OpenCV fisheye / Kalibr equidistant, [k1 k2 k3 k4] (cv::fisheye)
// The projection is templated on the scalar so Ceres can differentiate it (Jets).
// Intrinsics are [fx fy cx cy]. YAML reading is in core/camera_io.h, not here.
#pragma once

#include <optional>

#include <Eigen/Core>

#include "core/types.h"

namespace waymark {

// Projects p_camera (3) to px (2) with the given model.
// `intrinsics` = [fx fy cx cy]; `distortion` has CameraInfo::DistortionSize(model) entries.
// Returns false (px untouched) for a point behind the camera or too close to the
// camera's plane (z <= kMinDepth), where the model is undefined.
template <typename T>
bool ProjectPoint(CameraModel model, const T* intrinsics, const T* distortion, const T* p_camera, T* px);

inline constexpr double kMinDepth = 1e-6;

// A camera with its calibration; double-precision convenience around ProjectPoint.
class Camera {
 public:
  explicit Camera(CameraInfo info);

  const CameraInfo& info() const { return info_; }
  const std::string& name() const { return info_.name; }
  int width() const { return info_.width; }
  int height() const { return info_.height; }

  // Pixel of a point in the camera frame; nullopt behind the camera.
  // If J_px_p is given it receives d(px)/d(p_camera) (2x3), analytic.
  std::optional<Eigen::Vector2d> Project(const Eigen::Vector3d& p_camera,
                                         Eigen::Matrix<double, 2, 3>* J_px_p = nullptr) const;

  // Ray through a pixel: normalized coordinates (x/z, y/z, 1) of the undistorted point,
  // found by Gauss-Newton on the distortion model. nullopt if it does not converge
  // (pixel far outside the calibrated field of view).
  std::optional<Eigen::Vector3d> Unproject(const Eigen::Vector2d& px) const;

  // Template-friendly access for Ceres functors.
  template <typename T>
  bool Project(const T* p_camera, T* px) const;

 private:
  CameraInfo info_;
};

}  // namespace waymark
