#include "io/map_io.h"

#include <Eigen/Eigenvalues>
#include <cmath>
#include <nlohmann/json.hpp>
#include <set>
#include <stdexcept>

#include "geometry/board.h"
#include "geometry/square_marker.h"
#include "io/json_util.h"
#include "io/util.h"

namespace waymark {
namespace {

constexpr const char* kMapFormat = "waymark-map";
constexpr long kMapVersion = 1;

Matrix6d ParseCovariance(const JsonSource& source, const nlohmann::json& value, const std::string& field) {
  const std::vector<double> numbers = JsonNumbers(source, value, field, 36);
  Matrix6d covariance;
  for (int r = 0; r < 6; ++r) {
    for (int c = 0; c < 6; ++c) covariance(r, c) = numbers[6 * r + c];
  }
  const double scale = std::max(1.0, covariance.cwiseAbs().maxCoeff());
  if ((covariance - covariance.transpose()).cwiseAbs().maxCoeff() > 1e-9 * scale) {
    ThrowJsonError(source, field, "expected a symmetric 6x6 matrix (row-major)");
  }
  if ((covariance.diagonal().array() < 0.0).any()) {
    ThrowJsonError(source, field, "expected a non-negative diagonal (variances)");
  }
  return covariance;
}

// covariance_factor: 6 k numbers, row-major 6 x k, with covariance - F F^T PSD (within 1e-6 of
// the largest variance).
CovarianceFactor ParseCovarianceFactor(const JsonSource& source, const nlohmann::json& value,
                                       const std::string& field, const std::optional<Matrix6d>& covariance) {
  if (!value.is_array() || value.empty() || value.size() % 6 != 0) {
    ThrowJsonError(source, field, "expected a non-empty array of 6 k numbers (row-major 6 x k)");
  }
  const std::vector<double> numbers = JsonNumbers(source, value, field, value.size());
  const int k = static_cast<int>(numbers.size() / 6);
  CovarianceFactor factor(6, k);
  for (int r = 0; r < 6; ++r) {
    for (int c = 0; c < k; ++c) factor(r, c) = numbers[k * r + c];
  }
  if (!covariance) ThrowJsonError(source, field, "expected a covariance with the covariance_factor");
  const Matrix6d residual = *covariance - factor * factor.transpose();
  const double min_eigenvalue = Eigen::SelfAdjointEigenSolver<Matrix6d>(residual).eigenvalues().minCoeff();
  if (min_eigenvalue < -1e-6 * covariance->diagonal().maxCoeff()) {
    ThrowJsonError(source, field,
                   "expected covariance - F F^T positive semi-definite (F F^T exceeds the covariance)");
  }
  return factor;
}

// position_covariance_factor (point landmarks): 3 k numbers, row-major 3 x k, with
// position_covariance - F F^T PSD (within 1e-6 of the largest variance). Held in memory as the
// translation rows (3..5, tangent order [r, t]) of MapMarker::covariance_factor, the rotation
// rows 0.
CovarianceFactor ParsePositionCovarianceFactor(const JsonSource& source, const nlohmann::json& value,
                                               const std::string& field,
                                               const std::optional<Eigen::Matrix3d>& covariance) {
  if (!value.is_array() || value.empty() || value.size() % 3 != 0) {
    ThrowJsonError(source, field, "expected a non-empty array of 3 k numbers (row-major 3 x k)");
  }
  const std::vector<double> numbers = JsonNumbers(source, value, field, value.size());
  const int k = static_cast<int>(numbers.size() / 3);
  CovarianceFactor factor = CovarianceFactor::Zero(6, k);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < k; ++c) factor(3 + r, c) = numbers[k * r + c];
  }
  if (!covariance) ThrowJsonError(source, field, "expected a position_covariance with the factor");
  const Eigen::Matrix3d residual = *covariance - factor.bottomRows<3>() * factor.bottomRows<3>().transpose();
  const double min_eigenvalue =
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(residual).eigenvalues().minCoeff();
  if (min_eigenvalue < -1e-6 * covariance->diagonal().maxCoeff()) {
    ThrowJsonError(
        source, field,
        "expected position_covariance - F F^T positive semi-definite (F F^T exceeds the covariance)");
  }
  return factor;
}

// {"tape_width_m": 0.05, "solid_side": "top", "dash_m": 0.1, "gap_m": 0.1}, every key optional.
SquareTape ParseSquareTape(const JsonSource& source, const nlohmann::json& value, const std::string& field,
                           double side_m, ReadWarnings* warnings) {
  if (!value.is_object()) ThrowJsonError(source, field, "expected an object");
  SquareTape tape;
  const auto number = [&](const char* key, double* out) {
    if (const nlohmann::json* v = JsonMember(source, value, field, key, false)) {
      *out = JsonNumber(source, *v, JsonField(field, key));
    }
  };
  number("tape_width_m", &tape.tape_width_m);
  number("dash_m", &tape.dash_m);
  number("gap_m", &tape.gap_m);
  if (const nlohmann::json* v = JsonMember(source, value, field, "solid_side", false)) {
    const std::string name = JsonString(source, *v, JsonField(field, "solid_side"));
    const std::optional<SquareSide> side = ParseSquareSide(name);
    if (!side) {
      ThrowJsonError(source, JsonField(field, "solid_side"),
                     "expected top, right, bottom or left, got \"" + name + "\"");
    }
    tape.solid_side = *side;
  }
  std::string why;
  if (!CheckSquareTape(tape, side_m, &why)) ThrowJsonError(source, field, why);
  JsonWarnUnknownKeys(source, value, field, {"tape_width_m", "solid_side", "dash_m", "gap_m"}, warnings);
  return tape;
}

// A point landmark: {"family", "id", "p_world_marker": [x, y, z], "position_covariance": [9],
// "fixed", "component"}; no size_m, T_world_marker, covariance or square.
// The optional `fixed` and `component` of a marker entry of either kind.
void ParseFixedAndComponent(const JsonSource& source, const nlohmann::json& value, const std::string& field,
                            MapMarker* marker) {
  if (const nlohmann::json* fixed = JsonMember(source, value, field, "fixed", false)) {
    marker->fixed = JsonBool(source, *fixed, JsonField(field, "fixed"));
  }
  if (const nlohmann::json* component = JsonMember(source, value, field, "component", false)) {
    const long number = JsonInteger(source, *component, JsonField(field, "component"));
    if (number < 0 || number > std::numeric_limits<int>::max()) {
      ThrowJsonError(source, JsonField(field, "component"),
                     "expected a non-negative integer, got " + component->dump());
    }
    marker->component = static_cast<int>(number);
  }
}

MapMarker ParsePointMarker(const JsonSource& source, const nlohmann::json& value, const std::string& field,
                           ReadWarnings* warnings) {
  MapMarker marker;
  marker.is_point = true;
  marker.key.family =
      JsonString(source, *JsonMember(source, value, field, "family", true), JsonField(field, "family"));
  if (!IsPointFamily(marker.key.family)) {
    ThrowJsonError(source, JsonField(field, "family"),
                   "unknown family \"" + marker.key.family +
                       "\" (expected barcode, qr, datamatrix, square or apriltag-<name>)");
  }
  marker.key.id = JsonString(source, *JsonMember(source, value, field, "id", true), JsonField(field, "id"));
  if (marker.key.id.empty()) ThrowJsonError(source, JsonField(field, "id"), "expected a non-empty string");
  const std::string p_field = JsonField(field, "p_world_marker");
  const std::vector<double> p =
      JsonNumbers(source, *JsonMember(source, value, field, "p_world_marker", true), p_field, 3);
  for (const double c : p) {
    if (std::abs(c) > kMaxCoordinateM) {
      ThrowJsonError(
          source, p_field,
          "expected coordinates within +-" + FormatDouble(kMaxCoordinateM) + " m, got " + FormatDouble(c));
    }
  }
  marker.T_world_marker = SE3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(p[0], p[1], p[2]));
  if (const nlohmann::json* cov = JsonMember(source, value, field, "position_covariance", false)) {
    const std::string cov_field = JsonField(field, "position_covariance");
    const std::vector<double> numbers = JsonNumbers(source, *cov, cov_field, 9);
    Eigen::Matrix3d covariance;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) covariance(r, c) = numbers[3 * r + c];
    }
    const double scale = std::max(1.0, covariance.cwiseAbs().maxCoeff());
    if ((covariance - covariance.transpose()).cwiseAbs().maxCoeff() > 1e-9 * scale)
      ThrowJsonError(source, cov_field, "expected a symmetric 3x3 matrix (row-major)");
    if ((covariance.diagonal().array() < 0.0).any())
      ThrowJsonError(source, cov_field, "expected a non-negative diagonal (variances)");
    marker.position_covariance = covariance;
  }
  if (const nlohmann::json* factor = JsonMember(source, value, field, "position_covariance_factor", false)) {
    marker.covariance_factor = ParsePositionCovarianceFactor(
        source, *factor, JsonField(field, "position_covariance_factor"), marker.position_covariance);
  }
  ParseFixedAndComponent(source, value, field, &marker);
  for (const char* key : {"size_m", "T_world_marker", "covariance", "covariance_factor", "square"}) {
    if (JsonMember(source, value, field, key, false)) {
      ThrowJsonError(source, JsonField(field, key),
                     "a point landmark (p_world_marker) has no " + std::string(key));
    }
  }
  JsonWarnUnknownKeys(source, value, field,
                      {"family", "id", "p_world_marker", "position_covariance", "position_covariance_factor",
                       "fixed", "component"},
                      warnings);
  return marker;
}

MapMarker ParseMarker(const JsonSource& source, const nlohmann::json& value, const std::string& field,
                      ReadWarnings* warnings, MapPoses poses) {
  if (value.is_object() && value.contains("p_world_marker"))
    return ParsePointMarker(source, value, field, warnings);
  MapMarker marker;
  marker.key.family =
      JsonString(source, *JsonMember(source, value, field, "family", true), JsonField(field, "family"));
  if (!IsKnownFamily(marker.key.family)) {
    ThrowJsonError(
        source, JsonField(field, "family"),
        "unknown family \"" + marker.key.family + "\" (expected qr, datamatrix, square or apriltag-<name>)");
  }
  marker.key.id = JsonString(source, *JsonMember(source, value, field, "id", true), JsonField(field, "id"));
  if (marker.key.id.empty()) ThrowJsonError(source, JsonField(field, "id"), "expected a non-empty string");
  marker.size_m =
      JsonNumber(source, *JsonMember(source, value, field, "size_m", true), JsonField(field, "size_m"));
  if (!(marker.size_m > 0.0)) {
    ThrowJsonError(source, JsonField(field, "size_m"),
                   "expected a positive size, got " + FormatDouble(marker.size_m));
  }
  if (const std::string why = CheckMarkerSize(marker.size_m); !why.empty()) {
    ThrowJsonError(source, JsonField(field, "size_m"), why);
  }
  const nlohmann::json* pose =
      JsonMember(source, value, field, "T_world_marker", poses == MapPoses::kRequired);
  if (pose != nullptr) {
    marker.T_world_marker = JsonPose(source, *pose, JsonField(field, "T_world_marker"));
  } else {
    marker.has_pose = false;
  }
  if (const nlohmann::json* covariance = JsonMember(source, value, field, "covariance", false)) {
    marker.covariance = ParseCovariance(source, *covariance, JsonField(field, "covariance"));
  }
  if (const nlohmann::json* factor = JsonMember(source, value, field, "covariance_factor", false)) {
    marker.covariance_factor =
        ParseCovarianceFactor(source, *factor, JsonField(field, "covariance_factor"), marker.covariance);
  }
  ParseFixedAndComponent(source, value, field, &marker);
  if (!marker.has_pose && (marker.fixed || marker.covariance)) {
    ThrowJsonError(source, JsonField(field, "T_world_marker"),
                   "expected a pose for a fixed marker or one with a covariance");
  }
  if (const nlohmann::json* square = JsonMember(source, value, field, "square", false)) {
    if (marker.key.family != kFamilySquare) {
      ThrowJsonError(source, JsonField(field, "square"), "only a marker of family square has a tape");
    }
    marker.square_tape =
        ParseSquareTape(source, *square, JsonField(field, "square"), marker.size_m, warnings);
  } else if (marker.key.family == kFamilySquare) {
    std::string why;
    if (!CheckSquareTape(SquareTape{}, marker.size_m, &why)) {
      ThrowJsonError(source, JsonField(field, "size_m"), "too small for the default tape (" + why + ")");
    }
  }
  JsonWarnUnknownKeys(source, value, field,
                      {"family", "id", "size_m", "T_world_marker", "covariance", "covariance_factor", "fixed",
                       "component", "square"},
                      warnings);
  return marker;
}

// {"range_a_m", "range_b", "bearing_rad", "odometry_q_t", "odometry_q_r", "odometry_c_d"}, all
// required: sigmas and q > 0, range_b and odometry_c_d >= 0; "odometry_delay_s" optional (0 when
// absent), a finite number of at most 10 s either way.
RangeBearingNoise ParseRangeBearingNoise(const JsonSource& source, const nlohmann::json& value,
                                         ReadWarnings* warnings,
                                         const std::string& field = "range_bearing_noise") {
  if (!value.is_object()) ThrowJsonError(source, field, "expected an object");
  RangeBearingNoise noise;
  const std::pair<const char*, double*> positive[] = {{"range_a_m", &noise.range_a_m},
                                                      {"bearing_rad", &noise.bearing_rad},
                                                      {"odometry_q_t", &noise.odometry_q_t},
                                                      {"odometry_q_r", &noise.odometry_q_r}};
  for (const auto& [key, out] : positive) {
    *out = JsonNumber(source, *JsonMember(source, value, field, key, true), JsonField(field, key));
    if (!(*out > 0.0))
      ThrowJsonError(source, JsonField(field, key), "expected a positive number, got " + FormatDouble(*out));
  }
  const std::pair<const char*, double*> non_negative[] = {{"range_b", &noise.range_b},
                                                          {"odometry_c_d", &noise.odometry_c_d}};
  for (const auto& [key, out] : non_negative) {
    *out = JsonNumber(source, *JsonMember(source, value, field, key, true), JsonField(field, key));
    if (!(*out >= 0.0))
      ThrowJsonError(source, JsonField(field, key), "expected a number >= 0, got " + FormatDouble(*out));
  }
  if (const nlohmann::json* delay = JsonMember(source, value, field, "odometry_delay_s", false)) {
    noise.odometry_delay_s = JsonNumber(source, *delay, JsonField(field, "odometry_delay_s"));
    if (!(std::abs(noise.odometry_delay_s) <= 10.0))
      ThrowJsonError(
          source, JsonField(field, "odometry_delay_s"),
          "expected a number of at most 10 s either way, got " + FormatDouble(noise.odometry_delay_s));
  }
  if (const nlohmann::json* scale = JsonMember(source, value, field, "range_scale_sigma", false)) {
    noise.range_scale_sigma = JsonNumber(source, *scale, JsonField(field, "range_scale_sigma"));
    if (!(noise.range_scale_sigma >= 0.0 && noise.range_scale_sigma < 1.0))
      ThrowJsonError(source, JsonField(field, "range_scale_sigma"),
                     "expected a number in [0, 1), got " + FormatDouble(noise.range_scale_sigma));
  }
  if (const nlohmann::json* time = JsonMember(source, value, field, "range_scale_time_s", false)) {
    noise.range_scale_time_s = JsonNumber(source, *time, JsonField(field, "range_scale_time_s"));
    if (!(noise.range_scale_time_s > 0.0 && std::isfinite(noise.range_scale_time_s)))
      ThrowJsonError(source, JsonField(field, "range_scale_time_s"),
                     "expected a positive number, got " + FormatDouble(noise.range_scale_time_s));
  }
  JsonWarnUnknownKeys(source, value, field,
                      {"range_a_m", "range_b", "bearing_rad", "odometry_q_t", "odometry_q_r", "odometry_c_d",
                       "odometry_delay_s", "range_scale_sigma", "range_scale_time_s"},
                      warnings);
  return noise;
}

// The sensor values of a `range_bearing_sensor` dataset entry or of its prior (all optional, 0
// when absent): finite numbers, the scales > -1 (a sigma: >= 0 when `sigmas`).
RangeBearingSensorValues ParseSensorValues(const JsonSource& source, const nlohmann::json& value,
                                           const std::string& field, bool sigmas,
                                           const std::vector<std::string>& other_keys,
                                           ReadWarnings* warnings) {
  if (!value.is_object()) ThrowJsonError(source, field, "expected an object");
  RangeBearingSensorValues values;
  const std::pair<const char*, double*> entries[] = {{"range_offset_m", &values.range_offset_m},
                                                     {"bearing_offset_rad", &values.bearing_offset_rad},
                                                     {"bearing_scale", &values.bearing_scale},
                                                     {"depth_share", &values.depth_share},
                                                     {"range_scale", &values.range_scale}};
  const auto check = [&](double v, const std::string& key, bool scale) {
    if (sigmas && !(v >= 0.0 && std::isfinite(v)))
      ThrowJsonError(source, JsonField(field, key), "expected a sigma >= 0, got " + FormatDouble(v));
    if (!sigmas && scale && !(v > -1.0 && v < 1.0))
      ThrowJsonError(source, JsonField(field, key),
                     "expected a scale error in (-1, 1), got " + FormatDouble(v));
  };
  for (const auto& [key, out] : entries) {
    if (const nlohmann::json* v = JsonMember(source, value, field, key, false)) {
      *out = JsonNumber(source, *v, JsonField(field, key));
      const std::string name = key;
      check(*out, name, name == "bearing_scale" || name == "range_scale");
    }
  }
  if (const nlohmann::json* c = JsonMember(source, value, field, "odometry_calibration", false)) {
    const std::string key = JsonField(field, "odometry_calibration");
    if (!c->is_array() || c->size() != 3)
      ThrowJsonError(source, key, "expected 3 numbers [heading drift, turn scale, distance scale]");
    for (int i = 0; i < 3; ++i) {
      values.odometry_calibration[i] = JsonNumber(source, (*c)[i], JsonField(key, i));
      check(values.odometry_calibration[i], JsonField("odometry_calibration", i), i > 0);
    }
  }
  std::set<std::string> keys = {"range_offset_m", "bearing_offset_rad", "bearing_scale",
                                "depth_share",    "range_scale",        "odometry_calibration"};
  keys.insert(other_keys.begin(), other_keys.end());
  JsonWarnUnknownKeys(source, value, field, keys, warnings);
  return values;
}

// {"range_model": "depth" | "distance", "datasets": [{"name", values..., "noise"}], "prior_mean",
// "prior_sigma"}: docs/formats.md.
RangeBearingSensorModel ParseRangeBearingSensor(const JsonSource& source, const nlohmann::json& value,
                                                ReadWarnings* warnings) {
  const std::string field = "range_bearing_sensor";
  if (!value.is_object()) ThrowJsonError(source, field, "expected an object");
  RangeBearingSensorModel model;
  const std::string range_model = JsonString(source, *JsonMember(source, value, field, "range_model", true),
                                             JsonField(field, "range_model"));
  if (range_model != "depth" && range_model != "distance")
    ThrowJsonError(source, JsonField(field, "range_model"),
                   "expected \"depth\" or \"distance\", got \"" + range_model + "\"");
  model.depth_ranges = range_model == "depth";
  const std::string datasets_field = JsonField(field, "datasets");
  const nlohmann::json& datasets = *JsonMember(source, value, field, "datasets", true);
  if (!datasets.is_array()) ThrowJsonError(source, datasets_field, "expected an array of datasets");
  std::set<std::string> names;
  for (size_t i = 0; i < datasets.size(); ++i) {
    const std::string entry = JsonField(datasets_field, i);
    RangeBearingSensorModel::Dataset dataset;
    dataset.values = ParseSensorValues(source, datasets[i], entry, false, {"name", "noise"}, warnings);
    dataset.name =
        JsonString(source, *JsonMember(source, datasets[i], entry, "name", true), JsonField(entry, "name"));
    if (!names.insert(dataset.name).second)
      ThrowJsonError(source, JsonField(entry, "name"), "duplicate dataset " + dataset.name);
    dataset.noise = ParseRangeBearingNoise(source, *JsonMember(source, datasets[i], entry, "noise", true),
                                           warnings, JsonField(entry, "noise"));
    model.datasets.push_back(dataset);
  }
  model.prior_mean = ParseSensorValues(source, *JsonMember(source, value, field, "prior_mean", true),
                                       JsonField(field, "prior_mean"), false, {}, warnings);
  model.prior_sigma = ParseSensorValues(source, *JsonMember(source, value, field, "prior_sigma", true),
                                        JsonField(field, "prior_sigma"), true, {}, warnings);
  if (!model.depth_ranges) {
    for (const char* key : {"depth_share", "range_scale"}) {
      const bool mean = std::string(key) == "depth_share" ? model.prior_mean.depth_share != 0.0
                                                          : model.prior_mean.range_scale != 0.0;
      if (mean)
        ThrowJsonError(source, JsonField(JsonField(field, "prior_mean"), key),
                       "expected 0 with range_model \"distance\"");
    }
  }
  // calibration_time_s (> 0) and calibration_turn_scale_sigma (>= 0), optional, together.
  const nlohmann::json* time = JsonMember(source, value, field, "calibration_time_s", false);
  const nlohmann::json* turn = JsonMember(source, value, field, "calibration_turn_scale_sigma", false);
  if ((time == nullptr) != (turn == nullptr))
    ThrowJsonError(source, JsonField(field, time ? "calibration_turn_scale_sigma" : "calibration_time_s"),
                   "expected calibration_time_s and calibration_turn_scale_sigma together");
  if (time) {
    RangeBearingSensorModel::CalibrationTime calibration;
    calibration.time_s = JsonNumber(source, *time, JsonField(field, "calibration_time_s"));
    if (!(calibration.time_s > 0.0 && std::isfinite(calibration.time_s)))
      ThrowJsonError(source, JsonField(field, "calibration_time_s"),
                     "expected a time > 0 (s), got " + FormatDouble(calibration.time_s));
    calibration.turn_scale_sigma =
        JsonNumber(source, *turn, JsonField(field, "calibration_turn_scale_sigma"));
    if (!(calibration.turn_scale_sigma >= 0.0 && std::isfinite(calibration.turn_scale_sigma)))
      ThrowJsonError(source, JsonField(field, "calibration_turn_scale_sigma"),
                     "expected a sigma >= 0, got " + FormatDouble(calibration.turn_scale_sigma));
    model.calibration_time = calibration;
  }
  if (const nlohmann::json* k = JsonMember(source, value, field, "online_variance_factor", false)) {
    const double factor = JsonNumber(source, *k, JsonField(field, "online_variance_factor"));
    if (!(factor > 0.0 && std::isfinite(factor)))
      ThrowJsonError(source, JsonField(field, "online_variance_factor"),
                     "expected a factor > 0, got " + FormatDouble(factor));
    model.online_variance_factor = factor;
  }
  JsonWarnUnknownKeys(source, value, field,
                      {"range_model", "datasets", "prior_mean", "prior_sigma", "calibration_time_s",
                       "calibration_turn_scale_sigma", "online_variance_factor"},
                      warnings);
  return model;
}

// One member of a board: {"family", "id", "T_board_marker"}.
BoardMember ParseBoardMember(const JsonSource& source, const nlohmann::json& value, const std::string& field,
                             ReadWarnings* warnings) {
  if (!value.is_object()) ThrowJsonError(source, field, "expected an object {family, id, T_board_marker}");
  BoardMember member;
  member.key.family =
      JsonString(source, *JsonMember(source, value, field, "family", true), JsonField(field, "family"));
  member.key.id = JsonString(source, *JsonMember(source, value, field, "id", true), JsonField(field, "id"));
  if (member.key.id.empty()) ThrowJsonError(source, JsonField(field, "id"), "expected a non-empty string");
  member.T_board_marker = JsonPose(source, *JsonMember(source, value, field, "T_board_marker", true),
                                   JsonField(field, "T_board_marker"));
  JsonWarnUnknownKeys(source, value, field, {"family", "id", "T_board_marker"}, warnings);
  return member;
}

// A rigid board: {"name", "T_world_board", "covariance", "fixed", "component", "markers": [...]};
// the pose is optional with MapPoses::kOptional (a known-markers file: board pose unknown).
MapBoard ParseBoard(const JsonSource& source, const nlohmann::json& value, const std::string& field,
                    ReadWarnings* warnings, MapPoses poses) {
  if (!value.is_object()) ThrowJsonError(source, field, "expected an object");
  MapBoard board;
  board.name = JsonString(source, *JsonMember(source, value, field, "name", true), JsonField(field, "name"));
  if (const nlohmann::json* pose =
          JsonMember(source, value, field, "T_world_board", poses == MapPoses::kRequired)) {
    board.T_world_board = JsonPose(source, *pose, JsonField(field, "T_world_board"));
    board.has_pose = true;
  }
  if (const nlohmann::json* covariance = JsonMember(source, value, field, "covariance", false)) {
    board.covariance = ParseCovariance(source, *covariance, JsonField(field, "covariance"));
  }
  MapMarker flags;
  ParseFixedAndComponent(source, value, field, &flags);
  board.fixed = flags.fixed;
  board.component = flags.component;
  const std::string members_field = JsonField(field, "markers");
  const nlohmann::json& members = *JsonMember(source, value, field, "markers", true);
  if (!members.is_array()) ThrowJsonError(source, members_field, "expected an array of codes");
  for (size_t i = 0; i < members.size(); ++i) {
    board.members.push_back(ParseBoardMember(source, members[i], JsonField(members_field, i), warnings));
  }
  JsonWarnUnknownKeys(source, value, field,
                      {"name", "T_world_board", "covariance", "fixed", "component", "markers"}, warnings);
  return board;
}

void CheckHeader(const JsonSource& source, const nlohmann::json& root) {
  const std::string format = JsonString(source, *JsonMember(source, root, "", "format", true), "format");
  if (format != kMapFormat) {
    ThrowJsonError(source, "format", std::string("expected \"") + kMapFormat + "\", got \"" + format + "\"");
  }
  const long version = JsonInteger(source, *JsonMember(source, root, "", "version", true), "version");
  if (version != kMapVersion) {
    ThrowJsonError(source, "version",
                   "expected " + std::to_string(kMapVersion) + ", got " + std::to_string(version));
  }
}

}  // namespace

MarkerMap ParseMap(const std::string& text, const std::filesystem::path& path, ReadWarnings* warnings,
                   MapPoses poses) {
  const nlohmann::json root = ParseJsonDocument(text, path, nullptr);
  const JsonSource source = JsonSourceForText(path, text);
  CheckHeader(source, root);
  const nlohmann::json& markers = *JsonMember(source, root, "", "markers", true);
  if (!markers.is_array()) ThrowJsonError(source, "markers", "expected an array of markers");
  JsonWarnUnknownKeys(
      source, root, "",
      {"format", "version", "markers", "range_bearing_noise", "range_bearing_sensor", "boards"}, warnings);

  MarkerMap map;
  if (const nlohmann::json* noise = JsonMember(source, root, "", "range_bearing_noise", false)) {
    map.range_bearing_noise = ParseRangeBearingNoise(source, *noise, warnings);
  }
  if (const nlohmann::json* sensor = JsonMember(source, root, "", "range_bearing_sensor", false)) {
    map.range_bearing_sensor = ParseRangeBearingSensor(source, *sensor, warnings);
  }
  std::set<MarkerKey> seen;
  std::optional<long> factor_columns;        // k, the same for every marker
  std::optional<long> point_factor_columns;  // k of position_covariance_factor, the same for every point
  for (size_t i = 0; i < markers.size(); ++i) {
    const std::string field = JsonField("markers", i);
    MapMarker marker = ParseMarker(source, markers[i], field, warnings, poses);
    if (!seen.insert(marker.key).second) {
      ThrowJsonError(source, field, "duplicate marker " + marker.key.ToString());
    }
    if (!marker.is_point && marker.covariance_factor) {
      const long k = marker.covariance_factor->cols();
      if (factor_columns && *factor_columns != k) {
        ThrowJsonError(source, JsonField(field, "covariance_factor"),
                       "expected 6 x " + std::to_string(*factor_columns) +
                           " like the markers before, got 6 x " + std::to_string(k));
      }
      factor_columns = k;
    }
    if (marker.is_point && marker.covariance_factor) {
      const long k = marker.covariance_factor->cols();
      if (point_factor_columns && *point_factor_columns != k) {
        ThrowJsonError(source, JsonField(field, "position_covariance_factor"),
                       "expected 3 x " + std::to_string(*point_factor_columns) +
                           " like the point landmarks before, got 3 x " + std::to_string(k));
      }
      point_factor_columns = k;
    }
    map.markers.push_back(std::move(marker));
  }
  if (const nlohmann::json* boards = JsonMember(source, root, "", "boards", false)) {
    if (!boards->is_array()) ThrowJsonError(source, "boards", "expected an array of boards");
    for (size_t b = 0; b < boards->size(); ++b) {
      map.boards.push_back(ParseBoard(source, (*boards)[b], JsonField("boards", b), warnings, poses));
    }
  }
  if (const std::optional<BoardProblem> problem = FindBoardProblem(map)) {
    std::string field = JsonField("boards", problem->board);
    if (problem->member >= 0) field = JsonField(JsonField(field, "markers"), problem->member);
    if (!problem->field.empty()) field = JsonField(field, problem->field);
    ThrowJsonError(source, field, problem->message);
  }
  return map;
}

MarkerMap ReadMap(const std::filesystem::path& path, ReadWarnings* warnings, MapPoses poses) {
  return ParseMap(ReadTextFile(path), path, warnings, poses);
}

namespace {

// nlohmann's dump writes doubles with the shortest round-trip representation.
nlohmann::ordered_json MarkerJson(const MapMarker& marker) {
  const Eigen::Vector3d& t = marker.T_world_marker.translation();
  const Eigen::Quaterniond& q = marker.T_world_marker.rotation();
  nlohmann::ordered_json json;
  if (marker.is_point) {
    json["family"] = marker.key.family;
    json["id"] = marker.key.id;
    json["p_world_marker"] = {t.x(), t.y(), t.z()};
    if (marker.position_covariance) {
      nlohmann::ordered_json covariance = nlohmann::ordered_json::array();
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) covariance.push_back((*marker.position_covariance)(r, c));
      }
      json["position_covariance"] = covariance;
    }
    if (marker.covariance_factor) {  // its translation rows
      nlohmann::ordered_json factor = nlohmann::ordered_json::array();
      for (int r = 3; r < 6; ++r) {
        for (int c = 0; c < marker.covariance_factor->cols(); ++c)
          factor.push_back((*marker.covariance_factor)(r, c));
      }
      json["position_covariance_factor"] = factor;
    }
    json["fixed"] = marker.fixed;
    if (marker.component) json["component"] = *marker.component;
    return json;
  }
  json["family"] = marker.key.family;
  json["id"] = marker.key.id;
  json["size_m"] = marker.size_m;
  if (marker.has_pose) {
    json["T_world_marker"] = {{"t", {t.x(), t.y(), t.z()}}, {"q_xyzw", {q.x(), q.y(), q.z(), q.w()}}};
  }
  if (marker.covariance) {
    nlohmann::ordered_json covariance = nlohmann::ordered_json::array();
    for (int r = 0; r < 6; ++r) {
      for (int c = 0; c < 6; ++c) covariance.push_back((*marker.covariance)(r, c));
    }
    json["covariance"] = covariance;
  }
  if (marker.covariance_factor) {
    nlohmann::ordered_json factor = nlohmann::ordered_json::array();
    for (int r = 0; r < 6; ++r) {
      for (int c = 0; c < marker.covariance_factor->cols(); ++c)
        factor.push_back((*marker.covariance_factor)(r, c));
    }
    json["covariance_factor"] = factor;
  }
  json["fixed"] = marker.fixed;
  if (marker.component) json["component"] = *marker.component;
  if (marker.square_tape) {
    const SquareTape& tape = *marker.square_tape;
    json["square"] = {{"tape_width_m", tape.tape_width_m},
                      {"solid_side", SquareSideName(tape.solid_side)},
                      {"dash_m", tape.dash_m},
                      {"gap_m", tape.gap_m}};
  }
  return json;
}

// One board, its codes one per line.
std::string BoardJson(const MapBoard& board) {
  const auto pose = [](const SE3d& T) {
    const Eigen::Vector3d& t = T.translation();
    const Eigen::Quaterniond& q = T.rotation();
    return nlohmann::ordered_json{{"t", {t.x(), t.y(), t.z()}}, {"q_xyzw", {q.x(), q.y(), q.z(), q.w()}}};
  };
  const std::string name = "map writer: board \"" + board.name + "\": ";
  nlohmann::ordered_json json;
  json["name"] = board.name;
  if (board.has_pose) json["T_world_board"] = pose(board.T_world_board);
  if (board.covariance) {
    if (!board.covariance->allFinite()) throw std::invalid_argument(name + "covariance not finite");
    nlohmann::ordered_json covariance = nlohmann::ordered_json::array();
    for (int r = 0; r < 6; ++r) {
      for (int c = 0; c < 6; ++c) covariance.push_back((*board.covariance)(r, c));
    }
    json["covariance"] = covariance;
  }
  json["fixed"] = board.fixed;
  if (board.component) {
    if (*board.component < 0) throw std::invalid_argument(name + "negative component");
    json["component"] = *board.component;
  }
  if (board.has_pose && board.T_world_board.translation().cwiseAbs().maxCoeff() > kMaxCoordinateM)
    throw std::invalid_argument(name + "T_world_board beyond the coordinate range");
  std::string text = json.dump();
  text.pop_back();  // the closing brace: the codes follow, one per line
  text += ", \"markers\": [";
  for (size_t i = 0; i < board.members.size(); ++i) {
    const BoardMember& member = board.members[i];
    const nlohmann::ordered_json m = {{"family", member.key.family},
                                      {"id", member.key.id},
                                      {"T_board_marker", pose(member.T_board_marker)}};
    text += (i == 0 ? "\n   " : ",\n   ") + m.dump();
  }
  return text + "]}";
}

void CheckWritablePoint(const MapMarker& marker, std::set<MarkerKey>* seen) {
  const std::string name = "map writer: point landmark " + marker.key.ToString() + ": ";
  if (!IsPointFamily(marker.key.family)) throw std::invalid_argument(name + "unknown family");
  if (marker.key.id.empty()) throw std::invalid_argument(name + "empty id");
  if (!marker.T_world_marker.IsFinite()) throw std::invalid_argument(name + "position not finite");
  if (marker.T_world_marker.translation().cwiseAbs().maxCoeff() > kMaxCoordinateM)
    throw std::invalid_argument(name + "position beyond the coordinate range");
  if (marker.covariance || marker.square_tape)
    throw std::invalid_argument(name + "a pose covariance or tape on a point");
  if (marker.position_covariance && !marker.position_covariance->allFinite())
    throw std::invalid_argument(name + "position_covariance not finite");
  // A point's covariance_factor is its position factor: translation rows only.
  if (marker.covariance_factor && (!marker.position_covariance || marker.covariance_factor->cols() == 0 ||
                                   !marker.covariance_factor->allFinite() ||
                                   marker.covariance_factor->topRows<3>().cwiseAbs().maxCoeff() > 0.0))
    throw std::invalid_argument(name +
                                "position factor empty, not finite, with rotation rows or without a "
                                "position_covariance");
  if (marker.component && *marker.component < 0) throw std::invalid_argument(name + "negative component");
  if (!seen->insert(marker.key).second) throw std::invalid_argument(name + "duplicate");
}

void CheckWritable(const MapMarker& marker, std::set<MarkerKey>* seen) {
  if (marker.is_point) return CheckWritablePoint(marker, seen);
  const std::string name = "map writer: marker " + marker.key.ToString() + ": ";
  if (!IsKnownFamily(marker.key.family)) throw std::invalid_argument(name + "unknown family");
  if (marker.key.id.empty()) throw std::invalid_argument(name + "empty id");
  if (!(marker.size_m > 0.0) || !std::isfinite(marker.size_m))
    throw std::invalid_argument(name + "size_m not positive");
  if (const std::string why = CheckMarkerSize(marker.size_m); !why.empty())
    throw std::invalid_argument(name + "size_m: " + why);
  if (!marker.T_world_marker.IsFinite()) throw std::invalid_argument(name + "T_world_marker not finite");
  if (marker.T_world_marker.translation().cwiseAbs().maxCoeff() > kMaxCoordinateM)
    throw std::invalid_argument(name + "T_world_marker beyond the coordinate range");
  if (!marker.has_pose && (marker.fixed || marker.covariance))
    throw std::invalid_argument(name + "fixed or with a covariance but without a pose");
  if (marker.square_tape) {
    std::string why;
    if (marker.key.family != kFamilySquare)
      throw std::invalid_argument(name + "a tape on a marker not of family square");
    if (!CheckSquareTape(*marker.square_tape, marker.size_m, &why)) throw std::invalid_argument(name + why);
  }
  if (marker.covariance && !marker.covariance->allFinite())
    throw std::invalid_argument(name + "covariance not finite");
  if (marker.covariance_factor &&
      (!marker.covariance || marker.covariance_factor->cols() == 0 || !marker.covariance_factor->allFinite()))
    throw std::invalid_argument(name + "covariance_factor empty, not finite or without a covariance");
  if (marker.component && *marker.component < 0) throw std::invalid_argument(name + "negative component");
  if (!seen->insert(marker.key).second) throw std::invalid_argument(name + "duplicate");
}

// map.json `range_bearing_noise` (and a `range_bearing_sensor` dataset's `noise`).
nlohmann::ordered_json NoiseJson(const RangeBearingNoise& noise) {
  const double values[] = {noise.range_a_m,    noise.range_b,      noise.bearing_rad,
                           noise.odometry_q_t, noise.odometry_q_r, noise.odometry_c_d};
  for (const double v : values) {
    if (!std::isfinite(v) || v < 0.0)
      throw std::invalid_argument("map writer: range_bearing_noise not finite or negative");
  }
  if (!std::isfinite(noise.odometry_delay_s) || !(noise.range_scale_sigma >= 0.0) ||
      !(noise.range_scale_time_s > 0.0) || !std::isfinite(noise.range_scale_time_s))
    throw std::invalid_argument("map writer: range_bearing_noise odometry_delay_s or range scale not valid");
  nlohmann::ordered_json json = {{"range_a_m", noise.range_a_m},       {"range_b", noise.range_b},
                                 {"bearing_rad", noise.bearing_rad},   {"odometry_q_t", noise.odometry_q_t},
                                 {"odometry_q_r", noise.odometry_q_r}, {"odometry_c_d", noise.odometry_c_d}};
  if (noise.odometry_delay_s != 0.0) json["odometry_delay_s"] = noise.odometry_delay_s;
  if (noise.range_scale_sigma > 0.0) {
    json["range_scale_sigma"] = noise.range_scale_sigma;
    json["range_scale_time_s"] = noise.range_scale_time_s;
  }
  return json;
}

nlohmann::ordered_json SensorValuesJson(const RangeBearingSensorValues& values, bool sigmas) {
  const double all[] = {values.range_offset_m,
                        values.bearing_offset_rad,
                        values.bearing_scale,
                        values.depth_share,
                        values.range_scale,
                        values.odometry_calibration[0],
                        values.odometry_calibration[1],
                        values.odometry_calibration[2]};
  for (const double v : all) {
    if (!std::isfinite(v) || (sigmas && v < 0.0))
      throw std::invalid_argument("map writer: range_bearing_sensor value not finite (or a negative sigma)");
  }
  return {{"range_offset_m", values.range_offset_m},
          {"bearing_offset_rad", values.bearing_offset_rad},
          {"bearing_scale", values.bearing_scale},
          {"depth_share", values.depth_share},
          {"range_scale", values.range_scale},
          {"odometry_calibration",
           {values.odometry_calibration[0], values.odometry_calibration[1], values.odometry_calibration[2]}}};
}

}  // namespace

std::string FormatMap(const MarkerMap& map) {
  std::set<MarkerKey> seen;
  std::string text = std::string("{\"format\": \"") + kMapFormat +
                     "\", \"version\": " + std::to_string(kMapVersion) + ",\n \"markers\": [";
  for (size_t i = 0; i < map.markers.size(); ++i) {
    CheckWritable(map.markers[i], &seen);
    text += (i == 0 ? "\n  " : ",\n  ") + MarkerJson(map.markers[i]).dump();
  }
  text += map.markers.empty() ? "]" : "\n ]";
  if (!map.boards.empty()) {
    if (const std::optional<BoardProblem> problem = FindBoardProblem(map)) {
      throw std::invalid_argument("map writer: board " + std::to_string(problem->board) +
                                  (problem->member >= 0 ? " code " + std::to_string(problem->member) : "") +
                                  ": " + problem->message);
    }
    text += ",\n \"boards\": [";
    for (size_t b = 0; b < map.boards.size(); ++b)
      text += (b == 0 ? "\n  " : ",\n  ") + BoardJson(map.boards[b]);
    text += "\n ]";
  }
  if (const auto& noise = map.range_bearing_noise)
    text += ",\n \"range_bearing_noise\": " + NoiseJson(*noise).dump();
  if (const auto& sensor = map.range_bearing_sensor) {
    nlohmann::ordered_json datasets = nlohmann::ordered_json::array();
    for (const RangeBearingSensorModel::Dataset& dataset : sensor->datasets) {
      nlohmann::ordered_json json = {{"name", dataset.name}};
      const nlohmann::ordered_json values = SensorValuesJson(dataset.values, false);
      for (const auto& item : values.items()) json[item.key()] = item.value();
      json["noise"] = NoiseJson(dataset.noise);
      datasets.push_back(json);
    }
    nlohmann::ordered_json json = {{"range_model", sensor->depth_ranges ? "depth" : "distance"},
                                   {"datasets", datasets},
                                   {"prior_mean", SensorValuesJson(sensor->prior_mean, false)},
                                   {"prior_sigma", SensorValuesJson(sensor->prior_sigma, true)}};
    if (const auto& calibration = sensor->calibration_time) {
      if (!(calibration->time_s > 0.0 && std::isfinite(calibration->time_s)) ||
          !(calibration->turn_scale_sigma >= 0.0 && std::isfinite(calibration->turn_scale_sigma)))
        throw std::invalid_argument(
            "map writer: range_bearing_sensor calibration time not > 0 (or its sigma negative or not "
            "finite)");
      json["calibration_time_s"] = calibration->time_s;
      json["calibration_turn_scale_sigma"] = calibration->turn_scale_sigma;
    }
    if (const auto& factor = sensor->online_variance_factor) {
      if (!(*factor > 0.0 && std::isfinite(*factor)))
        throw std::invalid_argument("map writer: range_bearing_sensor online_variance_factor not > 0");
      json["online_variance_factor"] = *factor;
    }
    text += ",\n \"range_bearing_sensor\": " + json.dump();
  }
  return text + "}\n";
}

void WriteMap(const std::filesystem::path& path, const MarkerMap& map) {
  std::string text;
  try {
    text = FormatMap(map);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(path.string() + ": " + e.what());
  }
  AtomicWriteFile(path, text);
}

}  // namespace waymark
