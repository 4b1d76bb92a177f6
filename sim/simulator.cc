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

SimResult Simulate(const std::string& scenario, const ParamSet& params, std::uint64_t seed,
                   const std::vector<SimMarker>* markers) {
  CheckParams(params);
  const int stride = CameraStride(params);
  SimResult result;
  result.scenario = scenario;
  result.scene = BuildScene(scenario, params);
  if (markers) result.scene.world.markers = *markers;
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

struct SimStepper::Impl {
  ParamSet params;
  SimResult result;
  int stride = 1;
  double period_s = 0.0;
  double height_m = 0.0;
  std::mt19937_64 odometry_rng, detection_rng;
  std::normal_distribution<double> normal{0.0, 1.0};
  WheelOdometryModel model;
  std::unique_ptr<DetectionDrawer> drawer;
  std::vector<Camera> cameras;
  std::vector<int> frame_segments;
  SE2d T_world_robot, T_odom_robot;
  long k = 0;
  Sample first;

  Sample Record() {
    Sample sample;
    sample.stamp_s = k * period_s;
    sample.T_odom_robot = T_odom_robot.ToSE3();
    const SE3d T_world = T_world_robot.ToSE3(height_m);
    result.scene.truth.T_world_robot.push_back({sample.stamp_s, T_world});
    result.scene.truth.segment.push_back(0);
    result.dataset.odometry.push_back({sample.stamp_s, sample.T_odom_robot});
    if (k % stride == 0) {
      for (const Camera& camera : cameras) {
        result.true_keys.emplace_back();
        const SE3d T_world_camera = T_world * camera.info().T_robot_camera;
        sample.frames.push_back(
            drawer->Draw(camera, sample.stamp_s, T_world_camera, &result.true_keys.back(), &result.stats));
        result.dataset.detections.push_back(sample.frames.back());
        frame_segments.push_back(0);
        ++result.stats.frames;
      }
    }
    return sample;
  }
};

SimStepper::SimStepper(const std::string& scenario, const ParamSet& params, std::uint64_t seed,
                       const SE2d& T_world_start)
    : impl_(std::make_unique<Impl>()) {
  CheckParams(params);
  Impl& m = *impl_;
  m.params = params;
  m.stride = CameraStride(params);
  m.period_s = 1.0 / params.Double("rate.odometry_hz");
  m.result.scenario = scenario;
  m.result.scene = BuildScene(scenario, params);
  if (m.result.scene.odometry != OdometryKind::kWheel ||
      m.result.scene.world.motion != MotionModel::kPlanar) {
    throw std::invalid_argument("scenario " + scenario + " is not a planar robot with wheel odometry");
  }
  if (!m.result.scene.truth.T_world_robot.empty()) {
    m.height_m = m.result.scene.truth.T_world_robot.front().T.translation().z();
  }
  m.result.scene.truth = SimTrajectory();
  FillPlace(m.result, params, &m.result.dataset);
  m.result.dataset.has_odometry_file = true;
  m.result.dataset.has_detections_file = true;
  m.odometry_rng = MakeRng(seed, kOdometryStream);
  m.detection_rng = MakeRng(seed, kDetectionStream);
  m.model.track_width_m = params.Double("robot.track_width_m");
  m.model.wheel_radius_error_left = params.Double("odometry.wheel_radius_error_left");
  m.model.wheel_radius_error_right = params.Double("odometry.wheel_radius_error_right");
  m.model.track_width_error = params.Double("odometry.track_width_error");
  m.model.sigma = OdometrySigma{params.Double("odometry.trans_per_m"), params.Double("odometry.rot_per_rad")};
  const VisibilityLimits limits{params.Double("detect.min_range_m"), params.Double("detect.max_range_m"),
                                params.Double("detect.max_angle_deg"), params.Double("detect.border_px")};
  const DetectionNoise noise{params.Double("detect.pixel_sigma_px"), params.Double("detect.miss_fraction"),
                             params.Double("detect.misdecode_fraction"),
                             params.Double("detect.misdecode_random_share")};
  m.drawer = std::make_unique<DetectionDrawer>(m.result.scene.world, limits, noise, &m.detection_rng);
  for (const CameraInfo& info : m.result.scene.world.cameras) m.cameras.emplace_back(info);
  m.T_world_robot = T_world_start;
  m.first = m.Record();
}

SimStepper::~SimStepper() = default;

const SimStepper::Sample& SimStepper::first() const { return impl_->first; }
const SE2d& SimStepper::T_world_robot() const { return impl_->T_world_robot; }
double SimStepper::period_s() const { return impl_->period_s; }
const Dataset& SimStepper::dataset() const { return impl_->result.dataset; }

SimStepper::Sample SimStepper::Advance(double v_mps, double omega_radps) {
  Impl& m = *impl_;
  const double s = v_mps * m.period_s, dtheta = omega_radps * m.period_s;
  const SE2d step = std::abs(dtheta) < 1e-12
                        ? SE2d(s, 0.0, 0.0)
                        : SE2d(s / dtheta * std::sin(dtheta), s / dtheta * (1.0 - std::cos(dtheta)), dtheta);
  m.T_world_robot = m.T_world_robot * step;
  m.T_odom_robot = m.T_odom_robot * WheelOdometryStep(step, m.model, &m.odometry_rng, &m.normal);
  ++m.k;
  return m.Record();
}

SimResult SimStepper::Finish() {
  Impl& m = *impl_;
  m.result.dataset.groundtruth_trajectory = m.result.scene.truth.T_world_robot;
  SetComponents(&m.result, m.frame_segments);
  m.result.stats.markers = static_cast<long>(m.result.scene.world.markers.size());
  m.result.stats.path_length_m = m.result.scene.truth.LengthM();
  const Trajectory& truth = m.result.scene.truth.T_world_robot;
  m.result.stats.duration_s = truth.empty() ? 0.0 : truth.back().stamp_s - truth.front().stamp_s;
  m.drawer.reset();
  SimResult out = std::move(m.result);
  impl_.reset();
  return out;
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
