#include "io/camera_io.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "io/util.h"
#include "io/yaml_util.h"

namespace waymark {
namespace {

// "" when fx, fy are at most kMaxFocalLengthPx and the principal point lies within one image
// size of the image (a crop may move it outside, not further).
std::string CheckIntrinsicsRange(const double* intrinsics, int width, int height) {
  if (intrinsics[0] > kMaxFocalLengthPx || intrinsics[1] > kMaxFocalLengthPx) {
    return "expected focal lengths up to " + FormatDouble(kMaxFocalLengthPx) + " px, got " +
           FormatDouble(std::max(intrinsics[0], intrinsics[1]));
  }
  if (std::abs(intrinsics[2] - 0.5 * width) > 1.5 * width ||
      std::abs(intrinsics[3] - 0.5 * height) > 1.5 * height) {
    return "expected the principal point within one image size of the " + std::to_string(width) + "x" +
           std::to_string(height) + " image, got (" + FormatDouble(intrinsics[2]) + ", " +
           FormatDouble(intrinsics[3]) + ")";
  }
  return "";
}

std::string CheckDistortionRange(const std::vector<double>& distortion) {
  for (const double k : distortion) {
    if (std::abs(k) > kMaxDistortionCoefficient) {
      return "expected coefficients within +-" + FormatDouble(kMaxDistortionCoefficient) + ", got " +
             FormatDouble(k);
    }
  }
  return "";
}

std::string CheckCameraOffset(const SE3d& T_robot_camera) {
  const double offset_m = T_robot_camera.translation().norm();
  if (offset_m <= kMaxCameraOffsetM) return "";
  return "expected the camera within " + FormatDouble(kMaxCameraOffsetM) + " m of the robot, got " +
         FormatDouble(offset_m) + " m";
}

// The prior sigmas of an estimated mount: a rotation up to pi and a translation within the
// camera offset limit, both > 0.
std::string CheckMountSigma(double rot_rad, double trans_m) {
  if (!(rot_rad > 0.0 && rot_rad <= M_PI && trans_m > 0.0 && trans_m <= kMaxCameraOffsetM)) {
    return "expected [rotation rad in (0, pi], translation m in (0, " + FormatDouble(kMaxCameraOffsetM) +
           "]], got [" + FormatDouble(rot_rad) + ", " + FormatDouble(trans_m) + "]";
  }
  return "";
}

CameraModel ReadModel(const std::filesystem::path& path, const YAML::Node& root) {
  const YAML::Node node = YamlRequire(path, root, "model");
  const std::string name = YamlString(path, node, "model");
  const std::optional<CameraModel> model = ParseCameraModel(name);
  if (!model) {
    ThrowYamlError(path, node,
                   "model: unknown camera model '" + name + "' (expected " +
                       CameraModelName(CameraModel::kPinholeRadtan) + ", " +
                       CameraModelName(CameraModel::kPinholeEquidistant) + " or " +
                       CameraModelName(CameraModel::kEquisolid) + ")");
  }
  return *model;
}

int ReadSize(const std::filesystem::path& path, const YAML::Node& root, const std::string& key) {
  const YAML::Node node = YamlRequire(path, root, key);
  const long value = YamlInteger(path, node, key);
  if (value <= 0 || value > 1000000) {
    ThrowYamlError(path, node, key + ": expected a positive number of pixels, got " + std::to_string(value));
  }
  return static_cast<int>(value);
}

}  // namespace

CameraInfo ParseCameraYaml(const std::string& text, const std::filesystem::path& path,
                           const std::string& name, ReadWarnings* warnings) {
  const YAML::Node root = YamlLoadMap(path, text);
  CameraInfo camera;
  camera.name = name;
  camera.model = ReadModel(path, root);
  camera.width = ReadSize(path, root, "width");
  camera.height = ReadSize(path, root, "height");

  const YAML::Node intrinsics_node = YamlRequire(path, root, "intrinsics");
  const std::vector<double> intrinsics = YamlNumbers(path, intrinsics_node, "intrinsics", 4);
  if (!(intrinsics[0] > 0.0 && intrinsics[1] > 0.0)) {
    ThrowYamlError(path, intrinsics_node, "intrinsics: expected positive focal lengths fx, fy");
  }
  if (const std::string why = CheckIntrinsicsRange(intrinsics.data(), camera.width, camera.height);
      !why.empty()) {
    ThrowYamlError(path, intrinsics_node, "intrinsics: " + why);
  }
  for (int i = 0; i < 4; ++i) camera.intrinsics[i] = intrinsics[i];

  const size_t distortion_size = CameraInfo::DistortionSize(camera.model);
  camera.distortion =
      YamlNumbers(path, YamlRequire(path, root, "distortion"),
                  std::string("distortion (") + CameraModelName(camera.model) + ")", distortion_size);
  if (const std::string why = CheckDistortionRange(camera.distortion); !why.empty()) {
    ThrowYamlError(path, root["distortion"], "distortion: " + why);
  }
  const YAML::Node pose_node = YamlRequire(path, root, "T_robot_camera");
  camera.T_robot_camera = YamlPose(path, pose_node, "T_robot_camera");
  if (const std::string why = CheckCameraOffset(camera.T_robot_camera); !why.empty()) {
    ThrowYamlError(path, pose_node, "T_robot_camera.t: " + why);
  }

  if (const YAML::Node sigma = root["pixel_sigma"]; sigma.IsDefined() && !sigma.IsNull()) {
    camera.pixel_sigma = YamlNumber(path, sigma, "pixel_sigma");
    if (!(*camera.pixel_sigma > 0.0 && *camera.pixel_sigma <= kMaxPixelSigmaPx)) {
      ThrowYamlError(path, sigma,
                     "pixel_sigma: expected a positive number of pixels up to " +
                         FormatDouble(kMaxPixelSigmaPx) + ", got " + FormatDouble(*camera.pixel_sigma));
    }
  }
  if (const YAML::Node sigma = root["T_robot_camera_sigma"]; sigma.IsDefined() && !sigma.IsNull()) {
    const std::vector<double> values = YamlNumbers(path, sigma, "T_robot_camera_sigma", 2);
    if (const std::string why = CheckMountSigma(values[0], values[1]); !why.empty()) {
      ThrowYamlError(path, sigma, "T_robot_camera_sigma: " + why);
    }
    camera.T_robot_camera_sigma = std::array<double, 2>{values[0], values[1]};
  }
  if (const YAML::Node sigma = root["frame_wiggle_sigma"]; sigma.IsDefined() && !sigma.IsNull()) {
    const std::vector<double> values = YamlNumbers(path, sigma, "frame_wiggle_sigma", 2);
    if (const std::string why = CheckMountSigma(values[0], values[1]); !why.empty()) {
      ThrowYamlError(path, sigma, "frame_wiggle_sigma: " + why);
    }
    camera.frame_wiggle_sigma = std::array<double, 2>{values[0], values[1]};
  }
  YamlWarnUnknownKeys(path, root,
                      {"model", "width", "height", "intrinsics", "distortion", "T_robot_camera",
                       "pixel_sigma", "T_robot_camera_sigma", "frame_wiggle_sigma"},
                      "", warnings);
  return camera;
}

CameraInfo ReadCameraYaml(const std::filesystem::path& path, ReadWarnings* warnings) {
  return ParseCameraYaml(ReadTextFile(path), path, path.stem().string(), warnings);
}

namespace {

std::string NumberList(const double* values, size_t count) {
  std::string text = "[";
  for (size_t i = 0; i < count; ++i) text += (i ? ", " : "") + FormatDouble(values[i]);
  return text + "]";
}

void CheckWritable(const CameraInfo& camera) {
  const std::string name = "camera writer: " + camera.name + ": ";
  if (camera.width <= 0 || camera.height <= 0)
    throw std::invalid_argument(name + "width and height must be positive");
  if (!(camera.intrinsics[0] > 0.0 && camera.intrinsics[1] > 0.0) || !std::isfinite(camera.intrinsics[0]) ||
      !std::isfinite(camera.intrinsics[1]) || !std::isfinite(camera.intrinsics[2]) ||
      !std::isfinite(camera.intrinsics[3])) {
    throw std::invalid_argument(name + "intrinsics must be finite with positive fx, fy");
  }
  if (camera.distortion.size() != CameraInfo::DistortionSize(camera.model)) {
    throw std::invalid_argument(name + "distortion needs " +
                                std::to_string(CameraInfo::DistortionSize(camera.model)) +
                                " coefficients for " + CameraModelName(camera.model));
  }
  for (const double k : camera.distortion) {
    if (!std::isfinite(k)) throw std::invalid_argument(name + "distortion not finite");
  }
  if (!camera.T_robot_camera.IsFinite()) throw std::invalid_argument(name + "T_robot_camera not finite");
  if (const std::string why = CheckIntrinsicsRange(camera.intrinsics.data(), camera.width, camera.height) +
                              CheckDistortionRange(camera.distortion) +
                              CheckCameraOffset(camera.T_robot_camera);
      !why.empty()) {
    throw std::invalid_argument(name + why);
  }
  if (camera.pixel_sigma && !(*camera.pixel_sigma > 0.0 && std::isfinite(*camera.pixel_sigma))) {
    throw std::invalid_argument(name + "pixel_sigma must be positive");
  }
  if (camera.T_robot_camera_sigma) {
    const std::string why =
        CheckMountSigma((*camera.T_robot_camera_sigma)[0], (*camera.T_robot_camera_sigma)[1]);
    if (!why.empty()) throw std::invalid_argument(name + "T_robot_camera_sigma: " + why);
  }
  if (camera.frame_wiggle_sigma) {
    const std::string why = CheckMountSigma((*camera.frame_wiggle_sigma)[0], (*camera.frame_wiggle_sigma)[1]);
    if (!why.empty()) throw std::invalid_argument(name + "frame_wiggle_sigma: " + why);
  }
}

}  // namespace

std::string FormatCameraYaml(const CameraInfo& camera) {
  CheckWritable(camera);
  std::ostringstream out;
  out << "model: " << CameraModelName(camera.model) << "\n"
      << "width: " << camera.width << "\n"
      << "height: " << camera.height << "\n"
      << "intrinsics: " << NumberList(camera.intrinsics.data(), 4) << "\n"
      << "distortion: " << NumberList(camera.distortion.data(), camera.distortion.size()) << "\n"
      << "T_robot_camera: " << FormatPoseYaml(camera.T_robot_camera) << "\n";
  if (camera.pixel_sigma) out << "pixel_sigma: " << FormatDouble(*camera.pixel_sigma) << "\n";
  if (camera.T_robot_camera_sigma) {
    out << "T_robot_camera_sigma: " << NumberList(camera.T_robot_camera_sigma->data(), 2) << "\n";
  }
  if (camera.frame_wiggle_sigma) {
    out << "frame_wiggle_sigma: " << NumberList(camera.frame_wiggle_sigma->data(), 2) << "\n";
  }
  return out.str();
}

void WriteCameraYaml(const std::filesystem::path& path, const CameraInfo& camera) {
  std::string text;
  try {
    text = FormatCameraYaml(camera);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(path.string() + ": " + e.what());
  }
  AtomicWriteFile(path, text);
}

}  // namespace waymark
