#include "mapping/local_map_graph.h"

#include <ceres/ceres.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <memory>
#include <numeric>
#include <optional>
#include <sstream>
#include <stdexcept>

#include "factors/calibrated_odometry_factor.h"
#include "factors/odometry_se3_factor.h"
#include "factors/pose_block.h"
#include "mapping/serial_blas.h"
#include "util/check.h"
#include "util/format.h"

namespace waymark {
namespace {

using Block = std::array<double, kSE3BlockSize>;

// Robust scale of the sightings (whitened units), as the rest of the initializer.
constexpr double kSightingCauchyScale = 3.0;

// One code in one local map (a factor of the header comment).
struct Sighting {
  int map = 0;
  int marker = 0;
  const FusedPose* fused = nullptr;
  int instance = 0;
  Matrix6d covariance;  // penalized as RankingSigma
  bool inlier = false;  // after stage 1
};

struct Instance {
  int marker = 0;
  int first_map = 0;
  int best = 0;  // sighting of smallest RankingSigma
  double sigma = 0.0;
};

SE3d Flatten(bool planar, const SE3d& T) { return planar ? SE2d::FromSE3(T).ToSE3() : T; }

// Union-find with the lowest index as root.
class LowestRoot {
 public:
  explicit LowestRoot(int n) : parent_(n) { std::iota(parent_.begin(), parent_.end(), 0); }
  int Find(int i) {
    while (parent_[i] != i) i = parent_[i] = parent_[parent_[i]];
    return i;
  }
  void Join(int a, int b) {
    a = Find(a);
    b = Find(b);
    parent_[std::max(a, b)] = std::min(a, b);
  }

 private:
  std::vector<int> parent_;
};

// Sightings of every map, grouped into instances (header comment).
void FindInstances(const std::vector<LocalMap>& maps, double near_path_m, std::vector<Sighting>* sightings,
                   std::vector<Instance>* instances) {
  std::map<int, std::vector<int>> of_marker;  // marker -> sightings, in map order
  for (size_t i = 0; i < maps.size(); ++i) {
    for (const auto& [m, fused] : maps[i].codes) {
      Sighting s;
      s.map = static_cast<int>(i);
      s.marker = m;
      s.fused = &fused;
      const double penalty = !fused.stable ? kUnstablePenalty : (!fused.resolved ? kAmbiguousPenalty : 1.0);
      s.covariance = fused.covariance * penalty * penalty;
      s.covariance.diagonal().array() += 1e-12;
      of_marker[m].push_back(static_cast<int>(sightings->size()));
      sightings->push_back(s);
    }
  }
  for (const auto& [m, list] : of_marker) {
    int last_map = -1;
    for (int k : list) {
      Sighting& s = (*sightings)[k];
      const bool same = last_map >= 0 && maps[last_map].chain == maps[s.map].chain &&
                        maps[s.map].path_m - maps[last_map].path_m <= near_path_m;
      if (!same) instances->push_back({m, s.map, k, RankingSigma(*s.fused)});
      Instance& instance = instances->back();
      s.instance = static_cast<int>(instances->size()) - 1;
      if (RankingSigma(*s.fused) < instance.sigma) {
        instance.best = k;
        instance.sigma = RankingSigma(*s.fused);
      }
      last_map = s.map;
    }
  }
}

// The pose graph of the header comment: SE(3) blocks for maps and code nodes, c shared.
class Graph {
 public:
  Graph(const std::vector<SE3d>& T_world_ref, const std::vector<SE3d>& T_world_code,
        const Eigen::Vector3d& calibration, const LocalMapGraphOptions& options)
      : maps_(T_world_ref.size()),
        codes_(T_world_code.size()),
        prior_mean_(options.given_calibration_sigma ? *options.given_calibration : Eigen::Vector3d::Zero()),
        prior_sigma_(
            options.given_calibration_sigma.value_or(Eigen::Vector3d::Constant(options.calibration_sigma))) {
    ceres::Problem::Options problem_options;
    problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    problem_ = std::make_unique<ceres::Problem>(problem_options);
    for (size_t i = 0; i < maps_.size(); ++i) {
      SE3ToBlock(T_world_ref[i], maps_[i].data());
      problem_->AddParameterBlock(maps_[i].data(), kSE3BlockSize, &manifold_);
    }
    for (size_t i = 0; i < codes_.size(); ++i) {
      SE3ToBlock(T_world_code[i], codes_[i].data());
      problem_->AddParameterBlock(codes_[i].data(), kSE3BlockSize, &manifold_);
    }
    for (int i = 0; i < kOdometryCalibrationSize; ++i) calibration_[i] = calibration[i];
  }

  void AddOdometry(const LocalMapLink& link, const LocalMapGraphOptions& options) {
    if (!calibration_added_) {
      problem_->AddParameterBlock(calibration_.data(), kOdometryCalibrationSize);
      problem_->AddResidualBlock(OdometryCalibrationPrior::Create(prior_mean_, prior_sigma_), nullptr,
                                 calibration_.data());
      calibration_added_ = true;
    }
    Matrix6d covariance = link.odometry_covariance;
    covariance.diagonal().head<3>().array() += options.odometry_floor_rad * options.odometry_floor_rad;
    covariance.diagonal().tail<3>().array() += options.odometry_floor_m * options.odometry_floor_m;
    problem_->AddResidualBlock(CalibratedOdometrySE3Factor::Create(link.T_a_b, covariance), nullptr,
                               maps_[link.map_a].data(), maps_[link.map_b].data(), calibration_.data());
  }

  void AddSighting(const Sighting& sighting, int code, bool robust) {
    problem_->AddResidualBlock(OdometrySE3Factor::Create(sighting.fused->T_frame_marker, sighting.covariance),
                               robust ? new ceres::CauchyLoss(kSightingCauchyScale) : nullptr,
                               maps_[sighting.map].data(), codes_[code].data());
  }

  void HoldCalibrationConstant() {
    if (calibration_added_) problem_->SetParameterBlockConstant(calibration_.data());
  }
  void HoldMapConstant(int map) { problem_->SetParameterBlockConstant(maps_[map].data()); }
  void HoldCodeConstant(int code) { problem_->SetParameterBlockConstant(codes_[code].data()); }

  // Solves; on failure the values stay the start's.
  void Solve(int max_iterations) {
    const auto maps = maps_;
    const auto codes = codes_;
    const auto calibration = calibration_;
    ceres::Solver::Options options;
    options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
    options.max_num_iterations = max_iterations;
    options.logging_type = ceres::SILENT;
    ceres::Solver::Summary summary;
    {
      const ScopedSerialLinearAlgebra serial;  // the same result at any load
      ceres::Solve(options, problem_.get(), &summary);
    }
    if (summary.IsSolutionUsable()) return;
    maps_ = maps;
    codes_ = codes;
    calibration_ = calibration;
  }

  SE3d Map(int i) const { return SE3FromBlock(maps_[i].data()); }
  SE3d Code(int i) const { return SE3FromBlock(codes_[i].data()); }
  Eigen::Vector3d Calibration() const {
    return Eigen::Vector3d(calibration_[0], calibration_[1], calibration_[2]);
  }

 private:
  std::vector<Block> maps_, codes_;
  std::array<double, kOdometryCalibrationSize> calibration_{};
  const Eigen::Vector3d prior_mean_, prior_sigma_;
  bool calibration_added_ = false;
  SE3Manifold manifold_;  // outlives problem_ (declared before it)
  std::unique_ptr<ceres::Problem> problem_;
};

// Whitened squared error of a sighting at the given poses.
double SightingChi2(const Sighting& sighting, const SE3d& T_world_ref, const SE3d& T_world_code) {
  const Vector6d delta = sighting.fused->T_frame_marker.BoxMinus(T_world_ref.inverse() * T_world_code);
  return delta.dot(sighting.covariance.ldlt().solve(delta));
}

struct Stage {
  std::vector<SE3d> T_world_ref;   // stage 1: in each group's frame (its first map at identity)
  std::vector<SE3d> T_world_code;  // per instance
  std::vector<int> group;          // lowest map index of each map's group
  Eigen::Vector3d calibration = Eigen::Vector3d::Zero();
};

// Stage 1 of the header comment; marks the inlier sightings.
Stage SolveInstancesApart(const std::vector<LocalMap>& maps, const std::vector<LocalMapLink>& odometry,
                          std::vector<Sighting>* sightings, const std::vector<Instance>& instances,
                          bool planar, const LocalMapGraphOptions& options) {
  const int num_maps = static_cast<int>(maps.size());
  Stage stage;
  LowestRoot groups(num_maps);
  for (const LocalMapLink& link : odometry) groups.Join(link.map_a, link.map_b);
  for (const Sighting& s : *sightings) groups.Join(s.map, instances[s.instance].first_map);
  stage.group.resize(num_maps);
  for (int i = 0; i < num_maps; ++i) stage.group[i] = groups.Find(i);
  stage.T_world_ref = PlaceLocalMaps(num_maps, odometry, SpanningForest(num_maps, odometry), planar);
  // Maps joined to their group only through codes: placed from the first instance that holds them.
  std::vector<bool> placed(num_maps, false);
  for (const LocalMapLink& link : odometry) placed[link.map_a] = placed[link.map_b] = true;
  for (int i = 0; i < num_maps; ++i) placed[i] = placed[i] || stage.group[i] == i;
  for (size_t pass = 0; pass < 2; ++pass) {
    std::vector<std::optional<SE3d>> code_start(instances.size());
    for (const Sighting& s : *sightings) {
      if (placed[s.map] && !code_start[s.instance])
        code_start[s.instance] = stage.T_world_ref[s.map] * s.fused->T_frame_marker;
    }
    for (const Sighting& s : *sightings) {
      if (!placed[s.map] && code_start[s.instance]) {
        stage.T_world_ref[s.map] = *code_start[s.instance] * s.fused->T_frame_marker.inverse();
        placed[s.map] = true;
      }
    }
  }
  for (const Instance& instance : instances) {
    const Sighting& best = (*sightings)[instance.best];
    stage.T_world_code.push_back(stage.T_world_ref[best.map] * best.fused->T_frame_marker);
  }
  Graph graph(stage.T_world_ref, stage.T_world_code,
              options.given_calibration.value_or(Eigen::Vector3d::Zero()), options);
  for (const LocalMapLink& link : odometry) graph.AddOdometry(link, options);
  if (options.CalibrationHeld()) graph.HoldCalibrationConstant();
  for (const Sighting& s : *sightings) graph.AddSighting(s, s.instance, true);
  for (int i = 0; i < num_maps; ++i) {
    if (stage.group[i] == i) graph.HoldMapConstant(i);
  }
  graph.Solve(options.max_iterations);
  for (int i = 0; i < num_maps; ++i) stage.T_world_ref[i] = graph.Map(i);
  for (size_t k = 0; k < instances.size(); ++k) stage.T_world_code[k] = graph.Code(static_cast<int>(k));
  stage.calibration = graph.Calibration();
  for (Sighting& s : *sightings) {
    s.inlier =
        SightingChi2(s, stage.T_world_ref[s.map], stage.T_world_code[s.instance]) <= options.inlier_chi2;
  }
  return stage;
}

// A chain's maps re-composed from their stage-1 increments with an extra heading drift dk
// (rad/m), as the calibrated odometry bends an increment (factors/calibrated_odometry_factor.h):
//   T_a_b' = (Rz(-dk d) R_a_b, Rz(-dk d / 2) t_a_b),  d = path_b - path_a.
std::vector<SE3d> BendChain(const std::vector<LocalMap>& maps, const std::vector<int>& chain,
                            const std::vector<SE3d>& T_world_ref, double dk) {
  std::vector<SE3d> bent{T_world_ref[chain.front()]};
  for (size_t i = 1; i < chain.size(); ++i) {
    const int a = chain[i - 1], b = chain[i];
    const SE3d T_a_b = T_world_ref[a].inverse() * T_world_ref[b];
    const double angle = -dk * (maps[b].path_m - maps[a].path_m);
    const Eigen::Quaterniond turn(Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitZ()));
    const Eigen::Quaterniond half(Eigen::AngleAxisd(0.5 * angle, Eigen::Vector3d::UnitZ()));
    bent.push_back(bent.back() * SE3d(turn * T_a_b.rotation(), half * T_a_b.translation()));
  }
  return bent;
}

// The least-cost dk of the search: a coarse grid (step search_step_rad / length_m over
// +-search_max_rad_per_m), then a grid ten times finer around its kSearchCandidates best points;
// ties go to the smaller |dk|.
constexpr int kSearchCandidates = 5;
constexpr double kSearchSigmaM = 1.0;  // closure mismatch scale of the search cost
template <typename Cost>
double SearchGrid(const LocalMapGraphOptions& options, double length_m, const Cost& cost) {
  const double step = options.search_step_rad / length_m;
  const int steps = static_cast<int>(std::ceil(options.search_max_rad_per_m / step));
  std::vector<std::pair<double, double>> coarse;  // (cost, dk)
  for (int n = -steps; n <= steps; ++n) coarse.emplace_back(cost(n * step), n * step);
  const size_t keep = std::min<size_t>(kSearchCandidates, coarse.size());
  std::partial_sort(coarse.begin(), coarse.begin() + keep, coarse.end());
  std::pair<double, double> best = {cost(0.0), 0.0};
  const auto better = [](const std::pair<double, double>& a, const std::pair<double, double>& b) {
    return a.first < b.first - 1e-9 || (a.first <= b.first + 1e-9 && std::abs(a.second) < std::abs(b.second));
  };
  for (size_t c = 0; c < keep; ++c) {
    for (int n = -10; n <= 10; ++n) {
      const double dk = coarse[c].second + 0.1 * n * step;
      const std::pair<double, double> candidate = {cost(dk), dk};
      if (better(candidate, best)) best = candidate;
    }
  }

  return best.second;
}

constexpr size_t kMaxClosurePartners = 16;

// The mismatch up to which a closure counts in the heading-drift search, for two instances d
// metres of path apart: search_truncation_m, or stage 2's position gate for them when wider.
// What stage 1 leaves of a true closure grows with the path between its instances (a corner's
// turn error the codes do not see swings the whole next leg: 10 mrad on a 500 m leg is 5 m), as
// the gate says. With a fixed 5 m, a 1.4 km loop's right bend (more than 5 m off) cost as much
// as any other: the search kept stage 1's k and the gate rejected the closure, or it took a bend
// wrapped by two extra turns that passed the start within 5 m (header comment). The search's
// sigma scales with the truncation (kSearchSigmaM at search_truncation_m), so
// the cost is the same in whitened units at any size and the right bend's basin (the truncation
// either side) is always wider than the coarse grid's step: the step moves a closure by at most
// search_step_rad times the loop's extent, and the gate grows by gate_per_m times the path.
double SearchTruncationM(const LocalMapGraphOptions& options, double path_between_m) {
  return std::max(options.search_truncation_m, options.gate_m + options.gate_per_m * path_between_m);
}

// The heading-drift search of the header comment, per chain holding loop closures: moves the
// stage-1 maps and instances of the chain by the best dk on a grid; returns the dk of the
// longest chain searched (0 when none).
double SearchHeadingDrift(const std::vector<LocalMap>& maps, const std::vector<Sighting>& sightings,
                          const std::vector<Instance>& instances, const LocalMapGraphOptions& options,
                          Stage* stage) {
  std::map<int, std::vector<int>> chains;  // chain -> maps in order
  for (size_t i = 0; i < maps.size(); ++i) chains[maps[i].chain].push_back(static_cast<int>(i));
  // Each instance's pose in the frame of the map of its best sighting.
  std::vector<SE3d> T_map_code(instances.size());
  for (size_t k = 0; k < instances.size(); ++k) {
    T_map_code[k] = stage->T_world_ref[sightings[instances[k].best].map].inverse() * stage->T_world_code[k];
  }
  // chain -> marker -> instances whose first map is in the chain, in order.
  std::map<int, std::map<int, std::vector<int>>> chain_instances;
  for (size_t k = 0; k < instances.size(); ++k) {
    chain_instances[maps[instances[k].first_map].chain][instances[k].marker].push_back(static_cast<int>(k));
  }
  double longest_m = 0.0, result = 0.0;
  for (const auto& [chain, members] : chains) {
    // (earlier instance, later instance) of one code in this chain: each instance with at most
    // kMaxClosurePartners earlier ones, so a code revisited n times gives O(n) pairs, not n^2.
    std::vector<std::pair<int, int>> closures;
    std::vector<double> truncation_m;  // per closure: SearchTruncationM
    for (const auto& [marker, list] : chain_instances[chain]) {
      for (size_t b = 1; b < list.size(); ++b) {
        for (size_t a = b > kMaxClosurePartners ? b - kMaxClosurePartners : 0; a < b; ++a) {
          closures.emplace_back(list[a], list[b]);
          const double d =
              std::abs(maps[instances[list[b]].first_map].path_m - maps[instances[list[a]].first_map].path_m);
          truncation_m.push_back(SearchTruncationM(options, d));
        }
      }
    }
    const double length_m = maps[members.back()].path_m - maps[members.front()].path_m;
    if (closures.empty() || !(length_m > 0.0)) continue;
    std::vector<int> position(maps.size(), -1);
    for (size_t i = 0; i < members.size(); ++i) position[members[i]] = static_cast<int>(i);
    const auto cost = [&](const std::vector<SE3d>& bent) {
      double sum = 0.0;
      for (size_t c = 0; c < closures.size(); ++c) {
        const auto& [i, j] = closures[c];
        const SE3d T_i = bent[position[sightings[instances[i].best].map]] * T_map_code[i];
        const SE3d T_j = bent[position[sightings[instances[j].best].map]] * T_map_code[j];
        const double e2 = (T_i.translation() - T_j.translation()).squaredNorm() +
                          std::pow(kLinkLeverM * RotationAngleBetween(T_i, T_j), 2);
        // In units of the closure's own scale: kSearchSigmaM times truncation / search_truncation_m.
        const double scale = truncation_m[c] / options.search_truncation_m;
        sum += std::min(e2, truncation_m[c] * truncation_m[c]) / (scale * scale);
      }
      return sum;
    };
    const double best_dk = SearchGrid(options, length_m, [&](double dk) {
      return cost(BendChain(maps, members, stage->T_world_ref, dk)) / (kSearchSigmaM * kSearchSigmaM) +
             std::pow(dk / options.search_sigma_rad_per_m, 2);
    });
    const std::vector<SE3d> bent = BendChain(maps, members, stage->T_world_ref, best_dk);
    for (size_t i = 0; i < members.size(); ++i) stage->T_world_ref[members[i]] = bent[i];
    for (size_t k = 0; k < instances.size(); ++k) {
      const int map = sightings[instances[k].best].map;
      if (maps[map].chain == chain) stage->T_world_code[k] = stage->T_world_ref[map] * T_map_code[k];
    }
    if (length_m > longest_m) {
      longest_m = length_m;
      result = best_dk;
    }
  }
  return result;
}

// Stage 2's placement: the groups along a forest of instance pairs, then the gate; node[k] is the
// instance whose node instance k shares (itself when kept apart).
struct Placement {
  std::vector<SE3d> T_world_ref, T_world_code;
  std::vector<int> node;
  int accepted = 0, rejected = 0;
  int candidates = 0;  // instance pairs considered for the forest
};

Placement PlaceAndMerge(const std::vector<LocalMap>& maps, const Stage& stage,
                        const std::vector<Instance>& instances, bool planar,
                        const LocalMapGraphOptions& options) {
  const int num_maps = static_cast<int>(maps.size());
  std::vector<int> group_of_root(num_maps, -1);
  int num_groups = 0;
  for (int i = 0; i < num_maps; ++i) {
    if (stage.group[i] == i) group_of_root[i] = num_groups++;
  }
  const auto group = [&](int k) { return group_of_root[stage.group[instances[k].first_map]]; };
  // Candidate links: per code, the best instance (smallest sigma) of each group, each joined to
  // the best of the code's best group. The quality 1 / hypot(sigma_i, sigma_j) falls with either
  // sigma, so this star is a maximum spanning tree of all the code's instance pairs between groups
  // (every pair (i, j) closes a cycle through the hub whose other links are at least as good),
  // and the union over codes holds the maximum spanning forest of all pairs: the same forest
  // as from every pair (up to ties), with links linear in the instances instead of quadratic
  // (a code seen in n frames without odometry is n instances: test6, 1 546 frames).
  std::vector<LocalMapLink> between;
  std::vector<std::pair<int, int>> pair_of;  // instances of each entry of `between`
  std::vector<int> first(instances.size());  // first instance of each instance's code
  for (size_t begin = 0; begin < instances.size();) {
    size_t end = begin;
    while (end < instances.size() && instances[end].marker == instances[begin].marker) ++end;
    std::map<int, int> best_of_group;  // group -> its instance of least sigma (lowest index on ties)
    for (size_t k = begin; k < end; ++k) {
      first[k] = static_cast<int>(begin);
      const auto it = best_of_group.emplace(group(static_cast<int>(k)), static_cast<int>(k)).first;
      if (instances[k].sigma < instances[it->second].sigma) it->second = static_cast<int>(k);
    }
    int hub = -1;
    for (const auto& [g, k] : best_of_group) {
      if (hub < 0 || instances[k].sigma < instances[hub].sigma ||
          (instances[k].sigma == instances[hub].sigma && k < hub)) {
        hub = k;
      }
    }
    for (const auto& [g, k] : best_of_group) {
      if (k == hub) continue;
      const int i = std::min(hub, k), j = std::max(hub, k);
      LocalMapLink link;
      link.map_a = group(i);
      link.map_b = group(j);
      link.marker = instances[j].marker;
      link.T_a_b = stage.T_world_code[i] * stage.T_world_code[j].inverse();
      link.quality = 1.0 / std::max(1e-9, std::hypot(instances[i].sigma, instances[j].sigma));
      between.push_back(link);
      pair_of.emplace_back(i, j);
    }
    begin = end;
  }
  const std::vector<int> forest = SpanningForest(num_groups, between);
  const std::vector<SE3d> T_world_group = PlaceLocalMaps(num_groups, between, forest, planar);
  Placement placement;
  placement.candidates = static_cast<int>(between.size());
  for (int i = 0; i < num_maps; ++i) {
    placement.T_world_ref.push_back(
        Flatten(planar, T_world_group[group_of_root[stage.group[i]]] * stage.T_world_ref[i]));
  }
  for (size_t k = 0; k < instances.size(); ++k) {
    placement.T_world_code.push_back(T_world_group[group(static_cast<int>(k))] * stage.T_world_code[k]);
  }
  LowestRoot merged(static_cast<int>(instances.size()));
  for (int l : forest) merged.Join(pair_of[l].first, pair_of[l].second);
  for (size_t j = 0; j < instances.size(); ++j) {
    const int f = first[j];
    if (f == static_cast<int>(j)) continue;
    const LocalMap& a = maps[instances[f].first_map];
    const LocalMap& b = maps[instances[j].first_map];
    const double d = a.chain == b.chain ? std::abs(a.path_m - b.path_m) : 0.0;
    const SE3d E = placement.T_world_code[f].inverse() * placement.T_world_code[j];
    if (E.translation().norm() <= options.gate_m + options.gate_per_m * d &&
        RotationAngleBetween(SE3d::Identity(), E) <= options.gate_rad + options.gate_rad_per_m * d) {
      merged.Join(f, static_cast<int>(j));
    }
    (merged.Find(static_cast<int>(j)) == merged.Find(f) ? placement.accepted : placement.rejected) += 1;
  }
  for (size_t k = 0; k < instances.size(); ++k) placement.node.push_back(merged.Find(static_cast<int>(k)));
  return placement;
}

}  // namespace

bool LocalMapGraphOptions::Check(std::string* why) const {
  WAYMARK_CHECK_OPTION(IsFinitePositive(inlier_chi2), "local map graph: inlier_chi2 must be finite and > 0");
  WAYMARK_CHECK_OPTION(IsFinitePositive(search_truncation_m),
                       "local map graph: search_truncation_m must be finite and > 0");
  WAYMARK_CHECK_OPTION(IsFiniteAtLeast(near_path_m, 0.0) && IsFiniteAtLeast(gate_m, 0.0) &&
                           IsFiniteAtLeast(gate_per_m, 0.0) && IsFiniteAtLeast(gate_rad, 0.0) &&
                           IsFiniteAtLeast(gate_rad_per_m, 0.0),
                       "local map graph: near_path_m and the gates must be finite and >= 0");
  WAYMARK_CHECK_OPTION(IsFinitePositive(calibration_sigma) && IsFinitePositive(odometry_floor_m) &&
                           IsFinitePositive(odometry_floor_rad),
                       "local map graph: calibration_sigma and the odometry floors must be finite and > 0");
  WAYMARK_CHECK_OPTION(!given_calibration || OdometryCalibrationValid(*given_calibration),
                       "local map graph: " + std::string(kOdometryCalibrationRule));
  WAYMARK_CHECK_OPTION(
      !given_calibration_sigma ||
          (given_calibration && OdometryCalibrationSigmaValid(*given_calibration_sigma)),
      "local map graph: given_calibration_sigma needs given_calibration, and must be three finite "
      "numbers > 0");
  WAYMARK_CHECK_OPTION(max_iterations >= 1, "local map graph: max_iterations must be >= 1");
  return true;
}

LocalMapGraph SolveLocalMapGraph(const std::vector<LocalMap>& maps, const std::vector<LocalMapLink>& links,
                                 bool planar, const LocalMapGraphOptions& options) {
  std::string why;
  if (!options.Check(&why)) throw std::runtime_error(why);
  std::vector<LocalMapLink> odometry;
  for (const LocalMapLink& link : links) {
    if (link.marker < 0 && link.quality > 0.0 && std::isfinite(link.quality)) odometry.push_back(link);
  }
  std::vector<Sighting> sightings;
  std::vector<Instance> instances;
  FindInstances(maps, options.near_path_m, &sightings, &instances);
  Stage stage = SolveInstancesApart(maps, odometry, &sightings, instances, planar, options);
  const double dk =
      options.CalibrationHeld() ? 0.0 : SearchHeadingDrift(maps, sightings, instances, options, &stage);

  stage.calibration[0] += dk;
  const Placement placement = PlaceAndMerge(maps, stage, instances, planar, options);
  LocalMapGraph result;
  const int num_maps = static_cast<int>(maps.size());
  for (int i = 0; i < num_maps; ++i) result.groups += stage.group[i] == i ? 1 : 0;
  result.instances = static_cast<int>(instances.size());
  result.sightings = static_cast<int>(sightings.size());
  for (const Sighting& s : sightings) result.outlying_sightings += s.inlier ? 0 : 1;
  result.closures_accepted = placement.accepted;
  result.closures_rejected = placement.rejected;
  result.placement_candidates = placement.candidates;
  Graph graph(placement.T_world_ref, placement.T_world_code, stage.calibration, options);
  LowestRoot components(num_maps);
  for (const LocalMapLink& link : odometry) {
    graph.AddOdometry(link, options);
    components.Join(link.map_a, link.map_b);
  }
  std::vector<bool> used(instances.size(), false);
  for (const Sighting& s : sightings) {
    const int node = placement.node[s.instance];
    graph.AddSighting(s, node, !s.inlier);
    components.Join(s.map, instances[node].first_map);
    used[node] = true;
  }
  for (size_t k = 0; k < instances.size(); ++k) {
    if (!used[k]) graph.HoldCodeConstant(static_cast<int>(k));
  }
  for (int i = 0; i < num_maps; ++i) {
    if (components.Find(i) == i) graph.HoldMapConstant(i);
  }
  graph.HoldCalibrationConstant();  // header comment, stage 2
  graph.Solve(options.max_iterations);
  for (int i = 0; i < num_maps; ++i) result.T_world_ref.push_back(Flatten(planar, graph.Map(i)));
  result.odometry_calibration = graph.Calibration();
  return result;
}

std::string DescribeLocalMapGraph(const LocalMapGraph& graph) {
  const auto num = [](double value) { return FormatSignificant(value, 3); };
  return "local map graph: " + std::to_string(graph.groups) + " group(s) joined by odometry, " +
         std::to_string(graph.instances) + " code instances from " + std::to_string(graph.sightings) +
         " sightings (" + std::to_string(graph.outlying_sightings) + " outlying), loop closures " +
         std::to_string(graph.closures_accepted) + " accepted / " + std::to_string(graph.closures_rejected) +
         " rejected by the gate; odometry calibration k " +
         num(graph.odometry_calibration[0] * 180.0 / M_PI) + " deg/m, turn scale " +
         num(graph.odometry_calibration[1]) + ", distance scale " + num(graph.odometry_calibration[2]);
}

}  // namespace waymark
