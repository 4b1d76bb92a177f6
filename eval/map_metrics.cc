#include "eval/map_metrics.h"

#include <Eigen/Cholesky>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <map>
#include <regex>
#include <set>
#include <stdexcept>

namespace waymark::eval {
namespace {

constexpr double kRadToDeg = 180.0 / M_PI;

void CheckUniqueKeys(const MarkerMap& map, const char* which) {
  std::set<MarkerKey> seen;
  for (const MapMarker& marker : map.markers) {
    if (!seen.insert(marker.key).second) {
      throw std::invalid_argument(std::string(which) + " map holds marker " + marker.key.ToString() +
                                  " twice");
    }
  }
}

// Matched markers of one component: estimate and ground-truth poses, in map order.
struct ComponentMatches {
  std::vector<MarkerKey> keys;
  std::vector<SE3d> T_est_marker;
  std::vector<SE3d> T_gt_marker;
  size_t markers_total = 0;
  bool all_points = true;  // every matched estimate is a point landmark (no orientation)
};

std::map<int, ComponentMatches> MatchByComponent(const MarkerMap& est, const MarkerMap& gt) {
  std::map<int, ComponentMatches> components;
  for (const MapMarker& marker : est.markers) {
    ComponentMatches& c = components[marker.component.value_or(0)];
    ++c.markers_total;
    if (const MapMarker* truth = gt.Find(marker.key)) {
      c.keys.push_back(marker.key);
      c.T_est_marker.push_back(marker.T_world_marker);
      c.T_gt_marker.push_back(truth->T_world_marker);
      c.all_points = c.all_points && marker.is_point;
    }
  }
  return components;
}

// True when the points lie close to one line: the second singular value of the centred
// point matrix is below kMinSpreadRatio times the first (both in metres * sqrt(n)). Markers
// along one wall at one height are the common case; their centres leave the rotation about
// the wall's line to noise.
bool NearlyCollinear(const std::vector<Eigen::Vector3d>& points) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& p : points) mean += p / static_cast<double>(points.size());
  Eigen::MatrixXd centred(points.size(), 3);
  for (size_t i = 0; i < points.size(); ++i) centred.row(i) = (points[i] - mean).transpose();
  const Eigen::Vector3d s = Eigen::JacobiSVD<Eigen::MatrixXd>(centred).singularValues();
  return s(1) < kMinSpreadRatio * s(0);
}

ComponentResult AlignComponent(int component, const ComponentMatches& matches) {
  ComponentResult result;
  result.component = component;
  result.markers = matches.keys.size();
  result.markers_total = matches.markers_total;
  if (matches.keys.empty()) return result;
  std::vector<Eigen::Vector3d> p_est, p_gt;
  for (size_t i = 0; i < matches.keys.size(); ++i) {
    p_est.push_back(matches.T_est_marker[i].translation());
    p_gt.push_back(matches.T_gt_marker[i].translation());
  }
  if (matches.all_points && matches.keys.size() >= 2) {
    // Point landmarks of a planar map (issue 15): rotation about z and x, y translation.
    result.alignment = UmeyamaSE2(p_est, p_gt, /*with_scale=*/false);
    result.method = MapAlignmentMethod::kPointsSE2;
    return result;
  }
  if (matches.keys.size() >= 3 && !NearlyCollinear(p_gt)) {
    try {
      result.alignment = UmeyamaSim3(p_est, p_gt, /*with_scale=*/false);
      result.method = MapAlignmentMethod::kPositions;
      return result;
    } catch (const DegenerateAlignmentError&) {
      // The estimated centres collapsed (e.g. all equal): fall back to the poses.
    }
  }
  result.alignment = AlignByPoses(matches.T_est_marker, matches.T_gt_marker);
  result.method = MapAlignmentMethod::kPoses;
  return result;
}

double Rms(const std::vector<double>& values) {
  if (values.empty()) return 0.0;
  double sum = 0.0;
  for (const double v : values) sum += v * v;
  return std::sqrt(sum / static_cast<double>(values.size()));
}

std::vector<MarkerKey> KeysMissingFrom(const MarkerMap& from, const MarkerMap& other) {
  std::vector<MarkerKey> missing;
  for (const MapMarker& marker : from.markers) {
    if (other.Find(marker.key) == nullptr) missing.push_back(marker.key);
  }
  return missing;
}

}  // namespace

const char* MapAlignmentMethodName(MapAlignmentMethod method) {
  switch (method) {
    case MapAlignmentMethod::kPositions:
      return "positions";
    case MapAlignmentMethod::kPoses:
      return "poses";
    case MapAlignmentMethod::kPointsSE2:
      return "points-se2";
    case MapAlignmentMethod::kNone:
      return "none";
  }
  return "unknown";
}

Sim3Alignment AlignByPoses(const std::vector<SE3d>& T_est_marker, const std::vector<SE3d>& T_gt_marker) {
  if (T_est_marker.empty() || T_est_marker.size() != T_gt_marker.size()) {
    throw std::invalid_argument("AlignByPoses: needs equal, non-zero numbers of poses");
  }
  Eigen::Matrix3d M = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < T_est_marker.size(); ++i) {
    M += T_gt_marker[i].rotation_matrix() * T_est_marker[i].rotation_matrix().transpose();
  }
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(M, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Vector3d s_diag = Eigen::Vector3d::Ones();
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0.0) s_diag.z() = -1.0;
  Sim3Alignment alignment;
  alignment.R_gt_est = svd.matrixU() * s_diag.asDiagonal() * svd.matrixV().transpose();
  const double n = static_cast<double>(T_est_marker.size());
  for (size_t i = 0; i < T_est_marker.size(); ++i) {
    alignment.t_gt_est +=
        (T_gt_marker[i].translation() - alignment.R_gt_est * T_est_marker[i].translation()) / n;
  }
  return alignment;
}

MapEvalResult EvaluateMap(const MarkerMap& est, const MarkerMap& gt) {
  CheckUniqueKeys(est, "estimated");
  CheckUniqueKeys(gt, "ground-truth");
  MapEvalResult result;
  std::vector<double> all_position_m, all_orientation_deg;
  for (const auto& [component, matches] : MatchByComponent(est, gt)) {
    ComponentResult c = AlignComponent(component, matches);
    std::vector<double> position_m, orientation_deg;
    for (size_t i = 0; i < matches.keys.size(); ++i) {
      const SE3d T_gt_marker_est = c.alignment.Apply(matches.T_est_marker[i]);
      MarkerError error;
      error.key = matches.keys[i];
      error.component = component;
      error.position_error_m = (matches.T_gt_marker[i].translation() - T_gt_marker_est.translation()).norm();
      error.orientation_error_deg =
          matches.all_points ? 0.0
                             : kRadToDeg * RotationAngleBetween(matches.T_gt_marker[i], T_gt_marker_est);
      position_m.push_back(error.position_error_m);
      orientation_deg.push_back(error.orientation_error_deg);
      result.per_marker.push_back(error);
    }
    c.position_rmse_m = Rms(position_m);
    c.orientation_rmse_deg = Rms(orientation_deg);
    all_position_m.insert(all_position_m.end(), position_m.begin(), position_m.end());
    all_orientation_deg.insert(all_orientation_deg.end(), orientation_deg.begin(), orientation_deg.end());
    result.components.push_back(c);
  }
  result.markers = all_position_m.size();
  if (result.markers == 0)
    throw std::runtime_error("no marker is in both maps (compare the families and ids)");
  result.position_rmse_m = Rms(all_position_m);
  result.orientation_rmse_deg = Rms(all_orientation_deg);
  result.missing_in_estimate = KeysMissingFrom(gt, est);
  result.missing_in_groundtruth = KeysMissingFrom(est, gt);
  return result;
}

GroupResult EvaluateGroup(const MapEvalResult& result, const std::string& id_pattern) {
  std::regex pattern;
  try {
    pattern = std::regex(id_pattern, std::regex::ECMAScript);
  } catch (const std::regex_error& e) {
    throw std::invalid_argument("group pattern '" + id_pattern + "': " + e.what());
  }
  GroupResult group;
  group.pattern = id_pattern;
  std::vector<double> in_m, in_deg, out_m, out_deg;
  for (const MarkerError& e : result.per_marker) {
    const bool match = std::regex_search(e.key.id, pattern);
    (match ? in_m : out_m).push_back(e.position_error_m);
    (match ? in_deg : out_deg).push_back(e.orientation_error_deg);
  }
  group.markers = in_m.size();
  group.markers_other = out_m.size();
  group.position_rmse_m = Rms(in_m);
  group.orientation_rmse_deg = Rms(in_deg);
  group.other_position_rmse_m = Rms(out_m);
  group.other_orientation_rmse_deg = Rms(out_deg);
  return group;
}

std::vector<PredictedComponentError> PredictMapError(const MarkerMap& map) {
  std::map<int, std::vector<const MapMarker*>> components;
  for (const MapMarker& marker : map.markers) components[marker.component.value_or(0)].push_back(&marker);
  std::vector<PredictedComponentError> predictions;
  for (const auto& [component, markers] : components) {
    bool complete = true, joint = true;
    Eigen::Index rank = -1;
    std::vector<Eigen::Vector3d> centres;
    for (const MapMarker* m : markers) {
      centres.push_back(m->T_world_marker.translation());
      if (m->fixed) continue;
      complete = complete && m->covariance.has_value();
      const bool has_factor = m->covariance_factor.has_value() && m->covariance_factor->cols() > 0 &&
                              (rank < 0 || m->covariance_factor->cols() == rank);
      if (has_factor) rank = m->covariance_factor->cols();
      joint = joint && has_factor;
    }
    if (!complete || markers.size() < 3 || NearlyCollinear(centres)) continue;
    if (rank < 0) joint = false;
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const Eigen::Vector3d& p : centres) mean += p / static_cast<double>(centres.size());
    Matrix6d AtA = Matrix6d::Zero(), AtSA = Matrix6d::Zero();
    Eigen::MatrixXd AtG = Eigen::MatrixXd::Zero(6, joint ? rank : 0);
    double trace = 0.0;
    for (size_t i = 0; i < markers.size(); ++i) {
      Eigen::Matrix<double, 3, 6> A;
      A << Eigen::Matrix3d::Identity(), -Hat(Eigen::Vector3d(centres[i] - mean));
      AtA += A.transpose() * A;
      const MapMarker& m = *markers[i];
      if (m.fixed) continue;
      // Body-frame right perturbation [r t]: the world position moves by R t.
      const Eigen::Matrix3d R = m.T_world_marker.rotation().toRotationMatrix();
      const Eigen::Matrix3d P = R * m.covariance->bottomRightCorner<3, 3>() * R.transpose();
      trace += P.trace();
      Eigen::Matrix3d D = P;
      if (joint) {
        const Eigen::MatrixXd G = R * m.covariance_factor->bottomRows<3>();
        D -= G * G.transpose();
        AtG += A.transpose() * G;
      }
      AtSA += A.transpose() * D * A;
    }
    if (joint) AtSA += AtG * AtG.transpose();
    const double n = static_cast<double>(markers.size());
    const double removed = AtA.ldlt().solve(AtSA).trace();
    PredictedComponentError prediction;
    prediction.component = component;
    prediction.markers = markers.size();
    prediction.joint = joint;
    prediction.rms_m = std::sqrt(trace / n);
    prediction.aligned_rms_m = std::sqrt(std::max(0.0, trace - removed) / n);
    predictions.push_back(prediction);
  }
  return predictions;
}

std::optional<double> PooledAlignedRms(const std::vector<PredictedComponentError>& components) {
  double sum_sq = 0.0;
  size_t markers = 0;
  for (const PredictedComponentError& c : components) {
    sum_sq += static_cast<double>(c.markers) * c.aligned_rms_m * c.aligned_rms_m;
    markers += c.markers;
  }
  if (markers == 0) return std::nullopt;
  return std::sqrt(sum_sq / static_cast<double>(markers));
}

}  // namespace waymark::eval
