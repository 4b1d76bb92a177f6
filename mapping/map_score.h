// Scoring a solution (a map and, optionally, a trajectory) on a dataset's corner observations, so
// that two systems' solutions can be compared on the same observations (ours against a peer's,
// e.g. TagSLAM's reference/ of the tagslam sets).
//
// Reprojection of one corner k of an observation of marker m by camera c in frame f:
//   T_camera_marker = T_robot_camera^-1 * T_world_robot(f)^-1 * T_world_marker(m)
//   e_k = project_c(T_camera_marker * corner_marker_k) - corner_px_k            (px, 2-vector)
// An observation's error is rms_obs = sqrt(sum_k |e_k|^2 / 4); an RMS over several observations is
// over their corners, sqrt(sum |e_k|^2 / (4 n)). Observations whose corners do not project (behind
// the camera, beyond the field of view) are counted apart, never averaged in.
//
// Frame poses T_world_robot(f): from the given trajectory, the pose whose stamp is within
// stamp_tolerance_s of the frame's stamp (never interpolated: a frame the solution has no pose for
// is counted as "without a pose"). Without a trajectory, each frame seeing a mapped marker is
// solved with the map held fixed: candidates T_world_marker * T_robot_marker^-1 from both planar
// solutions of each view, the one with the least summed error wins, then least squares over the
// frame's corners.
//
// Only the frames of another solution (frames_of): frames that trajectory has no pose for (within
// stamp_tolerance_s) are left out and counted apart, so that two solutions, one of which has no
// pose for some frames, are scored on exactly the same observations.
//
// Missing markers (solve_missing_markers): a marker the map lacks, seen from frames with a pose, is
// solved with the frame poses held fixed: the consensus placement of mapping/initializer.h, then
// plain least squares on its corners. This scores a peer whose reference gives the trajectory but
// not every marker: its markers are then the best ones for its trajectory.
//
// Line fit (FitLine): the least-squares 3-D line through points (their centroid and the principal
// direction of their scatter); residuals are perpendicular distances to it.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "geometry/types.h"

namespace waymark {

struct MapScoreOptions {
  double stamp_tolerance_s = 1e-3;  // a trajectory pose serves a frame within this of its stamp
  bool solve_missing_markers = false;
  std::optional<Trajectory> frames_of;  // score only the frames this trajectory has a pose for
  int max_iterations = 100;             // per least-squares solve
  bool Check(std::string* why) const;
};

struct ReprojectionStats {
  std::string name;         // camera name, marker key, or "all"
  size_t observations = 0;  // scored (projected) observations
  double rms_px = 0.0;      // over corners
  double median_px = 0.0;   // of the per-observation rms
  double max_px = 0.0;      // of the per-observation rms
};

struct MapScore {
  ReprojectionStats all;
  std::vector<ReprojectionStats> per_camera;
  std::vector<ReprojectionStats> per_marker;
  size_t observations = 0;                // in the dataset
  size_t without_pose = 0;                // the frame has no pose
  size_t outside_frames_of = 0;           // left out: MapScoreOptions::frames_of has no pose there
  size_t without_marker = 0;              // the marker is not in the map (and was not solved)
  size_t not_projected = 0;               // a corner behind the camera or beyond the field of view
  size_t frames_solved = 0;               // frame poses solved from the map (no trajectory given)
  std::vector<MarkerKey> solved_markers;  // solved with the frames held fixed
  MarkerMap map;                          // the scored map, with the solved markers added
};

struct LineFit {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();       // centroid
  Eigen::Vector3d direction = Eigen::Vector3d::UnitX();  // unit
  double rms_m = 0.0;                                    // of the perpendicular distances
  double max_m = 0.0;
};

// Throws std::runtime_error on bad options, on the dataset errors of mapping/survey.h, and when
// a map marker has a non-positive size.
MapScore ScoreMap(const Dataset& dataset, const MarkerMap& map,
                  const std::optional<Trajectory>& T_world_robot, const MapScoreOptions& options = {});

// Throws std::invalid_argument with fewer than two points or when all points coincide.
LineFit FitLine(const std::vector<Eigen::Vector3d>& points);

// Human-readable report: counts, reprojection RMS overall, per camera and per marker.
std::string FormatMapScore(const MapScore& score);

}  // namespace waymark
