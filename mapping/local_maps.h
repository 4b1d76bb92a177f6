// Local maps ([George]) and the links that stitch them.
//
// Local map. A run of consecutive frames of one component, all joined by odometry, ending when
// the odometry since its first frame (the reference, `ref`) has travelled more than
// max_travel_m, turned more than max_turn_rad, or holds max_frames frames; a frame without an
// odometry link to the previous one starts a new map, so without odometry every frame is its
// own local map. Inside a map the frames are placed by odometry:
//   T_ref_robot(f) = M_ref_f1 * M_f1_f2 * ... * M_fk_f        (survey odometry links)
// Each code seen in the map gets one fused pose T_ref_marker (FuseMarkerViews below) over
// all its views in the map, with its covariance and a stability verdict.
//
// Fusion of one code over n views v (camera poses T_ref_camera(v) known):
//   r_v = (project(T_ref_camera(v)^-1 * T_ref_marker * corner_marker_k) - corner_px_vk) / sigma_px
//   minimize sum_v rho(|r_v|^2),  rho(s) = c^2 log(1 + s / c^2)    (Cauchy, c = cauchy_scale)
// by Levenberg-Marquardt over the right perturbation T_ref_marker * Exp([dr, dt]), from each
// seed: the two IPPE solutions of the code's least ambiguous view (the planar-square
// ambiguity). The seed with the lower robust cost wins; chi2 = sum_v |r_v|^2 at the winner and
// alt_chi2 at the other branch (if it converged to a rotation more than 2 degrees away). The
// flip is resolved when alt_chi2 - chi2 >= flip_chi2 (the fused form of TagSLAM's error-ratio
// gate), or when a single view is already unambiguous (error ratio >= ambiguity_ratio).
// (Tried and dropped: deciding by the sum over views of each view's own IPPE error evidence,
// which ignores the frame poses; on sim rooms seeds 1..5 it left more codes flipped.)
//   covariance = (sum_v w_v J_v^T J_v)^-1 * max(1, chi2 / (8 n - 6)), tangent [rx ry rz tx ty tz]
// (w_v the Cauchy weights at the solution).
// Variance-based rejection ([George] ignores codes whose corners vary too much): a code is
// unstable in a map when its residual RMS per coordinate, sqrt(chi2 / (8 n)),
// exceeds max_rms_sigma sigmas (views that disagree:
// a moving or misread code) or when the predicted position sigma of the fused pose exceeds
// max_position_sigma_m (far, small codes). Unstable codes are reported and only link maps
// that nothing else links.
//
// Link quality. Two local maps A, B that both hold code m give
//   T_A_B = T_A_m * T_B_m^-1
// whose error is that of both fused poses: with q = T_B_m^-1 * 0 (B's reference in the marker
// frame) and D(q) = [-Hat(q), I] (marker-frame point error for a perturbation [dr, dt]),
//   sigma_position^2 = tr(D Sigma_A D^T) + tr(D Sigma_B D^T),  sigma_rotation^2 = tr(Sigma_A,rr) +
//   tr(Sigma_B,rr) sigma_link = sqrt(sigma_position^2 + (kLinkLeverM sigma_rotation)^2),  quality = 1 /
//   sigma_link (1/m)
// i.e. the error of B's frame at its origin and 1 m away. Consecutive local maps are also
// linked by odometry, sigma from the summed odometry covariance plus a systematic allowance
// (odometry_systematic times the distance travelled and the angle turned). An ambiguous (not
// resolved) code's link is divided by kAmbiguousPenalty, an unstable one's by kUnstablePenalty.
// Each local map holding code m is linked to the code's two best local maps (smallest own
// sigma), so the number of links grows linearly with the observations.
//
// Stitching: mapping/local_map_graph.h places the maps by a pose graph over the odometry links
// and the codes' sightings. SpanningForest and PlaceLocalMaps below give a maximum-quality
// spanning forest of links (Kruskal), one tree per component, rooted at its first map
// (T_world_ref = identity), placed by composing the tree's link transforms outwards
// (planarized for planar surveys); the graph uses them for its start values.
#pragma once

#include <limits>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "geometry/camera.h"
#include "geometry/pose.h"
#include "mapping/survey.h"

namespace waymark {

struct SingleView;  // mapping/initializer.h

inline constexpr double kLinkLeverM = 1.0;
inline constexpr double kAmbiguousPenalty = 100.0;
inline constexpr double kUnstablePenalty = 1e4;

struct LocalMapOptions {
  double max_travel_m = 0.5;
  double max_turn_rad = 1.6;  // about 90 degrees
  int max_frames = 60;
  double ambiguity_ratio = 3.0;  // single-view gate (geometry/marker_pose.h)
  double flip_chi2 = 9.0;        // fused gate: alt_chi2 - chi2 for a resolved flip
  double cauchy_scale = 3.0;     // whitened units
  double max_rms_sigma = 3.0;    // residual RMS per coordinate, in sigmas, above which a code is unstable
  double max_position_sigma_m = 0.05;
  double odometry_systematic = 0.03;  // allowance per metre travelled and per radian turned
  int max_iterations = 15;
  bool Check(std::string* why) const;
};

// One view of a code for fusion: the camera and its pose in the fusion frame.
struct FusionView {
  const Camera* camera = nullptr;
  SE3d T_frame_camera;
  const std::array<Eigen::Vector2d, 4>* corners_px = nullptr;
  double sigma_px = 1.0;
};

struct FusedPose {
  SE3d T_frame_marker;
  Matrix6d covariance = Matrix6d::Identity();                 // right perturbation [rx ry rz tx ty tz]
  double chi2 = 0.0;                                          // at the winner, whitened
  double alt_chi2 = std::numeric_limits<double>::infinity();  // other branch, +inf if none
  double robust_cost = 0.0;
  int views = 0;           // views that project at the winner
  double rms_sigma = 0.0;  // residual RMS per coordinate, in sigmas (about 1 for pure noise)
  double position_sigma_m = 0.0;
  bool resolved = false;  // flip branch decided (header comment)
  bool stable = false;
  std::string why;  // when not stable
};

// The fusion view of one observation whose robot is at T_frame_robot.
FusionView MakeFusionView(const Camera& camera, const SE3d& T_frame_robot, const SurveyObservation& obs);

// Fuses the views from the given seeds (header comment); nullopt when no seed has a view that
// projects. `single_view_unambiguous`: some view's error ratio passed the single-view gate.
std::optional<FusedPose> FuseMarkerViews(const std::vector<FusionView>& views, double size_m,
                                         const std::vector<SE3d>& seeds, bool single_view_unambiguous,
                                         const LocalMapOptions& options);

struct LocalMap {
  int component = -1;
  std::vector<int> frames;         // first one is the reference
  std::vector<SE3d> T_ref_robot;   // per entry of `frames`
  std::map<int, FusedPose> codes;  // marker -> fused pose in the ref frame
  double travel_m = 0.0;
  double turn_rad = 0.0;
  // Chains: maps following one another by odometry (each map's first frame has an odometry link
  // from the previous map's last frame) share a chain number; path_m is the odometry path length
  // from the chain's first frame to this map's reference (mapping/local_map_graph.h).
  int chain = -1;
  double path_m = 0.0;
};

struct LocalMapLink {
  int map_a = 0;
  int map_b = 0;
  int marker = -1;       // the shared code; -1 for an odometry link
  SE3d T_a_b;            // T_refA_refB
  double sigma_m = 0.0;  // header comment
  double quality = 0.0;  // 1 / sigma_m, after penalties
  // Odometry links: the summed covariance of their odometry steps, [rx ry rz tx ty tz], without
  // the systematic allowance (mapping/local_map_graph.h estimates the systematic errors instead).
  Matrix6d odometry_covariance = Matrix6d::Zero();
};

// Local maps of every component (frames with component -1 belong to none), in time order.
std::vector<LocalMap> BuildLocalMaps(const Survey& survey, const std::map<std::string, Camera>& cameras,
                                     const std::vector<SingleView>& views,
                                     const std::vector<int>& frame_component, const LocalMapOptions& options);

// Code links (each map to the code's two best maps) and odometry links between consecutive maps.
std::vector<LocalMapLink> FindLocalMapLinks(const Survey& survey, const std::vector<LocalMap>& maps,
                                            const LocalMapOptions& options);

// Maximum-quality spanning forest: the indices of the chosen links.
std::vector<int> SpanningForest(int num_maps, const std::vector<LocalMapLink>& links);

// T_world_ref of every map from the forest: the first map (lowest index) of each tree is the
// identity, the others follow its links outwards. Planarized when `planar`.
std::vector<SE3d> PlaceLocalMaps(int num_maps, const std::vector<LocalMapLink>& links,
                                 const std::vector<int>& forest, bool planar);

// sqrt(tr Sigma_tt + kLinkLeverM^2 tr Sigma_rr) of a fused pose, times kUnstablePenalty when
// unstable or kAmbiguousPenalty when its flip is not resolved: ranks a code's local maps.
double RankingSigma(const FusedPose& fused);

// Position sigma (m) of a point q (marker frame) under a pose covariance: sqrt(tr(D Sigma D^T)).
double PointSigma(const Matrix6d& covariance, const Eigen::Vector3d& q_marker);

}  // namespace waymark
