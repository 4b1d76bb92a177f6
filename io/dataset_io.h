// Dataset directories (docs/design.md "Contracts: Dataset directory"):
//
//   dataset.yaml                the index (below); other paths are relative to the directory
//   cameras/<name>.yaml         one per camera listed in dataset.yaml (io/camera_io.h)
//   odometry.tum                optional, T_odom_robot (io/tum_io.h)
//   detections.jsonl            optional (io/detections_io.h)
//   images.csv                  optional, "t,camera,path" rows (header line optional)
//   markers.json                optional, known markers in the map format (io/map_io.h)
//   groundtruth/trajectory.tum  optional, T_world_robot;  groundtruth/markers.json optional
//   reference/trajectory.tum    optional, a peer's estimate; reference/markers.json optional
//
// dataset.yaml:
//   format: waymark-dataset          # required, exactly this
//   version: 1                       # required, integer 1
//   name: corridor-1m                # optional (default: the directory's name)
//   motion: planar                   # required: planar | free
//   cameras: [cam0, cam1]            # required, distinct names; [] for range-bearing-only datasets
//   default_marker_size_m: 0.10      # optional, > 0
//   odometry_sigma: {trans_per_m: 0.02, rot_per_rad: 0.02}   # optional; these two keys required, >= 0;
//     optional random-walk terms (>= 0, default 0): trans_per_sqrt_s, rot_per_sqrt_s,
//     trans_per_sqrt_m, rot_per_sqrt_m (docs/formats.md; OdometrySigma in geometry/types.h)
//   payload: {pattern: "^(\\d+)/(-?[0-9.]+)/(-?[0-9.]+)$", fields: [kind, x, y]}   # optional
//   odometry: odometry.tum           # optional file names (defaults shown); a file named
//   detections: detections.jsonl     #   here must exist, a default-named one may be absent
//   images: images.csv
//   markers: markers.json
//   range_bearing: range_bearing.jsonl   # io/range_bearing_io.h
//   start_prior: {T_world_robot: {t: [x, y, z], q_xyzw: [...]}, sigma_m: 0.01, sigma_rad: 0.01}   # optional
//
// payload: the pattern must compile as a regular expression (RE2 syntax) and have exactly one field name per
// capture group; names are distinct and non-empty; z and yaw_deg need x and y.
//
// Errors are FormatErrors naming the file and line; counted warnings (Dataset::warnings)
// cover unknown keys, rejected detections (io/detections_io.h), images.csv rows whose image
// file is missing, and markers seen in detections whose size is unknown (neither in
// markers.json nor default_marker_size_m).
#pragma once

#include <filesystem>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "geometry/types.h"

namespace waymark {

// dataset.yaml. `path` names the file in messages. `named_files`, when not null, receives
// the keys among odometry/detections/images/markers that the file sets explicitly.
DatasetConfig ParseDatasetYaml(const std::string& text, const std::filesystem::path& path,
                               ReadWarnings* warnings = nullptr,
                               std::set<std::string>* named_files = nullptr);
std::string FormatDatasetYaml(const DatasetConfig& config);

// Why a payload spec is unusable (empty string when it is fine).
std::string CheckPayloadSpec(const PayloadSpec& spec);

// images.csv: "t,camera,path" per row; an optional first line "t,camera,path"; blank lines
// ignored; the path is everything after the second comma (no quoting). When `cameras` is not
// null, the camera must be one of them.
std::vector<ImageEntry> ParseImagesCsv(const std::string& text, const std::filesystem::path& path,
                                       const std::vector<std::string>* cameras = nullptr);
std::string FormatImagesCsv(const std::vector<ImageEntry>& images);

// Reads every file present in `dir` and checks cross-references (cameras of detections and
// images must be listed in dataset.yaml; out-of-image corners are warnings). Throws
// FormatError naming the file (and line) on the first error.
Dataset LoadDataset(const std::filesystem::path& dir);

// Writes the whole directory: dataset.yaml, cameras/<name>.yaml for every listed camera, and
// each optional file when it has content (or its has_*_file flag is set). Every file is
// formatted (and checked) before any is written, then written atomically. Throws
// std::invalid_argument when the dataset is inconsistent (a listed camera without its
// CameraInfo, a CameraInfo not listed, a detection or image of an unlisted camera).
void WriteDataset(const std::filesystem::path& dir, const Dataset& dataset);

// Figures `waymark dataset info` prints.
struct DatasetSummary {
  long frames = 0;      // lines of detections.jsonl
  long detections = 0;  // markers kept, all frames
  std::map<std::string, long> detections_per_family;
  long distinct_markers = 0;  // distinct (family, id) in detections
  long known_markers = 0;     // markers.json
  long odometry_poses = 0;
  double odometry_span_s = 0.0;         // last stamp - first stamp
  double odometry_path_length_m = 0.0;  // sum of |t_i+1 - t_i| of T_odom_robot
};
DatasetSummary SummarizeDataset(const Dataset& dataset);

}  // namespace waymark
