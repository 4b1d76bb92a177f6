// Survey ingest: a Dataset (DESIGN.md) turned into the indexed problem mapping works on.
//
// Frames. One robot pose per distinct detection stamp: the cameras of one stamp share it
// (stamps closer than IngestOptions::stamp_merge_s are one stamp). Every detection line
// makes a frame, with or without markers, so the smoothed trajectory covers the survey.
//
// Odometry. The odometry file holds T_odom_robot, which drifts; only increments are used.
// Each frame stamp is interpolated inside the odometry (linear in translation, slerp in
// rotation). A time gap between two odometry samples longer than max_odometry_gap_s (the
// robot carried, a restart) splits the odometry into segments; frames in different segments,
// in a gap or outside the odometry's time span get no odometry link between them (reported
// in Survey::notes). Between consecutive frames a and b of one segment:
//   M_a_b = T_odom_robot(t_a)^-1 * T_odom_robot(t_b)
//   Sigma_a_b = sum over the odometry samples k in [t_a, t_b] of Sigma(M_k,k+1)
//   (rotation sigma of each increment: hypot(rot_per_rad * angle, model_rot_per_m * distance))
// with Sigma from factors/odometry_covariance.h and odometry_sigma (the dataset's noise model
// is per increment of its own odometry stream, so the increments' covariances add).
//
// Errors (std::runtime_error, one line naming the file): a detection for a camera that the
// dataset does not list, a marker without a size (no markers.json entry and no
// default_marker_size_m), a non-finite stamp.
#pragma once

#include <array>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/payload.h"
#include "core/types.h"

namespace waymark {

struct IngestOptions {
  double stamp_merge_s = 1e-6;         // detection stamps closer than this share a robot pose
  double max_odometry_gap_s = 1.0;     // longer gaps between odometry samples split the odometry
  // Used when dataset.yaml has no odometry_sigma.
  OdometrySigma default_odometry_sigma{0.02, 0.02};
  // Allowance for systematic odometry errors that the per-increment model leaves out (a wheel
  // radius or track width error turns straight runs into arcs): a heading noise per metre
  // travelled, added in quadrature to every odometry increment's rotation sigma.
  double model_rot_per_m = 0.0;
  bool Check(std::string* why) const;
};

// One code seen in one image.
struct SurveyObservation {
  int frame = 0;      // index into Survey::frames
  int marker = 0;     // index into Survey::markers
  std::string camera;
  std::array<Eigen::Vector2d, 4> corners_px;
  size_t detection_line = 0;  // index of the DetectionFrame in Dataset::detections
};

struct SurveyFrame {
  double stamp_s = 0.0;
  std::optional<SE3d> T_odom_robot;  // interpolated; nullopt outside the odometry or in a gap
  int segment = -1;                  // odometry segment, -1 without odometry
  std::vector<int> observations;     // indices into Survey::observations
};

struct SurveyMarker {
  MarkerKey key;
  double size_m = 0.0;
  std::optional<MapMarker> known;     // entry of markers.json, if any
  std::optional<PayloadData> payload; // coordinates printed in the payload, if any
  std::vector<int> observations;
};

// Odometry between consecutive frames a < b of one segment.
struct OdometryLink {
  int frame_a = 0;
  int frame_b = 0;
  SE3d T_a_b;                    // M_a_b of the header comment
  Matrix6d covariance_se3;       // [rx ry rz tx ty tz]
  Eigen::Matrix3d covariance_se2;  // [x y theta]
};

struct Survey {
  MotionModel motion = MotionModel::kPlanar;
  std::map<std::string, CameraInfo> cameras;
  std::vector<SurveyFrame> frames;  // by stamp
  std::vector<SurveyMarker> markers;
  std::vector<SurveyObservation> observations;
  std::vector<OdometryLink> odometry_links;
  int odometry_segments = 0;
  std::vector<std::string> notes;  // odometry gaps and other facts worth a line in the summary

  int FindMarker(const MarkerKey& key) const;  // -1 when absent
};

// Throws std::runtime_error on the errors of the header comment and on bad options.
Survey IngestDataset(const Dataset& dataset, const IngestOptions& options = {});

// T_odom_robot at `stamp_s`, interpolated between the samples around it; nullopt outside the
// trajectory's span or when the samples around it are more than max_gap_s apart.
std::optional<SE3d> InterpolatePose(const Trajectory& trajectory, double stamp_s, double max_gap_s);

}  // namespace waymark
