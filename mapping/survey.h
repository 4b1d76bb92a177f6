// Survey ingest: a Dataset (docs/design.md) turned into the indexed problem mapping works on.
//
// Frames. One robot pose per distinct detection stamp: the cameras of one stamp share it
// (stamps closer than IngestOptions::stamp_merge_s are one stamp). Every detection line
// makes a frame, with or without markers, so the smoothed trajectory covers the survey.
//
// Odometry. The odometry file holds T_odom_robot, which drifts; only increments are used.
// Each frame stamp t is looked up at t + delta in the odometry, delta being the odometry's time
// offset (below), and interpolated there (linear in translation, slerp in rotation). A time gap
// between two odometry samples longer than max_odometry_gap_s (the robot carried, a restart)
// splits the odometry into segments; frames in different segments, in a gap or outside the
// odometry's time span get no odometry link between them (reported in Survey::notes): the
// survey never bridges a gap with an increment it did not measure. Between consecutive frames
// a and b of one segment:
//   M_a_b = T_odom_robot(t_a + delta)^-1 * T_odom_robot(t_b + delta)
//   Sigma_a_b = sum over the odometry samples k in [t_a + delta, t_b + delta] of Sigma(M_k,k+1)
//               + sigma_stamp^2 (j_a j_a^T + j_b j_b^T)
//               + diag(e_r^2 I3, e_t^2 I3) at a and at b         (interpolation)
// (sigma_stamp: IngestOptions::stamp_sigma_s, or unsynced_stamp_sigma_s when delta != 0)
// Sigma(M) from factors/odometry_covariance.h and odometry_sigma (the dataset's noise model is
// per increment of its own odometry stream, so the increments' covariances add; the rotation
// sigma of each increment is hypot(rot_per_rad * angle, model_rot_per_m * distance)). The last
// term is the stamp uncertainty: j_a = d BoxMinus(M_a_b, M_a_b(t_a + eps)) / d eps, the motion of
// the odometry per second of clock error at frame a (central differences), likewise j_b; it
// grows with the speed, so a fast, jerky motion between sparse odometry samples is trusted less
// than a slow one, while a standstill keeps the plain model. The interpolation term bounds the
// error of interpolating a frame at fraction s of a sample interval of length D: with a (alpha)
// the largest change of linear (angular) velocity per second between that interval and its
// neighbours, e_t = 0.5 a s (1 - s) D^2 and e_r = 0.5 alpha s (1 - s) D^2 per axis: zero at a
// sample, at constant velocity and for dense odometry, large for a frame in the middle of a
// second-long gap of hand-held motion (tagslam-test22's 4 Hz odometry).
//
// Time offset delta (odometry clock minus image clock). Given (IngestOptions::
// odometry_time_offset_s), or estimated from the survey itself (estimate_time_offset): every
// code seen in two frames a, b at most offset_window_s apart gives, from its single views
// (geometry/marker_pose.h), the robot's displacement |p_b - p_a| in the code's frame and, when both
// views are unambiguous, the rotation angle between the two robot poses; the odometry gives the
// same two figures for M_a_b(delta). With the robust cost
//   C(delta) = mean over the pairs of log(1 + (e_t / s_t)^2) + log(1 + (e_r / s_r)^2),
//   e_t = |p_b - p_a| - |t(M_a_b)|,  s_t = 0.02 m + 0.05 * mean range to the code,
//   e_r = angle(R_a^T R_b) - angle(M_a_b),  s_r = 0.05 rad (single-view precision scales),
// delta is the minimum of C over [-max_time_offset_s, max_time_offset_s] (a 0.05 s grid, then
// 0.005 s around the best). It is applied only when C(delta) <= (1 - time_offset_min_gain) C(0):
// an offset that barely explains the disagreement is noise, and delta stays 0. A constant offset
// is what a mis-stamped odometry topic gives (tagslam-test22: the T265 odometry is stamped about
// half a second off its images).
//
// Square ceiling markers (family `square`) carry no id: their detections are first told apart by
// the odometry (mapping/square_association.h), a line in notes says how many squares.
//
// Errors (std::runtime_error, one line naming the file): a detection for a camera that the
// dataset does not list, a marker without a size (no markers.json entry and no
// default_marker_size_m), a non-finite stamp.
#pragma once

#include <Eigen/Core>
#include <array>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "geometry/payload.h"
#include "geometry/types.h"

namespace waymark {

struct IngestOptions {
  double stamp_merge_s = 1e-6;      // detection stamps closer than this share a robot pose
  double max_odometry_gap_s = 1.0;  // longer gaps between odometry samples split the odometry
  // Used when dataset.yaml has no odometry_sigma.
  OdometrySigma default_odometry_sigma{0.02, 0.02};
  // Allowance for systematic odometry errors that the per-increment model leaves out (a wheel
  // radius or track width error turns straight runs into arcs): a heading noise per metre
  // travelled, added in quadrature to every odometry increment's rotation sigma.
  double model_rot_per_m = 0.0;
  // Uncertainty of the odometry's time alignment to the images (s): the sigma_stamp term of the
  // header comment. stamp_sigma_s applies to odometry on the images' clock (delta = 0); an
  // odometry with a time offset (given or applied) is not hardware-synchronized, and its stamps
  // also jitter (approximate sync), hence unsynced_stamp_sigma_s. 0 turns the term off.
  double stamp_sigma_s = 0.0;
  double unsynced_stamp_sigma_s = 0.02;
  // Time offset of the odometry (odometry clock minus image clock, s). When set, it is used as
  // given; otherwise it is estimated when estimate_time_offset is true (header comment).
  std::optional<double> odometry_time_offset_s;
  bool estimate_time_offset = true;
  bool interpolation_noise = true;    // the interpolation term of the header comment
  double max_time_offset_s = 1.0;     // search range of the estimate
  double offset_window_s = 5.0;       // views of a code at most this far apart are paired
  double time_offset_min_gain = 0.1;  // relative drop of C(delta) below C(0) needed to apply
  bool Check(std::string* why) const;
};

// One code seen in one image.
struct SurveyObservation {
  int frame = 0;   // index into Survey::frames
  int marker = 0;  // index into Survey::markers
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
  std::optional<MapMarker> known;         // entry of markers.json, if any
  std::optional<PayloadData> payload;     // coordinates printed in the payload, if any
  std::optional<SquareTape> square_tape;  // family square: its tape (markers.json entry)
  std::vector<int> observations;
  // On a rigid board (markers.json `boards`, mapping/boards.h): the board's index in
  // Survey::boards and the code's pose on it; -1 otherwise. A board code's `known` is the pose
  // its board's world information gives it (for the initializer), not a prior of its own.
  int board = -1;
  SE3d T_board_marker;
};

// A pose prior of a board: mean and covariance (right perturbation, board frame).
struct BoardPrior {
  SE3d T_world_board;
  Matrix6d covariance;
};

// A rigid board of markers.json as the survey sees it (mapping/boards.h).
struct SurveyBoard {
  std::string name;
  std::vector<int> markers;        // its codes seen in the survey (indices into Survey::markers)
  size_t codes = 0;                // its codes in markers.json
  std::optional<SE3d> fixed_pose;  // held constant at this pose (the board or one of its codes fixed)
  std::vector<BoardPrior> priors;  // pose priors (the board's, or its codes' moved onto it)
  std::string world;               // how its world pose is known, for the summary
};

// Odometry between consecutive frames a < b of one segment.
struct OdometryLink {
  int frame_a = 0;
  int frame_b = 0;
  SE3d T_a_b;                      // M_a_b of the header comment
  Matrix6d covariance_se3;         // [rx ry rz tx ty tz]
  Eigen::Matrix3d covariance_se2;  // [x y theta]
};

struct Survey {
  MotionModel motion = MotionModel::kPlanar;
  std::map<std::string, CameraInfo> cameras;
  std::vector<SurveyFrame> frames;  // by stamp
  std::vector<SurveyMarker> markers;
  std::vector<SurveyObservation> observations;
  std::vector<OdometryLink> odometry_links;
  std::vector<SurveyBoard> boards;
  int odometry_segments = 0;
  double odometry_time_offset_s = 0.0;  // delta applied (header comment)
  double odometry_stamp_sigma_s = 0.0;  // sigma_stamp used (header comment)
  std::vector<std::string> notes;       // odometry gaps and other facts worth a line in the summary

  int FindMarker(const MarkerKey& key) const;  // -1 when absent
};

// Throws std::runtime_error on the errors of the header comment and on bad options.
Survey IngestDataset(const Dataset& dataset, const IngestOptions& options = {});

// The time offset estimate of the header comment.
struct TimeOffsetEstimate {
  double offset_s = 0.0;      // argmin of C
  double cost = 0.0;          // C(offset_s)
  double cost_at_zero = 0.0;  // C(0)
  size_t pairs = 0;           // view pairs in C(0)
  bool applied = false;       // the gain test passed
};

// Estimates delta for a survey whose frames and observations are filled (odometry not yet
// attached); nullopt when fewer than 10 view pairs have odometry at both ends.
std::optional<TimeOffsetEstimate> EstimateOdometryTimeOffset(const Survey& survey, const Trajectory& odometry,
                                                             const IngestOptions& options);

}  // namespace waymark
