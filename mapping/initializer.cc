#include "mapping/initializer.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <set>
#include <sstream>

#include "geometry/robot_pnp.h"
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

SE3d Planarize(MotionModel motion, const SE3d& T) {
  return motion == MotionModel::kPlanar ? SE2d::FromSE3(T).ToSE3() : T;
}

// PnP of a frame against its placed codes (held constant), Cauchy loss; the start when the
// frame sees no placed code.
SE3d RefineFrame(const Survey& survey, const std::map<std::string, Camera>& cameras,
                 const Initialization& init, int frame, const SE3d& T_world_robot,
                 const InitializerOptions& options) {
  std::vector<PnpView> pnp;
  for (int o : survey.frames[frame].observations) {
    const SurveyObservation& obs = survey.observations[o];
    const auto& T_world_marker = init.T_world_marker[obs.marker];
    if (!init.views[o].usable || !T_world_marker) continue;
    const Camera& camera = cameras.at(obs.camera);
    pnp.push_back({&camera, &obs.corners_px, CornerSigmaPx(camera.info()), survey.markers[obs.marker].size_m,
                   *T_world_marker});
  }
  if (pnp.empty()) return T_world_robot;
  return RefineRobotPose(pnp, T_world_robot, survey.motion == MotionModel::kPlanar, options.cauchy_scale,
                         options.pnp_iterations);
}

// Adds `T` to `seeds` unless one is within 3 degrees of it.
void AddSeed(const SE3d& T, std::vector<SE3d>* seeds) {
  constexpr double kSameSeedRad = 3.0 * M_PI / 180.0;
  for (const SE3d& seed : *seeds) {
    if (RotationAngleBetween(seed, T) < kSameSeedRad) return;
  }
  seeds->push_back(T);
}

// A code fused over all its usable views in placed frames, seeded by `current` (if any) and
// both solutions of its `max_candidates` least ambiguous views.
std::optional<FusedPose> FuseInWorld(const Survey& survey, const std::map<std::string, Camera>& cameras,
                                     const std::vector<SingleView>& views,
                                     const std::vector<std::optional<SE3d>>& T_world_robot, int marker,
                                     const std::optional<SE3d>& current, size_t max_candidates,
                                     const LocalMapOptions& options) {
  std::vector<int> seen;
  std::vector<FusionView> fusion;
  for (int o : survey.markers[marker].observations) {
    const SurveyObservation& obs = survey.observations[o];
    if (!views[o].usable || !T_world_robot[obs.frame]) continue;
    const Camera& camera = cameras.at(obs.camera);
    seen.push_back(o);
    fusion.push_back(MakeFusionView(camera, *T_world_robot[obs.frame], obs));
  }
  if (seen.empty()) return std::nullopt;
  std::vector<SE3d> seeds;
  if (current) seeds.push_back(*current);
  std::vector<int> proposers = seen;
  const size_t n = std::min(max_candidates, proposers.size());
  std::partial_sort(proposers.begin(), proposers.begin() + n, proposers.end(),
                    [&](int a, int b) { return views[a].error_ratio > views[b].error_ratio; });
  for (size_t i = 0; i < n; ++i) {
    for (const SE3d& T_robot_marker : views[proposers[i]].T_robot_marker) {
      AddSeed(*T_world_robot[survey.observations[proposers[i]].frame] * T_robot_marker, &seeds);
    }
  }
  return FuseMarkerViews(fusion, survey.markers[marker].size_m, seeds, false, options);
}

LocalMapOptions EffectiveLocalMapOptions(const InitializerOptions& options) {
  LocalMapOptions local = options.local_maps;
  local.ambiguity_ratio = options.ambiguity_ratio;
  local.cauchy_scale = options.cauchy_scale;
  return local;
}

// Frames and codes from the placed local maps; each code from its most certain local map.
void PlaceFromLocalMaps(const Survey& survey, const std::vector<SE3d>& T_world_ref, Initialization* init) {
  std::vector<double> best_sigma(survey.markers.size(), std::numeric_limits<double>::infinity());
  for (size_t i = 0; i < init->local_maps.size(); ++i) {
    const LocalMap& map = init->local_maps[i];
    for (size_t k = 0; k < map.frames.size(); ++k) {
      init->T_world_robot[map.frames[k]] = Planarize(survey.motion, T_world_ref[i] * map.T_ref_robot[k]);
    }
    for (const auto& [m, fused] : map.codes) {
      const double sigma = RankingSigma(fused);
      if (sigma < best_sigma[m] || !init->T_world_marker[m]) {
        best_sigma[m] = sigma;
        init->T_world_marker[m] = T_world_ref[i] * fused.T_frame_marker;
      }
    }
  }
  init->marker_link_quality.assign(survey.markers.size(), 0.0);
  for (const LocalMapLink& link : init->links) {
    if (link.marker >= 0)
      init->marker_link_quality[link.marker] = std::max(init->marker_link_quality[link.marker], link.quality);
  }
}

// Every placed code re-fused over all its views at the current frame poses.
void RefineMarkers(const Survey& survey, const std::map<std::string, Camera>& cameras,
                   const LocalMapOptions& options, Initialization* init) {
  for (size_t m = 0; m < survey.markers.size(); ++m) {
    if (!init->T_world_marker[m]) continue;
    const std::optional<FusedPose> fused =
        FuseInWorld(survey, cameras, init->views, init->T_world_robot, static_cast<int>(m),
                    init->T_world_marker[m], 2, options);
    if (fused) init->T_world_marker[m] = fused->T_frame_marker;
  }
}

// PnP of every placed frame but each component's first (it stays the identity: the gauge).
void RefineFrames(const Survey& survey, const std::map<std::string, Camera>& cameras,
                  const InitializerOptions& options, Initialization* init) {
  std::set<int> roots, components;
  for (const LocalMap& map : init->local_maps) {
    if (components.insert(map.component).second) roots.insert(map.frames.front());
  }
  for (size_t f = 0; f < survey.frames.size(); ++f) {
    if (!init->T_world_robot[f] || roots.count(static_cast<int>(f)) > 0) continue;
    init->T_world_robot[f] =
        RefineFrame(survey, cameras, *init, static_cast<int>(f), *init->T_world_robot[f], options);
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

// Position sigma (m) and rotation sigma (rad) of an anchor: 0 for a fixed one, else the root
// mean of the diagonal of its covariance's translation and rotation blocks.
std::pair<double, double> AnchorSigmas(const MapMarker& known) {
  if (known.fixed || !known.covariance) return {0.0, 0.0};
  const Matrix6d& c = *known.covariance;
  return {std::sqrt(std::max(0.0, c.block<3, 3>(3, 3).trace() / 3.0)),
          std::sqrt(std::max(0.0, c.block<3, 3>(0, 0).trace() / 3.0))};
}

// How far the anchors are from T * (their initialized poses): sum over anchors of
// rho(|dp|^2 / s_p^2 + angle^2 / s_r^2), rho the Cauchy loss of scale 3 (a rough survey has some
// priors far off); fixed anchors weigh as priors of 1 mm / 1 mrad.
double AnchorMisfit(const Survey& survey, const Initialization& init, const std::vector<int>& anchors,
                    const SE3d& T) {
  constexpr double kFixedSigmaM = 1e-3, kFixedSigmaRad = 1e-3, kScale2 = 9.0;
  double cost = 0.0;
  for (int m : anchors) {
    const MapMarker& known = *survey.markers[m].known;
    auto [sp, sr] = AnchorSigmas(known);
    if (known.fixed || !known.covariance) sp = kFixedSigmaM, sr = kFixedSigmaRad;
    const SE3d placed = T * *init.T_world_marker[m];
    const double s = (placed.translation() - known.T_world_marker.translation()).squaredNorm() / (sp * sp) +
                     std::pow(RotationAngleBetween(placed, known.T_world_marker) / sr, 2);
    cost += kScale2 * std::log1p(s / kScale2);
  }
  return cost;
}

// The rotation R and translation t minimizing sum w_i |R a_i + t - b_i|^2 (Kabsch with weights);
// nullopt when the points are (nearly) collinear, which leaves a rotation free.
std::optional<SE3d> WeightedKabsch(const std::vector<Eigen::Vector3d>& a,
                                   const std::vector<Eigen::Vector3d>& b, const std::vector<double>& w) {
  double w_sum = 0.0;
  Eigen::Vector3d a_mean = Eigen::Vector3d::Zero(), b_mean = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < a.size(); ++i) {
    w_sum += w[i];
    a_mean += w[i] * a[i];
    b_mean += w[i] * b[i];
  }
  if (!(w_sum > 0.0)) return std::nullopt;
  a_mean /= w_sum;
  b_mean /= w_sum;
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < a.size(); ++i) H += w[i] * (a[i] - a_mean) * (b[i] - b_mean).transpose();
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(H, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Vector3d sv = svd.singularValues();
  if (!(sv[1] > 1e-6 * std::max(1e-12, sv[0]))) return std::nullopt;  // collinear
  Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
  if ((svd.matrixV() * svd.matrixU().transpose()).determinant() < 0.0) D(2, 2) = -1.0;
  const Eigen::Matrix3d R = svd.matrixV() * D * svd.matrixU().transpose();
  return SE3d(Eigen::Quaterniond(R), b_mean - R * a_mean);
}

// T_world_init of a component from its anchors. A fixed anchor gives it exactly (the one that
// agrees best with the other anchors). Anchors that are priors (a rough survey: sigmas of tens
// of centimetres, some entries farther off) are each a candidate; the one the others agree with
// best (AnchorMisfit) is refined, when three or more anchors within 3 sigmas of it are not
// collinear, by a weighted fit of their positions (Kabsch, weights 1 / sigma^2; planar surveys:
// yaw and x, y, then the mean z offset), which averages the priors' errors instead of trusting
// one, and kept if it agrees better.
SE3d AlignToAnchors(const Survey& survey, const Initialization& init, const std::vector<int>& anchors) {
  const bool planar = survey.motion == MotionModel::kPlanar;
  const auto flatten = [planar](const SE3d& T) { return planar ? SE2d::FromSE3(T).ToSE3() : T; };
  bool any_fixed = false;
  for (int m : anchors) any_fixed = any_fixed || survey.markers[m].known->fixed;
  std::optional<SE3d> best;
  double best_cost = std::numeric_limits<double>::infinity();
  for (int m : anchors) {
    if (any_fixed && !survey.markers[m].known->fixed) continue;
    const SE3d T = flatten(survey.markers[m].known->T_world_marker * init.T_world_marker[m]->inverse());
    const double cost = AnchorMisfit(survey, init, anchors, T);
    if (cost < best_cost) best = T, best_cost = cost;
  }
  if (any_fixed) return *best;
  std::vector<Eigen::Vector3d> a, b;
  std::vector<double> w;
  for (int m : anchors) {
    const MapMarker& known = *survey.markers[m].known;
    const double sp = std::max(1e-6, AnchorSigmas(known).first);
    const Eigen::Vector3d placed = *best * init.T_world_marker[m]->translation();
    if ((placed - known.T_world_marker.translation()).norm() > 3.0 * sp) continue;
    a.push_back(init.T_world_marker[m]->translation());
    b.push_back(known.T_world_marker.translation());
    w.push_back(1.0 / (sp * sp));
  }
  if (a.size() < 3) return *best;
  std::optional<SE3d> fit;
  if (planar) {
    std::vector<Eigen::Vector2d> a2, b2;
    for (size_t i = 0; i < a.size(); ++i) a2.push_back(a[i].head<2>()), b2.push_back(b[i].head<2>());
    fit = Fit2d(a2, b2);
  } else {
    fit = WeightedKabsch(a, b, w);
  }
  if (fit && AnchorMisfit(survey, init, anchors, flatten(*fit)) < best_cost) return flatten(*fit);
  return *best;
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
    return AlignToAnchors(survey, init, anchors);
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
    if (!planar && dz_count > 0)
      T = SE3d(T.rotation(), T.translation() + Eigen::Vector3d(0, 0, dz_sum / dz_count));
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

// Components holding an anchor (a fixed pose or a prior in markers.json) are, once aligned onto
// their anchors, in one world frame: they become one component (the number of the first of them);
// components are renumbered 0, 1, ... in the order of their first frame, their gauges joined.
void MergeWorldComponents(const Survey& survey, Initialization* init) {
  std::vector<bool> anchored(init->components, false);
  for (size_t m = 0; m < survey.markers.size(); ++m) {
    const int c = init->marker_component[m];
    if (c >= 0 && init->T_world_marker[m] && IsAnchor(survey.markers[m])) anchored[c] = true;
  }
  std::vector<int> target(init->components);
  int world = -1;
  for (int c = 0; c < init->components; ++c) {  // components are numbered in order of first frame
    if (anchored[c] && world < 0) world = c;
    target[c] = anchored[c] ? world : c;
  }
  std::vector<int> number(init->components, -1);
  int next = 0;
  for (int c = 0; c < init->components; ++c) {
    if (number[target[c]] < 0) number[target[c]] = next++;
  }
  if (next == init->components) return;
  std::vector<std::string> gauge(next);
  std::vector<int> anchor_count(next, 0);
  for (size_t m = 0; m < survey.markers.size(); ++m) {
    const int c = init->marker_component[m];
    if (c >= 0 && init->T_world_marker[m] && IsAnchor(survey.markers[m])) ++anchor_count[number[target[c]]];
  }
  for (int c = 0; c < init->components; ++c) {
    const int n = number[target[c]];
    gauge[n] = anchored[c] ? std::to_string(anchor_count[n]) + " anchor marker(s)" : init->gauge[c];
  }
  for (int& c : init->frame_component) c = c >= 0 ? number[target[c]] : c;
  for (int& c : init->marker_component) c = c >= 0 ? number[target[c]] : c;
  for (LocalMap& map : init->local_maps)
    map.component = map.component >= 0 ? number[target[map.component]] : -1;
  init->gauge = gauge;
  init->components = next;
}

}  // namespace

std::optional<SE3d> OtherFlipBranch(const Survey& survey, const std::map<std::string, Camera>& cameras,
                                    const std::vector<SingleView>& views,
                                    const std::vector<std::optional<SE3d>>& T_world_robot, int marker,
                                    const SE3d& current, const LocalMapOptions& options) {
  std::vector<FusionView> fusion;
  Eigen::Vector3d ray_sum = Eigen::Vector3d::Zero();
  for (int o : survey.markers[marker].observations) {
    const SurveyObservation& obs = survey.observations[o];
    if (!views[o].usable || !T_world_robot[obs.frame]) continue;
    fusion.push_back(MakeFusionView(cameras.at(obs.camera), *T_world_robot[obs.frame], obs));
    ray_sum += (fusion.back().T_frame_camera.translation() - current.translation()).normalized();
  }
  if (fusion.empty() || ray_sum.norm() < 1e-9) return std::nullopt;
  const Eigen::Vector3d v = ray_sum.normalized();
  const Eigen::Vector3d n = current.rotation() * Eigen::Vector3d::UnitZ();
  const Eigen::Quaterniond reflect = Eigen::Quaterniond::FromTwoVectors(n, 2.0 * n.dot(v) * v - n);
  const SE3d mirrored(reflect * current.rotation(), current.translation());
  if (RotationAngleBetween(mirrored, current) < kFlipCheckMinRad) return std::nullopt;  // seen head-on
  const std::optional<FusedPose> fused =
      FuseMarkerViews(fusion, survey.markers[marker].size_m, {current, mirrored}, false, options);
  if (!fused || !fused->resolved || RotationAngleBetween(fused->T_frame_marker, current) < kFlipCheckMinRad) {
    return std::nullopt;
  }
  return fused->T_frame_marker;
}

std::optional<SE3d> MarkerByConsensus(const Survey& survey, const std::map<std::string, Camera>& cameras,
                                      const std::vector<SingleView>& views,
                                      const std::vector<std::optional<SE3d>>& T_world_robot, int marker,
                                      double cauchy_scale, size_t max_candidates) {
  LocalMapOptions options;
  options.cauchy_scale = cauchy_scale;
  const std::optional<FusedPose> fused =
      FuseInWorld(survey, cameras, views, T_world_robot, marker, std::nullopt, max_candidates, options);
  if (!fused) return std::nullopt;
  return fused->T_frame_marker;
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
    if (init->views[o].usable)
      sets.Join(survey.observations[o].frame, num_frames + survey.observations[o].marker);
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
  const LocalMapOptions local = EffectiveLocalMapOptions(options);
  Initialization init;
  PhaseClock clock(&init.phases);
  init.views = ComputeSingleViews(survey, cameras, options.ambiguity_ratio);
  FindComponents(survey, &init);
  clock.Lap("single views");
  init.T_world_robot.assign(survey.frames.size(), std::nullopt);
  init.T_world_marker.assign(survey.markers.size(), std::nullopt);
  init.local_maps = BuildLocalMaps(survey, cameras, init.views, init.frame_component, local);
  init.links = FindLocalMapLinks(survey, init.local_maps, local);
  const int num_maps = static_cast<int>(init.local_maps.size());
  init.tree = SpanningForest(num_maps, init.links);
  clock.Lap("local maps");
  const LocalMapGraph graph =
      SolveLocalMapGraph(init.local_maps, init.links, survey.motion == MotionModel::kPlanar, options.graph);
  init.odometry_calibration = graph.odometry_calibration;
  clock.Lap("local map graph");
  PlaceFromLocalMaps(survey, graph.T_world_ref, &init);
  RefineMarkers(survey, cameras, local, &init);
  for (int round = 0; round < options.refine_rounds; ++round) {
    RefineFrames(survey, cameras, options, &init);
    RefineMarkers(survey, cameras, local, &init);
  }
  for (int c = 0; c < init.components; ++c) AlignComponent(survey, c, &init);
  clock.Lap("initial refinement");
  const int connected = init.components;
  MergeWorldComponents(survey, &init);
  init.notes = DescribeInitialization(survey, init);
  if (init.components < connected) {
    init.notes.push_back(std::to_string(connected) +
                         " groups of codes that share no observation are one map: " +
                         "their anchors or priors put them in one world frame");
  }
  init.notes.push_back(DescribeLocalMapGraph(graph));
  return init;
}

std::vector<std::string> DescribeInitialization(const Survey& survey, const Initialization& init) {
  size_t code_links = 0, odometry_links = 0;
  double weakest = std::numeric_limits<double>::infinity();
  for (int l : init.tree) {
    (init.links[l].marker >= 0 ? code_links : odometry_links) += 1;
    weakest = std::min(weakest, init.links[l].quality);
  }
  std::set<int> unstable, unresolved;
  for (const LocalMap& map : init.local_maps) {
    for (const auto& [m, fused] : map.codes) {
      if (!fused.stable)
        unstable.insert(m);
      else if (!fused.resolved)
        unresolved.insert(m);
    }
  }
  std::ostringstream line;
  line << "initialization: " << init.local_maps.size() << " local maps joined by " << code_links
       << " code and " << odometry_links << " odometry links";
  if (!init.tree.empty()) line << " (weakest link sigma " << 1000.0 / weakest << " mm)";
  std::vector<std::string> notes{line.str()};
  const auto list = [&](const std::set<int>& markers, const std::string& what) {
    if (markers.empty()) return;
    std::string text = std::to_string(markers.size()) + " code(s) " + what + ":";
    size_t shown = 0;
    for (int m : markers) {
      if (shown++ == 8) {
        text += " ...";
        break;
      }
      text += " " + survey.markers[m].key.ToString();
    }
    notes.push_back(text);
  };
  list(unstable, "unstable in some local map (views disagree or too uncertain)");
  list(unresolved, "with an unresolved planar flip in some local map");
  return notes;
}

}  // namespace waymark
