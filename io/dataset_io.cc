#include "io/dataset_io.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <iterator>
#include <sstream>
#include <stdexcept>
#include <string_view>
#include <utility>

#include "geometry/payload.h"
#include "io/camera_io.h"
#include "io/detections_io.h"
#include "io/map_io.h"
#include "io/range_bearing_io.h"
#include "io/tum_io.h"
#include "io/util.h"
#include "io/yaml_util.h"

namespace waymark {
namespace {

namespace fs = std::filesystem;

constexpr const char* kDatasetFormat = "waymark-dataset";
constexpr long kDatasetVersion = 1;
constexpr const char* kImagesHeader = "t,camera,path";

// A camera name becomes a file name: cameras/<name>.yaml.
bool IsValidCameraName(const std::string& name) {
  if (name.empty() || name == "." || name == "..") return false;
  for (const char c : name) {
    if (c == '/' || c == '\\' || static_cast<unsigned char>(c) < 0x20) return false;
  }
  return true;
}

MotionModel ReadMotion(const fs::path& path, const YAML::Node& root) {
  const YAML::Node node = YamlRequire(path, root, "motion");
  const std::string motion = YamlString(path, node, "motion");
  if (motion == "planar") return MotionModel::kPlanar;
  if (motion == "free") return MotionModel::kFree;
  ThrowYamlError(path, node, "motion: expected planar or free, got '" + motion + "'");
}

std::vector<std::string> ReadCameraNames(const fs::path& path, const YAML::Node& root) {
  const YAML::Node node = YamlRequire(path, root, "cameras");
  const std::vector<std::string> names = YamlStrings(path, node, "cameras");
  std::set<std::string> seen;
  for (const std::string& name : names) {
    if (!IsValidCameraName(name))
      ThrowYamlError(path, node, "cameras: '" + name + "' is not a valid file name");
    if (!seen.insert(name).second) ThrowYamlError(path, node, "cameras: '" + name + "' is listed twice");
  }
  return names;
}

OdometrySigma ReadOdometrySigma(const fs::path& path, const YAML::Node& node) {
  if (!node.IsMap())
    ThrowYamlError(path, node, "odometry_sigma: expected a map {trans_per_m, rot_per_rad, ...}");
  OdometrySigma sigma;
  // trans_per_m and rot_per_rad are required (version 1); the random-walk terms are optional (0).
  const std::pair<const char*, double*> keys[] = {
      {"trans_per_m", &sigma.trans_per_m},           {"rot_per_rad", &sigma.rot_per_rad},
      {"trans_per_sqrt_s", &sigma.trans_per_sqrt_s}, {"rot_per_sqrt_s", &sigma.rot_per_sqrt_s},
      {"trans_per_sqrt_m", &sigma.trans_per_sqrt_m}, {"rot_per_sqrt_m", &sigma.rot_per_sqrt_m}};
  for (size_t i = 0; i < std::size(keys); ++i) {
    const std::string key = keys[i].first;
    const YAML::Node value = i < 2 ? YamlRequire(path, node, key) : node[key];
    if (!value.IsDefined() || value.IsNull()) continue;
    *keys[i].second = YamlNumber(path, value, "odometry_sigma." + key);
    if (*keys[i].second < 0.0)
      ThrowYamlError(path, value, "odometry_sigma." + key + ": expected a non-negative noise figure");
  }
  for (const auto& key_value : node) {
    const std::string key = key_value.first.Scalar();
    if (std::none_of(std::begin(keys), std::end(keys), [&](const auto& k) { return key == k.first; })) {
      ThrowYamlError(path, key_value.first,
                     "odometry_sigma: unknown key '" + key +
                         "' (expected trans_per_m, rot_per_rad, trans_per_sqrt_s, rot_per_sqrt_s, "
                         "trans_per_sqrt_m, rot_per_sqrt_m)");
    }
  }
  return sigma;
}

// start_prior: {T_world_robot: {t: [x, y, z], q_xyzw: [...]}, sigma_m: 0.01, sigma_rad: 0.01}
StartPrior ReadStartPrior(const fs::path& path, const YAML::Node& node) {
  if (!node.IsMap())
    ThrowYamlError(path, node, "start_prior: expected a map {T_world_robot, sigma_m, sigma_rad}");
  StartPrior prior;
  prior.T_world_robot = YamlPose(path, YamlRequire(path, node, "T_world_robot"), "start_prior.T_world_robot");
  prior.sigma_m = YamlNumber(path, YamlRequire(path, node, "sigma_m"), "start_prior.sigma_m");
  prior.sigma_rad = YamlNumber(path, YamlRequire(path, node, "sigma_rad"), "start_prior.sigma_rad");
  if (!(prior.sigma_m > 0.0) || !(prior.sigma_rad > 0.0))
    ThrowYamlError(path, node, "start_prior: expected positive sigma_m and sigma_rad");
  for (const auto& key_value : node) {
    const std::string key = key_value.first.Scalar();
    if (key != "T_world_robot" && key != "sigma_m" && key != "sigma_rad") {
      ThrowYamlError(path, key_value.first,
                     "start_prior: unknown key '" + key + "' (expected T_world_robot, sigma_m, sigma_rad)");
    }
  }
  return prior;
}

PayloadSpec ReadPayload(const fs::path& path, const YAML::Node& node) {
  if (!node.IsMap()) ThrowYamlError(path, node, "payload: expected a map {pattern, fields[, default_z_m]}");
  PayloadSpec spec;
  spec.pattern = YamlString(path, YamlRequire(path, node, "pattern"), "payload.pattern");
  spec.fields = YamlStrings(path, YamlRequire(path, node, "fields"), "payload.fields");
  for (const auto& key_value : node) {
    const std::string key = key_value.first.Scalar();
    if (key != "pattern" && key != "fields" && key != "default_z_m") {
      ThrowYamlError(path, key_value.first,
                     "payload: unknown key '" + key + "' (expected pattern, fields, default_z_m)");
    }
  }
  if (const YAML::Node z = node["default_z_m"]; z.IsDefined() && !z.IsNull()) {
    spec.default_z_m = YamlNumber(path, z, "payload.default_z_m");
    if (std::abs(*spec.default_z_m) > kMaxCoordinateM) {
      ThrowYamlError(path, z,
                     "payload.default_z_m: expected a coordinate within +-" + FormatDouble(kMaxCoordinateM) +
                         " m, got " + FormatDouble(*spec.default_z_m));
    }
  }
  if (const std::string why = CheckPayloadSpec(spec); !why.empty())
    ThrowYamlError(path, node, "payload: " + why);
  return spec;
}

// An optional file name key; records it in *named_files.
void ReadFileName(const fs::path& path, const YAML::Node& root, const std::string& key, std::string* file,
                  std::set<std::string>* named_files) {
  const YAML::Node node = root[key];
  if (!node.IsDefined() || node.IsNull()) return;
  *file = YamlString(path, node, key);
  if (file->empty()) ThrowYamlError(path, node, key + ": expected a file name");
  if (named_files) named_files->insert(key);
}

void CheckHeader(const fs::path& path, const YAML::Node& root) {
  const YAML::Node format = YamlRequire(path, root, "format");
  if (YamlString(path, format, "format") != kDatasetFormat) {
    ThrowYamlError(path, format,
                   std::string("format: expected ") + kDatasetFormat + ", got '" + format.Scalar() + "'");
  }
  const YAML::Node version = YamlRequire(path, root, "version");
  const long number = YamlInteger(path, version, "version");
  if (number != kDatasetVersion) {
    ThrowYamlError(
        path, version,
        "version: expected " + std::to_string(kDatasetVersion) + ", got " + std::to_string(number));
  }
}

}  // namespace

std::string CheckPayloadSpec(const PayloadSpec& spec) {
  try {
    ValidatePayloadSpec(spec);  // the parser's own rules, so a spec that loads also parses
  } catch (const std::runtime_error& e) {
    const std::string what = e.what();
    const std::string prefix = "payload: ";
    return what.compare(0, prefix.size(), prefix) == 0 ? what.substr(prefix.size()) : what;
  }
  return "";
}

DatasetConfig ParseDatasetYaml(const std::string& text, const fs::path& path, ReadWarnings* warnings,
                               std::set<std::string>* named_files) {
  const YAML::Node root = YamlLoadMap(path, text);
  CheckHeader(path, root);
  DatasetConfig config;
  if (const YAML::Node name = root["name"]; name.IsDefined() && !name.IsNull()) {
    config.name = YamlString(path, name, "name");
  }
  config.motion = ReadMotion(path, root);
  config.cameras = ReadCameraNames(path, root);
  if (const YAML::Node size = root["default_marker_size_m"]; size.IsDefined() && !size.IsNull()) {
    config.default_marker_size_m = YamlNumber(path, size, "default_marker_size_m");
    if (!(*config.default_marker_size_m > 0.0))
      ThrowYamlError(path, size, "default_marker_size_m: expected a positive size");
    if (const std::string why = CheckMarkerSize(*config.default_marker_size_m); !why.empty())
      ThrowYamlError(path, size, "default_marker_size_m: " + why);
  }
  if (const YAML::Node sigma = root["odometry_sigma"]; sigma.IsDefined() && !sigma.IsNull()) {
    config.odometry_sigma = ReadOdometrySigma(path, sigma);
  }
  if (const YAML::Node payload = root["payload"]; payload.IsDefined() && !payload.IsNull()) {
    config.payload = ReadPayload(path, payload);
  }
  ReadFileName(path, root, "odometry", &config.odometry_file, named_files);
  ReadFileName(path, root, "detections", &config.detections_file, named_files);
  ReadFileName(path, root, "images", &config.images_file, named_files);
  ReadFileName(path, root, "markers", &config.markers_file, named_files);
  ReadFileName(path, root, "range_bearing", &config.range_bearing_file, named_files);
  if (const YAML::Node prior = root["start_prior"]; prior.IsDefined() && !prior.IsNull()) {
    config.start_prior = ReadStartPrior(path, prior);
  }
  YamlWarnUnknownKeys(
      path, root,
      {"format", "version", "name", "motion", "cameras", "default_marker_size_m", "odometry_sigma", "payload",
       "odometry", "detections", "images", "markers", "range_bearing", "start_prior"},
      "", warnings);
  return config;
}

namespace {

std::string QuotedList(const std::vector<std::string>& items) {
  std::string text = "[";
  for (size_t i = 0; i < items.size(); ++i) text += (i ? ", " : "") + QuoteString(items[i]);
  return text + "]";
}

}  // namespace

std::string FormatDatasetYaml(const DatasetConfig& config) {
  for (const std::string& name : config.cameras) {
    if (!IsValidCameraName(name))
      throw std::invalid_argument("dataset writer: invalid camera name '" + name + "'");
  }
  std::ostringstream out;
  out << "format: " << kDatasetFormat << "\nversion: " << kDatasetVersion << "\n";
  if (!config.name.empty()) out << "name: " << QuoteString(config.name) << "\n";
  out << "motion: " << (config.motion == MotionModel::kPlanar ? "planar" : "free") << "\n";
  out << "cameras: " << QuotedList(config.cameras) << "\n";
  if (config.default_marker_size_m) {
    if (!(*config.default_marker_size_m > 0.0) || !std::isfinite(*config.default_marker_size_m)) {
      throw std::invalid_argument("dataset writer: default_marker_size_m must be positive");
    }
    out << "default_marker_size_m: " << FormatDouble(*config.default_marker_size_m) << "\n";
  }
  if (const auto& sigma = config.odometry_sigma) {
    const std::pair<const char*, double> terms[] = {
        {"trans_per_m", sigma->trans_per_m},           {"rot_per_rad", sigma->rot_per_rad},
        {"trans_per_sqrt_s", sigma->trans_per_sqrt_s}, {"rot_per_sqrt_s", sigma->rot_per_sqrt_s},
        {"trans_per_sqrt_m", sigma->trans_per_sqrt_m}, {"rot_per_sqrt_m", sigma->rot_per_sqrt_m}};
    for (const auto& [key, value] : terms) {
      if (!(value >= 0.0) || !std::isfinite(value))
        throw std::invalid_argument("dataset writer: odometry_sigma must be finite and non-negative");
    }
    out << "odometry_sigma: {trans_per_m: " << FormatDouble(sigma->trans_per_m)
        << ", rot_per_rad: " << FormatDouble(sigma->rot_per_rad);
    for (size_t i = 2; i < std::size(terms); ++i) {  // the random-walk terms, only when set
      if (terms[i].second > 0.0) out << ", " << terms[i].first << ": " << FormatDouble(terms[i].second);
    }
    out << "}\n";
  }
  if (config.payload) {
    if (const std::string why = CheckPayloadSpec(*config.payload); !why.empty()) {
      throw std::invalid_argument("dataset writer: payload: " + why);
    }
    out << "payload: {pattern: " << QuoteString(config.payload->pattern)
        << ", fields: " << QuotedList(config.payload->fields);
    if (config.payload->default_z_m) out << ", default_z_m: " << FormatDouble(*config.payload->default_z_m);
    out << "}\n";
  }
  if (const auto& prior = config.start_prior) {
    const Eigen::Vector3d& t = prior->T_world_robot.translation();
    const Eigen::Quaterniond& q = prior->T_world_robot.rotation();
    if (!prior->T_world_robot.IsFinite() || !(prior->sigma_m > 0.0) || !(prior->sigma_rad > 0.0) ||
        !std::isfinite(prior->sigma_m) || !std::isfinite(prior->sigma_rad)) {
      throw std::invalid_argument("dataset writer: start_prior must be finite with positive sigmas");
    }
    out << "start_prior: {T_world_robot: {t: [" << FormatDouble(t.x()) << ", " << FormatDouble(t.y()) << ", "
        << FormatDouble(t.z()) << "], q_xyzw: [" << FormatDouble(q.x()) << ", " << FormatDouble(q.y()) << ", "
        << FormatDouble(q.z()) << ", " << FormatDouble(q.w())
        << "]}, sigma_m: " << FormatDouble(prior->sigma_m)
        << ", sigma_rad: " << FormatDouble(prior->sigma_rad) << "}\n";
  }
  const DatasetConfig defaults;
  const std::pair<const char*, std::pair<std::string, std::string>> files[] = {
      {"range_bearing", {config.range_bearing_file, defaults.range_bearing_file}},
      {"odometry", {config.odometry_file, defaults.odometry_file}},
      {"detections", {config.detections_file, defaults.detections_file}},
      {"images", {config.images_file, defaults.images_file}},
      {"markers", {config.markers_file, defaults.markers_file}}};
  for (const auto& [key, names] : files) {
    if (names.first.empty())
      throw std::invalid_argument(std::string("dataset writer: empty ") + key + " file name");
    if (names.first != names.second) out << key << ": " << QuoteString(names.first) << "\n";
  }
  return out.str();
}

std::vector<ImageEntry> ParseImagesCsv(const std::string& text, const fs::path& path,
                                       const std::vector<std::string>* cameras) {
  std::vector<ImageEntry> images;
  ForEachLine(text, [&](long line_number, std::string_view line) {
    if (line.find_first_not_of(" \t") == std::string_view::npos) return;
    if (line_number == 1 && line == kImagesHeader) return;
    const size_t comma1 = line.find(',');
    const size_t comma2 = comma1 == std::string_view::npos ? comma1 : line.find(',', comma1 + 1);
    if (comma2 == std::string_view::npos) {
      throw FormatError(path, line_number, std::string("expected 3 fields '") + kImagesHeader + "'");
    }
    ImageEntry entry;
    const std::string_view stamp = line.substr(0, comma1);
    const std::optional<double> stamp_s = ParseFiniteDouble(stamp);
    if (!stamp_s)
      throw FormatError(path, line_number, "t: expected a finite number, got '" + std::string(stamp) + "'");
    entry.stamp_s = *stamp_s;
    entry.camera = std::string(line.substr(comma1 + 1, comma2 - comma1 - 1));
    entry.path = std::string(line.substr(comma2 + 1));
    if (entry.camera.empty()) throw FormatError(path, line_number, "camera: expected a camera name");
    if (entry.path.empty()) throw FormatError(path, line_number, "path: expected an image path");
    if (cameras && std::find(cameras->begin(), cameras->end(), entry.camera) == cameras->end()) {
      throw FormatError(path, line_number, "camera: '" + entry.camera + "' is not in dataset.yaml cameras");
    }
    images.push_back(std::move(entry));
  });
  return images;
}

std::string FormatImagesCsv(const std::vector<ImageEntry>& images) {
  std::string text = std::string(kImagesHeader) + "\n";
  for (const ImageEntry& entry : images) {
    if (!std::isfinite(entry.stamp_s) || entry.camera.empty() || entry.path.empty() ||
        entry.camera.find_first_of(",\n\r") != std::string::npos ||
        entry.path.find_first_of("\n\r") != std::string::npos) {
      throw std::invalid_argument("images.csv writer: row at t=" + FormatDouble(entry.stamp_s) +
                                  " needs a finite t, a camera without commas and a one-line path");
    }
    text += FormatDouble(entry.stamp_s) + "," + entry.camera + "," + entry.path + "\n";
  }
  return text;
}

namespace {

// dir / file when it exists; an error when it is missing but dataset.yaml names it.
std::optional<fs::path> OptionalFile(const fs::path& dir, const std::string& file, const std::string& key,
                                     const std::set<std::string>& named_files) {
  const fs::path path = dir / file;
  std::error_code ec;
  if (fs::is_regular_file(path, ec)) return path;
  if (named_files.count(key)) {
    throw FormatError(dir / "dataset.yaml", key + ": file '" + file + "' not found in " + dir.string());
  }
  return std::nullopt;
}

void LoadDatasetCameras(Dataset* dataset) {
  for (const std::string& name : dataset->config.cameras) {
    const fs::path path = dataset->dir / "cameras" / (name + ".yaml");
    CameraInfo camera = ParseCameraYaml(ReadTextFile(path), path, name, &dataset->warnings);
    dataset->cameras.emplace(name, std::move(camera));
  }
}

void LoadImages(Dataset* dataset, const fs::path& path) {
  dataset->images = ParseImagesCsv(ReadTextFile(path), path, &dataset->config.cameras);
  dataset->has_images_file = true;
  long line = 0;
  for (const ImageEntry& entry : dataset->images) {
    ++line;
    std::error_code ec;
    if (!fs::exists(dataset->dir / entry.path, ec)) {
      dataset->warnings.Add("missing image", path.string() + ": image '" + entry.path + "' (row " +
                                                 std::to_string(line) + ") not found");
    }
  }
}

// Markers seen in detections with no size from markers.json or default_marker_size_m.
void WarnMarkersWithoutSize(Dataset* dataset) {
  std::set<MarkerKey> warned;
  for (const DetectionFrame& frame : dataset->detections) {
    for (const MarkerObservation& marker : frame.markers) {
      if (dataset->MarkerSize(marker.key) || !warned.insert(marker.key).second) continue;
      dataset->warnings.Add("marker without size",
                            (dataset->dir / dataset->config.detections_file).string() + ": marker " +
                                marker.key.ToString() +
                                " has no size (not in markers.json, no default_marker_size_m)");
    }
  }
}

void LoadTruthAndReference(Dataset* dataset) {
  std::error_code ec;
  const auto trajectory = [&](const fs::path& path) -> std::optional<Trajectory> {
    if (!fs::is_regular_file(path, ec)) return std::nullopt;
    return ReadTum(path);
  };
  const auto map = [&](const fs::path& path) -> std::optional<MarkerMap> {
    if (!fs::is_regular_file(path, ec)) return std::nullopt;
    return ReadMap(path, &dataset->warnings);
  };
  dataset->groundtruth_trajectory = trajectory(dataset->dir / "groundtruth" / "trajectory.tum");
  dataset->groundtruth_markers = map(dataset->dir / "groundtruth" / "markers.json");
  dataset->reference_trajectory = trajectory(dataset->dir / "reference" / "trajectory.tum");
  dataset->reference_markers = map(dataset->dir / "reference" / "markers.json");
}

}  // namespace

Dataset LoadDataset(const fs::path& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw FormatError(dir, "not a directory (expected a dataset directory)");
  Dataset dataset;
  dataset.dir = dir;
  const fs::path yaml_path = dir / "dataset.yaml";
  std::set<std::string> named_files;
  dataset.config = ParseDatasetYaml(ReadTextFile(yaml_path), yaml_path, &dataset.warnings, &named_files);
  if (dataset.config.name.empty())
    dataset.config.name = fs::absolute(dir).lexically_normal().filename().string();
  if (dataset.config.name.empty())
    dataset.config.name = fs::absolute(dir).lexically_normal().parent_path().filename().string();
  LoadDatasetCameras(&dataset);

  const DatasetConfig& config = dataset.config;
  if (const auto path = OptionalFile(dir, config.odometry_file, "odometry", named_files)) {
    dataset.odometry = ReadTum(*path);
    dataset.has_odometry_file = true;
  }
  if (const auto path = OptionalFile(dir, config.markers_file, "markers", named_files)) {
    dataset.known_markers = ReadMap(*path, &dataset.warnings, MapPoses::kOptional);
  }
  if (const auto path = OptionalFile(dir, config.detections_file, "detections", named_files)) {
    dataset.detections = ReadDetections(*path, &dataset.warnings, &dataset.cameras);
    dataset.has_detections_file = true;
  }
  if (const auto path = OptionalFile(dir, config.images_file, "images", named_files))
    LoadImages(&dataset, *path);
  if (const auto path = OptionalFile(dir, config.range_bearing_file, "range_bearing", named_files)) {
    dataset.range_bearing = ReadRangeBearing(*path, &dataset.warnings);
    dataset.has_range_bearing_file = true;
  }
  LoadTruthAndReference(&dataset);
  WarnMarkersWithoutSize(&dataset);
  return dataset;
}

namespace {

// Cross-references WriteDataset needs before writing anything.
void CheckConsistent(const Dataset& dataset) {
  const std::vector<std::string>& names = dataset.config.cameras;
  for (const std::string& name : names) {
    if (!dataset.cameras.count(name))
      throw std::invalid_argument("dataset writer: camera " + name + " has no CameraInfo");
  }
  for (const auto& [name, camera] : dataset.cameras) {
    if (std::find(names.begin(), names.end(), name) == names.end()) {
      throw std::invalid_argument("dataset writer: camera " + name + " is not in config.cameras");
    }
  }
  for (const DetectionFrame& frame : dataset.detections) {
    if (!dataset.cameras.count(frame.camera)) {
      throw std::invalid_argument("dataset writer: detection at t=" + FormatDouble(frame.stamp_s) +
                                  " of unlisted camera " + frame.camera);
    }
  }
  for (const ImageEntry& entry : dataset.images) {
    if (!dataset.cameras.count(entry.camera)) {
      throw std::invalid_argument("dataset writer: image " + entry.path + " of unlisted camera " +
                                  entry.camera);
    }
  }
}

}  // namespace

void WriteDataset(const fs::path& dir, const Dataset& dataset) {
  CheckConsistent(dataset);
  // Format everything first: a dataset the readers would reject writes nothing.
  std::vector<std::pair<fs::path, std::string>> files;
  const DatasetConfig& config = dataset.config;
  files.emplace_back(dir / "dataset.yaml", FormatDatasetYaml(config));
  for (const std::string& name : config.cameras) {
    files.emplace_back(dir / "cameras" / (name + ".yaml"), FormatCameraYaml(dataset.cameras.at(name)));
  }
  if (dataset.has_odometry_file || !dataset.odometry.empty()) {
    files.emplace_back(dir / config.odometry_file, FormatTum(dataset.odometry));
  }
  if (dataset.has_detections_file || !dataset.detections.empty()) {
    files.emplace_back(dir / config.detections_file, FormatDetections(dataset.detections));
  }
  if (dataset.has_images_file || !dataset.images.empty()) {
    files.emplace_back(dir / config.images_file, FormatImagesCsv(dataset.images));
  }
  if (dataset.has_range_bearing_file || !dataset.range_bearing.empty()) {
    files.emplace_back(dir / config.range_bearing_file, FormatRangeBearing(dataset.range_bearing));
  }
  if (dataset.known_markers) files.emplace_back(dir / config.markers_file, FormatMap(*dataset.known_markers));
  if (dataset.groundtruth_trajectory) {
    files.emplace_back(dir / "groundtruth" / "trajectory.tum", FormatTum(*dataset.groundtruth_trajectory));
  }
  if (dataset.groundtruth_markers)
    files.emplace_back(dir / "groundtruth" / "markers.json", FormatMap(*dataset.groundtruth_markers));
  if (dataset.reference_trajectory) {
    files.emplace_back(dir / "reference" / "trajectory.tum", FormatTum(*dataset.reference_trajectory));
  }
  if (dataset.reference_markers)
    files.emplace_back(dir / "reference" / "markers.json", FormatMap(*dataset.reference_markers));
  for (const auto& [path, text] : files) AtomicWriteFile(path, text);
}

DatasetSummary SummarizeDataset(const Dataset& dataset) {
  DatasetSummary summary;
  std::set<MarkerKey> distinct;
  summary.frames = static_cast<long>(dataset.detections.size());
  for (const DetectionFrame& frame : dataset.detections) {
    for (const MarkerObservation& marker : frame.markers) {
      ++summary.detections;
      ++summary.detections_per_family[marker.key.family];
      distinct.insert(marker.key);
    }
  }
  summary.distinct_markers = static_cast<long>(distinct.size());
  if (dataset.known_markers) summary.known_markers = static_cast<long>(dataset.known_markers->markers.size());
  const Trajectory& odometry = dataset.odometry;
  summary.odometry_poses = static_cast<long>(odometry.size());
  if (!odometry.empty()) summary.odometry_span_s = odometry.back().stamp_s - odometry.front().stamp_s;
  for (size_t i = 1; i < odometry.size(); ++i) {
    summary.odometry_path_length_m += (odometry[i].T.translation() - odometry[i - 1].T.translation()).norm();
  }
  return summary;
}

}  // namespace waymark
