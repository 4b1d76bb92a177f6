// Components and initial values for the global optimization.
//
// Single views. Every observation gets its single-code pose (core/marker_pose.h, IPPE with
// both solutions of the planar ambiguity): T_robot_marker = T_robot_camera * T_camera_marker.
// Observations whose single view fails (degenerate quad, corner outside the field of view)
// are rejected and counted.
//
// Components. A graph whose nodes are frames and markers, joined by every usable observation
// and every odometry link; its connected groups that hold a marker are the components, numbered
// 0, 1, ... in the order of their first frame. Each has its own world frame. Frames without any
// marker in their group get component -1 (no pose).
//
// Initialization, per component (an incremental, spanning-tree placement):
//   - the root frame (the component's first frame with a usable view) is the identity;
//   - sweeping the frames forward and backward in time, a frame is placed from the placed
//     codes it sees (candidates T_world_robot = T_world_marker * T_robot_marker^-1 from both IPPE
//     solutions, and the odometry prediction T_world_robot_a * M_a_b from a placed neighbour,
//     the one with the least robust reprojection cost wins, then refined by PnP over every
//     placed code of the frame, Cauchy loss), else from odometry alone;
//   - a code is placed from a placed frame by its strongest view: at once when the view is
//     unambiguous (error ratio >= ambiguity_ratio, TagSLAM's gate), otherwise at the end of the
//     sweep from the view with the largest error ratio among placed frames;
//   - sweeps repeat until nothing changes;
//   - then every code is re-placed by consensus over its views (the fused local map of the
//     code): each view's solutions (both, when ambiguous) are candidates, and the candidate with
//     the least summed Cauchy cost over all of the code's views wins. This undoes a code placed
//     from a flipped or misdecoded first view.
// Planar surveys keep every robot pose in SE(2) (z = 0, yaw only).
// Then the component is moved onto its priors: anchors (markers.json entries, fixed or with a
// covariance) give the transform directly (SE(2) for planar surveys); otherwise two or more
// payload positions give yaw and x, y (2-D fit), and the mean z offset of those with z.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/marker_pose.h"
#include "mapping/survey.h"

namespace waymark {

struct InitializerOptions {
  double ambiguity_ratio = 3.0;     // TagSLAM's gate on the two IPPE solutions' errors
  double cauchy_scale = 3.0;        // robust scale, whitened units, for the frame PnP
  int pnp_iterations = 20;
};

// The single view of one observation.
struct SingleView {
  bool usable = false;
  std::string why;                    // when not usable
  std::vector<SE3d> T_robot_marker;   // one or two solutions, best first
  double error_ratio = 0.0;
  double rms_px = 0.0;
  double area_px2 = 0.0;              // image area of the quad
};

struct Initialization {
  std::vector<SingleView> views;                    // per observation
  std::vector<int> frame_component;                 // per frame, -1 without
  std::vector<int> marker_component;                // per marker, -1 without
  int components = 0;
  std::vector<std::optional<SE3d>> T_world_robot;   // per frame
  std::vector<std::optional<SE3d>> T_world_marker;  // per marker
  std::vector<std::string> gauge;                   // per component: how its frame was fixed
};

// Throws std::runtime_error when a camera's calibration is unusable.
std::map<std::string, Camera> MakeCameras(const Survey& survey);

std::vector<SingleView> ComputeSingleViews(const Survey& survey, const std::map<std::string, Camera>& cameras,
                                           double ambiguity_ratio);

// Connected components of the header comment; fills frame_component, marker_component and
// components of `init` from `init->views`.
void FindComponents(const Survey& survey, Initialization* init);

// The consensus placement of the header comment for one marker, given frame poses; nullopt
// when no view of the marker is in a placed frame. At most `max_candidates` views (largest
// error ratio first) propose candidates.
std::optional<SE3d> MarkerByConsensus(const Survey& survey, const std::map<std::string, Camera>& cameras,
                                      const std::vector<SingleView>& views,
                                      const std::vector<std::optional<SE3d>>& T_world_robot, int marker,
                                      double cauchy_scale, size_t max_candidates = 20);

Initialization Initialize(const Survey& survey, const InitializerOptions& options = {});

}  // namespace waymark
