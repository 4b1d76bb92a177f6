#include "sim/world.h"

#include <cmath>
#include <stdexcept>

namespace waymark::sim {

Occluder VerticalWall(const Eigen::Vector2d& from_world, const Eigen::Vector2d& to_world, double z0_m,
                      double z1_m) {
  const Eigen::Vector2d along = to_world - from_world;
  const Eigen::Vector2d mid = 0.5 * (from_world + to_world);
  const Eigen::Vector3d normal(-along.y(), along.x(), 0.0);
  Occluder wall;
  wall.T_world_panel = SE3d(RotationFromZY(normal, Eigen::Vector3d::UnitZ()),
                            Eigen::Vector3d(mid.x(), mid.y(), 0.5 * (z0_m + z1_m)));
  wall.half_width_m = 0.5 * along.norm();
  wall.half_height_m = 0.5 * std::abs(z1_m - z0_m);
  return wall;
}

Eigen::Quaterniond RotationFromZY(const Eigen::Vector3d& z_axis, const Eigen::Vector3d& y_hint) {
  const Eigen::Vector3d z = z_axis.normalized();
  const Eigen::Vector3d y_raw = y_hint - y_hint.dot(z) * z;
  if (y_raw.norm() < 1e-9) throw std::invalid_argument("RotationFromZY: y hint parallel to z");
  const Eigen::Vector3d y = y_raw.normalized();
  Eigen::Matrix3d R;
  R.col(0) = y.cross(z);
  R.col(1) = y;
  R.col(2) = z;
  return Eigen::Quaterniond(R).normalized();
}

SE3d WallMarkerPose(const Eigen::Vector3d& centre_world, const Eigen::Vector3d& normal_world) {
  return SE3d(RotationFromZY(normal_world, Eigen::Vector3d::UnitZ()), centre_world);
}

bool SegmentOccluded(const std::vector<Occluder>& occluders, const Eigen::Vector3d& a_world,
                     const Eigen::Vector3d& b_world) {
  // Relative margin on the segment parameter: 1e-6 of a few metres is a few micrometres.
  constexpr double kEndMargin = 1e-6;
  const Eigen::Vector3d ab = b_world - a_world;
  for (const Occluder& o : occluders) {
    const Eigen::Vector3d n = o.T_world_panel.rotation() * Eigen::Vector3d::UnitZ();
    const double denom = n.dot(ab);
    if (std::abs(denom) < 1e-12) continue;  // parallel to the panel
    const double s = n.dot(o.T_world_panel.translation() - a_world) / denom;
    if (s <= kEndMargin || s >= 1.0 - kEndMargin) continue;
    const Eigen::Vector3d hit_panel = o.T_world_panel.inverse() * (a_world + s * ab);
    if (std::abs(hit_panel.x()) <= o.half_width_m && std::abs(hit_panel.y()) <= o.half_height_m) return true;
  }
  return false;
}

std::optional<std::array<Eigen::Vector2d, 4>> VisibleCorners(const Camera& camera, const SE3d& T_world_camera,
                                                             const SimMarker& marker,
                                                             const std::vector<Occluder>& occluders,
                                                             const VisibilityLimits& limits) {
  const Eigen::Vector3d camera_world = T_world_camera.translation();
  const Eigen::Vector3d to_camera = camera_world - marker.T_world_marker.translation();
  const double range_m = to_camera.norm();
  if (range_m < limits.min_range_m || range_m > limits.max_range_m) return std::nullopt;
  const Eigen::Vector3d normal_world = marker.T_world_marker.rotation() * Eigen::Vector3d::UnitZ();
  if (normal_world.dot(to_camera) < range_m * std::cos(limits.max_angle_deg * M_PI / 180.0))
    return std::nullopt;

  const SE3d T_camera_world = T_world_camera.inverse();
  const auto corners_marker = MarkerCorners(marker.size_m);
  std::array<Eigen::Vector2d, 4> corners_px;
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector3d corner_world = marker.T_world_marker * corners_marker[i];
    const Eigen::Vector3d corner_camera = T_camera_world * corner_world;
    if (corner_camera.z() <= kMinDepth) return std::nullopt;
    const std::optional<Eigen::Vector2d> px = camera.Project(corner_camera);
    if (!px) return std::nullopt;
    if (px->x() < limits.border_px || px->y() < limits.border_px ||
        px->x() > camera.width() - limits.border_px || px->y() > camera.height() - limits.border_px) {
      return std::nullopt;
    }
    if (SegmentOccluded(occluders, camera_world, corner_world)) return std::nullopt;
    corners_px[i] = *px;
  }
  return corners_px;
}

}  // namespace waymark::sim
