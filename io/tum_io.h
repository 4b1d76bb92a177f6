// TUM trajectory files (docs/design.md "Contracts"): one pose per line,
//   t tx ty tz qx qy qz qw
// with t in seconds, (tx, ty, tz) in metres and the quaternion in q_xyzw order. The pose is
// T_a_b of the file's convention: T_odom_robot for odometry.tum, T_world_robot for
// groundtruth/ and reference/ trajectories. Lines starting with '#' (after optional spaces)
// and blank lines are ignored.
//
// Strict: exactly 8 finite numbers per line (spaces or tabs between them), unit quaternion
// within kQuaternionNormTolerance (then normalized), stamps strictly increasing. Any
// violation is a FormatError "path:line: what was expected".
#pragma once

#include <filesystem>
#include <string>

#include "geometry/types.h"

namespace waymark {

// Parses TUM text; `path` only names the file in messages.
Trajectory ParseTum(const std::string& text, const std::filesystem::path& path);
// Reads a TUM file (a missing file is a FormatError naming it).
Trajectory ReadTum(const std::filesystem::path& path);

// TUM text with full double precision (reading it back gives the same doubles). `comment`,
// when not empty, is written first as "# comment" lines. Throws std::invalid_argument when a
// pose is not finite or the stamps are not strictly increasing (the reader would reject it).
std::string FormatTum(const Trajectory& trajectory, const std::string& comment = "");
// FormatTum written atomically (AtomicWriteFile).
void WriteTum(const std::filesystem::path& path, const Trajectory& trajectory,
              const std::string& comment = "");

}  // namespace waymark
