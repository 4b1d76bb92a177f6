#include "sim/render_io.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>
#include <system_error>

#include "io/dataset_io.h"
#include "io/detections_io.h"
#include "io/util.h"

namespace waymark::sim {
namespace {

namespace fs = std::filesystem;

// The true T_world_robot at `stamp_s`: camera frames are taken at odometry samples exactly.
const SE3d& TruePoseAt(const Trajectory& truth, double stamp_s) {
  const auto it = std::lower_bound(truth.begin(), truth.end(), stamp_s,
                                   [](const StampedSE3& s, double t) { return s.stamp_s < t; });
  if (it == truth.end() || it->stamp_s != stamp_s) {
    throw std::logic_error("render: camera frame at t=" + FormatDouble(stamp_s) +
                           " is not a true-path sample");
  }
  return it->T;
}

std::string ImagePath(const std::string& camera, long frame_number) {
  char name[32];
  std::snprintf(name, sizeof(name), "%06ld.png", frame_number);
  return "images/" + camera + "/" + name;
}

// images.csv and the exact corners (groundtruth/corners.jsonl) of a rendered run.
void WriteRenderIndex(const fs::path& dir, const std::vector<ImageEntry>& images,
                      const std::vector<DetectionFrame>& truth_frames) {
  AtomicWriteFile(dir / "images.csv", FormatImagesCsv(images));
  std::error_code ec;
  fs::create_directories(dir / "groundtruth", ec);
  WriteDetections(dir / "groundtruth" / "corners.jsonl", truth_frames);
}

}  // namespace

RenderStats RenderRun(const SimResult& result, const RenderOptions& options, std::uint64_t seed, long every,
                      const fs::path& dir, const std::function<void(long, long)>& progress) {
  if (every < 1) throw std::invalid_argument("render: --render-every must be at least 1");
  const World& world = result.scene.world;
  const Renderer renderer(world, options);
  std::map<std::string, Camera> cameras;
  for (const auto& [name, info] : result.dataset.cameras) cameras.emplace(name, Camera(info));
  const long per_sample = static_cast<long>(std::max<size_t>(1, world.cameras.size()));
  const std::vector<DetectionFrame>& frames = result.dataset.detections;
  const long total = (static_cast<long>(frames.size()) / per_sample + every - 1) / every * per_sample;

  const auto start = std::chrono::steady_clock::now();
  std::vector<ImageEntry> images;
  std::vector<DetectionFrame> truth_frames;
  RenderStats stats;
  for (size_t i = 0; i < frames.size(); ++i) {
    const long frame_number = static_cast<long>(i) / per_sample;
    if (frame_number % every != 0) continue;
    const Camera& camera = cameras.at(frames[i].camera);
    const SE3d T_world_camera =
        TruePoseAt(result.scene.truth.T_world_robot, frames[i].stamp_s) * camera.info().T_robot_camera;
    const ImageEntry entry{frames[i].stamp_s, frames[i].camera, ImagePath(frames[i].camera, frame_number)};
    std::error_code ec;
    fs::create_directories((dir / entry.path).parent_path(), ec);
    const cv::Mat image = renderer.Render(camera, T_world_camera, seed, static_cast<std::uint64_t>(i));
    if (ec || !cv::imwrite((dir / entry.path).string(), image)) {
      throw std::runtime_error((dir / entry.path).string() + ": cannot write image");
    }
    DetectionFrame truth_frame;
    truth_frame.stamp_s = entry.stamp_s;
    truth_frame.camera = entry.camera;
    truth_frame.markers = renderer.GroundTruth(camera, T_world_camera);
    stats.codes += static_cast<long>(truth_frame.markers.size());
    truth_frames.push_back(std::move(truth_frame));
    images.push_back(entry);
    ++stats.images;
    if (progress) progress(stats.images, total);
  }
  WriteRenderIndex(dir, images, truth_frames);
  stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return stats;
}

SE3d InterpolateTrajectoryClamped(const Trajectory& truth, double stamp_s) {
  if (truth.empty()) throw std::logic_error("InterpolateTrajectoryClamped: empty trajectory");
  const auto it = std::lower_bound(truth.begin(), truth.end(), stamp_s,
                                   [](const StampedSE3& s, double t) { return s.stamp_s < t; });
  if (it == truth.begin()) return truth.front().T;
  if (it == truth.end()) return truth.back().T;
  const StampedSE3& a = *(it - 1);
  const StampedSE3& b = *it;
  return InterpolateProduct(a.T, b.T, (stamp_s - a.stamp_s) / (b.stamp_s - a.stamp_s));
}

RenderStats RenderIrRun(const SimResult& result, const IrOptions& options, std::uint64_t seed, long every,
                        const fs::path& dir, const std::function<void(long, long)>& progress) {
  if (every < 1) throw std::invalid_argument("render: --render-every must be at least 1");
  if (!result.scene.ir_room) throw std::logic_error("RenderIrRun: the scene has no infrared room");
  const World& world = result.scene.world;
  const IrRenderer renderer(world, *result.scene.ir_room, options, seed);
  std::map<std::string, Camera> cameras;  // the true ones
  for (const CameraInfo& info : world.cameras) cameras.emplace(info.name, Camera(info));
  const long per_sample = static_cast<long>(std::max<size_t>(1, world.cameras.size()));
  const std::vector<DetectionFrame>& frames = result.dataset.detections;
  const long total = (static_cast<long>(frames.size()) / per_sample + every - 1) / every * per_sample * 2;
  const Trajectory& truth = result.scene.truth.T_world_robot;
  const VisibilityLimits limits;  // every square whose corners are in the image

  const auto start = std::chrono::steady_clock::now();
  std::vector<ImageEntry> images;
  std::vector<DetectionFrame> truth_frames;
  RenderStats stats;
  for (size_t i = 0; i < frames.size(); ++i) {
    const long frame_number = static_cast<long>(i) / per_sample;
    if (frame_number % every != 0) continue;
    const Camera& camera = cameras.at(frames[i].camera);
    const double t_on = frames[i].stamp_s, t_off = t_on + options.pair_gap_s;
    for (const bool on : {true, false}) {
      const double t = on ? t_on : t_off;
      const SE3d T_world_camera = InterpolateTrajectoryClamped(truth, t) * camera.info().T_robot_camera;
      std::string path = ImagePath(frames[i].camera, frame_number);
      path.replace(path.size() - 4, 4, on ? "-on.png" : "-off.png");
      const ImageEntry entry{t, frames[i].camera, path};
      std::error_code ec;
      fs::create_directories((dir / entry.path).parent_path(), ec);
      const cv::Mat image =
          renderer.Render(camera, T_world_camera, t, on, 2 * static_cast<std::uint64_t>(i) + (on ? 0 : 1));
      if (ec || !cv::imwrite((dir / entry.path).string(), image)) {
        throw std::runtime_error((dir / entry.path).string() + ": cannot write image");
      }
      images.push_back(entry);
      ++stats.images;
      if (on) {
        DetectionFrame truth_frame;
        truth_frame.stamp_s = t_on;
        truth_frame.camera = entry.camera;
        for (const SimMarker& marker : world.markers) {
          const auto corners = VisibleCorners(camera, T_world_camera, marker, {}, limits);
          if (!corners) continue;
          MarkerObservation observation;
          observation.key = marker.key;
          observation.corners_px = *corners;
          truth_frame.markers.push_back(observation);
        }
        stats.codes += static_cast<long>(truth_frame.markers.size());
        truth_frames.push_back(std::move(truth_frame));
      }
      if (progress) progress(stats.images, total);
    }
  }
  WriteRenderIndex(dir, images, truth_frames);
  stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return stats;
}

}  // namespace waymark::sim
