#include "io/detections_io.h"

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string_view>

#include "geometry/square_marker.h"
#include "io/json_util.h"
#include "io/util.h"

namespace waymark {
namespace {

// Other writers (Python's json module among them) write NaN, Infinity and -Infinity, which
// are not JSON. Outside strings they become null, so a non-finite corner is a counted
// warning rather than a malformed line.
std::string NonFiniteLiteralsToNull(std::string_view line) {
  std::string out;
  out.reserve(line.size());
  bool in_string = false;
  for (size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (in_string) {
      out += c;
      if (c == '\\' && i + 1 < line.size()) {
        out += line[++i];
      } else if (c == '"') {
        in_string = false;
      }
      continue;
    }
    if (c == '"') in_string = true;
    bool replaced = false;
    for (const std::string_view literal : {"-Infinity", "Infinity", "-NaN", "NaN"}) {
      if (line.substr(i, literal.size()) == literal) {
        out += "null";
        i += literal.size() - 1;
        replaced = true;
        break;
      }
    }
    if (!replaced) out += c;
  }
  return out;
}

// The four corners; nullopt (with a counted warning) when one is null or not finite.
std::optional<std::array<Eigen::Vector2d, 4>> ParseCorners(const JsonSource& source,
                                                           const nlohmann::json& value,
                                                           const std::string& field, ReadWarnings* warnings) {
  if (!value.is_array() || value.size() != 4) {
    ThrowJsonError(source, field,
                   "expected 4 corners [[x, y], ...], got " +
                       (value.is_array() ? std::to_string(value.size()) : std::string("no array")));
  }
  std::array<Eigen::Vector2d, 4> corners;
  bool finite = true;
  for (size_t i = 0; i < 4; ++i) {
    const std::string corner_field = JsonField(field, i);
    const nlohmann::json& point = value[i];
    if (!point.is_array() || point.size() != 2)
      ThrowJsonError(source, corner_field, "expected a point [x, y]");
    for (size_t k = 0; k < 2; ++k) {
      if (point[k].is_null() || (point[k].is_number() && !std::isfinite(point[k].get<double>()))) {
        finite = false;
        corners[i][k] = std::nan("");
      } else if (point[k].is_number()) {
        corners[i][k] = point[k].get<double>();
      } else {
        ThrowJsonError(source, JsonField(corner_field, k), "expected a number");
      }
    }
  }
  if (!finite) {
    if (warnings) {
      warnings->Add("non-finite corner", JsonErrorText(source, field, "non-finite corner, marker ignored"));
    }
    return std::nullopt;
  }
  return corners;
}

// One marker; nullopt (with a counted warning) when it must be ignored.
std::optional<MarkerObservation> ParseMarker(const JsonSource& source, const nlohmann::json& value,
                                             const std::string& field, const CameraInfo* camera,
                                             ReadWarnings* warnings) {
  MarkerObservation marker;
  marker.key.family =
      JsonString(source, *JsonMember(source, value, field, "family", true), JsonField(field, "family"));
  marker.key.id = JsonString(source, *JsonMember(source, value, field, "id", true), JsonField(field, "id"));
  const std::optional<std::array<Eigen::Vector2d, 4>> corners =
      ParseCorners(source, *JsonMember(source, value, field, "corners_px", true),
                   JsonField(field, "corners_px"), warnings);
  if (const nlohmann::json* quality = JsonMember(source, value, field, "quality", false)) {
    marker.quality = JsonNumber(source, *quality, JsonField(field, "quality"));
  }
  JsonWarnUnknownKeys(source, value, field, {"family", "id", "corners_px", "quality"}, warnings);
  if (!corners) return std::nullopt;
  marker.corners_px = *corners;
  if (!IsKnownFamily(marker.key.family)) {
    if (warnings) {
      warnings->Add("unknown family",
                    JsonErrorText(source, JsonField(field, "family"),
                                  "unknown family \"" + marker.key.family + "\", marker ignored"));
    }
    return std::nullopt;
  }
  if (marker.key.id.empty()) ThrowJsonError(source, JsonField(field, "id"), "expected a non-empty string");
  if (camera != nullptr) {
    // A detector that fits lines to a code's edges (AprilTag) puts the corners of a code cut by
    // the image border where those lines meet, outside the image: a valid measurement of where
    // the corner projects. A corner is kept up to half the quad's shorter diagonal outside (a
    // code mostly in view; a single wild corner cannot widen it, one diagonal avoids it);
    // farther out the detection is garbage.
    const std::array<Eigen::Vector2d, 4>& c = marker.corners_px;
    const double margin_px = 0.5 * std::min((c[2] - c[0]).norm(), (c[3] - c[1]).norm());
    for (const Eigen::Vector2d& corner_px : marker.corners_px) {
      if (corner_px.x() >= -margin_px && corner_px.y() >= -margin_px &&
          corner_px.x() <= camera->width + margin_px && corner_px.y() <= camera->height + margin_px) {
        continue;
      }
      if (warnings) {
        warnings->Add("corner outside image",
                      JsonErrorText(source, JsonField(field, "corners_px"),
                                    "corner (" + FormatDouble(corner_px.x()) + ", " +
                                        FormatDouble(corner_px.y()) + ") outside the " +
                                        std::to_string(camera->width) + "x" + std::to_string(camera->height) +
                                        " image by more than half the code's diagonal, marker ignored"));
      }
      return std::nullopt;
    }
  }
  return marker;
}

// The frame's camera; an error when `cameras` is given and does not hold it.
const CameraInfo* FindCamera(const JsonSource& source, const std::string& name,
                             const std::map<std::string, CameraInfo>* cameras) {
  if (cameras == nullptr) return nullptr;
  const auto it = cameras->find(name);
  if (it != cameras->end()) return &it->second;
  std::string known;
  for (const auto& [camera_name, camera] : *cameras) known += (known.empty() ? "" : ", ") + camera_name;
  ThrowJsonError(source, "camera", "camera \"" + name + "\" is not in the dataset (cameras: " + known + ")");
}

// A code seen twice in one frame: which sighting is it? Every copy is dropped, counted once.
// Squares not identified yet (id "*", geometry/square_marker.h) are not codes: several may be
// in view, each is told apart later.
void DropDuplicateMarkers(const JsonSource& source, DetectionFrame* frame, ReadWarnings* warnings) {
  std::map<MarkerKey, int> count;
  for (const MarkerObservation& marker : frame->markers) ++count[marker.key];
  for (const auto& [key, n] : count) {
    if (n < 2 || (key.family == kFamilySquare && key.id == kUnidentifiedSquareId)) continue;
    if (warnings) {
      warnings->Add("duplicate marker in frame", JsonErrorText(source, "markers",
                                                               key.ToString() + " seen " + std::to_string(n) +
                                                                   " times in one frame, all ignored"));
    }
    frame->markers.erase(std::remove_if(frame->markers.begin(), frame->markers.end(),
                                        [&key = key](const MarkerObservation& m) { return m.key == key; }),
                         frame->markers.end());
  }
}

DetectionFrame ParseFrame(const JsonSource& source, const nlohmann::json& root,
                          const std::map<std::string, CameraInfo>* cameras, ReadWarnings* warnings) {
  if (!root.is_object())
    ThrowJsonError(source, "", "expected a JSON object {\"t\", \"camera\", \"markers\"}");
  DetectionFrame frame;
  frame.stamp_s = JsonNumber(source, *JsonMember(source, root, "", "t", true), "t");
  frame.camera = JsonString(source, *JsonMember(source, root, "", "camera", true), "camera");
  if (frame.camera.empty()) ThrowJsonError(source, "camera", "expected a non-empty string");
  const CameraInfo* camera = FindCamera(source, frame.camera, cameras);
  if (const nlohmann::json* image = JsonMember(source, root, "", "image", false)) {
    frame.image = JsonString(source, *image, "image");
  }
  if (const nlohmann::json* number = JsonMember(source, root, "", "frame", false)) {
    frame.frame = JsonInteger(source, *number, "frame");
  }
  const nlohmann::json& markers = *JsonMember(source, root, "", "markers", true);
  if (!markers.is_array())
    ThrowJsonError(source, "markers", "expected an array (empty when nothing was seen)");
  if (markers.size() > kMaxMarkersPerFrame) {
    ThrowJsonError(source, "markers",
                   "expected at most " + std::to_string(kMaxMarkersPerFrame) + " markers in one frame, got " +
                       std::to_string(markers.size()));
  }
  for (size_t i = 0; i < markers.size(); ++i) {
    std::optional<MarkerObservation> marker =
        ParseMarker(source, markers[i], JsonField("markers", i), camera, warnings);
    if (marker) frame.markers.push_back(std::move(*marker));
  }
  DropDuplicateMarkers(source, &frame, warnings);
  JsonWarnUnknownKeys(source, root, "", {"t", "camera", "image", "frame", "markers"}, warnings);
  return frame;
}

JsonSource LineSource(const std::filesystem::path& path, long line_number) {
  JsonSource source;
  source.path = path;
  source.line_of = [line_number](const std::string&) -> std::optional<long> { return line_number; };
  return source;
}

}  // namespace

std::vector<DetectionFrame> ParseDetections(const std::string& text, const std::filesystem::path& path,
                                            ReadWarnings* warnings,
                                            const std::map<std::string, CameraInfo>* cameras) {
  std::vector<DetectionFrame> frames;
  std::map<std::string, double> last_stamp_s;  // per camera
  ForEachLine(text, [&](long line_number, std::string_view line) {
    if (line.find_first_not_of(" \t") == std::string_view::npos) return;
    const JsonSource source = LineSource(path, line_number);
    const nlohmann::json root = ParseJsonLine(NonFiniteLiteralsToNull(line), path, line_number);
    DetectionFrame frame = ParseFrame(source, root, cameras, warnings);
    const auto [it, inserted] = last_stamp_s.emplace(frame.camera, frame.stamp_s);
    if (!inserted) {
      if (frame.stamp_s < it->second) {
        ThrowJsonError(source, "t",
                       "expected stamps non-decreasing per camera, got " + FormatDouble(frame.stamp_s) +
                           " after " + FormatDouble(it->second) + " for " + frame.camera);
      }
      it->second = frame.stamp_s;
    }
    frames.push_back(std::move(frame));
  });
  return frames;
}

std::vector<DetectionFrame> ReadDetections(const std::filesystem::path& path, ReadWarnings* warnings,
                                           const std::map<std::string, CameraInfo>* cameras) {
  return ParseDetections(ReadTextFile(path), path, warnings, cameras);
}

std::string FormatDetectionLine(const DetectionFrame& frame) {
  const std::string name = "detections writer: frame at t=" + FormatDouble(frame.stamp_s) + ": ";
  if (!std::isfinite(frame.stamp_s)) throw std::invalid_argument(name + "t not finite");
  if (frame.camera.empty()) throw std::invalid_argument(name + "empty camera name");
  if (frame.markers.size() > kMaxMarkersPerFrame) {
    throw std::invalid_argument(name + std::to_string(frame.markers.size()) + " markers, more than " +
                                std::to_string(kMaxMarkersPerFrame));
  }
  nlohmann::ordered_json json;
  json["t"] = frame.stamp_s;
  json["camera"] = frame.camera;
  if (frame.image) json["image"] = *frame.image;
  if (frame.frame) json["frame"] = *frame.frame;
  json["markers"] = nlohmann::ordered_json::array();
  for (const MarkerObservation& marker : frame.markers) {
    if (!IsKnownFamily(marker.key.family))
      throw std::invalid_argument(name + "unknown family " + marker.key.family);
    if (marker.key.id.empty()) throw std::invalid_argument(name + "empty id");
    nlohmann::ordered_json entry;
    entry["family"] = marker.key.family;
    entry["id"] = marker.key.id;
    if (marker.quality) {
      if (!std::isfinite(*marker.quality)) throw std::invalid_argument(name + "quality not finite");
      entry["quality"] = *marker.quality;
    }
    entry["corners_px"] = nlohmann::ordered_json::array();
    for (const Eigen::Vector2d& corner_px : marker.corners_px) {
      if (!corner_px.allFinite())
        throw std::invalid_argument(name + "corner not finite for " + marker.key.ToString());
      entry["corners_px"].push_back({corner_px.x(), corner_px.y()});
    }
    json["markers"].push_back(std::move(entry));
  }
  // ensure_ascii=false keeps UTF-8 payloads readable; invalid UTF-8 is an error.
  try {
    return json.dump(-1, ' ', false, nlohmann::ordered_json::error_handler_t::strict);
  } catch (const nlohmann::json::exception& e) {
    throw std::invalid_argument(name + "text is not valid UTF-8");
  }
}

std::string FormatDetections(const std::vector<DetectionFrame>& frames) {
  std::map<std::string, double> last_stamp_s;
  std::string text;
  for (const DetectionFrame& frame : frames) {
    const auto [it, inserted] = last_stamp_s.emplace(frame.camera, frame.stamp_s);
    if (!inserted) {
      if (frame.stamp_s < it->second) {
        throw std::invalid_argument("detections writer: stamps decreasing for camera " + frame.camera + " (" +
                                    FormatDouble(frame.stamp_s) + " after " + FormatDouble(it->second) + ")");
      }
      it->second = frame.stamp_s;
    }
    text += FormatDetectionLine(frame);
    text += '\n';
  }
  return text;
}

void WriteDetections(const std::filesystem::path& path, const std::vector<DetectionFrame>& frames) {
  std::string text;
  try {
    text = FormatDetections(frames);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(path.string() + ": " + e.what());
  }
  AtomicWriteFile(path, text);
}

}  // namespace waymark
