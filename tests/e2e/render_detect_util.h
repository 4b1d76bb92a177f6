// End to end, in process: a scenario's place and path (sim/scenarios.h), frames rendered
// by sim::Renderer, the project's detectors on every image, and the detections matched to
// the renderer's exact ground truth (Renderer::GroundTruth: the codes fully visible, within
// 89 deg, unoccluded). Acceptance (issue 3): of the codes whose shortest side is over
// 40 px, >= 98 % detected with their exact id and all four corners within 0.5 px, and no
// detection with an id that is not in the world.
//
// Frames: every camera frame of the path (odometry samples at the camera rate, every
// camera) that shows at least one code over 40 px is a candidate; `frames` of them,
// evenly spread over the run, are rendered (seed kRenderSeed, image index = the frame's
// number). A scenario can be redrawn in another family (`family`): every code keeps its
// place and size; DataMatrix keeps the text, AprilTag takes the code's index as its tag
// number.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "detect/detector.h"
#include "geometry/camera.h"
#include "sim/render.h"
#include "sim/scenarios.h"

namespace waymark::e2e {

inline constexpr double kWideCodePx = 40.0;  // issue 3: codes wider than 40 px
inline constexpr double kCornerTolerancePx = 0.5;
inline constexpr std::uint64_t kRenderSeed = 11;

struct FamilyTally {
  long wide = 0;          // ground-truth codes over kWideCodePx
  long matched = 0;       // of those: exact id, every corner within kCornerTolerancePx
  long detected = 0;      // of those: exact id found (any corner error)
  double worst_px = 0.0;  // largest corner error of a detected wide code
  long misread = 0;       // detections whose id is not in the world
};

struct E2eRun {
  long images = 0;
  std::map<std::string, FamilyTally> families;  // by family
};

// One camera frame: camera index and T_world_camera.
struct FrameAt {
  size_t camera = 0;
  long number = 0;
  SE3d T_world_camera;
};

// The scenario's world with every code redrawn in `family` ("" keeps the scenario's).
inline sim::World Redrawn(sim::World world, const std::string& family) {
  if (family.empty()) return world;
  for (size_t i = 0; i < world.markers.size(); ++i) {
    MarkerKey& key = world.markers[i].key;
    key.family = family;
    if (family.rfind("apriltag-", 0) == 0) key.id = std::to_string(i);
  }
  return world;
}

inline bool HasWideCode(const std::vector<MarkerObservation>& truth) {
  return std::any_of(truth.begin(), truth.end(), [](const MarkerObservation& t) {
    return sim::ShortestSidePx(t.corners_px) > kWideCodePx;
  });
}

// `count` frames with a wide code, evenly spread over the path's camera frames.
inline std::vector<FrameAt> PickFrames(const sim::Scene& scene, const sim::ParamSet& params,
                                       const sim::Renderer& renderer, const std::vector<Camera>& cameras,
                                       size_t count) {
  const long step =
      std::max(1L, std::lround(params.Double("rate.odometry_hz") / params.Double("rate.camera_hz")));
  const Trajectory& path = scene.truth.T_world_robot;
  std::vector<FrameAt> candidates;
  for (size_t s = 0; s < path.size(); s += static_cast<size_t>(step)) {
    for (size_t c = 0; c < cameras.size(); ++c) {
      const SE3d T_world_camera = path[s].T * cameras[c].info().T_robot_camera;
      if (HasWideCode(renderer.GroundTruth(cameras[c], T_world_camera))) {
        candidates.push_back({c, static_cast<long>(s / step), T_world_camera});
      }
    }
  }
  std::vector<FrameAt> picked;
  for (size_t k = 0; k < count && k < candidates.size(); ++k) {
    picked.push_back(candidates[k * candidates.size() / std::min(count, candidates.size())]);
  }
  return picked;
}

// Tallies one image's detections against its ground truth.
inline void Tally(const std::vector<MarkerObservation>& truth, const std::vector<MarkerObservation>& found,
                  const std::set<MarkerKey>& world_keys, std::map<std::string, FamilyTally>* families) {
  for (const MarkerObservation& obs : found)
    (*families)[obs.key.family].misread += world_keys.count(obs.key) == 0;
  for (const MarkerObservation& t : truth) {
    if (sim::ShortestSidePx(t.corners_px) <= kWideCodePx) continue;
    FamilyTally& tally = (*families)[t.key.family];
    ++tally.wide;
    for (const MarkerObservation& obs : found) {
      if (obs.key != t.key) continue;
      double max_px = 0.0;
      for (int k = 0; k < 4; ++k) max_px = std::max(max_px, (obs.corners_px[k] - t.corners_px[k]).norm());
      ++tally.detected;
      tally.worst_px = std::max(tally.worst_px, max_px);
      tally.matched += max_px <= kCornerTolerancePx;
      break;
    }
  }
}

// Renders `frames` frames of `scenario` (its default keys), codes in `family` ("" = the
// scenario's), detects with the detectors of the world's families, and tallies.
inline E2eRun RenderAndDetect(const std::string& scenario, const std::string& family, size_t frames) {
  const sim::ParamSet params = sim::ScenarioParams(scenario);
  const sim::Scene scene = sim::BuildScene(scenario, params);
  const sim::World world = Redrawn(scene.world, family);
  const sim::Renderer renderer(world, sim::RenderOptionsFromParams(params));
  std::vector<Camera> cameras;
  for (const CameraInfo& info : world.cameras) cameras.emplace_back(info);
  std::set<MarkerKey> world_keys;
  std::set<std::string> world_families;
  for (const sim::SimMarker& m : world.markers) {
    world_keys.insert(m.key);
    world_families.insert(m.key.family);
  }
  // Default options: the second passes are bounded by counts, so ctest's load cannot change
  // what is read.
  const auto detector = CreateMultiDetector({world_families.begin(), world_families.end()});
  E2eRun run;
  for (const FrameAt& frame : PickFrames(scene, params, renderer, cameras, frames)) {
    const Camera& camera = cameras[frame.camera];
    const cv::Mat image =
        renderer.Render(camera, frame.T_world_camera, kRenderSeed, static_cast<std::uint64_t>(frame.number));
    Tally(renderer.GroundTruth(camera, frame.T_world_camera), detector->Detect(image), world_keys,
          &run.families);
    ++run.images;
  }
  return run;
}

// Prints one line per family and checks the acceptance; at least `min_wide` wide codes.
inline void ExpectAccepted(const std::string& label, const E2eRun& run, long min_wide) {
  long wide = 0;
  for (const auto& [family, t] : run.families) {
    std::printf(
        "%-28s %-15s %3ld images: %ld/%ld wide codes matched (%.1f %%), %ld detected, worst corner "
        "error %.3f px, %ld misread\n",
        label.c_str(), family.c_str(), run.images, t.matched, t.wide,
        t.wide > 0 ? 100.0 * t.matched / t.wide : 0.0, t.detected, t.worst_px, t.misread);
    wide += t.wide;
    EXPECT_GE(static_cast<double>(t.matched), 0.98 * t.wide) << label << " " << family;
    EXPECT_EQ(t.misread, 0) << label << " " << family;
  }
  EXPECT_GE(wide, min_wide) << label;
}

}  // namespace waymark::e2e
