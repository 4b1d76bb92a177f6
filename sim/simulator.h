// Runs a scenario: builds its place and path (sim/scenarios.h), then draws the noise from
// `seed`: odometry (sim/motion.h) and detections, and assembles a Dataset (docs/design.md) with
// exact ground truth.
//
// Detections. Camera frames are taken every (rate.odometry_hz / rate.camera_hz)-th odometry
// sample, at its stamp and true pose: T_world_camera = T_world_robot * T_robot_camera. Every
// camera frame gets a DetectionFrame, empty or not. A code visible under the limits of
// sim/world.h is then
//   missed       with probability detect.miss_fraction (random occlusion, glare, blur),
//   observed     corners_px = project(T_camera_world * T_world_marker * corner_marker)
//                             + N(0, detect.pixel_sigma_px^2 I2), independently per corner,
//                and dropped if a noisy corner leaves the image,
//   misdecoded   with probability detect.misdecode_fraction: its id is replaced by random text
//                (share detect.misdecode_random_share) or by another code's id of the same family.
// Noise streams: odometry and detections draw from two generators seeded from (seed, stream),
// so changing a detection setting does not change the odometry noise and vice versa.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "geometry/types.h"
#include "sim/params.h"
#include "sim/scenarios.h"

namespace waymark::sim {

struct SimStats {
  long frames = 0;      // camera frames (detections.jsonl lines)
  long detections = 0;  // emitted marker observations
  long missed = 0;      // visible but dropped at random or by noise leaving the image
  long misdecoded = 0;  // emitted with a wrong id
  long markers = 0;     // codes in the place
  double path_length_m = 0.0;
  double duration_s = 0.0;
};

struct SimResult {
  std::string scenario;
  Scene scene;      // the world and the true path (noise-free), reusable by a renderer
  Dataset dataset;  // what WriteDataset writes; dataset.dir is empty until written
  // true_keys[i][j]: the code that produced dataset.detections[i].markers[j] (differs from
  // the emitted key when misdecoded).
  std::vector<std::vector<MarkerKey>> true_keys;
  SimStats stats;
};

// Simulates `scenario` with `params` (from ScenarioParams, possibly overridden). Throws
// std::invalid_argument for inconsistent parameters (e.g. camera rate not dividing the
// odometry rate, min range above max range).
SimResult Simulate(const std::string& scenario, const ParamSet& params, std::uint64_t seed);

// One line: "corridor: 1335 frames (2 cameras), 1234 detections, 64 markers, 40.0 m path, 140.2 s".
std::string SummaryLine(const SimResult& result);

}  // namespace waymark::sim
