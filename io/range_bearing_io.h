// Range-bearing observation files, range_bearing.jsonl (docs/formats.md "Range-bearing
// observations"): one JSON object per line, one line per stamp at which the sensor reported
// something:
//
//   {"t": 12.345,
//    "landmarks": [{"family": "barcode", "id": "23", "range_m": 3.79, "bearing_rad": -0.257,
//                   "elevation_rad": 0.01, "sigma_range_m": 0.05, "sigma_bearing_rad": 0.02,
//                   "sigma_elevation_rad": 0.02}],
//    "robots": [{"robot": "robot3", "barcode": "41", "range_m": 2.1, "bearing_rad": 0.3}]}
//
// Observations are in the robot frame (x forward, y left, z up; docs/design.md): range = |p|,
// bearing = atan2(p_y, p_x), elevation = atan2(p_z, hypot(p_x, p_y)).
// Required: t (finite seconds, non-decreasing), landmarks (array, may be empty); each landmark:
// family (a point family: barcode or a known code family), id (non-empty string), range_m (> 0,
// finite), bearing_rad (finite, within [-pi, pi]). Optional: elevation_rad (within
// [-pi/2, pi/2]), sigma_range_m, sigma_bearing_rad, sigma_elevation_rad (each > 0), and robots
// (sightings of other robots, each robot and barcode non-empty strings, range_m > 0, bearing_rad
// within [-pi, pi]; kept for cooperative methods, not used by the map build).
//
// Errors (FormatError "path:line: field: what was expected"): invalid JSON, a missing or
// mistyped field, a value out of its range, a stamp smaller than the previous one. A landmark
// seen twice on one line is ambiguous: every copy is dropped with the counted warning
// "duplicate landmark in frame". Unknown keys are counted warnings.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "geometry/types.h"

namespace waymark {

// The most landmarks or robots one line may hold.
inline constexpr size_t kMaxRangeBearingPerFrame = 1000;

std::vector<RangeBearingFrame> ParseRangeBearing(const std::string& text, const std::filesystem::path& path,
                                                 ReadWarnings* warnings);
std::vector<RangeBearingFrame> ReadRangeBearing(const std::filesystem::path& path, ReadWarnings* warnings);

// One line (without the newline), full double precision. Throws std::invalid_argument for a
// frame the reader would reject.
std::string FormatRangeBearingLine(const RangeBearingFrame& frame);
// All lines; throws std::invalid_argument when stamps decrease.
std::string FormatRangeBearing(const std::vector<RangeBearingFrame>& frames);

}  // namespace waymark
