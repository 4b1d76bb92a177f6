#include "mapping/survey.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "factors/odometry_covariance.h"
#include "geometry/camera.h"
#include "geometry/marker_pose.h"
#include "mapping/boards.h"
#include "mapping/square_association.h"
#include "util/check.h"
#include "util/format.h"

namespace waymark {
namespace {

std::string Num(double value) { return FormatSignificant(value, 10); }

// Segment number of every odometry sample: a new segment starts after each long gap.
std::vector<int> OdometrySegments(const Trajectory& odometry, double max_gap_s,
                                  std::vector<std::string>* notes) {
  std::vector<int> segment(odometry.size(), 0);
  for (size_t i = 1; i < odometry.size(); ++i) {
    const double gap_s = odometry[i].stamp_s - odometry[i - 1].stamp_s;
    segment[i] = segment[i - 1];
    if (gap_s > max_gap_s) {
      ++segment[i];
      notes->push_back("odometry: gap of " + Num(gap_s) + " s between t = " + Num(odometry[i - 1].stamp_s) +
                       " and t = " + Num(odometry[i].stamp_s) +
                       " s: the odometry is split there (no odometry link across the gap)");
    }
  }
  return segment;
}

// Distinct stamps of the detections, each frame listing its detection lines.
std::vector<SurveyFrame> MakeFrames(const Dataset& dataset, double merge_s, std::vector<int>* frame_of_line) {
  std::vector<size_t> order(dataset.detections.size());
  for (size_t i = 0; i < order.size(); ++i) {
    if (!std::isfinite(dataset.detections[i].stamp_s)) {
      throw std::runtime_error(dataset.config.detections_file + ": detection frame " + std::to_string(i + 1) +
                               ": stamp is not a finite number");
    }
    order[i] = i;
  }
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    return dataset.detections[a].stamp_s < dataset.detections[b].stamp_s;
  });
  std::vector<SurveyFrame> frames;
  frame_of_line->assign(order.size(), -1);
  for (size_t i : order) {
    const double t = dataset.detections[i].stamp_s;
    if (frames.empty() || t - frames.back().stamp_s > merge_s) {
      SurveyFrame frame;
      frame.stamp_s = t;
      frames.push_back(frame);
    }
    (*frame_of_line)[i] = static_cast<int>(frames.size()) - 1;
  }
  return frames;
}

void CheckCamera(const Dataset& dataset, size_t line, const std::string& camera) {
  if (dataset.cameras.count(camera) > 0) return;
  std::string known;
  for (const auto& [name, info] : dataset.cameras) known += (known.empty() ? "" : ", ") + name;
  throw std::runtime_error(dataset.config.detections_file + ": detection frame " + std::to_string(line + 1) +
                           " (t = " + Num(dataset.detections[line].stamp_s) + " s): camera '" + camera +
                           "' is not a camera of the dataset (known: " + known + ")");
}

int AddMarker(const Dataset& dataset, const MarkerKey& key, const std::optional<PayloadParser>& parser,
              Survey* survey, std::map<MarkerKey, int>* index) {
  if (const auto it = index->find(key); it != index->end()) return it->second;
  SurveyMarker marker;
  marker.key = key;
  const std::optional<double> size_m = dataset.MarkerSize(key);
  if (!size_m || !(*size_m > 0.0)) {
    throw std::runtime_error(dataset.config.detections_file + ": marker " + key.ToString() +
                             " has no size: it is not in " + dataset.config.markers_file +
                             " and dataset.yaml has no default_marker_size_m");
  }
  marker.size_m = *size_m;
  if (dataset.known_markers) {
    // Size-only entries gave the size above; only a known pose makes a known marker.
    const MapMarker* known = dataset.known_markers->Find(key);
    if (known != nullptr && known->has_pose) marker.known = *known;
    if (known != nullptr) marker.square_tape = known->square_tape;
  }
  if (parser && (key.family == kFamilyQr || key.family == kFamilyDataMatrix)) {
    std::optional<PayloadData> data = parser->Parse(key.id);
    if (data && data->HasPosition()) marker.payload = std::move(data);
  }
  survey->markers.push_back(std::move(marker));
  const int id = static_cast<int>(survey->markers.size()) - 1;
  (*index)[key] = id;
  return id;
}

// Covariance of the odometry between two (odometry-clock) stamps: the sum over the samples in
// between.
void SumOdometryCovariance(const Trajectory& odometry, double t_a, double t_b, const SE3d& T_a,
                           const SE3d& T_b, const OdometrySigma& sigma, double model_rot_per_m,
                           OdometryLink* link) {
  std::vector<SE3d> poses{T_a};
  for (long k = SampleAtOrBefore(odometry, t_a) + 1;
       k < static_cast<long>(odometry.size()) && odometry[k].stamp_s < t_b; ++k) {
    if (odometry[k].stamp_s > t_a) poses.push_back(odometry[k].T);
  }
  poses.push_back(T_b);
  link->covariance_se3.setZero();
  link->covariance_se2.setZero();
  double path_m = 0.0;
  for (size_t i = 1; i < poses.size(); ++i) {
    const SE3d T_i_j = poses[i - 1].inverse() * poses[i];
    path_m += T_i_j.translation().norm();
    // The floor is added once per link below, not once per sample.
    const OdometryNoiseFloor tiny{1e-12, 1e-12};
    link->covariance_se3 += OdometryCovarianceSE3(sigma, T_i_j, tiny);
    link->covariance_se2 += OdometryCovarianceSE2(sigma, SE2d::FromSE3(T_i_j), tiny);
    const double model_r2 = std::pow(model_rot_per_m * T_i_j.translation().norm(), 2);
    link->covariance_se3.diagonal().head<3>().array() += model_r2;
    link->covariance_se2(2, 2) += model_r2;
  }
  // The random-walk terms over the link's duration and path (geometry/odometry_noise.h).
  const OdometryWalkVariance walk = OdometryRandomWalk(sigma, std::max(0.0, t_b - t_a), path_m);
  link->covariance_se3.diagonal() +=
      (Vector6d() << Eigen::Vector3d::Constant(walk.rotation), Eigen::Vector3d::Constant(walk.translation))
          .finished();
  link->covariance_se2.diagonal() += Eigen::Vector3d(walk.translation, walk.translation, walk.rotation);
  const OdometryNoiseFloor floor;
  const double m2 = floor.sigma_m * floor.sigma_m, r2 = floor.sigma_rad * floor.sigma_rad;
  link->covariance_se3.diagonal() += (Vector6d() << r2, r2, r2, m2, m2, m2).finished();
  link->covariance_se2.diagonal() += Eigen::Vector3d(m2, m2, r2);
}

// The odometry read on the image clock: T_odom_robot(t) is the odometry at t + offset_s.
struct OdometryClock {
  const Trajectory& odometry;
  const std::vector<int>& sample_segment;  // per odometry sample
  double offset_s = 0.0;
  double max_gap_s = 1.0;

  std::optional<SE3d> PoseAt(double t) const {
    return InterpolateTrajectory(odometry, t + offset_s, max_gap_s);
  }
  int SegmentAt(double t) const {
    return sample_segment[std::max(0L, SampleAtOrBefore(odometry, t + offset_s))];
  }
};

// The stamp term of the header comment: sigma_stamp^2 (j_a j_a^T + j_b j_b^T), added to the link.
void AddStampUncertainty(const OdometryClock& clock, double t_a, double t_b, double sigma_s,
                         OdometryLink* link) {
  if (!(sigma_s > 0.0)) return;
  constexpr double kStepS = 0.01;
  const SE3d M = link->T_a_b;
  const SE2d M_se2 = SE2d::FromSE3(M);
  for (const bool at_a : {true, false}) {
    const double t = at_a ? t_a : t_b;
    const std::optional<SE3d> plus = clock.PoseAt(t + kStepS), minus = clock.PoseAt(t - kStepS);
    if (!plus || !minus) continue;  // at the odometry's ends: the plain model
    const SE3d T_other = at_a ? *clock.PoseAt(t_b) : *clock.PoseAt(t_a);
    const SE3d M_plus = at_a ? plus->inverse() * T_other : T_other.inverse() * *plus;
    const SE3d M_minus = at_a ? minus->inverse() * T_other : T_other.inverse() * *minus;
    const Vector6d j = (M.BoxMinus(M_plus) - M.BoxMinus(M_minus)) / (2.0 * kStepS);
    const Eigen::Vector3d j_se2 =
        (M_se2.BoxMinus(SE2d::FromSE3(M_plus)) - M_se2.BoxMinus(SE2d::FromSE3(M_minus))) / (2.0 * kStepS);
    link->covariance_se3 += sigma_s * sigma_s * j * j.transpose();
    link->covariance_se2 += sigma_s * sigma_s * j_se2 * j_se2.transpose();
  }
}

// Velocity (world-frame translation per second, body rotation vector per second) of the odometry
// interval [k, k+1].
std::pair<Eigen::Vector3d, Eigen::Vector3d> IntervalVelocity(const Trajectory& odometry, long k) {
  const double dt = odometry[k + 1].stamp_s - odometry[k].stamp_s;
  return {(odometry[k + 1].T.translation() - odometry[k].T.translation()) / dt,
          LogSO3(odometry[k].T.rotation().conjugate() * odometry[k + 1].T.rotation()) / dt};
}

// The interpolation term of the header comment at odometry-clock time t: variances (rotation,
// translation) of 0.5 a s (1 - s) Delta^2 per axis, with a the change of velocity from the
// interval around t to its neighbours.
std::pair<double, double> InterpolationVariance(const Trajectory& odometry, double t) {
  const long k = SampleAtOrBefore(odometry, t);
  if (k < 0 || k + 1 >= static_cast<long>(odometry.size()) || odometry[k].stamp_s == t) return {0.0, 0.0};
  const double delta_s = odometry[k + 1].stamp_s - odometry[k].stamp_s;
  const double s = (t - odometry[k].stamp_s) / delta_s;
  const auto [v, w] = IntervalVelocity(odometry, k);
  double a = 0.0, alpha = 0.0;
  for (const long j : {k - 1, k + 1}) {
    if (j < 0 || j + 1 >= static_cast<long>(odometry.size())) continue;
    const auto [v_j, w_j] = IntervalVelocity(odometry, j);
    const double mean_dt = 0.5 * (delta_s + odometry[j + 1].stamp_s - odometry[j].stamp_s);
    a = std::max(a, (v_j - v).norm() / mean_dt);
    alpha = std::max(alpha, (w_j - w).norm() / mean_dt);
  }
  const double lever = 0.5 * s * (1.0 - s) * delta_s * delta_s;
  return {std::pow(alpha * lever, 2), std::pow(a * lever, 2)};
}

// ---- Time offset estimate (header comment) ----

constexpr double kViewSigmaM = 0.02;         // single-view position precision: constant part
constexpr double kViewSigmaPerRange = 0.05;  // ... and the part proportional to the range
constexpr double kViewSigmaRad = 0.05;       // single-view rotation precision
constexpr size_t kMaxPairsPerView = 10;      // a view is paired with its next views of the code
constexpr size_t kMinOffsetPairs = 10;

// Where a single view puts the robot in the code's frame.
struct ViewGeometry {
  int frame = 0;
  Eigen::Vector3d p_marker_robot;
  Eigen::Quaterniond q_marker_robot;
  bool ambiguous = true;
  double range_m = 0.0;
};

// One entry per code: its usable views in time order.
std::vector<std::vector<ViewGeometry>> ComputeViewGeometry(const Survey& survey) {
  std::map<std::string, Camera> cameras;
  for (const auto& [name, info] : survey.cameras) cameras.emplace(name, Camera(info));
  std::vector<std::vector<ViewGeometry>> per_marker(survey.markers.size());
  for (const SurveyObservation& obs : survey.observations) {
    MarkerPoseEstimate estimate;
    try {
      estimate =
          EstimateMarkerPose(obs.corners_px, survey.markers[obs.marker].size_m, cameras.at(obs.camera));
    } catch (const std::exception&) {
      continue;  // a degenerate or unprojectable view says nothing about the offset
    }
    const SE3d T_marker_robot =
        (survey.cameras.at(obs.camera).T_robot_camera * estimate.best().T_camera_marker).inverse();
    per_marker[obs.marker].push_back({obs.frame, T_marker_robot.translation(), T_marker_robot.rotation(),
                                      estimate.ambiguous, T_marker_robot.translation().norm()});
  }
  for (auto& views : per_marker) {
    std::stable_sort(views.begin(), views.end(),
                     [](const ViewGeometry& a, const ViewGeometry& b) { return a.frame < b.frame; });
  }
  return per_marker;
}

// One pair of views of a code, with what does not depend on the offset: the distance and the
// rotation angle between the two robot poses the views put in the code's frame.
struct ViewPair {
  int frame_a = 0, frame_b = 0;
  double views_distance_m = 0.0;
  double views_angle_rad = -1.0;  // < 0: a view is ambiguous, rotation not compared
  double sigma_m = 0.0;
};

// The pairs of ComputeViewGeometry's views: each view with its next kMaxPairsPerView views
// of the code from other frames at most window_s later.
std::vector<ViewPair> MakeViewPairs(const Survey& survey,
                                    const std::vector<std::vector<ViewGeometry>>& per_marker,
                                    double window_s) {
  std::vector<ViewPair> pairs;
  for (const std::vector<ViewGeometry>& views : per_marker) {
    for (size_t i = 0; i < views.size(); ++i) {
      const ViewGeometry& a = views[i];
      for (size_t j = i + 1; j < views.size() && j <= i + kMaxPairsPerView; ++j) {
        const ViewGeometry& b = views[j];
        if (survey.frames[b.frame].stamp_s - survey.frames[a.frame].stamp_s > window_s || b.frame == a.frame)
          continue;
        ViewPair pair;
        pair.frame_a = a.frame;
        pair.frame_b = b.frame;
        pair.views_distance_m = (b.p_marker_robot - a.p_marker_robot).norm();
        if (!a.ambiguous && !b.ambiguous)
          pair.views_angle_rad = LogSO3(a.q_marker_robot.conjugate() * b.q_marker_robot).norm();
        pair.sigma_m = kViewSigmaM + kViewSigmaPerRange * 0.5 * (a.range_m + b.range_m);
        pairs.push_back(pair);
      }
    }
  }
  return pairs;
}

// Robust cost of one view pair against the odometry increment M_a_b.
double PairCost(const ViewPair& pair, const SE3d& M_a_b) {
  const double e_t = (pair.views_distance_m - M_a_b.translation().norm()) / pair.sigma_m;
  double cost = std::log1p(e_t * e_t);
  if (pair.views_angle_rad >= 0.0) {
    const double e_r = (pair.views_angle_rad - LogSO3(M_a_b.rotation()).norm()) / kViewSigmaRad;
    cost += std::log1p(e_r * e_r);
  }
  return cost;
}

// Mean pair cost C(delta) over the pairs with odometry at both ends in one segment.
double MeanOffsetCost(const Survey& survey, const OdometryClock& clock,
                      const std::vector<ViewPair>& view_pairs, size_t* pairs) {
  struct FrameOdometry {
    bool done = false;
    std::optional<SE3d> T_odom_robot;
    int segment = -1;
  };
  std::vector<FrameOdometry> cache(survey.frames.size());
  const auto at = [&](int frame) -> const FrameOdometry& {
    FrameOdometry& f = cache[frame];
    if (!f.done) {
      f.T_odom_robot = clock.PoseAt(survey.frames[frame].stamp_s);
      if (f.T_odom_robot) f.segment = clock.SegmentAt(survey.frames[frame].stamp_s);
      f.done = true;
    }
    return f;
  };
  double sum = 0.0;
  *pairs = 0;
  for (const ViewPair& pair : view_pairs) {
    const FrameOdometry& a = at(pair.frame_a);
    const FrameOdometry& b = at(pair.frame_b);
    if (!a.T_odom_robot || !b.T_odom_robot || a.segment != b.segment) continue;
    sum += PairCost(pair, a.T_odom_robot->inverse() * *b.T_odom_robot);
    ++*pairs;
  }
  return *pairs > 0 ? sum / static_cast<double>(*pairs) : 0.0;
}

std::string OffsetNote(const TimeOffsetEstimate& e) {
  return "odometry: time offset estimated at " + Num(std::round(e.offset_s * 1e3) / 1e3) +
         " s (odometry clock minus image clock; mean pair cost " +
         Num(std::round(e.cost_at_zero * 1e3) / 1e3) + " at 0 s, " + Num(std::round(e.cost * 1e3) / 1e3) +
         " there, " + std::to_string(e.pairs) +
         " view pairs): " + (e.applied ? "applied" : "not applied (gain below the threshold)");
}

// The offset delta to use: given, estimated (and noted), or 0.
double ChooseTimeOffset(const Survey& survey, const Trajectory& odometry, const IngestOptions& options,
                        std::vector<std::string>* notes) {
  if (options.odometry_time_offset_s) {
    if (*options.odometry_time_offset_s != 0.0) {
      notes->push_back("odometry: time offset " + Num(*options.odometry_time_offset_s) + " s (given)");
    }
    return *options.odometry_time_offset_s;
  }
  if (!options.estimate_time_offset) return 0.0;
  const std::optional<TimeOffsetEstimate> estimate = EstimateOdometryTimeOffset(survey, odometry, options);
  if (!estimate) return 0.0;
  if (estimate->applied || std::abs(estimate->offset_s) >= 0.05) notes->push_back(OffsetNote(*estimate));
  return estimate->applied ? estimate->offset_s : 0.0;
}

void AttachOdometry(const Dataset& dataset, const IngestOptions& options, Survey* survey) {
  const Trajectory& odometry = dataset.odometry;
  if (odometry.empty()) return;
  const std::vector<int> segment = OdometrySegments(odometry, options.max_odometry_gap_s, &survey->notes);
  survey->odometry_segments = segment.back() + 1;
  survey->odometry_time_offset_s = ChooseTimeOffset(*survey, odometry, options, &survey->notes);
  survey->odometry_stamp_sigma_s =
      survey->odometry_time_offset_s != 0.0 ? options.unsynced_stamp_sigma_s : options.stamp_sigma_s;
  const OdometryClock clock{odometry, segment, survey->odometry_time_offset_s, options.max_odometry_gap_s};
  long outside = 0;
  for (SurveyFrame& frame : survey->frames) {
    frame.T_odom_robot = clock.PoseAt(frame.stamp_s);
    if (!frame.T_odom_robot) {
      ++outside;
      continue;
    }
    frame.segment = clock.SegmentAt(frame.stamp_s);
  }
  if (outside > 0) {
    survey->notes.push_back(std::to_string(outside) + " frame(s) outside the odometry's span or in a gap: " +
                            "placed from the codes alone");
  }
  const OdometrySigma sigma = dataset.config.odometry_sigma.value_or(options.default_odometry_sigma);
  for (size_t b = 1; b < survey->frames.size(); ++b) {
    const SurveyFrame& fa = survey->frames[b - 1];
    const SurveyFrame& fb = survey->frames[b];
    if (fa.segment < 0 || fa.segment != fb.segment) continue;
    OdometryLink link;
    link.frame_a = static_cast<int>(b) - 1;
    link.frame_b = static_cast<int>(b);
    link.T_a_b = fa.T_odom_robot->inverse() * *fb.T_odom_robot;
    SumOdometryCovariance(odometry, fa.stamp_s + clock.offset_s, fb.stamp_s + clock.offset_s,
                          *fa.T_odom_robot, *fb.T_odom_robot, sigma, options.model_rot_per_m, &link);
    AddStampUncertainty(clock, fa.stamp_s, fb.stamp_s, survey->odometry_stamp_sigma_s, &link);
    if (options.interpolation_noise) {
      for (const double t : {fa.stamp_s, fb.stamp_s}) {
        const auto [var_rad2, var_m2] = InterpolationVariance(odometry, t + clock.offset_s);
        link.covariance_se3.diagonal() +=
            (Vector6d() << Eigen::Vector3d::Constant(var_rad2), Eigen::Vector3d::Constant(var_m2)).finished();
        link.covariance_se2.diagonal() += Eigen::Vector3d(var_m2, var_m2, var_rad2);
      }
    }
    survey->odometry_links.push_back(link);
  }
}

}  // namespace

bool IngestOptions::Check(std::string* why) const {
  WAYMARK_CHECK_OPTION(IsFiniteAtLeast(stamp_merge_s, 0.0), "stamp_merge_s must be finite and >= 0");
  WAYMARK_CHECK_OPTION(max_odometry_gap_s > 0.0, "max_odometry_gap_s must be > 0");
  WAYMARK_CHECK_OPTION(IsFiniteAtLeast(model_rot_per_m, 0.0), "model_rot_per_m must be finite and >= 0");
  WAYMARK_CHECK_OPTION(default_odometry_sigma.trans_per_m >= 0.0 && default_odometry_sigma.rot_per_rad >= 0.0,
                       "default odometry sigma must be >= 0");
  WAYMARK_CHECK_OPTION(IsFiniteAtLeast(stamp_sigma_s, 0.0) && IsFiniteAtLeast(unsynced_stamp_sigma_s, 0.0),
                       "stamp_sigma_s and unsynced_stamp_sigma_s must be finite and >= 0");
  WAYMARK_CHECK_OPTION(!odometry_time_offset_s || std::isfinite(*odometry_time_offset_s),
                       "odometry_time_offset_s must be finite");
  WAYMARK_CHECK_OPTION(IsFiniteAtLeast(max_time_offset_s, 0.0), "max_time_offset_s must be finite and >= 0");
  WAYMARK_CHECK_OPTION(IsFinitePositive(offset_window_s), "offset_window_s must be finite and > 0");
  WAYMARK_CHECK_OPTION(time_offset_min_gain >= 0.0 && time_offset_min_gain < 1.0,
                       "time_offset_min_gain must be in [0, 1)");
  return true;
}

int Survey::FindMarker(const MarkerKey& key) const {
  for (size_t i = 0; i < markers.size(); ++i) {
    if (markers[i].key == key) return static_cast<int>(i);
  }
  return -1;
}

std::optional<TimeOffsetEstimate> EstimateOdometryTimeOffset(const Survey& survey, const Trajectory& odometry,
                                                             const IngestOptions& options) {
  if (odometry.empty()) return std::nullopt;
  std::vector<std::string> ignored;
  const std::vector<int> segment = OdometrySegments(odometry, options.max_odometry_gap_s, &ignored);
  const std::vector<ViewPair> view_pairs =
      MakeViewPairs(survey, ComputeViewGeometry(survey), options.offset_window_s);
  size_t pairs = 0;
  const auto cost_at = [&](double offset_s) {
    const OdometryClock clock{odometry, segment, offset_s, options.max_odometry_gap_s};
    return MeanOffsetCost(survey, clock, view_pairs, &pairs);
  };
  TimeOffsetEstimate estimate;
  estimate.cost_at_zero = cost_at(0.0);
  estimate.pairs = pairs;
  if (pairs < kMinOffsetPairs) return std::nullopt;
  estimate.cost = estimate.cost_at_zero;
  // A coarse grid over the range, then a fine one around its best point.
  for (const auto& [half_range, step] :
       {std::pair{options.max_time_offset_s, 0.05}, std::pair{0.05, 0.005}}) {
    const double centre = estimate.offset_s;
    const int n = static_cast<int>(std::round(half_range / step));
    for (int i = -n; i <= n; ++i) {
      const double offset_s = centre + i * step;
      if (std::abs(offset_s) > options.max_time_offset_s + 1e-9) continue;
      const double cost = cost_at(offset_s);
      if (pairs >= kMinOffsetPairs && cost < estimate.cost) {
        estimate.cost = cost;
        estimate.offset_s = offset_s;
      }
    }
  }
  estimate.applied = estimate.cost <= (1.0 - options.time_offset_min_gain) * estimate.cost_at_zero;
  return estimate;
}

Survey IngestDataset(const Dataset& input, const IngestOptions& options) {
  std::string why;
  if (!options.Check(&why)) throw std::runtime_error("mapping ingest options: " + why);
  Survey survey;
  // Square ceiling markers carry no id: told apart by the odometry first (square_association.h).
  std::optional<Dataset> associated;
  if (HasSquareDetections(input)) {
    SquareAssociationStats stats;
    associated = AssociateSquares(input, &stats);
    survey.notes.push_back(
        "squares: " + std::to_string(stats.sightings) + " sightings of " + std::to_string(stats.known_used) +
        " known and " + std::to_string(stats.new_squares) + " new square(s)" +
        (stats.unplaced > 0 ? ", " + std::to_string(stats.unplaced) + " left out (no pose)" : ""));
  }
  const Dataset& dataset = associated ? *associated : input;
  survey.motion = dataset.config.motion;
  survey.cameras = dataset.cameras;
  std::vector<int> frame_of_line;
  survey.frames = MakeFrames(dataset, options.stamp_merge_s, &frame_of_line);
  std::optional<PayloadParser> parser;
  if (dataset.config.payload) parser.emplace(*dataset.config.payload);
  std::map<MarkerKey, int> index;
  for (size_t line = 0; line < dataset.detections.size(); ++line) {
    const DetectionFrame& detection = dataset.detections[line];
    CheckCamera(dataset, line, detection.camera);
    for (const MarkerObservation& seen : detection.markers) {
      SurveyObservation observation;
      observation.frame = frame_of_line[line];
      observation.marker = AddMarker(dataset, seen.key, parser, &survey, &index);
      observation.camera = detection.camera;
      observation.corners_px = seen.corners_px;
      observation.detection_line = line;
      const int id = static_cast<int>(survey.observations.size());
      survey.frames[observation.frame].observations.push_back(id);
      survey.markers[observation.marker].observations.push_back(id);
      survey.observations.push_back(std::move(observation));
    }
  }
  AttachOdometry(dataset, options, &survey);
  if (dataset.known_markers) AttachBoards(*dataset.known_markers, &survey);
  return survey;
}

}  // namespace waymark
