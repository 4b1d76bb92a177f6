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
#include <memory>
#include <string>
#include <vector>

#include "geometry/pose.h"
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
// `markers`, when given, replace the scenario's codes (same walls, cameras and path): a survey
// of a planned layout (`waymark plan-codes`, `waymark sim --markers`).
SimResult Simulate(const std::string& scenario, const ParamSet& params, std::uint64_t seed,
                   const std::vector<SimMarker>* markers = nullptr);

// The closed loop (plan/drive.h): the same place, cameras, odometry and detection noise as
// Simulate, but the robot's motion is decided step by step by a caller (a controller fed by
// the localizer) instead of by the scenario's path. Planar wheel-odometry scenarios only. The
// robot starts at the true pose `T_world_start` at stamp 0 and each Advance moves it for one
// odometry period with constant (v, omega) (an exact arc); camera frames are drawn at every
// (rate.odometry_hz / rate.camera_hz)-th sample, from the first one, as Simulate does. The noise
// streams are seeded as in Simulate.
class SimStepper {
 public:
  struct Sample {
    double stamp_s = 0.0;
    SE3d T_odom_robot;                   // the odometry at this sample
    std::vector<DetectionFrame> frames;  // one per camera on camera samples, else none
  };

  // Throws std::invalid_argument for a scenario without wheel odometry or inconsistent params.
  SimStepper(const std::string& scenario, const ParamSet& params, std::uint64_t seed,
             const SE2d& T_world_start);
  ~SimStepper();
  SimStepper(const SimStepper&) = delete;
  SimStepper& operator=(const SimStepper&) = delete;

  const Sample& first() const;  // the sample at the start (stamp 0)
  Sample Advance(double v_mps, double omega_radps);
  const SE2d& T_world_robot() const;  // the true pose now
  double period_s() const;
  const Dataset& dataset() const;  // cameras (as calibrated), known markers, config
  // Everything driven so far as a SimResult (truth, odometry, detections, ground truth); the
  // stepper is spent afterwards.
  SimResult Finish();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// One line: "corridor: 1335 frames (2 cameras), 1234 detections, 64 markers, 40.0 m path, 140.2 s".
std::string SummaryLine(const SimResult& result);

}  // namespace waymark::sim
