#include "io/range_bearing_io.h"

#include <cmath>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string_view>

#include "io/json_util.h"
#include "io/util.h"
#include "util/format.h"

namespace waymark {
namespace {

constexpr double kPi = 3.14159265358979323846;

JsonSource LineSource(const std::filesystem::path& path, long line_number) {
  JsonSource source;
  source.path = path;
  source.line_of = [line_number](const std::string&) -> std::optional<long> { return line_number; };
  return source;
}

// Why a value is out of its range ("" when fine); shared by the reader and the writer.
std::string CheckRange(double range_m) {
  if (!std::isfinite(range_m) || !(range_m > 0.0) || range_m > kMaxCoordinateM)
    return "expected a range > 0 m, got " + FormatDouble(range_m);
  return "";
}
std::string CheckAngle(double angle_rad, double limit_rad) {
  if (!std::isfinite(angle_rad) || std::abs(angle_rad) > limit_rad)
    return "expected an angle within +-" + FormatDouble(limit_rad) + " rad, got " + FormatDouble(angle_rad);
  return "";
}
std::string CheckSigma(double sigma) {
  if (!std::isfinite(sigma) || !(sigma > 0.0)) return "expected a positive sigma, got " + FormatDouble(sigma);
  return "";
}

double Checked(const JsonSource& source, const nlohmann::json& object, const std::string& parent,
               const std::string& key, const std::function<std::string(double)>& check) {
  const std::string field = JsonField(parent, key);
  const double value = JsonNumber(source, *JsonMember(source, object, parent, key, true), field);
  if (const std::string why = check(value); !why.empty()) ThrowJsonError(source, field, why);
  return value;
}

std::optional<double> OptionalChecked(const JsonSource& source, const nlohmann::json& object,
                                      const std::string& parent, const std::string& key,
                                      const std::function<std::string(double)>& check) {
  if (!JsonMember(source, object, parent, key, false)) return std::nullopt;
  return Checked(source, object, parent, key, check);
}

RangeBearingObservation ParseLandmark(const JsonSource& source, const nlohmann::json& value,
                                      const std::string& field, ReadWarnings* warnings) {
  if (!value.is_object())
    ThrowJsonError(source, field, "expected an object {family, id, range_m, bearing_rad}");
  RangeBearingObservation obs;
  obs.key.family =
      JsonString(source, *JsonMember(source, value, field, "family", true), JsonField(field, "family"));
  if (!IsPointFamily(obs.key.family)) {
    ThrowJsonError(source, JsonField(field, "family"),
                   "unknown family \"" + obs.key.family +
                       "\" (expected barcode, qr, datamatrix, square or apriltag-<name>)");
  }
  obs.key.id = JsonString(source, *JsonMember(source, value, field, "id", true), JsonField(field, "id"));
  if (obs.key.id.empty()) ThrowJsonError(source, JsonField(field, "id"), "expected a non-empty string");
  obs.range_m = Checked(source, value, field, "range_m", CheckRange);
  obs.bearing_rad = Checked(source, value, field, "bearing_rad", [](double a) { return CheckAngle(a, kPi); });
  obs.elevation_rad = OptionalChecked(source, value, field, "elevation_rad",
                                      [](double a) { return CheckAngle(a, 0.5 * kPi); });
  obs.sigma_range_m = OptionalChecked(source, value, field, "sigma_range_m", CheckSigma);
  obs.sigma_bearing_rad = OptionalChecked(source, value, field, "sigma_bearing_rad", CheckSigma);
  obs.sigma_elevation_rad = OptionalChecked(source, value, field, "sigma_elevation_rad", CheckSigma);
  JsonWarnUnknownKeys(source, value, field,
                      {"family", "id", "range_m", "bearing_rad", "elevation_rad", "sigma_range_m",
                       "sigma_bearing_rad", "sigma_elevation_rad"},
                      warnings);
  return obs;
}

RobotSighting ParseRobot(const JsonSource& source, const nlohmann::json& value, const std::string& field,
                         ReadWarnings* warnings) {
  if (!value.is_object())
    ThrowJsonError(source, field, "expected an object {robot, barcode, range_m, bearing_rad}");
  RobotSighting sighting;
  sighting.robot =
      JsonString(source, *JsonMember(source, value, field, "robot", true), JsonField(field, "robot"));
  sighting.barcode =
      JsonString(source, *JsonMember(source, value, field, "barcode", true), JsonField(field, "barcode"));
  if (sighting.robot.empty())
    ThrowJsonError(source, JsonField(field, "robot"), "expected a non-empty string");
  if (sighting.barcode.empty())
    ThrowJsonError(source, JsonField(field, "barcode"), "expected a non-empty string");
  sighting.range_m = Checked(source, value, field, "range_m", CheckRange);
  sighting.bearing_rad =
      Checked(source, value, field, "bearing_rad", [](double a) { return CheckAngle(a, kPi); });
  JsonWarnUnknownKeys(source, value, field, {"robot", "barcode", "range_m", "bearing_rad"}, warnings);
  return sighting;
}

const nlohmann::json& Array(const JsonSource& source, const nlohmann::json& root, const std::string& key,
                            bool required) {
  static const nlohmann::json kEmpty = nlohmann::json::array();
  const nlohmann::json* value = JsonMember(source, root, "", key, required);
  if (value == nullptr) return kEmpty;
  if (!value->is_array()) ThrowJsonError(source, key, "expected an array (empty when nothing was seen)");
  if (value->size() > kMaxRangeBearingPerFrame) {
    ThrowJsonError(source, key,
                   "expected at most " + std::to_string(kMaxRangeBearingPerFrame) + " entries, got " +
                       std::to_string(value->size()));
  }
  return *value;
}

RangeBearingFrame ParseFrame(const JsonSource& source, const nlohmann::json& root, ReadWarnings* warnings) {
  if (!root.is_object()) ThrowJsonError(source, "", "expected a JSON object {\"t\", \"landmarks\"}");
  RangeBearingFrame frame;
  frame.stamp_s = JsonNumber(source, *JsonMember(source, root, "", "t", true), "t");
  const nlohmann::json& landmarks = Array(source, root, "landmarks", true);
  std::map<MarkerKey, int> count;
  for (size_t i = 0; i < landmarks.size(); ++i) {
    frame.landmarks.push_back(ParseLandmark(source, landmarks[i], JsonField("landmarks", i), warnings));
    ++count[frame.landmarks.back().key];
  }
  for (const auto& [key, n] : count) {
    if (n < 2) continue;
    if (warnings) {
      warnings->Add(
          "duplicate landmark in frame",
          JsonErrorText(source, "landmarks",
                        key.ToString() + " seen " + std::to_string(n) + " times in one frame, all ignored"));
    }
    std::vector<RangeBearingObservation> kept;
    for (RangeBearingObservation& obs : frame.landmarks) {
      if (obs.key != key) kept.push_back(std::move(obs));
    }
    frame.landmarks = std::move(kept);
  }
  const nlohmann::json& robots = Array(source, root, "robots", false);
  for (size_t i = 0; i < robots.size(); ++i) {
    frame.robots.push_back(ParseRobot(source, robots[i], JsonField("robots", i), warnings));
  }
  JsonWarnUnknownKeys(source, root, "", {"t", "landmarks", "robots"}, warnings);
  return frame;
}

}  // namespace

std::vector<RangeBearingFrame> ParseRangeBearing(const std::string& text, const std::filesystem::path& path,
                                                 ReadWarnings* warnings) {
  std::vector<RangeBearingFrame> frames;
  ForEachLine(text, [&](long line_number, std::string_view line) {
    if (line.find_first_not_of(" \t") == std::string_view::npos) return;
    const JsonSource source = LineSource(path, line_number);
    const nlohmann::json root = ParseJsonLine(line, path, line_number);
    RangeBearingFrame frame = ParseFrame(source, root, warnings);
    if (!frames.empty() && frame.stamp_s < frames.back().stamp_s) {
      ThrowJsonError(source, "t",
                     "expected non-decreasing stamps, got " + FormatDouble(frame.stamp_s) + " after " +
                         FormatDouble(frames.back().stamp_s));
    }
    frames.push_back(std::move(frame));
  });
  return frames;
}

std::vector<RangeBearingFrame> ReadRangeBearing(const std::filesystem::path& path, ReadWarnings* warnings) {
  return ParseRangeBearing(ReadTextFile(path), path, warnings);
}

std::string FormatRangeBearingLine(const RangeBearingFrame& frame) {
  const std::string name = "range_bearing writer: t=" + FormatDouble(frame.stamp_s) + ": ";
  if (!std::isfinite(frame.stamp_s)) throw std::invalid_argument(name + "stamp not finite");
  const auto check = [&](const std::string& why) {
    if (!why.empty()) throw std::invalid_argument(name + why);
  };
  nlohmann::ordered_json root;
  root["t"] = frame.stamp_s;
  root["landmarks"] = nlohmann::ordered_json::array();
  for (const RangeBearingObservation& obs : frame.landmarks) {
    if (!IsPointFamily(obs.key.family) || obs.key.id.empty())
      throw std::invalid_argument(name + "bad key " + obs.key.ToString());
    check(CheckRange(obs.range_m));
    check(CheckAngle(obs.bearing_rad, kPi));
    nlohmann::ordered_json entry;
    entry["family"] = obs.key.family;
    entry["id"] = obs.key.id;
    entry["range_m"] = obs.range_m;
    entry["bearing_rad"] = obs.bearing_rad;
    if (obs.elevation_rad) {
      check(CheckAngle(*obs.elevation_rad, 0.5 * kPi));
      entry["elevation_rad"] = *obs.elevation_rad;
    }
    const std::pair<const char*, const std::optional<double>*> sigmas[] = {
        {"sigma_range_m", &obs.sigma_range_m},
        {"sigma_bearing_rad", &obs.sigma_bearing_rad},
        {"sigma_elevation_rad", &obs.sigma_elevation_rad}};
    for (const auto& [key, sigma] : sigmas) {
      if (!*sigma) continue;
      check(CheckSigma(**sigma));
      entry[key] = **sigma;
    }
    root["landmarks"].push_back(entry);
  }
  if (!frame.robots.empty()) {
    root["robots"] = nlohmann::ordered_json::array();
    for (const RobotSighting& s : frame.robots) {
      if (s.robot.empty() || s.barcode.empty())
        throw std::invalid_argument(name + "robot sighting without names");
      check(CheckRange(s.range_m));
      check(CheckAngle(s.bearing_rad, kPi));
      root["robots"].push_back({{"robot", s.robot},
                                {"barcode", s.barcode},
                                {"range_m", s.range_m},
                                {"bearing_rad", s.bearing_rad}});
    }
  }
  return root.dump();
}

std::string FormatRangeBearing(const std::vector<RangeBearingFrame>& frames) {
  std::string text;
  for (size_t i = 0; i < frames.size(); ++i) {
    if (i > 0 && frames[i].stamp_s < frames[i - 1].stamp_s)
      throw std::invalid_argument("range_bearing writer: stamps decrease at t=" +
                                  FormatDouble(frames[i].stamp_s));
    text += FormatRangeBearingLine(frames[i]) + "\n";
  }
  return text;
}

}  // namespace waymark
