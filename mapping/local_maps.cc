#include "mapping/local_maps.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>
#include <queue>

#include "factors/pose_block.h"
#include "mapping/initializer.h"
#include "mapping/residuals.h"
#include "util/check.h"

namespace waymark {
namespace {

using Residuals8 = Eigen::Matrix<double, 8, 1>;
using Jacobian86 = Eigen::Matrix<double, 8, 6>;

// Squared whitened error given to a view that does not project (as the initializer does).
constexpr double kNoProjectionChi2 = 1e12;
// Two seeds that converge to rotations closer than this are one branch.
constexpr double kSameBranchRad = 2.0 * M_PI / 180.0;

// Whitened residuals r_v of one view and dr/d[dr, dt] for the right perturbation of
// T_frame_marker; false if a corner does not project.
bool ViewResiduals(const FusionView& view, const std::array<Eigen::Vector3d, 4>& corners_marker,
                   const SE3d& T_frame_marker, Residuals8* r, Jacobian86* J) {
  const SE3d T_camera_marker = view.T_frame_camera.inverse() * T_frame_marker;
  const Eigen::Matrix3d R = T_camera_marker.rotation_matrix();
  for (int k = 0; k < 4; ++k) {
    Eigen::Matrix<double, 2, 3> J_px_p;
    const std::optional<Eigen::Vector2d> px =
        view.camera->Project(T_camera_marker * corners_marker[k], J != nullptr ? &J_px_p : nullptr);
    if (!px) return false;
    r->segment<2>(2 * k) = (*px - (*view.corners_px)[k]) / view.sigma_px;
    if (J != nullptr) {
      J->block<2, 3>(2 * k, 0) = -J_px_p * R * Hat(corners_marker[k]) / view.sigma_px;
      J->block<2, 3>(2 * k, 3) = J_px_p * R / view.sigma_px;
    }
  }
  return true;
}

// The robust normal equations of all views at T (Cauchy weights, IRLS).
struct Normal {
  Matrix6d H = Matrix6d::Zero();
  Vector6d g = Vector6d::Zero();
  double robust_cost = 0.0;  // sum rho(s_v), kNoProjectionChi2 for views that do not project
  double chi2 = 0.0;         // sum s_v over views that project
  int views = 0;             // views that project
};

Normal Linearize(const std::vector<FusionView>& views, const std::array<Eigen::Vector3d, 4>& corners_marker,
                 const SE3d& T, double cauchy_scale) {
  const double c2 = cauchy_scale * cauchy_scale;
  Normal n;
  Residuals8 r;
  Jacobian86 J;
  for (const FusionView& view : views) {
    if (!ViewResiduals(view, corners_marker, T, &r, &J)) {
      n.robust_cost += c2 * std::log1p(kNoProjectionChi2 / c2);
      continue;
    }
    const double s = r.squaredNorm();
    const double w = 1.0 / (1.0 + s / c2);
    n.H += w * J.transpose() * J;
    n.g += w * J.transpose() * r;
    n.robust_cost += c2 * std::log1p(s / c2);
    n.chi2 += s;
    ++n.views;
  }
  return n;
}

struct Fit {
  SE3d T;
  Normal normal;
};

// Levenberg-Marquardt on the robust cost from `seed`.
Fit FitFromSeed(const std::vector<FusionView>& views, const std::array<Eigen::Vector3d, 4>& corners_marker,
                const SE3d& seed, const LocalMapOptions& options) {
  Fit fit{seed, Linearize(views, corners_marker, seed, options.cauchy_scale)};
  double lambda = 1e-4;
  for (int iteration = 0; iteration < options.max_iterations && fit.normal.views > 0; ++iteration) {
    Matrix6d A = fit.normal.H;
    A.diagonal() += lambda * fit.normal.H.diagonal() + Vector6d::Constant(1e-12);
    const Vector6d delta = A.ldlt().solve(-fit.normal.g);
    const SE3d T_new = fit.T.BoxPlus(delta);
    const Normal n_new = Linearize(views, corners_marker, T_new, options.cauchy_scale);
    if (delta.allFinite() && n_new.robust_cost < fit.normal.robust_cost) {
      const double decrease = fit.normal.robust_cost - n_new.robust_cost;
      fit = {T_new, n_new};
      lambda = std::max(lambda * 0.1, 1e-10);
      if (decrease < 1e-9 * (1.0 + fit.normal.robust_cost) || delta.norm() < 1e-10) break;
    } else {
      lambda *= 10.0;
      if (lambda > 1e8) break;
    }
  }
  return fit;
}

}  // namespace

bool LocalMapOptions::Check(std::string* why) const {
  WAYMARK_CHECK_OPTION(
      IsFinitePositive(max_travel_m) && IsFinitePositive(max_turn_rad) && IsFinitePositive(ambiguity_ratio) &&
          IsFinitePositive(flip_chi2) && IsFinitePositive(cauchy_scale) && IsFinitePositive(max_rms_sigma) &&
          IsFinitePositive(max_position_sigma_m) && IsFiniteAtLeast(odometry_systematic, 0.0),
      "local map options must be finite and > 0 (odometry_systematic >= 0)");
  WAYMARK_CHECK_OPTION(max_frames >= 1 && max_iterations >= 1,
                       "local map max_frames and max_iterations must be >= 1");
  return true;
}

double RankingSigma(const FusedPose& fused) {
  const double sigma =
      std::sqrt(std::max(0.0, fused.covariance.block<3, 3>(3, 3).trace() +
                                  kLinkLeverM * kLinkLeverM * fused.covariance.block<3, 3>(0, 0).trace()));
  if (!fused.stable) return sigma * kUnstablePenalty;
  if (!fused.resolved) return sigma * kAmbiguousPenalty;
  return sigma;
}

double PointSigma(const Matrix6d& covariance, const Eigen::Vector3d& q_marker) {
  Eigen::Matrix<double, 3, 6> D;
  D << -Hat(q_marker), Eigen::Matrix3d::Identity();
  return std::sqrt(std::max(0.0, (D * covariance * D.transpose()).trace()));
}

std::optional<FusedPose> FuseMarkerViews(const std::vector<FusionView>& views, double size_m,
                                         const std::vector<SE3d>& seeds, bool single_view_unambiguous,
                                         const LocalMapOptions& options) {
  const std::array<Eigen::Vector3d, 4> corners_marker = MarkerCorners(size_m);
  std::vector<Fit> fits;
  for (const SE3d& seed : seeds) {
    Fit fit = FitFromSeed(views, corners_marker, seed, options);
    if (fit.normal.views > 0 && fit.T.IsFinite()) fits.push_back(std::move(fit));
  }
  if (fits.empty()) return std::nullopt;
  std::sort(fits.begin(), fits.end(),
            [](const Fit& a, const Fit& b) { return a.normal.robust_cost < b.normal.robust_cost; });
  const Fit& best = fits.front();
  FusedPose fused;
  fused.T_frame_marker = best.T;
  fused.chi2 = best.normal.chi2;
  fused.robust_cost = best.normal.robust_cost;
  fused.views = best.normal.views;
  for (size_t i = 1; i < fits.size(); ++i) {
    if (RotationAngleBetween(fits[i].T, best.T) > kSameBranchRad) {
      fused.alt_chi2 = std::min(fused.alt_chi2, fits[i].normal.chi2);
    }
  }
  const int dof = std::max(1, 8 * fused.views - 6);
  const double inflation = std::max(1.0, best.normal.chi2 / dof);
  Matrix6d H = best.normal.H;
  H.diagonal() += Vector6d::Constant(1e-12);
  fused.covariance = H.ldlt().solve(Matrix6d::Identity()) * inflation;
  fused.rms_sigma = std::sqrt(best.normal.chi2 / (8.0 * fused.views));
  fused.position_sigma_m = std::sqrt(std::max(0.0, fused.covariance.block<3, 3>(3, 3).trace()));
  fused.resolved = single_view_unambiguous || fused.alt_chi2 - fused.chi2 >= options.flip_chi2;
  fused.stable = true;
  if (fused.rms_sigma > options.max_rms_sigma) {
    fused.stable = false;
    fused.why = "views disagree (corner RMS " + std::to_string(fused.rms_sigma) + " sigma)";
  } else if (!(fused.position_sigma_m <= options.max_position_sigma_m)) {
    fused.stable = false;
    fused.why = "position too uncertain (sigma " + std::to_string(fused.position_sigma_m) + " m)";
  }
  return fused;
}

namespace {

// Index of the odometry link ending at each frame, -1 without.
std::vector<int> PreviousLinks(const Survey& survey) {
  std::vector<int> prev(survey.frames.size(), -1);
  for (size_t i = 0; i < survey.odometry_links.size(); ++i)
    prev[survey.odometry_links[i].frame_b] = static_cast<int>(i);
  return prev;
}

SE3d Planarize(MotionModel motion, const SE3d& T) {
  return motion == MotionModel::kPlanar ? SE2d::FromSE3(T).ToSE3() : T;
}

// Splits the frames into local maps (header comment), without codes yet.
std::vector<LocalMap> SplitFrames(const Survey& survey, const std::vector<int>& frame_component,
                                  const LocalMapOptions& options) {
  const std::vector<int> prev = PreviousLinks(survey);
  std::vector<LocalMap> maps;
  std::map<int, int> open;  // component -> index of its open map
  for (size_t f = 0; f < survey.frames.size(); ++f) {
    const int c = frame_component[f];
    if (c < 0) continue;
    const auto it = open.find(c);
    if (it != open.end()) {
      LocalMap& map = maps[it->second];
      const int l = prev[f];
      if (l >= 0 && survey.odometry_links[l].frame_a == map.frames.back()) {
        const SE3d& step = survey.odometry_links[l].T_a_b;
        const double travel = map.travel_m + step.translation().norm();
        const double turn = map.turn_rad + RotationAngleBetween(SE3d::Identity(), step);
        if (travel <= options.max_travel_m && turn <= options.max_turn_rad &&
            static_cast<int>(map.frames.size()) < options.max_frames) {
          map.T_ref_robot.push_back(Planarize(survey.motion, map.T_ref_robot.back() * step));
          map.frames.push_back(static_cast<int>(f));
          map.travel_m = travel;
          map.turn_rad = turn;
          continue;
        }
      }
    }
    LocalMap map;
    map.component = c;
    map.frames.push_back(static_cast<int>(f));
    map.T_ref_robot.push_back(SE3d::Identity());
    open[c] = static_cast<int>(maps.size());
    maps.push_back(std::move(map));
  }
  return maps;
}

}  // namespace

FusionView MakeFusionView(const Camera& camera, const SE3d& T_frame_robot, const SurveyObservation& obs) {
  FusionView fusion;
  fusion.camera = &camera;
  fusion.T_frame_camera = T_frame_robot * camera.info().T_robot_camera;
  fusion.corners_px = &obs.corners_px;
  fusion.sigma_px = CornerSigmaPx(camera.info());
  return fusion;
}

namespace {

// Fuses every code seen in one local map at the map's current frame poses.
void FuseCodes(const Survey& survey, const std::map<std::string, Camera>& cameras,
               const std::vector<SingleView>& views, const LocalMapOptions& options, LocalMap* map) {
  map->codes.clear();
  std::map<int, std::vector<std::pair<int, int>>> seen;  // marker -> (entry in map, observation)
  for (size_t i = 0; i < map->frames.size(); ++i) {
    for (int o : survey.frames[map->frames[i]].observations) {
      if (views[o].usable) seen[survey.observations[o].marker].emplace_back(static_cast<int>(i), o);
    }
  }
  for (const auto& [m, entries] : seen) {
    std::vector<FusionView> fusion;
    int seed_view = -1;
    for (const auto& [i, o] : entries) {
      const SurveyObservation& obs = survey.observations[o];
      const Camera& camera = cameras.at(obs.camera);
      fusion.push_back(MakeFusionView(camera, map->T_ref_robot[i], obs));
      if (seed_view < 0 || views[o].error_ratio > views[entries[seed_view].second].error_ratio) {
        seed_view = static_cast<int>(fusion.size()) - 1;
      }
    }
    const auto& [seed_entry, seed_obs] = entries[seed_view];
    std::vector<SE3d> seeds;
    for (const SE3d& T_robot_marker : views[seed_obs].T_robot_marker) {
      seeds.push_back(map->T_ref_robot[seed_entry] * T_robot_marker);
    }
    const bool unambiguous = views[seed_obs].error_ratio >= options.ambiguity_ratio;
    std::optional<FusedPose> fused =
        FuseMarkerViews(fusion, survey.markers[m].size_m, seeds, unambiguous, options);
    if (!fused) {  // keeps the map linked; marked unstable so that links avoid it
      fused = FusedPose();
      fused->T_frame_marker = seeds.front();
      fused->why = "no fused pose: no view projects";
    }
    map->codes.emplace(m, *fused);
  }
}

LocalMapLink CodeLink(const std::vector<LocalMap>& maps, int a, int b, int marker) {
  const FusedPose& fa = maps[a].codes.at(marker);
  const FusedPose& fb = maps[b].codes.at(marker);
  LocalMapLink link;
  link.map_a = a;
  link.map_b = b;
  link.marker = marker;
  link.T_a_b = fa.T_frame_marker * fb.T_frame_marker.inverse();
  const Eigen::Vector3d q = fb.T_frame_marker.inverse().translation();
  const double position2 =
      std::pow(PointSigma(fa.covariance, q), 2) + std::pow(PointSigma(fb.covariance, q), 2);
  const double rotation2 = fa.covariance.block<3, 3>(0, 0).trace() + fb.covariance.block<3, 3>(0, 0).trace();
  link.sigma_m = std::sqrt(std::max(0.0, position2 + kLinkLeverM * kLinkLeverM * rotation2));
  double penalty = 1.0;
  if (!fa.stable || !fb.stable) {
    penalty = kUnstablePenalty;
  } else if (!fa.resolved || !fb.resolved) {
    penalty = kAmbiguousPenalty;
  }
  link.quality = 1.0 / (std::max(link.sigma_m, 1e-9) * penalty);
  return link;
}

// The odometry link from map a's reference to map b's (b's first frame follows a's last).
std::optional<LocalMapLink> OdometryLinkBetween(const Survey& survey, const std::vector<int>& prev,
                                                const std::vector<LocalMap>& maps, int a, int b,
                                                const LocalMapOptions& options) {
  const int l = prev[maps[b].frames.front()];
  if (l < 0 || survey.odometry_links[l].frame_a != maps[a].frames.back()) return std::nullopt;
  const OdometryLink& step = survey.odometry_links[l];
  Matrix6d covariance = step.covariance_se3;
  for (size_t i = 1; i < maps[a].frames.size(); ++i)
    covariance += survey.odometry_links[prev[maps[a].frames[i]]].covariance_se3;
  const double travel = maps[a].travel_m + step.T_a_b.translation().norm();
  const double turn = maps[a].turn_rad + RotationAngleBetween(SE3d::Identity(), step.T_a_b);
  const double position2 =
      covariance.block<3, 3>(3, 3).trace() + std::pow(options.odometry_systematic * travel, 2);
  const double rotation2 =
      covariance.block<3, 3>(0, 0).trace() + std::pow(options.odometry_systematic * turn, 2);
  LocalMapLink link;
  link.map_a = a;
  link.map_b = b;
  link.T_a_b = Planarize(survey.motion, maps[a].T_ref_robot.back() * step.T_a_b);
  link.odometry_covariance = covariance;
  link.sigma_m = std::sqrt(position2 + kLinkLeverM * kLinkLeverM * rotation2);
  link.quality = 1.0 / std::max(link.sigma_m, 1e-9);
  return link;
}

// Chains and path lengths of the maps (LocalMap::chain, path_m), in time order per component.
void NumberChains(const Survey& survey, std::vector<LocalMap>* maps) {
  const std::vector<int> prev = PreviousLinks(survey);
  std::map<int, int> last_of_component;
  int chains = 0;
  for (size_t b = 0; b < maps->size(); ++b) {
    LocalMap& map = (*maps)[b];
    const auto it = last_of_component.find(map.component);
    const int l = prev[map.frames.front()];
    if (it != last_of_component.end() && l >= 0 &&
        survey.odometry_links[l].frame_a == (*maps)[it->second].frames.back()) {
      const LocalMap& before = (*maps)[it->second];
      map.chain = before.chain;
      map.path_m = before.path_m + before.travel_m + survey.odometry_links[l].T_a_b.translation().norm();
    } else {
      map.chain = chains++;
      map.path_m = 0.0;
    }
    last_of_component[map.component] = static_cast<int>(b);
  }
}

}  // namespace

std::vector<LocalMap> BuildLocalMaps(const Survey& survey, const std::map<std::string, Camera>& cameras,
                                     const std::vector<SingleView>& views,
                                     const std::vector<int>& frame_component,
                                     const LocalMapOptions& options) {
  std::string why;
  if (!options.Check(&why)) throw std::runtime_error("initializer options: " + why);
  std::vector<LocalMap> maps = SplitFrames(survey, frame_component, options);
  for (LocalMap& map : maps) FuseCodes(survey, cameras, views, options, &map);
  NumberChains(survey, &maps);
  return maps;
}

std::vector<LocalMapLink> FindLocalMapLinks(const Survey& survey, const std::vector<LocalMap>& maps,
                                            const LocalMapOptions& options) {
  std::vector<LocalMapLink> links;
  std::map<int, std::vector<std::pair<double, int>>> holders;  // marker -> (own sigma, map)
  for (size_t i = 0; i < maps.size(); ++i) {
    for (const auto& [m, fused] : maps[i].codes)
      holders[m].emplace_back(RankingSigma(fused), static_cast<int>(i));
  }
  for (auto& [m, list] : holders) {
    std::sort(list.begin(), list.end());
    const size_t hubs = std::min<size_t>(2, list.size());
    for (size_t h = 0; h < hubs; ++h) {
      for (size_t i = h + 1; i < list.size(); ++i)
        links.push_back(CodeLink(maps, list[h].second, list[i].second, m));
    }
  }
  const std::vector<int> prev = PreviousLinks(survey);
  std::map<int, int> last_of_component;
  for (size_t b = 0; b < maps.size(); ++b) {
    const auto it = last_of_component.find(maps[b].component);
    if (it != last_of_component.end()) {
      if (auto link = OdometryLinkBetween(survey, prev, maps, it->second, static_cast<int>(b), options)) {
        links.push_back(*link);
      }
    }
    last_of_component[maps[b].component] = static_cast<int>(b);
  }
  return links;
}

std::vector<int> SpanningForest(int num_maps, const std::vector<LocalMapLink>& links) {
  std::vector<int> order(links.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(),
                   [&](int a, int b) { return links[a].quality > links[b].quality; });
  std::vector<int> parent(num_maps);
  std::iota(parent.begin(), parent.end(), 0);
  const auto find = [&](int i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  };
  std::vector<int> forest;
  for (int l : order) {
    const int a = find(links[l].map_a), b = find(links[l].map_b);
    if (a == b) continue;
    parent[a] = b;
    forest.push_back(l);
  }
  return forest;
}

std::vector<SE3d> PlaceLocalMaps(int num_maps, const std::vector<LocalMapLink>& links,
                                 const std::vector<int>& forest, bool planar) {
  std::vector<std::vector<int>> adjacent(num_maps);
  for (int l : forest) {
    adjacent[links[l].map_a].push_back(l);
    adjacent[links[l].map_b].push_back(l);
  }
  const auto flatten = [planar](const SE3d& T) { return planar ? SE2d::FromSE3(T).ToSE3() : T; };
  std::vector<std::optional<SE3d>> T_world_ref(num_maps);
  for (int root = 0; root < num_maps; ++root) {
    if (T_world_ref[root]) continue;
    T_world_ref[root] = SE3d::Identity();
    std::queue<int> pending;
    pending.push(root);
    while (!pending.empty()) {
      const int i = pending.front();
      pending.pop();
      for (int l : adjacent[i]) {
        const LocalMapLink& link = links[l];
        const int j = link.map_a == i ? link.map_b : link.map_a;
        if (T_world_ref[j]) continue;
        T_world_ref[j] =
            flatten(link.map_a == i ? *T_world_ref[i] * link.T_a_b : *T_world_ref[i] * link.T_a_b.inverse());
        pending.push(j);
      }
    }
  }
  std::vector<SE3d> placed;
  for (const auto& T : T_world_ref) placed.push_back(*T);
  return placed;
}

}  // namespace waymark
