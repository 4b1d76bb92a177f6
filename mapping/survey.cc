#include "mapping/survey.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "factors/odometry_covariance.h"

namespace waymark {
namespace {

std::string Num(double value) {
  std::ostringstream out;
  out.precision(10);
  out << value;
  return out.str();
}

// Index of the last sample with stamp <= t, or -1.
long SampleAtOrBefore(const Trajectory& trajectory, double t) {
  const auto it = std::upper_bound(trajectory.begin(), trajectory.end(), t,
                                   [](double s, const StampedSE3& p) { return s < p.stamp_s; });
  return static_cast<long>(it - trajectory.begin()) - 1;
}

// Segment number of every odometry sample: a new segment starts after each long gap.
std::vector<int> OdometrySegments(const Trajectory& odometry, double max_gap_s, std::vector<std::string>* notes) {
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

// Covariance of the odometry between two stamps: the sum over the samples in between.
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
  for (size_t i = 1; i < poses.size(); ++i) {
    const SE3d T_i_j = poses[i - 1].inverse() * poses[i];
    // The floor is added once per link below, not once per sample.
    const OdometryNoiseFloor tiny{1e-12, 1e-12};
    link->covariance_se3 += OdometryCovarianceSE3(sigma, T_i_j, tiny);
    link->covariance_se2 += OdometryCovarianceSE2(sigma, SE2d::FromSE3(T_i_j), tiny);
    const double model_r2 = std::pow(model_rot_per_m * T_i_j.translation().norm(), 2);
    link->covariance_se3.diagonal().head<3>().array() += model_r2;
    link->covariance_se2(2, 2) += model_r2;
  }
  const OdometryNoiseFloor floor;
  const double m2 = floor.sigma_m * floor.sigma_m, r2 = floor.sigma_rad * floor.sigma_rad;
  link->covariance_se3.diagonal() += (Vector6d() << r2, r2, r2, m2, m2, m2).finished();
  link->covariance_se2.diagonal() += Eigen::Vector3d(m2, m2, r2);
}

void AttachOdometry(const Dataset& dataset, const IngestOptions& options, Survey* survey) {
  const Trajectory& odometry = dataset.odometry;
  if (odometry.empty()) return;
  const std::vector<int> segment = OdometrySegments(odometry, options.max_odometry_gap_s, &survey->notes);
  survey->odometry_segments = segment.back() + 1;
  long outside = 0;
  for (SurveyFrame& frame : survey->frames) {
    frame.T_odom_robot = InterpolatePose(odometry, frame.stamp_s, options.max_odometry_gap_s);
    if (!frame.T_odom_robot) {
      ++outside;
      continue;
    }
    frame.segment = segment[std::max(0L, SampleAtOrBefore(odometry, frame.stamp_s))];
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
    SumOdometryCovariance(odometry, fa.stamp_s, fb.stamp_s, *fa.T_odom_robot, *fb.T_odom_robot, sigma, options.model_rot_per_m, &link);
    survey->odometry_links.push_back(link);
  }
}

}  // namespace

bool IngestOptions::Check(std::string* why) const {
  if (!(stamp_merge_s >= 0.0) || !std::isfinite(stamp_merge_s)) {
    *why = "stamp_merge_s must be finite and >= 0";
    return false;
  }
  if (!(max_odometry_gap_s > 0.0)) {
    *why = "max_odometry_gap_s must be > 0";
    return false;
  }
  if (!(model_rot_per_m >= 0.0) || !std::isfinite(model_rot_per_m)) {
    *why = "model_rot_per_m must be finite and >= 0";
    return false;
  }
  if (!(default_odometry_sigma.trans_per_m >= 0.0) || !(default_odometry_sigma.rot_per_rad >= 0.0)) {
    *why = "default odometry sigma must be >= 0";
    return false;
  }
  return true;
}

int Survey::FindMarker(const MarkerKey& key) const {
  for (size_t i = 0; i < markers.size(); ++i) {
    if (markers[i].key == key) return static_cast<int>(i);
  }
  return -1;
}

std::optional<SE3d> InterpolatePose(const Trajectory& trajectory, double stamp_s, double max_gap_s) {
  const long i = SampleAtOrBefore(trajectory, stamp_s);
  if (i < 0) return std::nullopt;
  if (trajectory[i].stamp_s == stamp_s) return trajectory[i].T;
  if (i + 1 >= static_cast<long>(trajectory.size())) return std::nullopt;
  const StampedSE3& a = trajectory[i];
  const StampedSE3& b = trajectory[i + 1];
  if (b.stamp_s - a.stamp_s > max_gap_s) return std::nullopt;
  const double s = (stamp_s - a.stamp_s) / (b.stamp_s - a.stamp_s);
  const Eigen::Quaterniond q = a.T.rotation().slerp(s, b.T.rotation());
  return SE3d(q, (1.0 - s) * a.T.translation() + s * b.T.translation());
}

Survey IngestDataset(const Dataset& dataset, const IngestOptions& options) {
  std::string why;
  if (!options.Check(&why)) throw std::runtime_error("mapping ingest options: " + why);
  Survey survey;
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
  return survey;
}

}  // namespace waymark
