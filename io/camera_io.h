// Camera files, cameras/<name>.yaml (docs/design.md "Contracts"):
//
//   model: pinhole-radtan              # or pinhole-equidistant
//   width: 1280                        # px, positive integers
//   height: 960
//   intrinsics: [fx, fy, cx, cy]       # px; fx, fy > 0
//   distortion: [k1, k2, p1, p2, k3]   # radtan: 5 numbers; equidistant: [k1, k2, k3, k4]
//   T_robot_camera: {t: [x, y, z], q_xyzw: [qx, qy, qz, qw]}   # p_robot = T_robot_camera * p_camera
//   pixel_sigma: 0.5                   # optional, corner noise in px, > 0
//   T_robot_camera_sigma: [0.035, 0.03]  # optional, [rad, m]: the map build estimates the mount
//                                        # with this prior (extrinsic self-calibration)
//   frame_wiggle_sigma: [0.01, 0.01]     # optional, [rad, m]: each frame's camera pose may
//                                        # deviate from the mount by this much (not synchronized)
//
// Every key but pixel_sigma, T_robot_camera_sigma and frame_wiggle_sigma is required. Errors are FormatErrors
// "path:line: field: what was expected" (e.g. "cameras/cam0.yaml:5: intrinsics: expected 4 numbers, got 3");
// unknown keys are counted warnings. The camera's name is the file's stem.
#pragma once

#include <filesystem>
#include <string>

#include "geometry/types.h"

namespace waymark {

// Parses camera YAML; `path` names the file in messages, `name` becomes CameraInfo::name.
CameraInfo ParseCameraYaml(const std::string& text, const std::filesystem::path& path,
                           const std::string& name, ReadWarnings* warnings = nullptr);
// Reads cameras/<name>.yaml; the name is the file's stem.
CameraInfo ReadCameraYaml(const std::filesystem::path& path, ReadWarnings* warnings = nullptr);

// Camera YAML with full double precision. Throws std::invalid_argument for a camera the
// reader would reject (sizes, counts, non-finite numbers).
std::string FormatCameraYaml(const CameraInfo& camera);
// FormatCameraYaml written atomically.
void WriteCameraYaml(const std::filesystem::path& path, const CameraInfo& camera);

}  // namespace waymark
