// Components and initial values for the global optimization.
//
// Single views. Every observation gets its single-code pose (geometry/marker_pose.h, IPPE with
// both solutions of the planar ambiguity): T_robot_marker = T_robot_camera * T_camera_marker.
// Observations whose single view fails (degenerate quad, corner outside the field of view)
// are rejected and counted.
//
// Components. A graph whose nodes are frames and markers, joined by every usable observation
// and every odometry link; its connected groups that hold a marker are initialized apart, each
// in its own frame. After the alignment onto priors (below), the groups holding anchors are all
// in the world frame and become one component (MergeWorldComponents in initializer.cc); the
// components are numbered 0, 1, ... in the order of their first frame, and only groups without
// anchors keep a frame of their own. Frames without any marker in their group get component -1
// (no pose).
//
// Initialization, per component, by local maps stitched along a spanning tree
// (mapping/local_maps.h has the equations):
//   - the frames are cut into local maps (short odometry runs; without odometry one frame
//     each); inside a map, frames are placed by odometry and every code seen gets one pose
//     fused over its views, both branches of the planar ambiguity tried, unstable ones marked;
//   - local maps are linked by shared codes (quality 1 / predicted error of the link) and by
//     odometry, and placed by a pose graph over the links in two stages, which estimates the
//     odometry's systematic errors from the links between maps close along the odometry before
//     it closes the long loops (mapping/local_map_graph.h); the component's first local map
//     stays at the identity;
//   - every frame gets T_world_ref * T_ref_robot; every code the pose of its most certain
//     local map;
//   - then every code is re-fused over all its views at the placed frames (seeds: its pose
//     and both solutions of its least ambiguous views; the lowest robust cost wins, which
//     undoes a flipped or misdecoded first view), frames seeing codes are refined by PnP
//     against them (Cauchy loss), and codes are fused once more.
// Planar surveys keep every robot pose in SE(2) (z = 0, yaw only).
// Then each group is moved onto its priors: a fixed anchor gives the transform directly (the
// one the other anchors agree with best); anchors that are priors each propose one, the one the
// others agree with best (Cauchy cost of their whitened misfits) is taken, and replaced by a
// weighted Kabsch fit of the positions of the anchors within 3 sigma of it (>= 3, not collinear)
// when that agrees better (SE(2) for planar surveys). Otherwise two or more payload positions
// give yaw and x, y (2-D fit), and the mean z offset of those with z.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "geometry/camera.h"
#include "geometry/marker_pose.h"
#include "mapping/build_stats.h"
#include "mapping/local_map_graph.h"
#include "mapping/local_maps.h"
#include "mapping/survey.h"

namespace waymark {

struct InitializerOptions {
  double ambiguity_ratio = 3.0;  // TagSLAM's gate on the two IPPE solutions' errors
  double cauchy_scale = 3.0;     // robust scale, whitened units, for the frame PnP and fusion
  int pnp_iterations = 20;
  int refine_rounds = 2;  // frames by PnP, then codes fused again (header comment)
  // Local maps; its ambiguity_ratio and cauchy_scale are taken from the two fields above.
  LocalMapOptions local_maps;
  LocalMapGraphOptions graph;  // their placement (mapping/local_map_graph.h)
};

// The single view of one observation.
struct SingleView {
  bool usable = false;
  std::string why;                   // when not usable
  std::vector<SE3d> T_robot_marker;  // one or two solutions, best first
  double error_ratio = 0.0;
  double rms_px = 0.0;
  double area_px2 = 0.0;  // image area of the quad
};

struct Initialization {
  std::vector<SingleView> views;      // per observation
  std::vector<int> frame_component;   // per frame, -1 without
  std::vector<int> marker_component;  // per marker, -1 without
  int components = 0;
  std::vector<std::optional<SE3d>> T_world_robot;   // per frame
  std::vector<std::optional<SE3d>> T_world_marker;  // per marker
  std::vector<std::string> gauge;                   // per component: how its frame was fixed
  // Local maps and their stitching (mapping/local_maps.h).
  std::vector<LocalMap> local_maps;
  std::vector<LocalMapLink> links;          // every candidate link
  std::vector<int> tree;                    // indices into `links`: the spanning forest
  std::vector<double> marker_link_quality;  // per marker: best quality of a link through it, 0 if none
  // The odometry's systematic errors estimated with the placement (mapping/local_map_graph.h):
  // [k_rad_per_m, turn_scale, distance_scale] of factors/calibrated_odometry_factor.h.
  Eigen::Vector3d odometry_calibration = Eigen::Vector3d::Zero();
  std::vector<std::string> notes;  // facts for the build summary
  std::vector<PhaseTime> phases;   // single views, local maps, graph, refinement
};

// Lines for the build summary: local maps, links in the tree (code / odometry), the weakest
// tree link, codes unstable in some local map or with an unresolved flip.
std::vector<std::string> DescribeInitialization(const Survey& survey, const Initialization& init);

// Throws std::runtime_error when a camera's calibration is unusable.
std::map<std::string, Camera> MakeCameras(const Survey& survey);

std::vector<SingleView> ComputeSingleViews(const Survey& survey, const std::map<std::string, Camera>& cameras,
                                           double ambiguity_ratio);

// Connected components of the header comment; fills frame_component, marker_component and
// components of `init` from `init->views`.
void FindComponents(const Survey& survey, Initialization* init);

// The consensus placement of the header comment for one marker, given frame poses: the code
// fused over all its views in placed frames (mapping/local_maps.h), seeded by both solutions
// of at most `max_candidates` views (largest error ratio first; seeds closer than 3 degrees
// to one already tried are skipped); nullopt when no view of the marker is in a placed frame.
std::optional<SE3d> MarkerByConsensus(const Survey& survey, const std::map<std::string, Camera>& cameras,
                                      const std::vector<SingleView>& views,
                                      const std::vector<std::optional<SE3d>>& T_world_robot, int marker,
                                      double cauchy_scale, size_t max_candidates = 20);

// The planar-flip check at solved frame poses. Inside a local map the frames come from odometry,
// whose few tenths of a degree of error are pixels on a code 2 m away, so a code seen from one
// place can keep the wrong branch of the planar ambiguity through the initialization; once the
// global solve has placed every frame from all the views and the odometry, the branches are
// compared again at those frames. The other branch of `current` is its mirror about the mean
// viewing ray v (unit, from the code centre towards the cameras seeing it):
//   n' = 2 (n . v) v - n      (n the code's normal, z of T_world_marker; the centre stays),
// i.e. the rotation by twice the angle between n and v about n x v. The code is fused over all
// its views at T_world_robot from both (mapping/local_maps.h, FuseMarkerViews); the result is the
// fused pose when it lies on the other branch (more than kFlipCheckMinRad from `current`) and
// the flip is resolved (alt_chi2 - chi2 >= options.flip_chi2), nullopt otherwise (current
// branch kept, code seen head-on, no view in a placed frame).
inline constexpr double kFlipCheckMinRad = 0.1;
std::optional<SE3d> OtherFlipBranch(const Survey& survey, const std::map<std::string, Camera>& cameras,
                                    const std::vector<SingleView>& views,
                                    const std::vector<std::optional<SE3d>>& T_world_robot, int marker,
                                    const SE3d& current, const LocalMapOptions& options);

Initialization Initialize(const Survey& survey, const InitializerOptions& options = {});

}  // namespace waymark
