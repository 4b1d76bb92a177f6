#include "mapping/id_consistency.h"

#include <algorithm>
#include <cmath>
#include <optional>

#include "geometry/marker_pose.h"
#include "mapping/residuals.h"
#include "util/check.h"

namespace waymark {
namespace {

// A view alone in its odometry segment is inconsistent when another segment holds a cluster of
// at least this many consistent views of the code.
constexpr int kMinSupportElsewhere = 3;
// A cluster in one segment is inconsistent when another segment's is this many times larger.
constexpr int kMinorityFactor = 8;

// One judged view: the code's centre in the odometry frame, its range and path position.
struct OdomView {
  int observation = 0;
  Eigen::Vector3d p_odom;
  double range_m = 0.0;
  double path_m = 0.0;
};

// Odometry path length at each frame, from the start of its segment (chords between frames).
std::vector<double> PathLengths(const Survey& survey) {
  std::vector<double> path_m(survey.frames.size(), 0.0);
  int last = -1;
  for (size_t f = 0; f < survey.frames.size(); ++f) {
    const SurveyFrame& frame = survey.frames[f];
    if (!frame.T_odom_robot) continue;
    if (last >= 0 && survey.frames[last].segment == frame.segment) {
      path_m[f] =
          path_m[last] +
          (frame.T_odom_robot->translation() - survey.frames[last].T_odom_robot->translation()).norm();
    }
    last = static_cast<int>(f);
  }
  return path_m;
}

std::optional<OdomView> MakeView(const Survey& survey, const std::map<std::string, Camera>& cameras,
                                 const std::vector<double>& path_m, int o) {
  const SurveyObservation& obs = survey.observations[o];
  const SurveyFrame& frame = survey.frames[obs.frame];
  if (!frame.T_odom_robot) return std::nullopt;
  const Camera& camera = cameras.at(obs.camera);
  MarkerPoseOptions pose_options;
  pose_options.sigma_px = CornerSigmaPx(camera.info());
  try {
    const MarkerPoseEstimate estimate =
        EstimateMarkerPose(obs.corners_px, survey.markers[obs.marker].size_m, camera, pose_options);
    const Eigen::Vector3d& t_camera_marker = estimate.best().T_camera_marker.translation();
    OdomView view;
    view.observation = o;
    view.p_odom = *frame.T_odom_robot * (camera.info().T_robot_camera * t_camera_marker);
    view.range_m = t_camera_marker.norm();
    view.path_m = path_m[obs.frame];
    return view;
  } catch (const std::exception&) {
    return std::nullopt;  // an unusable single view; the initializer reports it
  }
}

bool Consistent(const OdomView& a, const OdomView& b, const IdCheckOptions& options) {
  const double gate_m = options.base_gate_m + options.drift_per_m * std::abs(a.path_m - b.path_m) +
                        options.range_fraction * (a.range_m + b.range_m);
  return (a.p_odom - b.p_odom).norm() <= gate_m;
}

// Size of each view's visit (header comment): views linked along the path, each to one of the
// previous options.visit_link_window views in path order that it is consistent with.
std::vector<int> VisitSizes(const std::vector<OdomView>& views, const IdCheckOptions& options) {
  std::vector<size_t> order(views.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(),
                   [&](size_t a, size_t b) { return views[a].path_m < views[b].path_m; });
  std::vector<size_t> parent(views.size());
  for (size_t i = 0; i < parent.size(); ++i) parent[i] = i;
  const auto root = [&](size_t i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  };
  for (size_t k = 1; k < order.size(); ++k) {
    for (size_t back = 1; back <= options.visit_link_window && back <= k; ++back) {
      if (Consistent(views[order[k]], views[order[k - back]], options))
        parent[root(order[k])] = root(order[k - back]);
    }
  }
  std::map<size_t, int> count;
  for (size_t i = 0; i < views.size(); ++i) ++count[root(i)];
  std::vector<int> size(views.size());
  for (size_t i = 0; i < views.size(); ++i) size[i] = count[root(i)];
  return size;
}

// Judges the views of one code in one segment (header comment); returns the seed's support.
// The views not found inconsistent are added to *kept.
int JudgeViews(const std::vector<OdomView>& views, const IdCheckOptions& options,
               std::vector<int>* inconsistent, std::vector<int>* kept) {
  if (views.size() == 1) kept->push_back(views[0].observation);
  if (views.size() < 2) return static_cast<int>(views.size());
  const std::vector<int> visit = VisitSizes(views, options);
  const size_t stride = (views.size() + options.max_reference_views - 1) / options.max_reference_views;
  std::vector<int> support(views.size(), 0);
  for (size_t i = 0; i < views.size(); ++i) {
    for (size_t j = 0; j < views.size(); j += stride)
      support[i] += Consistent(views[i], views[j], options) ? 1 : 0;
    if (stride > 1 && i % stride != 0) ++support[i];  // itself, when not among the references
  }
  const size_t seed = std::max_element(support.begin(), support.end()) - support.begin();
  for (size_t i = 0; i < views.size(); ++i) {
    if (support[seed] == 1) {
      inconsistent->push_back(views[i].observation);  // no two views agree
    } else if (!Consistent(views[i], views[seed], options) && 2 * support[i] <= support[seed] &&
               visit[i] < options.min_visit_views) {
      inconsistent->push_back(views[i].observation);
    } else {
      kept->push_back(views[i].observation);
    }
  }
  return support[seed];
}

}  // namespace

bool IdCheckOptions::Check(std::string* why) const {
  WAYMARK_CHECK_OPTION(IsFiniteAtLeast(base_gate_m, 0.0) && IsFiniteAtLeast(drift_per_m, 0.0) &&
                           IsFiniteAtLeast(range_fraction, 0.0),
                       "id check: base_gate_m, drift_per_m and range_fraction must be finite and >= 0");
  WAYMARK_CHECK_OPTION(max_reference_views >= 1, "id check: max_reference_views must be >= 1");
  WAYMARK_CHECK_OPTION(min_visit_views >= 2 && visit_link_window >= 1,
                       "id check: min_visit_views must be >= 2 and visit_link_window >= 1");
  return true;
}

std::vector<int> FindInconsistentIds(const Survey& survey, const std::map<std::string, Camera>& cameras,
                                     const IdCheckOptions& options) {
  std::string why;
  if (!options.Check(&why)) throw std::runtime_error(why);
  const std::vector<double> path_m = PathLengths(survey);
  std::vector<int> inconsistent;
  for (const SurveyMarker& marker : survey.markers) {
    std::map<int, std::vector<OdomView>> by_segment;
    for (int o : marker.observations) {
      const std::optional<OdomView> view = MakeView(survey, cameras, path_m, o);
      if (view) by_segment[survey.frames[survey.observations[o].frame].segment].push_back(*view);
    }
    std::vector<int> support;
    std::vector<std::vector<int>> kept;
    for (const auto& [segment, views] : by_segment) {
      kept.emplace_back();
      support.push_back(JudgeViews(views, options, &inconsistent, &kept.back()));
    }
    // A small cluster in one segment of a code seen consistently in another (swapped ids seen
    // after a carry, where the odometry cannot compare positions).
    const int best = support.empty() ? 0 : *std::max_element(support.begin(), support.end());
    for (size_t i = 0; i < support.size(); ++i) {
      const bool alone = support[i] == 1 && best >= kMinSupportElsewhere;
      if (alone || kMinorityFactor * support[i] <= best) {
        inconsistent.insert(inconsistent.end(), kept[i].begin(), kept[i].end());
      }
    }
  }
  std::sort(inconsistent.begin(), inconsistent.end());
  return inconsistent;
}

Survey WithoutObservations(const Survey& survey, const std::vector<int>& removed) {
  std::vector<bool> drop(survey.observations.size(), false);
  for (int o : removed) drop.at(o) = true;
  Survey out = survey;
  out.observations.clear();
  for (SurveyFrame& frame : out.frames) frame.observations.clear();
  for (SurveyMarker& marker : out.markers) marker.observations.clear();
  for (size_t o = 0; o < survey.observations.size(); ++o) {
    if (drop[o]) continue;
    const SurveyObservation& obs = survey.observations[o];
    const int index = static_cast<int>(out.observations.size());
    out.observations.push_back(obs);
    out.frames[obs.frame].observations.push_back(index);
    out.markers[obs.marker].observations.push_back(index);
  }
  return out;
}

}  // namespace waymark
