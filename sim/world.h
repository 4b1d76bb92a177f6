// The simulated world: where the codes are, what occludes them, the cameras on the robot,
// and the geometric test of what a camera sees. Kept free of noise and of file formats so
// that an image renderer can reuse it: every marker has its plane (the x-y plane of its
// frame), its size and its true pose T_world_marker; every camera frame has its true pose
// T_world_camera = T_world_robot * T_robot_camera.
//
// Visibility of a marker from a camera (all must hold; docs/design.md frames):
//   range      r = |c_world - m_world| in [min_range_m, max_range_m]   (c: camera centre,
//              m: marker centre)
//   facing     angle between the marker's z axis (out of the face) and (c_world - m_world)
//              at most max_angle_deg, i.e. z_marker . (c - m) >= r cos(max_angle)
//   in view    each corner_camera = T_camera_world * T_world_marker * corner_marker has
//              z > kMinDepth and projects inside the image, at least border_px from its edge
//   occlusion  no occluder rectangle crosses the open segment from c to any corner
#pragma once

#include <Eigen/Core>
#include <array>
#include <optional>
#include <string>
#include <vector>

#include "geometry/camera.h"
#include "geometry/pose.h"
#include "geometry/types.h"

namespace waymark::sim {

struct SimMarker {
  MarkerKey key;
  double size_m = 0.0;
  SE3d T_world_marker;  // z out of the printed face, y up as read (docs/design.md)
  bool anchor = false;  // its pose is given as known (markers.json, fixed)
  int region = 0;       // scenario-defined grouping (room, rack face, ...), for tests and docs
  std::optional<SquareTape> square_tape;  // family square: its tape (absent: the defaults)
};

// An opaque rectangle: the part |x| <= half_width_m, |y| <= half_height_m of the x-y
// plane of frame `panel` (a wall, a rack face, a closed door).
struct Occluder {
  SE3d T_world_panel;
  double half_width_m = 0.0;
  double half_height_m = 0.0;
};

// A vertical wall from (x0, y0) to (x1, y1) on the floor, from z0_m to z1_m.
Occluder VerticalWall(const Eigen::Vector2d& from_world, const Eigen::Vector2d& to_world, double z0_m,
                      double z1_m);

// Rotation whose camera/marker axes are given in the parent frame: z = `z_axis`, y = the
// part of `y_hint` orthogonal to z, x = y cross z. Both need not be unit; they must not be
// parallel.
Eigen::Quaterniond RotationFromZY(const Eigen::Vector3d& z_axis, const Eigen::Vector3d& y_hint);

// A marker on a vertical wall, read upright: z = the wall's outward normal (horizontal),
// y = world up. `centre_world` is the symbol centre.
SE3d WallMarkerPose(const Eigen::Vector3d& centre_world, const Eigen::Vector3d& normal_world);

struct VisibilityLimits {
  double min_range_m = 0.0;
  double max_range_m = 1e9;
  double max_angle_deg = 90.0;
  double border_px = 0.0;
};

struct World {
  std::string name;
  MotionModel motion = MotionModel::kPlanar;
  std::vector<SimMarker> markers;
  std::vector<Occluder> occluders;
  std::vector<CameraInfo> cameras;  // the true cameras (lens and mount)
  // The calibration the dataset is given (cameras/<name>.yaml) where it differs from the truth
  // (lens calibration error, mount tilt); empty: the true cameras.
  std::vector<CameraInfo> calibrated_cameras;
  std::optional<PayloadSpec> payload;
  double default_marker_size_m = 0.0;
};

// True if some occluder crosses the segment between a and b (end points excluded, so a
// marker lying on a wall is not hidden by that wall).
bool SegmentOccluded(const std::vector<Occluder>& occluders, const Eigen::Vector3d& a_world,
                     const Eigen::Vector3d& b_world);

// The true pixels of the four corners (docs/design.md order) if `marker` is visible from the
// camera at T_world_camera under `limits`; nullopt otherwise.
std::optional<std::array<Eigen::Vector2d, 4>> VisibleCorners(const Camera& camera, const SE3d& T_world_camera,
                                                             const SimMarker& marker,
                                                             const std::vector<Occluder>& occluders,
                                                             const VisibilityLimits& limits);

}  // namespace waymark::sim
