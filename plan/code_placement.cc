#include "plan/code_placement.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <stdexcept>

#include "eval/map_metrics.h"
#include "mapping/map_builder.h"
#include "runner/run.h"
#include "sim/world.h"
#include "util/check.h"
#include "util/format.h"

namespace waymark::plan {
namespace {

struct Candidate {
  sim::SimMarker marker;
  int frames = 0;
};

// Every candidate code of a layout (both faces of every wall).
std::vector<sim::SimMarker> Candidates(const FloorPlan& plan, double size_m, double spacing_m) {
  std::vector<sim::SimMarker> out;
  for (const FloorWall& wall : plan.walls) {
    const Eigen::Vector2d d = (wall.to_world - wall.from_world).normalized();
    const double length = (wall.to_world - wall.from_world).norm();
    const double margin = plan.margin_m + size_m;
    if (plan.code_height_m + 0.5 * size_m > wall.height_m) continue;
    for (const double side : {1.0, -1.0}) {
      const Eigen::Vector2d normal = side * Eigen::Vector2d(-d.y(), d.x());
      for (double s = 0.5 * spacing_m; s <= length - margin + 1e-9; s += spacing_m) {
        if (s < margin - 1e-9) continue;
        const Eigen::Vector2d c = wall.from_world + s * d;
        sim::SimMarker m;
        m.size_m = size_m;
        m.T_world_marker =
            sim::WallMarkerPose({c.x(), c.y(), plan.code_height_m}, {normal.x(), normal.y(), 0.0});
        out.push_back(m);
      }
    }
  }
  return out;
}

std::vector<sim::Occluder> Walls(const FloorPlan& plan) {
  std::vector<sim::Occluder> out;
  for (const FloorWall& w : plan.walls)
    out.push_back(sim::VerticalWall(w.from_world, w.to_world, 0.0, w.height_m));
  return out;
}

// Camera frames: every stride-th path sample, stride = path rate / camera_hz (at least 1).
size_t Stride(const FloorPlan& plan, const Trajectory& path) {
  const double duration = path.back().stamp_s - path.front().stamp_s;
  if (!(duration > 0.0)) return 1;
  const double rate = (path.size() - 1) / duration;
  return std::max<size_t>(1, static_cast<size_t>(std::lround(rate / plan.camera_hz)));
}

bool SegmentsCross(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c,
                   const Eigen::Vector2d& d) {
  auto cross = [](const Eigen::Vector2d& u, const Eigen::Vector2d& v) {
    return u.x() * v.y() - u.y() * v.x();
  };
  const double d1 = cross(b - a, c - a), d2 = cross(b - a, d - a), d3 = cross(d - c, a - c),
               d4 = cross(d - c, b - c);
  return ((d1 > 0 && d2 < 0) || (d1 < 0 && d2 > 0)) && ((d3 > 0 && d4 < 0) || (d3 < 0 && d4 > 0));
}

double PositionSigma(const Matrix6d& covariance) {
  return std::sqrt(covariance.bottomRightCorner<3, 3>().trace());
}

}  // namespace

bool PlacementOptions::Check(std::string* why) const {
  WAYMARK_CHECK_OPTION(IsFinitePositive(target_m), "the target error must be > 0");
  WAYMARK_CHECK_OPTION(!spacings_m.empty(), "at least one spacing");
  for (double s : spacings_m) WAYMARK_CHECK_OPTION(IsFinitePositive(s), "spacings must be > 0");
  return true;
}

void CheckPath(const FloorPlan& plan, const Trajectory& path) {
  if (path.size() < 2) throw std::invalid_argument("the path has fewer than two poses");
  Eigen::Vector2d lo = plan.walls.front().from_world, hi = lo;
  for (const FloorWall& w : plan.walls) {
    lo = lo.cwiseMin(w.from_world).cwiseMin(w.to_world);
    hi = hi.cwiseMax(w.from_world).cwiseMax(w.to_world);
  }
  for (size_t i = 0; i < path.size(); ++i) {
    const Eigen::Vector2d p = path[i].T.translation().head<2>();
    if ((p.array() < lo.array()).any() || (p.array() > hi.array()).any()) {
      throw std::invalid_argument(
          "pose " + std::to_string(i + 1) + " of the path (t = " + FormatFixed(path[i].stamp_s, 3) +
          " s) at (" + FormatFixed(p.x(), 2) + ", " + FormatFixed(p.y(), 2) +
          ") is outside the floor plan (walls span [" + FormatDouble(lo.x()) + ", " + FormatDouble(hi.x()) +
          "] x [" + FormatDouble(lo.y()) + ", " + FormatDouble(hi.y()) + "])");
    }
    if (i == 0) continue;
    const Eigen::Vector2d q = path[i - 1].T.translation().head<2>();
    for (size_t w = 0; w < plan.walls.size(); ++w) {
      if (SegmentsCross(q, p, plan.walls[w].from_world, plan.walls[w].to_world)) {
        throw std::invalid_argument("pose " + std::to_string(i + 1) +
                                    " of the path (t = " + FormatFixed(path[i].stamp_s, 3) +
                                    " s) is behind wall " + std::to_string(w + 1) + ": the path crosses it");
      }
    }
  }
}

LayoutPrediction PredictLayout(const FloorPlan& plan, const Trajectory& path, double size_m,
                               double spacing_m) {
  LayoutPrediction out;
  out.size_m = size_m;
  out.spacing_m = spacing_m;
  const std::vector<sim::Occluder> walls = Walls(plan);
  const sim::VisibilityLimits limits{plan.min_range_m, plan.max_range_m, plan.max_angle_deg, plan.border_px};
  std::vector<Camera> cameras;
  for (CameraInfo info : plan.cameras) {
    info.pixel_sigma = plan.pixel_sigma_px;
    cameras.emplace_back(info);
  }
  const size_t stride = Stride(plan, path);
  std::vector<Candidate> candidates;
  for (const sim::SimMarker& m : Candidates(plan, size_m, spacing_m)) candidates.push_back({m, 0});
  // Visibility of every candidate in every frame (exact corners), then keep those seen twice.
  struct View {
    size_t frame;
    size_t camera;
    size_t candidate;
    std::array<Eigen::Vector2d, 4> corners;
  };
  std::vector<View> views;
  for (size_t k = 0; k < path.size(); k += stride) {
    for (size_t c = 0; c < cameras.size(); ++c) {
      const SE3d T_world_camera = path[k].T * cameras[c].info().T_robot_camera;
      for (size_t i = 0; i < candidates.size(); ++i) {
        const auto corners =
            sim::VisibleCorners(cameras[c], T_world_camera, candidates[i].marker, walls, limits);
        if (!corners) continue;
        views.push_back({k, c, i, *corners});
        ++candidates[i].frames;
      }
    }
  }
  std::vector<int> index(candidates.size(), -1);
  Dataset survey;
  survey.config.name = "plan-codes";
  survey.config.motion = MotionModel::kPlanar;
  survey.config.default_marker_size_m = size_m;
  survey.config.odometry_sigma = plan.odometry_sigma;
  MarkerMap known;
  for (size_t i = 0; i < candidates.size(); ++i) {
    if (candidates[i].frames < 2) continue;
    index[i] = static_cast<int>(known.markers.size());
    char id[32];
    std::snprintf(id, sizeof(id), "P%03zu", known.markers.size());
    MapMarker m;
    m.key = {plan.family, id};
    m.size_m = size_m;
    m.T_world_marker = candidates[i].marker.T_world_marker;
    m.fixed = static_cast<int>(known.markers.size()) < plan.anchors;
    out.markers.markers.push_back(m);
    m.has_pose = m.fixed;
    known.markers.push_back(m);
  }
  if (known.markers.empty()) return out;
  for (const Camera& camera : cameras) {
    survey.config.cameras.push_back(camera.name());
    survey.cameras[camera.name()] = camera.info();
  }
  survey.known_markers = known;
  survey.odometry = path;
  survey.has_odometry_file = true;
  survey.has_detections_file = true;
  size_t v = 0;
  for (size_t k = 0; k < path.size(); k += stride) {
    for (size_t c = 0; c < cameras.size(); ++c) {
      DetectionFrame frame;
      frame.stamp_s = path[k].stamp_s;
      frame.camera = cameras[c].name();
      for (; v < views.size() && views[v].frame == k && views[v].camera == c; ++v) {
        if (index[views[v].candidate] < 0) continue;
        frame.markers.push_back(
            {known.markers[index[views[v].candidate]].key, views[v].corners, std::nullopt});
      }
      survey.detections.push_back(frame);
    }
  }
  const MapBuildResult build = BuildMap(survey);
  out.components = static_cast<int>(build.components.size());
  out.unmapped = static_cast<int>(build.unmapped.size());
  out.map_rms_m = eval::PooledAlignedRms(eval::PredictMapError(build.map));
  // Codes the build leaves unmapped are of no use: left out of the layout.
  std::vector<MapMarker> mapped;
  for (MapMarker& m : out.markers.markers) {
    const MapMarker* built = build.map.Find(m.key);
    if (!built) continue;
    if (built->covariance) m.covariance = built->covariance;
    mapped.push_back(m);
  }
  out.markers.markers = mapped;
  // The pose relative to the map (the map taken as exact): routes and goals are given in the
  // map's frame, so the map's own frame error moves them with the robot; it is the map criterion.
  LocalizeRunOptions options;
  options.localizer = DefaultLocalizerOptions(survey);
  options.localizer.map_uncertainty = MapUncertainty::kIgnore;
  const LocalizeRun run = RunLocalizer(survey, build.map, options);
  // Arc length along the path at each stamp.
  std::map<double, double> along;
  double s = 0.0;
  for (size_t k = 0; k < path.size(); ++k) {
    if (k > 0) s += (path[k].T.translation() - path[k - 1].T.translation()).head<2>().norm();
    along[path[k].stamp_s] = s;
  }
  out.path_length_m = s;
  out.per_metre.resize(static_cast<size_t>(std::floor(s)) + 1);
  for (size_t b = 0; b < out.per_metre.size(); ++b) out.per_metre[b].from_m = static_cast<double>(b);
  std::vector<std::set<MarkerKey>> seen(out.per_metre.size());
  double sum2 = 0.0;
  long tracked = 0;
  long since_start = 0;  // frames from the first tracked one on
  for (const PoseOutput& pose : run.outputs) {
    if (since_start > 0 || pose.tracking == TrackingStatus::kTracking) ++since_start;
    if (since_start == 0) continue;
    const size_t bin = std::min(out.per_metre.size() - 1, static_cast<size_t>(along[pose.stamp_s]));
    if (pose.tracking != TrackingStatus::kTracking || !pose.covariance) {
      out.per_metre[bin].online_max_sigma_m = std::numeric_limits<double>::infinity();
      continue;
    }
    const double sigma = std::sqrt((*pose.covariance)(0, 0) + (*pose.covariance)(1, 1));
    sum2 += sigma * sigma;
    ++tracked;
    out.online_max_m = std::max(out.online_max_m, sigma);
    out.per_metre[bin].online_max_sigma_m = std::max(out.per_metre[bin].online_max_sigma_m, sigma);
  }
  for (const DetectionFrame& frame : survey.detections) {
    const size_t bin = std::min(out.per_metre.size() - 1, static_cast<size_t>(along[frame.stamp_s]));
    for (const MarkerObservation& o : frame.markers) seen[bin].insert(o.key);
  }
  for (size_t b = 0; b < seen.size(); ++b) {
    double map2 = 0.0;
    int n = 0;
    for (const MarkerKey& key : seen[b]) {
      const MapMarker* m = build.map.Find(key);
      if (!m || !m->covariance) continue;
      map2 += std::pow(PositionSigma(*m->covariance), 2);
      ++n;
    }
    out.per_metre[b].codes_in_view = static_cast<int>(seen[b].size());
    out.per_metre[b].map_sigma_m = n ? std::sqrt(map2 / n) : 0.0;
  }
  out.tracked_fraction = since_start == 0 ? 0.0 : static_cast<double>(tracked) / since_start;
  out.online_rms_m = tracked ? std::sqrt(sum2 / tracked) : std::numeric_limits<double>::infinity();
  return out;
}

PlacementResult PlanCodes(const FloorPlan& plan, const Trajectory& path, const PlacementOptions& options) {
  std::string why;
  if (!options.Check(&why)) throw std::invalid_argument("plan-codes: " + why);
  CheckPath(plan, path);
  std::vector<double> sizes = plan.code_sizes_m;
  std::sort(sizes.begin(), sizes.end());
  std::vector<double> spacings = options.spacings_m;
  std::sort(spacings.rbegin(), spacings.rend());
  PlacementResult result;
  for (double size : sizes) {
    for (double spacing : spacings) {
      LayoutPrediction p = PredictLayout(plan, path, size, spacing);
      p.meets = p.map_rms_m && *p.map_rms_m <= options.target_m && p.online_rms_m <= options.target_m &&
                p.components == 1 && p.tracked_fraction >= 0.95;
      if (options.progress) {
        options.progress("size " + FormatDouble(size) + " m, spacing " + FormatDouble(spacing) +
                         " m: " + std::to_string(p.markers.markers.size()) + " codes, map " +
                         (p.map_rms_m ? FormatFixed(1000.0 * *p.map_rms_m, 1) + " mm" : std::string("-")) +
                         ", online " + FormatFixed(1000.0 * p.online_rms_m, 1) + " mm" +
                         (p.meets ? " (meets the target)" : ""));
      }
      result.tried.push_back(std::move(p));
      const LayoutPrediction& last = result.tried.back();
      if (!last.meets) continue;
      if (result.chosen < 0 ||
          last.markers.markers.size() < result.tried[result.chosen].markers.markers.size()) {
        result.chosen = static_cast<int>(result.tried.size()) - 1;
      }
      break;  // denser layouts of this size have more codes
    }
  }
  return result;
}

}  // namespace waymark::plan
