// Map files (docs/design.md "Contracts": map.json; also groundtruth/markers.json, reference/
// markers.json and the known markers.json of a dataset):
//
//   {"format": "waymark-map", "version": 1,
//    "markers": [{"family": "datamatrix", "id": "A01", "size_m": 0.08,
//                 "T_world_marker": {"t": [x, y, z], "q_xyzw": [qx, qy, qz, qw]},
//                 "covariance": [36 numbers], "fixed": false, "component": 0}]}
//
// covariance (optional) is row-major 6x6 of the right perturbation
//   T_world_marker = T̂_world_marker · Exp(δ),  δ = [δr, δt]  (rotation first, marker frame),
// symmetric with a non-negative diagonal. fixed (default false) and component (a
// non-negative integer) are optional.
//
// covariance_factor (optional, needs covariance): 6 k numbers, row-major 6 x k, the marker's
// rows F_i of the map's low-rank joint covariance Sigma ~ F F^T + blockdiag(D_i),
// D_i = covariance - F_i F_i^T (mapping/map_covariance.h): markers' errors are correlated
// through the k shared columns. covariance - F_i F_i^T must be PSD (within 1e-6 of the largest
// variance) and k the same for every marker that has one. Writers omit it when unset.
//
// A dataset's known markers.json may also hold size-only entries (no T_world_marker): codes
// whose size is known but not their pose (read with MapPoses::kOptional; such an entry has
// has_pose = false and may not be fixed or carry a covariance). Everywhere else a pose is
// required.
//
// boards (optional, top level): rigid boards, {"name", "T_world_board", "covariance", "fixed",
// "component", "markers": [{"family", "id", "T_board_marker"}]} (geometry/types.h MapBoard);
// T_world_board is required with MapPoses::kRequired, and every board obeys geometry/board.h's
// rules (each code also in "markers", on one board, no overlap, no conflicting poses), which both
// the reader and the writer check.
//
// Strict: every field is checked (type, count, finiteness, family known, size_m > 0, unit
// quaternion, no duplicate (family, id)); an error is a FormatError "path:line: field: what
// was expected". Unknown keys are counted warnings.
#pragma once

#include <filesystem>
#include <string>

#include "geometry/types.h"

namespace waymark {

enum class MapPoses { kRequired, kOptional };

// Parses map JSON; `path` names the file in messages. Unknown keys are added to `warnings`
// when it is not null.
MarkerMap ParseMap(const std::string& text, const std::filesystem::path& path,
                   ReadWarnings* warnings = nullptr, MapPoses poses = MapPoses::kRequired);
MarkerMap ReadMap(const std::filesystem::path& path, ReadWarnings* warnings = nullptr,
                  MapPoses poses = MapPoses::kRequired);

// Map JSON with full double precision, one marker per line. Throws std::invalid_argument for a
// map its reader would reject (non-finite numbers, unknown family, size_m <= 0, duplicates).
std::string FormatMap(const MarkerMap& map);
// FormatMap written atomically.
void WriteMap(const std::filesystem::path& path, const MarkerMap& map);

}  // namespace waymark
