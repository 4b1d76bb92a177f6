#include "online/visibility.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include "util/check.h"

namespace waymark {

bool VisibilityOptions::Check(std::string* why) const {
  const auto probability = [](double p) { return p > 0.0 && p < 1.0; };
  WAYMARK_CHECK_OPTION(min_code_px > 0.0 && max_range_m > 0.0 && border_px >= 0.0,
                       "visibility options: min_code_px and max_range_m must be > 0, border_px >= 0");
  WAYMARK_CHECK_OPTION(max_angle_deg > 0.0 && max_angle_deg < 90.0,
                       "visibility options: max_angle_deg must be in (0, 90)");
  WAYMARK_CHECK_OPTION(min_in_view >= 0.0 && min_in_view < 1.0,
                       "visibility options: min_in_view must be in [0, 1)");
  WAYMARK_CHECK_OPTION(probability(max_detection_probability) && min_detection_probability >= 0.0 &&
                           min_detection_probability < max_detection_probability &&
                           probability(blind_onset_probability) && probability(blind_stay_probability) &&
                           probability(hit_probability_if_wrong),
                       "visibility options: probabilities must be in (0, 1)");
  WAYMARK_CHECK_OPTION(
      forget_trials >= 1.0 && code_prior_trials > 0.0 && decay_time_s > 0.0,
      "visibility options: forget_trials must be >= 1, code_prior_trials and decay_time_s > 0");
  WAYMARK_CHECK_OPTION(suspect_llr > 0.0 && lost_llr >= suspect_llr && learn_below_llr >= 0.0,
                       "visibility options: need 0 < suspect_llr <= lost_llr and learn_below_llr >= 0");
  return true;
}

namespace {

double NormalCdf(double x) { return 0.5 * std::erfc(-x / std::sqrt(2.0)); }

// P(lo <= x + delta <= hi for every corner coordinate x), delta ~ N(0, sigma^2): the quad
// shifted along one image axis stays within [lo, hi].
double InsideProbability(double min_coord, double max_coord, double lo, double hi, double sigma) {
  const double slack_low = min_coord - lo, slack_high = hi - max_coord;
  return std::max(0.0, NormalCdf(slack_high / sigma) - NormalCdf(-slack_low / sigma));
}

// Area of the predicted quad (shoelace), px^2.
double QuadArea(const Vector8d& px) {
  double twice = 0.0;
  for (int j = 0; j < 4; ++j) {
    const int k = (j + 1) % 4;
    twice += px(2 * j) * px(2 * k + 1) - px(2 * k) * px(2 * j + 1);
  }
  return 0.5 * std::abs(twice);
}

// The cheap geometric tests of step 1 on the code's centre (no square root until they pass):
// in front of the camera (optical axis z_world), facing it, near and large enough, at most
// max_angle_deg off its normal. The cosine of the viewing angle.
std::optional<double> Facing(const CodeIndex::Entry& code, const Eigen::Vector3d& camera_world,
                             const Eigen::Vector3d& axis_world, const VisibilityOptions& options,
                             double focal_px, double min_cos_angle) {
  const Eigen::Vector3d to_camera = camera_world - code.centre_world;
  if (to_camera.dot(axis_world) >= 0.0) return std::nullopt;  // centre behind the camera
  const double facing_m = code.normal_world.dot(to_camera);
  if (facing_m <= 0.0) return std::nullopt;
  const double range_sq = to_camera.squaredNorm();
  const double size_px = focal_px * code.size_m;
  if (range_sq > options.max_range_m * options.max_range_m ||
      size_px * size_px < options.min_code_px * options.min_code_px * range_sq ||
      facing_m * facing_m < min_cos_angle * min_cos_angle * range_sq)
    return std::nullopt;
  return facing_m / std::sqrt(range_sq);
}

// 2x2 covariance of the code centre's pixel under the state's covariance and the marker's map
// covariance: H_c = J_p [d p_c / d position, d p_c / d yaw] with p_c = T_camera_robot c_r,
//   d c_r / d t_world_robot = -R_world_robot^T,  d c_r / d yaw = -R_world_robot^T Hat(e_z) (m_w -
//   t_world_robot)
// (online/marker_measurement.h), and the marker's translation error et (right perturbation):
//   d p_c / d et = R_camera_world R_world_marker.
// nullopt when the centre does not project.
std::optional<Eigen::Matrix2d> CentreCovariance(const EkfState& state, const Camera& camera,
                                                const MapMarker& marker, const SE3d& T_camera_world) {
  const Eigen::Vector3d& centre_world = marker.T_world_marker.translation();
  Eigen::Matrix<double, 2, 3> J_p;
  if (!camera.Project(T_camera_world * centre_world, &J_p)) return std::nullopt;
  const SE3d T_world_robot = state.T_world_robot();
  const Eigen::Matrix3d R_camera_world = T_camera_world.rotation_matrix();
  const Eigen::Vector3d from_robot_world = centre_world - T_world_robot.translation();
  const int n = state.yaw_index();  // position dimensions: 2 planar, 3 free
  Eigen::Matrix<double, 2, Eigen::Dynamic, 0, 2, 4> H(2, state.dim());
  H.leftCols(n) = -J_p * R_camera_world.leftCols(n);
  H.col(n) = -J_p * R_camera_world * Eigen::Vector3d::UnitZ().cross(from_robot_world);
  Eigen::Matrix2d covariance = H * state.covariance() * H.transpose();
  if (marker.covariance) {
    const Eigen::Matrix<double, 2, 3> J_marker =
        J_p * R_camera_world * marker.T_world_marker.rotation_matrix();
    covariance += J_marker * marker.covariance->bottomRightCorner<3, 3>() * J_marker.transpose();
  }
  return covariance;
}

// P(in view) of a predicted quad under the centre's pixel covariance (header, step 1).
double InViewProbability(const Vector8d& px, const Eigen::Matrix2d& covariance, const Camera& camera,
                         double border_px) {
  const double sigma_u = std::sqrt(std::max(covariance(0, 0), 1.0));
  const double sigma_v = std::sqrt(std::max(covariance(1, 1), 1.0));
  Eigen::Vector2d min_px = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector2d max_px = -min_px;
  for (int j = 0; j < 4; ++j) {
    min_px = min_px.cwiseMin(px.segment<2>(2 * j));
    max_px = max_px.cwiseMax(px.segment<2>(2 * j));
  }
  return InsideProbability(min_px.x(), max_px.x(), border_px, camera.width() - border_px, sigma_u) *
         InsideProbability(min_px.y(), max_px.y(), border_px, camera.height() - border_px, sigma_v);
}

}  // namespace

CodeIndex::CodeIndex(const MarkerMap& map) {
  for (size_t i = 0; i < map.markers.size(); ++i) {
    const MapMarker& marker = map.markers[i];
    if (!marker.has_pose) continue;
    entries_.push_back({marker.T_world_marker.translation(),
                        marker.T_world_marker.rotation() * Eigen::Vector3d::UnitZ(), marker.size_m, i});
    max_size_m_ = std::max(max_size_m_, marker.size_m);
  }
}

std::vector<size_t> CodeIndex::Near(const Eigen::Vector3d& point_world, double radius_m) const {
  std::vector<size_t> near;
  for (size_t i = 0; i < entries_.size(); ++i) {
    if ((entries_[i].centre_world - point_world).squaredNorm() <= radius_m * radius_m) near.push_back(i);
  }
  return near;
}

const std::vector<size_t>& NearCodes::Around(const CodeIndex& codes, const Camera& camera,
                                             const Eigen::Vector3d& camera_world,
                                             const VisibilityOptions& options) {
  if (!scan_point_world_ || (camera_world - *scan_point_world_).norm() > kRescanM) {
    const double focal_px = std::max(camera.info().intrinsics[0], camera.info().intrinsics[1]);
    const double radius_m =
        std::min(options.max_range_m, codes.max_size_m() * focal_px / options.min_code_px);
    near_ = codes.Near(camera_world, radius_m + kRescanM);
    scan_point_world_ = camera_world;
  }
  return near_;
}

std::vector<ExpectedCode> PredictExpectedCodes(const EkfState& state, const Camera& camera,
                                               const MarkerMap& map, const CodeIndex& codes,
                                               const VisibilityOptions& options, std::optional<int> component,
                                               const std::vector<size_t>* near) {
  std::vector<ExpectedCode> expected;
  const SE3d T_world_camera = state.T_world_robot() * camera.info().T_robot_camera;
  const SE3d T_camera_world = T_world_camera.inverse();
  const double focal_px = std::max(camera.info().intrinsics[0], camera.info().intrinsics[1]);
  const double min_cos_angle = std::cos(options.max_angle_deg * M_PI / 180.0);  // > 0: max_angle_deg < 90
  const Eigen::Vector3d axis_world = T_world_camera.rotation() * Eigen::Vector3d::UnitZ();
  const size_t count = near ? near->size() : codes.entries().size();
  for (size_t k = 0; k < count; ++k) {
    const CodeIndex::Entry& entry = codes.entries()[near ? (*near)[k] : k];
    const std::optional<double> cos_angle =
        Facing(entry, T_world_camera.translation(), axis_world, options, focal_px, min_cos_angle);
    if (!cos_angle) continue;
    const MapMarker& marker = map.markers.at(entry.marker_index);
    if (component && marker.component && *marker.component != *component) continue;
    ExpectedCode code;
    code.marker = &marker;
    bool projects = true;
    const std::array<Eigen::Vector3d, 4> corners_marker = MarkerCorners(marker.size_m);
    for (int j = 0; j < 4 && projects; ++j) {
      const Eigen::Vector3d corner_camera = T_camera_world * (marker.T_world_marker * corners_marker[j]);
      const std::optional<Eigen::Vector2d> px =
          corner_camera.z() > 1e-3 ? camera.Project(corner_camera) : std::nullopt;
      projects = px.has_value();
      if (projects) code.px.segment<2>(2 * j) = *px;
    }
    if (!projects) continue;
    code.size_px = std::sqrt(QuadArea(code.px));
    code.cos_angle = *cos_angle;
    if (code.size_px < options.min_code_px) continue;
    const std::optional<Eigen::Matrix2d> covariance = CentreCovariance(state, camera, marker, T_camera_world);
    if (!covariance) continue;
    code.in_view = InViewProbability(code.px, *covariance, camera, options.border_px);
    if (code.in_view >= options.min_in_view) expected.push_back(code);
  }
  return expected;
}

bool CoversExpected(const ExpectedCode& expected, const std::array<Eigen::Vector2d, 4>& corners_px) {
  const Eigen::Vector2d centre = 0.25 * (corners_px[0] + corners_px[1] + corners_px[2] + corners_px[3]);
  Eigen::Vector2d min_px = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector2d max_px = -min_px;
  for (int j = 0; j < 4; ++j) {
    min_px = min_px.cwiseMin(expected.px.segment<2>(2 * j));
    max_px = max_px.cwiseMax(expected.px.segment<2>(2 * j));
  }
  const Eigen::Vector2d grow = 0.5 * (max_px - min_px);
  return (centre.array() >= (min_px - grow).array()).all() &&
         (centre.array() <= (max_px + grow).array()).all();
}

// ---------------------------------------------------------------- DetectionModel

int DetectionModel::Cell(const ExpectedCode& code) {
  // Size bins: edges 18, 27, 40, 60, 90, 135, 200 px (x1.5 apart); angle bins: 30, 45, 60 deg.
  int size_bin = 0;
  for (double edge = 18.0; size_bin < kSizeBins - 1 && code.size_px >= edge; edge *= 1.5) ++size_bin;
  const double angle_deg = std::acos(std::clamp(code.cos_angle, -1.0, 1.0)) * 180.0 / M_PI;
  const int angle_bin = angle_deg < 30.0 ? 0 : angle_deg < 45.0 ? 1 : angle_deg < 60.0 ? 2 : 3;
  return size_bin * kAngleBins + angle_bin;
}

double DetectionModel::CellProbability(const CameraCounts& counts, const ExpectedCode& code) {
  const Counts& cell = counts.cells[Cell(code)];
  return (cell.hits + 1.0) / (cell.trials + 2.0);  // Beta(1, 1) prior: 0.5 before any trial
}

double DetectionModel::Probability(const std::string& camera, const ExpectedCode& code) const {
  const auto counts = cameras_.find(camera);
  if (counts == cameras_.end()) return std::min(0.5, options_.max_detection_probability);
  double p_code = CellProbability(counts->second, code);
  const auto code_counts = counts->second.codes.find(code.marker);
  if (code_counts != counts->second.codes.end()) {
    const double k = options_.code_prior_trials;
    p_code *= (code_counts->second.hits + k) / (code_counts->second.trials + k);
  }
  return std::min(p_code, options_.max_detection_probability);
}

void DetectionModel::Learn(const std::string& camera, const ExpectedCode& code, bool hit, double weight) {
  if (!(weight > 0.0)) return;
  const double keep = 1.0 - 1.0 / options_.forget_trials;
  CameraCounts& counts = cameras_[camera];
  // The code's own counts are hits against hits expected from its cells (header, step 2).
  Counts& code_counts = counts.codes[code.marker];
  code_counts.hits = keep * code_counts.hits + (hit ? weight : 0.0);
  code_counts.trials = keep * code_counts.trials + weight * CellProbability(counts, code);
  Counts& cell = counts.cells[Cell(code)];
  cell.hits = keep * cell.hits + (hit ? weight : 0.0);
  cell.trials = keep * cell.trials + weight;
}

// ---------------------------------------------------------------- NegativeEvidenceTest

double NegativeEvidenceTest::blind_probability(const std::string& camera) const {
  const auto it = blind_.find(camera);
  return it == blind_.end() ? 0.0 : it->second;
}

void NegativeEvidenceTest::Restart() {
  llr_ = 0.0;
  blind_.clear();
}

double NegativeEvidenceTest::AddFrame(double stamp_s, const std::string& camera,
                                      const std::vector<ExpectedCode>& expected,
                                      const std::vector<ExpectedOutcome>& outcomes, int unexpected_hits,
                                      bool any_detection, bool learn) {
  const double eps = options_.blind_onset_probability, rho = options_.blind_stay_probability;
  const double b = blind_probability(camera);
  const double b_prior = rho * b + eps * (1.0 - b);
  // Log-likelihoods of the seeing camera under H_right and of the frame under H_wrong.
  double log_seeing = 0.0, log_wrong = unexpected_hits * std::log(options_.hit_probability_if_wrong);
  for (size_t i = 0; i < expected.size(); ++i) {
    const double p_code = model_.Probability(camera, expected[i]);
    if (p_code < options_.min_detection_probability) continue;  // no evidence
    const double p = expected[i].in_view * p_code;
    if (outcomes[i] == ExpectedOutcome::kHit) {
      log_seeing += std::log(std::max(p, 1e-9));
      log_wrong += std::log(options_.hit_probability_if_wrong);
    } else if (outcomes[i] == ExpectedOutcome::kMissed) {
      log_seeing += std::log1p(-p);
    }
  }
  // P(O | right) = b- [no detection] + (1 - b-) exp(log_seeing).
  const double seeing = (1.0 - b_prior) * std::exp(log_seeing);
  const double blind = any_detection ? 0.0 : b_prior;
  const double p_right = std::max(blind + seeing, 1e-300);
  blind_[camera] = blind / p_right;
  const double decay =
      has_stamp_ ? std::exp(-std::max(0.0, stamp_s - last_stamp_s_) / options_.decay_time_s) : 1.0;
  has_stamp_ = true;
  last_stamp_s_ = stamp_s;
  llr_ = std::max(0.0, decay * llr_ + log_wrong - std::log(p_right));
  if (learn) {
    const double seeing_weight = 1.0 - blind_[camera];
    for (size_t i = 0; i < expected.size(); ++i) {
      if (outcomes[i] == ExpectedOutcome::kOccupied) continue;
      model_.Learn(camera, expected[i], outcomes[i] == ExpectedOutcome::kHit,
                   expected[i].in_view * seeing_weight);
    }
  }
  return llr_;
}

}  // namespace waymark
