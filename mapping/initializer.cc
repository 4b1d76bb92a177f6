#include "mapping/initializer.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include <ceres/ceres.h>

#include "mapping/residuals.h"

namespace waymark {
namespace {

// Union-find over frames [0, F) and markers [F, F + M).
class DisjointSets {
 public:
  explicit DisjointSets(size_t n) : parent_(n) { std::iota(parent_.begin(), parent_.end(), 0); }
  size_t Find(size_t i) {
    while (parent_[i] != i) i = parent_[i] = parent_[parent_[i]];
    return i;
  }
  void Join(size_t a, size_t b) { parent_[Find(a)] = Find(b); }

 private:
  std::vector<size_t> parent_;
};

double QuadArea(const std::array<Eigen::Vector2d, 4>& c) {
  double twice = 0.0;
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector2d& a = c[i];
    const Eigen::Vector2d& b = c[(i + 1) % 4];
    twice += a.x() * b.y() - b.x() * a.y();
  }
  return 0.5 * std::abs(twice);
}

// The state of one component's placement.
class Placer {
 public:
  Placer(const Survey& survey, const std::map<std::string, Camera>& cameras, const InitializerOptions& options,
         Initialization* init)
      : survey_(survey), cameras_(cameras), options_(options), init_(init) {
    prev_link_.assign(survey.frames.size(), -1);
    next_link_.assign(survey.frames.size(), -1);
    for (size_t i = 0; i < survey.odometry_links.size(); ++i) {
      next_link_[survey.odometry_links[i].frame_a] = static_cast<int>(i);
      prev_link_[survey.odometry_links[i].frame_b] = static_cast<int>(i);
    }
  }

  void PlaceComponent(int component);

 private:
  bool PlaceFrame(int frame);
  void PlaceMarkersSeenBy(int frame, bool ambiguous_too);
  void PlaceDeferredMarkers(const std::vector<int>& frames);
  double RobustCost(int frame, const SE3d& T_world_robot) const;
  SE3d RefineFrame(int frame, const SE3d& T_world_robot) const;
  SE3d Planarize(const SE3d& T) const {
    return survey_.motion == MotionModel::kPlanar ? SE2d::FromSE3(T).ToSE3() : T;
  }

  const Survey& survey_;
  const std::map<std::string, Camera>& cameras_;
  const InitializerOptions& options_;
  Initialization* init_;
  std::vector<int> prev_link_, next_link_;
};

bool Placer::PlaceFrame(int frame) {
  std::vector<SE3d> candidates;
  for (int o : survey_.frames[frame].observations) {
    const SingleView& view = init_->views[o];
    const auto& T_world_marker = init_->T_world_marker[survey_.observations[o].marker];
    if (!view.usable || !T_world_marker) continue;
    for (const SE3d& T_robot_marker : view.T_robot_marker) {
      candidates.push_back(Planarize(*T_world_marker * T_robot_marker.inverse()));
    }
  }
  const bool from_codes = !candidates.empty();
  if (const int l = prev_link_[frame]; l >= 0 && init_->T_world_robot[survey_.odometry_links[l].frame_a]) {
    const OdometryLink& link = survey_.odometry_links[l];
    candidates.push_back(Planarize(*init_->T_world_robot[link.frame_a] * link.T_a_b));
  }
  if (const int l = next_link_[frame]; l >= 0 && init_->T_world_robot[survey_.odometry_links[l].frame_b]) {
    const OdometryLink& link = survey_.odometry_links[l];
    candidates.push_back(Planarize(*init_->T_world_robot[link.frame_b] * link.T_a_b.inverse()));
  }
  if (candidates.empty()) return false;
  if (!from_codes) {
    init_->T_world_robot[frame] = candidates.front();
    return true;
  }
  double best_cost = std::numeric_limits<double>::infinity();
  SE3d best = candidates.front();
  for (const SE3d& candidate : candidates) {
    const double cost = RobustCost(frame, candidate);
    if (cost < best_cost) {
      best_cost = cost;
      best = candidate;
    }
  }
  if (!std::isfinite(best_cost)) return false;
  init_->T_world_robot[frame] = RefineFrame(frame, best);
  return true;
}

// Sum over the frame's placed codes of the Cauchy cost of their whitened residuals.
double Placer::RobustCost(int frame, const SE3d& T_world_robot) const {
  const double c2 = options_.cauchy_scale * options_.cauchy_scale;
  double cost = 0.0;
  for (int o : survey_.frames[frame].observations) {
    const SurveyObservation& obs = survey_.observations[o];
    const auto& T_world_marker = init_->T_world_marker[obs.marker];
    if (!init_->views[o].usable || !T_world_marker) continue;
    const Camera& camera = cameras_.at(obs.camera);
    const SE3d T_camera_marker =
        (T_world_robot * camera.info().T_robot_camera).inverse() * *T_world_marker;
    const double rms = MarkerReprojectionRms(obs.corners_px, survey_.markers[obs.marker].size_m, camera,
                                             T_camera_marker);
    const double s = std::isfinite(rms) ? 4.0 * rms * rms / std::pow(CornerSigmaPx(camera.info()), 2) : 1e12;
    cost += c2 * std::log1p(s / c2);
  }
  return cost;
}

// PnP of the frame against its placed codes (codes held constant), Cauchy loss.
SE3d Placer::RefineFrame(int frame, const SE3d& T_world_robot) const {
  ceres::Problem::Options problem_options;
  ceres::Problem problem(problem_options);
  PoseBlock robot;
  RobotToBlock(survey_.motion, T_world_robot, &robot);
  AddRobotBlock(&problem, survey_.motion, &robot);
  std::vector<PoseBlock> markers;
  markers.reserve(survey_.frames[frame].observations.size());
  for (int o : survey_.frames[frame].observations) {
    const SurveyObservation& obs = survey_.observations[o];
    const auto& T_world_marker = init_->T_world_marker[obs.marker];
    if (!init_->views[o].usable || !T_world_marker) continue;
    const Camera& camera = cameras_.at(obs.camera);
    const SE3d T_camera_marker = (T_world_robot * camera.info().T_robot_camera).inverse() * *T_world_marker;
    // A code behind the camera at the start would make the solve fail at its first evaluation.
    if (!std::isfinite(MarkerReprojectionRms(obs.corners_px, survey_.markers[obs.marker].size_m, camera,
                                             T_camera_marker))) {
      continue;
    }
    markers.emplace_back();
    SE3ToBlock(*T_world_marker, markers.back().data());
    AddMarkerBlock(&problem, &markers.back());
    problem.SetParameterBlockConstant(markers.back().data());
    AddCornerResidual(&problem, survey_.motion, cameras_.at(obs.camera).info(), survey_.markers[obs.marker].size_m,
                      obs.corners_px, &robot, &markers.back(), new ceres::CauchyLoss(options_.cauchy_scale));
  }
  ceres::Solver::Options solver_options;
  solver_options.max_num_iterations = options_.pnp_iterations;
  solver_options.linear_solver_type = ceres::DENSE_QR;
  solver_options.num_threads = 1;
  ceres::Solver::Summary summary;
  ceres::Solve(solver_options, &problem, &summary);
  const SE3d refined = RobotFromBlock(survey_.motion, robot);
  return refined.IsFinite() ? refined : T_world_robot;
}

void Placer::PlaceMarkersSeenBy(int frame, bool ambiguous_too) {
  const SE3d& T_world_robot = *init_->T_world_robot[frame];
  for (int o : survey_.frames[frame].observations) {
    const SingleView& view = init_->views[o];
    const int m = survey_.observations[o].marker;
    if (!view.usable || init_->T_world_marker[m]) continue;
    if (!ambiguous_too && view.error_ratio < options_.ambiguity_ratio) continue;
    init_->T_world_marker[m] = T_world_robot * view.T_robot_marker.front();
  }
}

// Codes seen only ambiguously: placed from their view with the largest error ratio.
void Placer::PlaceDeferredMarkers(const std::vector<int>& frames) {
  std::map<int, int> best_view;  // marker -> observation
  for (int f : frames) {
    if (!init_->T_world_robot[f]) continue;
    for (int o : survey_.frames[f].observations) {
      const int m = survey_.observations[o].marker;
      if (!init_->views[o].usable || init_->T_world_marker[m]) continue;
      const auto it = best_view.find(m);
      if (it == best_view.end() || init_->views[o].error_ratio > init_->views[it->second].error_ratio) {
        best_view[m] = o;
      }
    }
  }
  for (const auto& [m, o] : best_view) {
    const int f = survey_.observations[o].frame;
    init_->T_world_marker[m] = *init_->T_world_robot[f] * init_->views[o].T_robot_marker.front();
  }
}

void Placer::PlaceComponent(int component) {
  std::vector<int> frames;
  for (size_t f = 0; f < survey_.frames.size(); ++f) {
    if (init_->frame_component[f] == component) frames.push_back(static_cast<int>(f));
  }
  for (int f : frames) {
    const auto& obs = survey_.frames[f].observations;
    if (std::any_of(obs.begin(), obs.end(), [&](int o) { return init_->views[o].usable; })) {
      init_->T_world_robot[f] = SE3d::Identity();
      PlaceMarkersSeenBy(f, true);
      break;
    }
  }
  for (bool changed = true; changed;) {
    changed = false;
    for (int pass = 0; pass < 2; ++pass) {
      for (size_t i = 0; i < frames.size(); ++i) {
        const int f = pass == 0 ? frames[i] : frames[frames.size() - 1 - i];
        if (init_->T_world_robot[f] || !PlaceFrame(f)) continue;
        changed = true;
        PlaceMarkersSeenBy(f, false);
      }
    }
    const size_t placed_before = std::count_if(init_->T_world_marker.begin(), init_->T_world_marker.end(),
                                               [](const auto& T) { return T.has_value(); });
    PlaceDeferredMarkers(frames);
    const size_t placed_after = std::count_if(init_->T_world_marker.begin(), init_->T_world_marker.end(),
                                              [](const auto& T) { return T.has_value(); });
    changed = changed || placed_after > placed_before;
  }
}

bool IsAnchor(const SurveyMarker& marker) {
  return marker.known && (marker.known->fixed || marker.known->covariance.has_value());
}

// The rigid 2-D fit b = R(yaw) a + t over point pairs (centred cross-covariance); as SE(3).
SE3d Fit2d(const std::vector<Eigen::Vector2d>& a, const std::vector<Eigen::Vector2d>& b) {
  Eigen::Vector2d a_mean = Eigen::Vector2d::Zero(), b_mean = Eigen::Vector2d::Zero();
  for (size_t i = 0; i < a.size(); ++i) {
    a_mean += a[i] / a.size();
    b_mean += b[i] / b.size();
  }
  double sin_sum = 0.0, cos_sum = 0.0;
  for (size_t i = 0; i < a.size(); ++i) {
    const Eigen::Vector2d u = a[i] - a_mean, v = b[i] - b_mean;
    sin_sum += u.x() * v.y() - u.y() * v.x();
    cos_sum += u.x() * v.x() + u.y() * v.y();
  }
  const SE2d R(0.0, 0.0, std::atan2(sin_sum, cos_sum));
  const Eigen::Vector2d t = b_mean - R * a_mean;
  return SE2d(t.x(), t.y(), R.theta()).ToSE3();
}

// T_world_init of a component from its priors, or nullopt (then the root frame stays the
// identity); *how says which.
std::optional<SE3d> PriorAlignment(const Survey& survey, const Initialization& init, int component,
                                   std::string* how) {
  std::vector<int> anchors, payloads;
  for (size_t m = 0; m < survey.markers.size(); ++m) {
    if (init.marker_component[m] != component || !init.T_world_marker[m]) continue;
    if (IsAnchor(survey.markers[m])) anchors.push_back(static_cast<int>(m));
    if (survey.markers[m].payload) payloads.push_back(static_cast<int>(m));
  }
  const bool planar = survey.motion == MotionModel::kPlanar;
  if (!anchors.empty()) {
    *how = std::to_string(anchors.size()) + " anchor marker(s)";
    const SE3d T = survey.markers[anchors[0]].known->T_world_marker * init.T_world_marker[anchors[0]]->inverse();
    return planar ? SE2d::FromSE3(T).ToSE3() : T;
  }
  if (payloads.size() >= 2) {
    *how = std::to_string(payloads.size()) + " payload position prior(s)";
    std::vector<Eigen::Vector2d> a, b;
    double dz_sum = 0.0;
    int dz_count = 0;
    for (int m : payloads) {
      const PayloadData& p = *survey.markers[m].payload;
      const Eigen::Vector3d& t = init.T_world_marker[m]->translation();
      a.push_back(t.head<2>());
      b.emplace_back(*p.x_m, *p.y_m);
      if (p.z_m) {
        dz_sum += *p.z_m - t.z();
        ++dz_count;
      }
    }
    SE3d T = Fit2d(a, b);
    if (!planar && dz_count > 0) T = SE3d(T.rotation(), T.translation() + Eigen::Vector3d(0, 0, dz_sum / dz_count));
    return T;
  }
  *how = "first frame held fixed";
  return std::nullopt;
}

void AlignComponent(const Survey& survey, int component, Initialization* init) {
  std::string how;
  const std::optional<SE3d> T_world_init = PriorAlignment(survey, *init, component, &how);
  init->gauge.push_back(how);
  if (!T_world_init) return;
  for (size_t f = 0; f < survey.frames.size(); ++f) {
    if (init->frame_component[f] == component && init->T_world_robot[f]) {
      init->T_world_robot[f] = *T_world_init * *init->T_world_robot[f];
    }
  }
  for (size_t m = 0; m < survey.markers.size(); ++m) {
    if (init->marker_component[m] == component && init->T_world_marker[m]) {
      init->T_world_marker[m] = *T_world_init * *init->T_world_marker[m];
    }
  }
}

// Cauchy cost of one observation for given poses (whitened units).
double ObservationCost(const Survey& survey, const std::map<std::string, Camera>& cameras, int o,
                       const SE3d& T_world_robot, const SE3d& T_world_marker, double cauchy_scale) {
  const SurveyObservation& obs = survey.observations[o];
  const Camera& camera = cameras.at(obs.camera);
  const SE3d T_camera_marker = (T_world_robot * camera.info().T_robot_camera).inverse() * T_world_marker;
  const double rms = MarkerReprojectionRms(obs.corners_px, survey.markers[obs.marker].size_m, camera, T_camera_marker);
  const double c2 = cauchy_scale * cauchy_scale;
  const double s = std::isfinite(rms) ? 4.0 * rms * rms / std::pow(CornerSigmaPx(camera.info()), 2) : 1e12;
  return c2 * std::log1p(s / c2);
}

}  // namespace

std::optional<SE3d> MarkerByConsensus(const Survey& survey, const std::map<std::string, Camera>& cameras,
                                      const std::vector<SingleView>& views,
                                      const std::vector<std::optional<SE3d>>& T_world_robot, int marker,
                                      double cauchy_scale, size_t max_candidates) {
  std::vector<int> seen;  // usable views from placed frames
  for (int o : survey.markers[marker].observations) {
    if (views[o].usable && T_world_robot[survey.observations[o].frame]) seen.push_back(o);
  }
  if (seen.empty()) return std::nullopt;
  std::vector<int> proposers = seen;
  std::sort(proposers.begin(), proposers.end(), [&](int a, int b) { return views[a].error_ratio > views[b].error_ratio; });
  if (proposers.size() > max_candidates) proposers.resize(max_candidates);
  std::optional<SE3d> best;
  double best_cost = std::numeric_limits<double>::infinity();
  for (int p : proposers) {
    for (const SE3d& T_robot_marker : views[p].T_robot_marker) {
      const SE3d candidate = *T_world_robot[survey.observations[p].frame] * T_robot_marker;
      double cost = 0.0;
      for (int o : seen) {
        cost += ObservationCost(survey, cameras, o, *T_world_robot[survey.observations[o].frame], candidate,
                                cauchy_scale);
        if (cost >= best_cost) break;
      }
      if (cost < best_cost) {
        best_cost = cost;
        best = candidate;
      }
    }
  }
  return best;
}

std::map<std::string, Camera> MakeCameras(const Survey& survey) {
  std::map<std::string, Camera> cameras;
  for (const auto& [name, info] : survey.cameras) {
    try {
      cameras.emplace(name, Camera(info));
    } catch (const std::exception& e) {
      throw std::runtime_error("cameras/" + name + ".yaml: " + e.what());
    }
  }
  return cameras;
}

std::vector<SingleView> ComputeSingleViews(const Survey& survey, const std::map<std::string, Camera>& cameras,
                                           double ambiguity_ratio) {
  std::vector<SingleView> views(survey.observations.size());
  for (size_t o = 0; o < views.size(); ++o) {
    const SurveyObservation& obs = survey.observations[o];
    const Camera& camera = cameras.at(obs.camera);
    MarkerPoseOptions options;
    options.ambiguity_ratio = ambiguity_ratio;
    options.sigma_px = CornerSigmaPx(camera.info());
    SingleView& view = views[o];
    try {
      const MarkerPoseEstimate estimate =
          EstimateMarkerPose(obs.corners_px, survey.markers[obs.marker].size_m, camera, options);
      for (const MarkerPoseSolution& s : estimate.solutions) {
        view.T_robot_marker.push_back(camera.info().T_robot_camera * s.T_camera_marker);
      }
      view.error_ratio = estimate.error_ratio;
      view.rms_px = estimate.best().rms_px;
      view.area_px2 = QuadArea(obs.corners_px);
      view.usable = true;
    } catch (const std::exception& e) {
      view.why = e.what();
    }
  }
  return views;
}

void FindComponents(const Survey& survey, Initialization* init) {
  const size_t num_frames = survey.frames.size();
  DisjointSets sets(num_frames + survey.markers.size());
  for (size_t o = 0; o < survey.observations.size(); ++o) {
    if (init->views[o].usable) sets.Join(survey.observations[o].frame, num_frames + survey.observations[o].marker);
  }
  for (const OdometryLink& link : survey.odometry_links) sets.Join(link.frame_a, link.frame_b);
  std::vector<bool> has_marker(num_frames + survey.markers.size(), false);
  for (size_t o = 0; o < survey.observations.size(); ++o) {
    if (init->views[o].usable) has_marker[sets.Find(num_frames + survey.observations[o].marker)] = true;
  }
  std::map<size_t, int> number;  // root -> component, in order of first frame
  init->frame_component.assign(num_frames, -1);
  init->marker_component.assign(survey.markers.size(), -1);
  for (size_t f = 0; f < num_frames; ++f) {
    const size_t root = sets.Find(f);
    if (!has_marker[root]) continue;
    const auto it = number.emplace(root, static_cast<int>(number.size())).first;
    init->frame_component[f] = it->second;
  }
  for (size_t m = 0; m < survey.markers.size(); ++m) {
    const auto it = number.find(sets.Find(num_frames + m));
    if (it != number.end()) init->marker_component[m] = it->second;
  }
  init->components = static_cast<int>(number.size());
}

Initialization Initialize(const Survey& survey, const InitializerOptions& options) {
  const std::map<std::string, Camera> cameras = MakeCameras(survey);
  Initialization init;
  init.views = ComputeSingleViews(survey, cameras, options.ambiguity_ratio);
  FindComponents(survey, &init);
  init.T_world_robot.assign(survey.frames.size(), std::nullopt);
  init.T_world_marker.assign(survey.markers.size(), std::nullopt);
  Placer placer(survey, cameras, options, &init);
  for (int c = 0; c < init.components; ++c) {
    placer.PlaceComponent(c);
    for (size_t m = 0; m < survey.markers.size(); ++m) {
      if (init.marker_component[m] != c || !init.T_world_marker[m]) continue;
      init.T_world_marker[m] = MarkerByConsensus(survey, cameras, init.views, init.T_world_robot, static_cast<int>(m),
                                                 options.cauchy_scale);
    }
    AlignComponent(survey, c, &init);
  }
  return init;
}

}  // namespace waymark
