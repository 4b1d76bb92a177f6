// Camera models: project a point in the camera frame (OpenCV: x right, y down, z forward)
// to pixels, and back. Three models, the first two with OpenCV's conventions exactly:
//   pinhole-radtan      OpenCV plumb-bob, distortion [k1 k2 p1 p2 k3] (cv::projectPoints)
//   pinhole-equidistant OpenCV fisheye / Kalibr equidistant, [k1 k2 k3 k4] (cv::fisheye)
//   equisolid           equisolid-angle fisheye (r = 2 f sin(theta/2), e.g. the FIT FI-23 lens
//                       of [Seki]), with the same polynomial in theta as equidistant, [k1 k2 k3 k4]
// The projection is templated on the scalar so Ceres can differentiate it (Jets).
// Intrinsics are [fx fy cx cy]. YAML reading is in io/camera_io.h, not here.
//
// Equations. With p_camera = (X, Y, Z), Z > 0, normalized x = X/Z, y = Y/Z, u = r^2 = x^2 + y^2:
//   radtan:       radial = 1 + k1 u + k2 u^2 + k3 u^3
//                 xd = x radial + 2 p1 x y + p2 (u + 2 x^2)
//                 yd = y radial + p1 (u + 2 y^2) + 2 p2 x y
//   equidistant:  theta = atan(r),  theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8)
//                 xd = x s,  yd = y s,  s = theta_d / r   (s -> 1 as r -> 0, evaluated by a
//                 series in u near r = 0 so that Jets never see the derivative of sqrt(0))
//   equisolid:    as equidistant with theta replaced by 2 sin(theta / 2) in front of the polynomial:
//                 rho = 2 sin(theta/2) (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8),
//                 xd = x s,  yd = y s,  s = rho / r   (series near r = 0 likewise). With zero
//                 coefficients the pixel radius is fx 2 sin(theta/2), fx = focal length / pixel pitch.
//   pixel:        px = (fx xd + cx, fy yd + cy)   (no skew)
//
// Valid field of view. Both distortion polynomials eventually fold back (r_d stops growing
// with r), after which OpenCV's formulas map far off-axis points to plausible pixels inside
// the image. ProjectPoint<T> follows OpenCV exactly and only rejects Z <= kMinDepth;
// Camera::Project and Camera::Unproject also reject points beyond the first fold
// (Camera::max_normalized_radius()), where the model is not one-to-one. The two fisheye
// models are used up to theta = 90 deg at most (points are (x/z, y/z, 1) rays): a pixel
// further out than 90 degrees off-axis has no ray.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <optional>

#include "geometry/types.h"

namespace waymark {

// Projects p_camera (3) to px (2) with the given model.
// `intrinsics` = [fx fy cx cy]; `distortion` has CameraInfo::DistortionSize(model) entries.
// Returns false (px untouched) for a point behind the camera or too close to the
// camera's plane (z <= kMinDepth), where the model is undefined.
template <typename T>
bool ProjectPoint(CameraModel model, const T* intrinsics, const T* distortion, const T* p_camera, T* px);

inline constexpr double kMinDepth = 1e-6;

// Below this u = r^2 the fisheye scales (equidistant s = theta_d / r, equisolid s = rho / r)
// are evaluated by their series in u.
inline constexpr double kEquidistantSeriesR2 = 1e-8;

// Radtan distortion of normalized coordinates (x, y) -> (xd, yd); d = [k1 k2 p1 p2 k3].
template <typename T>
void DistortRadtan(const T* d, const T& x, const T& y, T* xd, T* yd) {
  const T u = x * x + y * y;
  const T radial = T(1.0) + u * (d[0] + u * (d[1] + u * d[4]));
  const T two_xy = T(2.0) * x * y;
  *xd = x * radial + d[2] * two_xy + d[3] * (u + T(2.0) * x * x);
  *yd = y * radial + d[2] * (u + T(2.0) * y * y) + d[3] * two_xy;
}

// Equidistant scale s(u) = theta_d / r with u = r^2; d = [k1 k2 k3 k4]. Near u = 0:
//   s = 1 + (k1 - 1/3) u + (k2 - k1 + 1/5) u^2 + O(u^3),
// which is exact to double precision for u < kEquidistantSeriesR2 and has finite Jets at 0.
template <typename T>
T EquidistantScale(const T* d, const T& u) {
  using std::atan;
  using std::sqrt;
  if (u < T(kEquidistantSeriesR2)) {
    return T(1.0) + u * ((d[0] - T(1.0 / 3.0)) + u * (d[1] - d[0] + T(0.2)));
  }
  const T r = sqrt(u);
  const T theta = atan(r);
  const T t2 = theta * theta;
  const T theta_d = theta * (T(1.0) + t2 * (d[0] + t2 * (d[1] + t2 * (d[2] + t2 * d[3]))));
  return theta_d / r;
}

// Equisolid scale s(u) = rho / r with u = r^2; d = [k1 k2 k3 k4]. Near u = 0, from
// 2 sin(atan(r)/2) / r = 1 - 3/8 u + 31/128 u^2 + O(u^3) and theta^2 = u - 2/3 u^2 + O(u^3):
//   s = 1 + (k1 - 3/8) u + (k2 - 25/24 k1 + 31/128) u^2 + O(u^3).
template <typename T>
T EquisolidScale(const T* d, const T& u) {
  using std::atan;
  using std::sin;
  using std::sqrt;
  if (u < T(kEquidistantSeriesR2)) {
    return T(1.0) + u * ((d[0] - T(3.0 / 8.0)) + u * (d[1] - T(25.0 / 24.0) * d[0] + T(31.0 / 128.0)));
  }
  const T r = sqrt(u);
  const T theta = atan(r);
  const T t2 = theta * theta;
  const T rho = T(2.0) * sin(T(0.5) * theta) * (T(1.0) + t2 * (d[0] + t2 * (d[1] + t2 * (d[2] + t2 * d[3]))));
  return rho / r;
}

template <typename T>
bool ProjectPoint(CameraModel model, const T* intrinsics, const T* distortion, const T* p_camera, T* px) {
  if (!(p_camera[2] > T(kMinDepth))) return false;  // also false for NaN depth
  const T x = p_camera[0] / p_camera[2];
  const T y = p_camera[1] / p_camera[2];
  T xd, yd;
  if (model == CameraModel::kPinholeRadtan) {
    DistortRadtan(distortion, x, y, &xd, &yd);
  } else {
    const T u = x * x + y * y;
    const T s =
        model == CameraModel::kEquisolid ? EquisolidScale(distortion, u) : EquidistantScale(distortion, u);
    xd = x * s;
    yd = y * s;
  }
  px[0] = intrinsics[0] * xd + intrinsics[2];
  px[1] = intrinsics[1] * yd + intrinsics[3];
  return true;
}

// A camera with its calibration; double-precision convenience around ProjectPoint.
class Camera {
 public:
  // Throws std::runtime_error if the calibration is unusable (wrong number of distortion
  // coefficients, non-finite values, fx or fy <= 0, width or height <= 0).
  explicit Camera(CameraInfo info);

  const CameraInfo& info() const { return info_; }
  const std::string& name() const { return info_.name; }
  int width() const { return info_.width; }
  int height() const { return info_.height; }

  // Pixel of a point in the camera frame; nullopt behind the camera.
  // If J_px_p is given it receives d(px)/d(p_camera) (2x3), analytic.
  // Also nullopt beyond the valid field of view (see the header comment).
  std::optional<Eigen::Vector2d> Project(const Eigen::Vector3d& p_camera,
                                         Eigen::Matrix<double, 2, 3>* J_px_p = nullptr) const;

  // Ray through a pixel: normalized coordinates (x/z, y/z, 1) of the undistorted point,
  // found by Newton iterations on the distortion model. nullopt if it does not converge
  // (pixel far outside the calibrated field of view).
  std::optional<Eigen::Vector3d> Unproject(const Eigen::Vector2d& px) const;

  // Template-friendly access for Ceres functors.
  template <typename T>
  bool Project(const T* p_camera, T* px) const;

  // Largest normalized radius r = |(x/z, y/z)| inside the valid field of view: the first
  // fold of the distortion (d r_d / d r = 0), or +infinity if it never folds. For the
  // fisheye models (equidistant, equisolid) it is at most tan(pi/2 - 1e-6).
  double max_normalized_radius() const { return max_radius_; }

  // Distorted normalized coordinates (xd, yd) of normalized (x, y) and, if J is given,
  // d(xd, yd)/d(x, y). No field-of-view check.
  Eigen::Vector2d Distort(const Eigen::Vector2d& xy, Eigen::Matrix2d* J = nullptr) const;

 private:
  std::optional<Eigen::Vector2d> UndistortRadtan(const Eigen::Vector2d& xy_d) const;
  // Both fisheye models (equidistant, equisolid): solve rho(theta) = |xy_d| for theta.
  std::optional<Eigen::Vector2d> UndistortFisheye(const Eigen::Vector2d& xy_d) const;

  CameraInfo info_;
  double max_radius_ = 0.0;  // see max_normalized_radius()
};

template <typename T>
bool Camera::Project(const T* p_camera, T* px) const {
  const T intrinsics[4] = {T(info_.intrinsics[0]), T(info_.intrinsics[1]), T(info_.intrinsics[2]),
                           T(info_.intrinsics[3])};
  T distortion[5];
  for (size_t i = 0; i < info_.distortion.size() && i < 5; ++i) distortion[i] = T(info_.distortion[i]);
  return ProjectPoint(info_.model, intrinsics, distortion, p_camera, px);
}

}  // namespace waymark
