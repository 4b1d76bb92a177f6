// The plain data types every part of Waymark exchanges: marker keys, detections,
// trajectories, maps and datasets. Pure data, no I/O (readers and writers are in *_io.h).
// Conventions (frames, corner order, units) are those of docs/design.md.
#pragma once

#include <Eigen/Core>
#include <array>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <tuple>
#include <vector>

#include "geometry/pose.h"

namespace waymark {

// Marker families as written in files.
inline constexpr const char* kFamilyQr = "qr";
inline constexpr const char* kFamilyDataMatrix = "datamatrix";
inline constexpr const char* kFamilySquare = "square";
inline constexpr const char* kFamilyAprilTagPrefix = "apriltag-";  // e.g. apriltag-36h11

inline constexpr const char* kFamilyBarcode = "barcode";  // a 1-D barcode: point landmarks only

// True for qr, datamatrix, square and apriltag-<name> with a non-empty name.
bool IsKnownFamily(const std::string& family);
// Families a point landmark (range-bearing observations, map entries with p_world_marker) may
// have: every known family, and barcode.
bool IsPointFamily(const std::string& family);

// A marker's identity: (family, id). `id` is the decoded text for QR and DataMatrix
// and the tag number, as a string, for AprilTag.
struct MarkerKey {
  std::string family;
  std::string id;

  bool operator<(const MarkerKey& o) const { return std::tie(family, id) < std::tie(o.family, o.id); }
  bool operator==(const MarkerKey& o) const { return family == o.family && id == o.id; }
  bool operator!=(const MarkerKey& o) const { return !(*this == o); }
  std::string ToString() const { return family + ":" + id; }
};

// Object points of the four corners in the marker frame, docs/design.md order:
// top-left, top-right, bottom-right, bottom-left of the upright symbol.
inline std::array<Eigen::Vector3d, 4> MarkerCorners(double size_m) {
  const double h = 0.5 * size_m;
  return {Eigen::Vector3d(-h, h, 0.0), Eigen::Vector3d(h, h, 0.0), Eigen::Vector3d(h, -h, 0.0),
          Eigen::Vector3d(-h, -h, 0.0)};
}

// One marker seen in one image.
struct MarkerObservation {
  MarkerKey key;
  std::array<Eigen::Vector2d, 4> corners_px;  // docs/design.md corner order
  std::optional<double> quality;              // detector's quality figure, if any
};

// Everything detected in one image of one camera (one line of detections.jsonl).
struct DetectionFrame {
  double stamp_s = 0.0;
  std::string camera;
  std::vector<MarkerObservation> markers;
  std::optional<std::string> image;  // image path as given, for image inputs
  std::optional<long> frame;         // frame number, for video inputs
};

// A timestamped transform; in a trajectory it is T_world_robot (or T_odom_robot).
struct StampedSE3 {
  double stamp_s = 0.0;
  SE3d T;
};
using Trajectory = std::vector<StampedSE3>;  // sorted by stamp_s

// The index of the last sample at or before `stamp_s` (-1 when all are later); binary search.
long SampleAtOrBefore(const Trajectory& trajectory, double stamp_s);

// The pose at `stamp_s`, interpolated between the samples around it (InterpolateProduct);
// nullopt outside the trajectory's span or when those samples are more than max_gap_s apart.
std::optional<SE3d> InterpolateTrajectory(const Trajectory& trajectory, double stamp_s, double max_gap_s);

// Rows F_i of a map's low-rank joint marker covariance (6 x k; mapping/map_covariance.h).
using CovarianceFactor = Eigen::Matrix<double, 6, Eigen::Dynamic>;

// The tape of a `square` marker ([Seki]: retro-reflective tape on the ceiling). The marker's
// size_m is the side between the tape's centrelines, so its corners (MarkerCorners) are where
// the centrelines cross. One side is solid, the three others dashed: dashes of dash_m with
// gaps of about gap_m, spread evenly so that a dash covers each end of the side. The math is in
// geometry/square_marker.h.
enum class SquareSide { kTop, kRight, kBottom, kLeft };  // top: corners 0-1, right: 1-2, ...
struct SquareTape {
  double tape_width_m = 0.05;
  SquareSide solid_side = SquareSide::kTop;
  double dash_m = 0.10;
  double gap_m = 0.10;
};

// The noise of range-bearing observations and of a planar robot's odometry, as the range-bearing
// map build estimates it (mapping/range_bearing_map.h) and the range-bearing localizer uses it;
// map.json carries it as `range_bearing_noise`.
//   sigma_range = range_a_m + range_b * range,  sigma_bearing = bearing_rad
//   odometry random walk over an increment of distance d and turn dtheta:
//   sigma_t^2 = odometry_q_t (d + 1 mm),  sigma_theta^2 = odometry_q_r (|dtheta| + odometry_c_d d + 1 mrad)
struct RangeBearingNoise {
  double range_a_m = 0.05;
  double range_b = 0.02;  // per metre of range
  double bearing_rad = 0.02;
  double odometry_q_t = 1e-3;  // m^2 per metre travelled
  double odometry_q_r = 1e-3;  // rad^2 per radian turned
  double odometry_c_d = 0.1;   // rad per metre travelled, in the turn's variance
  // The odometry's lag behind the measurements (s): the odometry pose stamped t describes the
  // robot at t + odometry_delay_s (commanded velocities lead the motion they command).
  double odometry_delay_s = 0.0;
  // The range error common to the landmarks of one frame, relative to the range (a scale error,
  // e.g. of the apparent size): stationary sigma and correlation time of a first-order
  // Gauss-Markov process; 0 = none (the range sigma above then holds all the range noise).
  double range_scale_sigma = 0.0;
  double range_scale_time_s = 1.0;
};

// What a range-bearing map build learnt about each dataset's sensor and odometry (map.json
// `range_bearing_sensor`, docs/formats.md): the systematic errors of BiasedRangeBearingFactor
// (factors/range_bearing_factor.h) and of the odometry (factors/calibrated_odometry_factor.h).
struct RangeBearingSensorValues {
  double range_offset_m = 0.0;      // b_range
  double bearing_offset_rad = 0.0;  // b_bearing
  double bearing_scale = 0.0;       // k_bearing
  double depth_share = 0.0;         // c_depth
  double range_scale = 0.0;         // s_range
  Eigen::Vector3d odometry_calibration =
      Eigen::Vector3d::Zero();  // heading drift, turn scale, distance scale
};
struct RangeBearingSensorModel {
  // true: the build read each range as (1 + s) ((1 - c) distance + c depth) + b (c, s estimated);
  // false: as the distance plus b (c = s = 0).
  bool depth_ranges = false;
  struct Dataset {
    std::string name;
    RangeBearingSensorValues values;
    RangeBearingNoise noise;  // the dataset's own noise as the build estimated it
  };
  std::vector<Dataset> datasets;
  // For a robot that is not in the map: the mean and the spread of the datasets' values
  // (mapping/range_bearing_map.h, SensorPrior); a sigma of 0 holds the entry at its mean.
  RangeBearingSensorValues prior_mean, prior_sigma;
  // The correlation time of the odometry's turn scale variation and that variation's stationary
  // sigma, fitted by the build from the datasets' smoothed trajectories against their odometry
  // (mapping/odometry_calibration_time.h; map.json calibration_time_s, calibration_turn_scale_sigma):
  // the EKF's odometry calibration as a Gauss-Markov process of this time. Absent: no fit (a map
  // before 2026-11-26, or no decaying autocovariance: the calibration constant).
  struct CalibrationTime {
    double time_s = 0.0;            // > 0
    double turn_scale_sigma = 0.0;  // >= 0
  };
  std::optional<CalibrationTime> calibration_time;
  // The online EKF's variance factor k (map.json online_variance_factor, > 0): from the mean NEES / 3
  // of the range-bearing EKF run on each mapped dataset against the map of the others (leave one
  // out) with that dataset's smoothed trajectory as the reference, their geometric mean
  // (LeaveOneOutVarianceFactor; waymark map build --calibrate-online; docs/online.md). waymark
  // localize reports k P. Absent: not calibrated (k = 1).
  std::optional<double> online_variance_factor;
};

// A marker in a map (map.json; also ground-truth and known markers).
struct MapMarker {
  MarkerKey key;
  double size_m = 0.0;
  SE3d T_world_marker;                 // meaningful only when has_pose
  std::optional<Matrix6d> covariance;  // right perturbation, tangent order [rx ry rz tx ty tz]
  bool fixed = false;                  // an anchor: held constant by mapping
  std::optional<int> component;        // disconnected maps are numbered 0, 1, ...
  bool has_pose = true;                // false: a size-only entry of a known-markers file
  // Optional rows F_i (6 x k) of the map's low-rank joint covariance, Sigma ~ F F^T + blockdiag(D_i)
  // with D_i = covariance - F_i F_i^T (mapping/map_covariance.h); k is the same for every marker.
  std::optional<CovarianceFactor> covariance_factor = std::nullopt;
  // Family `square` only: its tape (absent: SquareTape's defaults, the paper's 50 mm tape).
  std::optional<SquareTape> square_tape = std::nullopt;
  // A point landmark (map.json `p_world_marker`): a position and no orientation, observed by
  // range and bearing. Its position is T_world_marker.translation() (rotation identity); size_m
  // is 0 and `covariance` unset; position_covariance is its 3 x 3 covariance, world frame.
  bool is_point = false;
  std::optional<Eigen::Matrix3d> position_covariance = std::nullopt;
};

// A rigid board (map.json `boards`): codes whose poses relative to each other are known (a printed
// calibration board, several codes on one shelf face). Each member is also an ordinary marker of
// the map (its size, and in a built map its pose T_world_board * T_board_marker). The board's own
// pose is known (`fixed`), a prior (`covariance`), or unknown (has_pose false, known markers
// only); the map build estimates one pose per board (geometry/board.h, docs/mapping.md).
struct BoardMember {
  MarkerKey key;
  SE3d T_board_marker;
};
struct MapBoard {
  std::string name;
  std::vector<BoardMember> members;
  bool has_pose = false;
  SE3d T_world_board;                  // meaningful only when has_pose
  std::optional<Matrix6d> covariance;  // right perturbation, [rx ry rz tx ty tz], board frame
  bool fixed = false;
  std::optional<int> component;
};

struct MarkerMap {
  std::vector<MapMarker> markers;
  std::optional<RangeBearingNoise> range_bearing_noise;         // map.json `range_bearing_noise`, optional
  std::optional<RangeBearingSensorModel> range_bearing_sensor;  // map.json `range_bearing_sensor`, optional
  std::vector<MapBoard> boards;                                 // map.json `boards`, optional

  // nullptr when absent.
  const MapMarker* Find(const MarkerKey& key) const;
  MapMarker* Find(const MarkerKey& key);
};

enum class CameraModel { kPinholeRadtan, kPinholeEquidistant, kEquisolid };

// "pinhole-radtan" / "pinhole-equidistant" / "equisolid"; ParseCameraModel returns nullopt otherwise.
const char* CameraModelName(CameraModel model);
std::optional<CameraModel> ParseCameraModel(const std::string& name);

// A camera's calibration and mounting (cameras/<name>.yaml). The math is in geometry/camera.h.
struct CameraInfo {
  std::string name;
  CameraModel model = CameraModel::kPinholeRadtan;
  int width = 0;
  int height = 0;
  std::array<double, 4> intrinsics{};  // fx, fy, cx, cy
  std::vector<double> distortion;      // radtan: k1 k2 p1 p2 k3; equidistant, equisolid: k1 k2 k3 k4
  SE3d T_robot_camera;
  std::optional<double> pixel_sigma;  // corner noise, px
  // Prior sigmas [rotation rad, translation m] of T_robot_camera: when set, the map build
  // estimates the mount (extrinsic self-calibration) instead of holding it as given.
  std::optional<std::array<double, 2>> T_robot_camera_sigma;
  // Prior sigmas [rad, m] of the camera's pose in each frame off T_robot_camera (cameras not
  // synchronized with the rig's frame stamp, a rig that flexes): when set, the map build gives
  // every frame of this camera its own small deviation with this prior.
  std::optional<std::array<double, 2>> frame_wiggle_sigma;

  // Number of distortion coefficients the model takes (5 or 4).
  static size_t DistortionSize(CameraModel model) { return model == CameraModel::kPinholeRadtan ? 5 : 4; }
  bool InImage(const Eigen::Vector2d& px) const {
    return px.x() >= 0.0 && px.y() >= 0.0 && px.x() <= width && px.y() <= height;
  }
};

enum class MotionModel { kPlanar, kFree };

// dataset.yaml's odometry_sigma (docs/mapping.md, "Odometry noise models"; the covariance of a
// relative motion: factors/odometry_covariance.h). White terms, per increment of the odometry
// stream, proportional to what the increment moved; random-walk terms, whose variance grows
// linearly with the time and with the distance between two instants whatever the sample rate.
struct OdometrySigma {
  double trans_per_m = 0.0;       // translation noise per metre travelled (white, per increment)
  double rot_per_rad = 0.0;       // rotation noise per radian turned (white, per increment)
  double trans_per_sqrt_s = 0.0;  // m / sqrt(s): position random walk in time (a VIO drifting at rest)
  double rot_per_sqrt_s = 0.0;    // rad / sqrt(s): attitude random walk in time (gyro drift)
  double trans_per_sqrt_m = 0.0;  // m / sqrt(m): position random walk per metre travelled
  double rot_per_sqrt_m = 0.0;  // rad / sqrt(m): heading random walk per metre (wheel radius, VIO yaw drift)
  bool HasRandomWalk() const {
    return trans_per_sqrt_s > 0.0 || rot_per_sqrt_s > 0.0 || trans_per_sqrt_m > 0.0 || rot_per_sqrt_m > 0.0;
  }
};

// One point landmark seen by a range-bearing sensor (range_bearing.jsonl), in the robot frame
// (x forward, y left, z up): range |p_robot|, bearing atan2(p_y, p_x), elevation
// atan2(p_z, hypot(p_x, p_y)). Sigmas are optional (the map build estimates them when absent).
struct RangeBearingObservation {
  MarkerKey key;
  double range_m = 0.0;
  double bearing_rad = 0.0;
  std::optional<double> elevation_rad;
  std::optional<double> sigma_range_m;
  std::optional<double> sigma_bearing_rad;
  std::optional<double> sigma_elevation_rad;
};

// Another robot seen by the same sensor (kept for cooperative methods; the map build ignores it).
struct RobotSighting {
  std::string robot;    // the other robot's dataset name, e.g. robot3
  std::string barcode;  // the code read on it
  double range_m = 0.0;
  double bearing_rad = 0.0;
};

// All range-bearing observations at one stamp (one line of range_bearing.jsonl).
struct RangeBearingFrame {
  double stamp_s = 0.0;
  std::vector<RangeBearingObservation> landmarks;
  std::vector<RobotSighting> robots;
};

// dataset.yaml `start_prior`: T_world_robot at the first odometry stamp, with isotropic sigmas
// on the position and on the rotation (e.g. a robot placed on a known spot).
struct StartPrior {
  SE3d T_world_robot;
  double sigma_m = 0.0;
  double sigma_rad = 0.0;
};

// Coordinates printed inside a code's payload (dataset.yaml `payload`).
struct PayloadSpec {
  std::string pattern;              // regular expression (RE2 syntax) over the decoded text
  std::vector<std::string> fields;  // one name per capture group; x, y, z, yaw_deg are special
  // dataset.yaml `payload.default_z_m`: the height of a code whose text gives x and y but no z
  // (e.g. [Kang]'s floor codes "0/x/y", printed on the floor at z = 0). Unset: z stays unknown.
  std::optional<double> default_z_m = std::nullopt;
};

// One row of images.csv.
struct ImageEntry {
  double stamp_s = 0.0;
  std::string camera;
  std::string path;  // relative to the dataset directory, as written
};

// dataset.yaml, with the paths of its files resolved against the dataset directory.
struct DatasetConfig {
  std::string name;
  MotionModel motion = MotionModel::kPlanar;
  std::vector<std::string> cameras;
  std::optional<double> default_marker_size_m;
  std::optional<OdometrySigma> odometry_sigma;
  std::optional<PayloadSpec> payload;
  std::string odometry_file = "odometry.tum";
  std::string detections_file = "detections.jsonl";
  std::string images_file = "images.csv";
  std::string markers_file = "markers.json";
  std::string range_bearing_file = "range_bearing.jsonl";
  std::optional<StartPrior> start_prior;
};

// Warnings counted while reading (docs/design.md: rejected, never silently used).
struct ReadWarnings {
  std::map<std::string, long> counts;       // reason -> count
  std::vector<std::string> first_messages;  // the first few, with file and line
  void Add(const std::string& reason, const std::string& message);
  long Total() const;
};

// A dataset directory in memory. Optional parts are empty when their file is absent.
struct Dataset {
  std::filesystem::path dir;
  DatasetConfig config;
  std::map<std::string, CameraInfo> cameras;  // by name
  Trajectory odometry;                        // T_odom_robot
  std::vector<DetectionFrame> detections;
  std::vector<ImageEntry> images;
  std::vector<RangeBearingFrame> range_bearing;  // range_bearing.jsonl
  std::optional<MarkerMap> known_markers;
  std::optional<Trajectory> groundtruth_trajectory;  // T_world_robot
  std::optional<MarkerMap> groundtruth_markers;
  std::optional<Trajectory> reference_trajectory;
  std::optional<MarkerMap> reference_markers;
  ReadWarnings warnings;
  bool has_odometry_file = false;
  bool has_detections_file = false;
  bool has_images_file = false;
  bool has_range_bearing_file = false;

  // Size of a marker: known_markers, then default_marker_size_m; nullopt if neither.
  std::optional<double> MarkerSize(const MarkerKey& key) const;
};

}  // namespace waymark
