#include "mapping/outlier_rejection.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <string>

#include "mapping/residuals.h"

namespace waymark {

// Observations usable in the optimization: a usable single view, both ends placed.
std::vector<int> UsableObservations(const Survey& survey, const Initialization& init,
                                    MapBuildResult* result) {
  std::vector<int> active;
  for (size_t o = 0; o < survey.observations.size(); ++o) {
    const SurveyObservation& obs = survey.observations[o];
    std::string reason;
    if (!init.views[o].usable) {
      reason = "single view failed: " + init.views[o].why;
    } else if (!init.T_world_robot[obs.frame] || !init.T_world_marker[obs.marker]) {
      reason = "could not be placed";
    }
    if (reason.empty()) {
      active.push_back(static_cast<int>(o));
    } else {
      result->outliers.push_back(
          {survey.markers[obs.marker].key, survey.frames[obs.frame].stamp_s, obs.camera, 0.0, reason});
    }
  }
  return active;
}

// Cosine of the largest angle between the faces of two codes taken for one (60 degrees).
constexpr double kMinDuplicateFacingCos = 0.5;

// The pairs (i, j), i < j, of `markers` whose centres are within `gate_m` in x, in lexicographic
// order: a sweep over the markers sorted by x, linear in the survey where all pairs are not.
std::vector<std::pair<size_t, size_t>> NearbyPairs(const std::vector<SE3d>& T_world_marker, double gate_m) {
  std::vector<size_t> by_x(T_world_marker.size());
  for (size_t i = 0; i < by_x.size(); ++i) by_x[i] = i;
  const auto x = [&](size_t i) { return T_world_marker[i].translation().x(); };
  std::sort(by_x.begin(), by_x.end(), [&](size_t a, size_t b) { return x(a) < x(b); });
  std::vector<std::pair<size_t, size_t>> pairs;
  for (size_t p = 0; p < by_x.size(); ++p) {
    for (size_t q = p + 1; q < by_x.size() && x(by_x[q]) - x(by_x[p]) <= gate_m; ++q) {
      pairs.emplace_back(std::min(by_x[p], by_x[q]), std::max(by_x[p], by_x[q]));
    }
  }
  std::sort(pairs.begin(), pairs.end());
  return pairs;
}

std::vector<int> RemoveDuplicateCodes(const Survey& survey, const Initialization& init,
                                      const GlobalProblem& problem, const std::vector<int>& active,
                                      MapBuildResult* result) {
  std::map<int, std::vector<int>> observations_of;  // marker -> active observations
  for (int o : active) observations_of[survey.observations[o].marker].push_back(o);
  std::vector<int> markers;
  std::vector<SE3d> T_world_marker;
  double largest_gate_m = 0.0;
  for (const auto& [m, obs] : observations_of) {
    markers.push_back(m);
    T_world_marker.push_back(problem.Marker(m));
    largest_gate_m = std::max(largest_gate_m, 0.5 * survey.markers[m].size_m);
  }
  std::set<int> dropped;
  for (const auto& [i, j] : NearbyPairs(T_world_marker, largest_gate_m)) {
    const int a = markers[i], b = markers[j];
    if (init.marker_component[a] != init.marker_component[b] || dropped.count(a) || dropped.count(b))
      continue;
    const double gate_m = 0.5 * std::max(survey.markers[a].size_m, survey.markers[b].size_m);
    const SE3d& T_world_a = T_world_marker[i];
    const SE3d& T_world_b = T_world_marker[j];
    if ((T_world_a.translation() - T_world_b.translation()).norm() > gate_m) continue;
    // Codes printed back to back on a thin wall share a place but face away from each other.
    const Eigen::Vector3d z_a = T_world_a.rotation() * Eigen::Vector3d::UnitZ();
    if (z_a.dot(T_world_b.rotation() * Eigen::Vector3d::UnitZ()) < kMinDuplicateFacingCos) continue;
    const bool a_loses = observations_of[a].size() < observations_of[b].size() ||
                         (observations_of[a].size() == observations_of[b].size() && survey.markers[b].known);
    const int loser = a_loses ? a : b, winner = a_loses ? b : a;
    if (survey.markers[loser].known && survey.markers[loser].known->fixed) continue;
    dropped.insert(loser);
    for (int o : observations_of[loser]) {
      result->outliers.push_back({survey.markers[loser].key,
                                  survey.frames[survey.observations[o].frame].stamp_s,
                                  survey.observations[o].camera, 0.0,
                                  "id conflicts with " + survey.markers[winner].key.ToString() +
                                      ", mapped at the same place (misdecoded?)"});
    }
  }
  std::vector<int> kept;
  for (int o : active) {
    if (!dropped.count(survey.observations[o].marker)) kept.push_back(o);
  }
  return kept;
}

// Stage 3: drops outliers, then codes seen in fewer than min_frames frames.
std::vector<int> RejectOutliers(const Survey& survey, const GlobalProblem& problem,
                                const std::vector<int>& active, const MapBuildOptions& options,
                                MapBuildResult* result) {
  std::vector<int> inliers;
  std::vector<std::set<int>> frames_of_marker(survey.markers.size());
  for (int o : active) {
    const SurveyObservation& obs = survey.observations[o];
    const double s = problem.SquaredError(o);
    if (s > options.outlier_chi2) {
      const double rms_px = std::sqrt(s / 4.0) * CornerSigmaPx(survey.cameras.at(obs.camera));
      result->outliers.push_back({survey.markers[obs.marker].key, survey.frames[obs.frame].stamp_s,
                                  obs.camera, rms_px, "reprojection error above the outlier gate"});
      continue;
    }
    inliers.push_back(o);
    frames_of_marker[obs.marker].insert(obs.frame);
  }
  std::vector<int> kept;
  for (int o : inliers) {
    const int m = survey.observations[o].marker;
    const SurveyMarker& marker = survey.markers[m];
    if (static_cast<int>(frames_of_marker[m].size()) >= options.min_frames || marker.known) kept.push_back(o);
  }
  for (size_t m = 0; m < survey.markers.size(); ++m) {
    const size_t n = frames_of_marker[m].size();
    if (static_cast<int>(n) >= options.min_frames || (survey.markers[m].known && n > 0)) continue;
    result->unmapped.push_back(
        {survey.markers[m].key,
         n == 0 ? "no usable observation" : "seen in " + std::to_string(n) + " frame(s) only"});
  }
  return kept;
}

}  // namespace waymark
