#include "sim/simulator.h"

#include <cmath>
#include <cstdio>
#include <map>
#include <random>
#include <stdexcept>

#include "geometry/camera.h"

namespace waymark::sim {
namespace {

enum Stream : std::uint64_t { kOdometryStream = 1, kDetectionStream = 2 };

std::mt19937_64 MakeRng(std::uint64_t seed, Stream stream) {
  std::seed_seq seq{static_cast<std::uint32_t>(seed), static_cast<std::uint32_t>(seed >> 32),
                    static_cast<std::uint32_t>(stream)};
  return std::mt19937_64(seq);
}

struct DetectionNoise {
  double pixel_sigma_px, miss_fraction, misdecode_fraction, misdecode_random_share;
};

// Draws the detections of every camera frame; fills result->dataset.detections, true_keys, stats.
class DetectionDrawer {
 public:
  DetectionDrawer(const World& world, const VisibilityLimits& limits, const DetectionNoise& noise,
                  std::mt19937_64* rng)
      : world_(world), limits_(limits), noise_(noise), rng_(rng) {
    for (const SimMarker& m : world.markers) ids_by_family_[m.key.family].push_back(m.key.id);
  }

  // Observations of one camera frame; `true_keys` receives the producing codes.
  DetectionFrame Draw(const Camera& camera, double stamp_s, const SE3d& T_world_camera,
                      std::vector<MarkerKey>* true_keys, SimStats* stats) {
    DetectionFrame frame;
    frame.stamp_s = stamp_s;
    frame.camera = camera.name();
    for (const SimMarker& marker : world_.markers) {
      const auto corners_px = VisibleCorners(camera, T_world_camera, marker, world_.occluders, limits_);
      if (!corners_px) continue;
      if (uniform_(*rng_) < noise_.miss_fraction) {
        ++stats->missed;
        continue;
      }
      MarkerObservation observation;
      observation.key = marker.key;
      bool inside = true;
      for (int i = 0; i < 4; ++i) {
        const double nx = normal_(*rng_), ny = normal_(*rng_);
        observation.corners_px[i] = (*corners_px)[i] + noise_.pixel_sigma_px * Eigen::Vector2d(nx, ny);
        inside = inside && camera.info().InImage(observation.corners_px[i]);
      }
      if (!inside) {
        ++stats->missed;
        continue;
      }
      if (uniform_(*rng_) < noise_.misdecode_fraction) {
        observation.key.id = WrongId(marker.key);
        ++stats->misdecoded;
      }
      frame.markers.push_back(observation);
      true_keys->push_back(marker.key);
      ++stats->detections;
    }
    return frame;
  }

 private:
  // Random text, or another code's id of the same family; never the true id.
  std::string WrongId(const MarkerKey& key) {
    const std::vector<std::string>& ids = ids_by_family_[key.family];
    if (ids.size() < 2 || uniform_(*rng_) < noise_.misdecode_random_share) {
      char text[32];
      std::snprintf(text, sizeof(text), "misread-%06llx",
                    static_cast<unsigned long long>((*rng_)() & 0xffffffULL));
      return text;
    }
    std::uniform_int_distribution<size_t> pick(0, ids.size() - 2);
    size_t index = pick(*rng_);
    if (ids[index] == key.id) index = ids.size() - 1;  // skip the true one
    return ids[index];
  }

  const World& world_;
  VisibilityLimits limits_;
  DetectionNoise noise_;
  std::mt19937_64* rng_;
  std::uniform_real_distribution<double> uniform_{0.0, 1.0};
  std::normal_distribution<double> normal_{0.0, 1.0};
  std::map<std::string, std::vector<std::string>> ids_by_family_;
};

// Camera frames are every `n`-th odometry sample; n must be a whole number.
int CameraStride(const ParamSet& params) {
  const double ratio = params.Double("rate.odometry_hz") / params.Double("rate.camera_hz");
  const long stride = std::lround(ratio);
  if (stride < 1 || std::abs(ratio - stride) > 1e-9) {
    throw std::invalid_argument("rate.camera_hz must divide rate.odometry_hz (got " +
                                FormatDouble(params.Double("rate.camera_hz")) + " and " +
                                FormatDouble(params.Double("rate.odometry_hz")) + ")");
  }
  return static_cast<int>(stride);
}

Trajectory SimulateOdometry(const Scene& scene, const ParamSet& params, std::uint64_t seed) {
  std::mt19937_64 rng = MakeRng(seed, kOdometryStream);
  const OdometrySigma sigma{params.Double("odometry.trans_per_m"), params.Double("odometry.rot_per_rad")};
  if (scene.odometry == OdometryKind::kWheel) {
    WheelOdometryModel model;
    model.track_width_m = params.Double("robot.track_width_m");
    model.wheel_radius_error_left = params.Double("odometry.wheel_radius_error_left");
    model.wheel_radius_error_right = params.Double("odometry.wheel_radius_error_right");
    model.track_width_error = params.Double("odometry.track_width_error");
    model.sigma = sigma;
    return SimulateWheelOdometry(scene.truth, model, &rng);
  }
  VisualOdometryModel model;
  model.scale_error = params.Double("odometry.scale_error");
  model.yaw_drift_rad_per_m = params.Double("odometry.yaw_drift_deg_per_m") * M_PI / 180.0;
  model.sigma = sigma;
  return SimulateVisualOdometry(scene.truth, model, &rng);
}

// The dataset's static parts: dataset.yaml fields, cameras, known and true markers.
void FillPlace(const SimResult& result, const ParamSet& params, Dataset* dataset) {
  const World& world = result.scene.world;
  DatasetConfig& config = dataset->config;
  config.name = world.name;
  config.motion = world.motion;
  config.default_marker_size_m = world.default_marker_size_m;
  config.odometry_sigma =
      OdometrySigma{params.Double("odometry.trans_per_m"), params.Double("odometry.rot_per_rad")};
  config.payload = world.payload;
  const double sigma_px = params.Double("detect.pixel_sigma_px");
  for (CameraInfo camera : world.calibrated_cameras.empty() ? world.cameras : world.calibrated_cameras) {
    if (sigma_px > 0.0) camera.pixel_sigma = sigma_px;
    config.cameras.push_back(camera.name);
    dataset->cameras[camera.name] = camera;
  }
  MarkerMap known, truth;
  for (const SimMarker& m : world.markers) {
    MapMarker entry;
    entry.key = m.key;
    entry.size_m = m.size_m;
    entry.T_world_marker = m.T_world_marker;
    entry.square_tape = m.square_tape;
    truth.markers.push_back(entry);
    // markers.json lists every code's size; only anchors also give their (fixed) pose.
    entry.fixed = m.anchor;
    entry.has_pose = m.anchor;
    if (!m.anchor) entry.T_world_marker = SE3d();
    known.markers.push_back(entry);
  }
  if (!known.markers.empty()) dataset->known_markers = known;
  dataset->groundtruth_markers = truth;
}

// Ground-truth `component` of each observed code: the trajectory segment it was seen in
// (segments are joined by nothing, docs/design.md); codes never observed get none.
void SetComponents(SimResult* result, const std::vector<int>& frame_segments) {
  std::map<MarkerKey, int> component;
  for (size_t i = 0; i < result->true_keys.size(); ++i) {
    for (const MarkerKey& key : result->true_keys[i]) component.emplace(key, frame_segments[i]);
  }
  for (MapMarker& m : result->dataset.groundtruth_markers->markers) {
    if (const auto it = component.find(m.key); it != component.end()) m.component = it->second;
  }
}

void CheckParams(const ParamSet& params) {
  if (params.Double("detect.min_range_m") > params.Double("detect.max_range_m")) {
    throw std::invalid_argument("detect.min_range_m is above detect.max_range_m");
  }
}

}  // namespace

SimResult Simulate(const std::string& scenario, const ParamSet& params, std::uint64_t seed) {
  CheckParams(params);
  const int stride = CameraStride(params);
  SimResult result;
  result.scenario = scenario;
  result.scene = BuildScene(scenario, params);
  const World& world = result.scene.world;
  const Trajectory& truth = result.scene.truth.T_world_robot;
  Dataset& dataset = result.dataset;
  FillPlace(result, params, &dataset);
  dataset.odometry = SimulateOdometry(result.scene, params, seed);
  dataset.has_odometry_file = true;
  dataset.groundtruth_trajectory = truth;

  const VisibilityLimits limits{params.Double("detect.min_range_m"), params.Double("detect.max_range_m"),
                                params.Double("detect.max_angle_deg"), params.Double("detect.border_px")};
  const DetectionNoise noise{params.Double("detect.pixel_sigma_px"), params.Double("detect.miss_fraction"),
                             params.Double("detect.misdecode_fraction"),
                             params.Double("detect.misdecode_random_share")};
  std::mt19937_64 rng = MakeRng(seed, kDetectionStream);
  DetectionDrawer drawer(world, limits, noise, &rng);
  std::vector<Camera> cameras;
  for (const CameraInfo& info : world.cameras) cameras.emplace_back(info);  // the true ones
  std::vector<int> frame_segments;
  for (size_t k = 0; k < truth.size(); k += stride) {
    for (const Camera& camera : cameras) {
      result.true_keys.emplace_back();
      const SE3d T_world_camera = truth[k].T * camera.info().T_robot_camera;
      dataset.detections.push_back(
          drawer.Draw(camera, truth[k].stamp_s, T_world_camera, &result.true_keys.back(), &result.stats));
      frame_segments.push_back(result.scene.truth.segment[k]);
      ++result.stats.frames;
    }
  }
  dataset.has_detections_file = true;
  SetComponents(&result, frame_segments);
  result.stats.markers = static_cast<long>(world.markers.size());
  result.stats.path_length_m = result.scene.truth.LengthM();
  result.stats.duration_s = truth.empty() ? 0.0 : truth.back().stamp_s - truth.front().stamp_s;
  return result;
}

std::string SummaryLine(const SimResult& result) {
  char line[256];
  std::snprintf(line, sizeof(line),
                "%s: %ld frames (%zu cameras), %ld detections (%ld misdecoded, %ld missed), %ld markers, "
                "%.1f m path, %.1f s",
                result.scenario.c_str(), result.stats.frames, result.scene.world.cameras.size(),
                result.stats.detections, result.stats.misdecoded, result.stats.missed, result.stats.markers,
                result.stats.path_length_m, result.stats.duration_s);
  return line;
}

}  // namespace waymark::sim
