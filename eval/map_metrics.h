// Map against map: how far each estimated marker is from its true pose.
//
// Each component c of the estimated map (markers with the same `component`; markers
// without one are component 0) has its own world frame, so each is aligned to the ground
// truth on its own, using the markers present in both maps:
//   - >= 3 markers, not all on one line: SE(3) Umeyama on the marker centres
//       (R, t) = argmin sum_i || p_gt,i - (R p_est,i + t) ||^2         ("positions")
//     "on one line": the true centres' second singular value (centred) is below
//     kMinSpreadRatio times the first, e.g. codes along one wall at one height, where the
//     rotation about the line would be fitted to noise;
//   - otherwise (1 or 2 markers, or nearly collinear centres): from the marker poses themselves
//       R = argmax_R tr(R^T sum_i R_gt,i R_est,i^T)   (chordal mean, by SVD, det = +1)
//       t = mean_i (p_gt,i - R p_est,i)                                   ("poses")
//     exact for a single marker.
// Then, per matched marker i (T_gt_est = (R, t) of its component):
//   position error    e_p,i = || p_gt,i - (R p_est,i + t) ||                      (m)
//   orientation error e_r,i = angle( R_gt,i^T R R_est,i )                        (deg)
// and RMS values sqrt(mean e^2) per component and over all matched markers.
// Markers in only one of the two maps are listed, not counted.
#pragma once

#include <string>
#include <vector>

#include "eval/alignment.h"
#include "geometry/types.h"

namespace waymark::eval {

// Centres whose spread across their main direction is below 5 % of the spread along it
// count as one line (see the header comment).
inline constexpr double kMinSpreadRatio = 0.05;

struct MarkerError {
  MarkerKey key;
  int component = 0;
  double position_error_m = 0.0;
  double orientation_error_deg = 0.0;
};

// kNone: no marker in common; kPointsSE2: a component of point landmarks only (issue 15),
// aligned in the plane, dst = R_z p_est + t by UmeyamaSE2 on >= 2 points; their orientation
// error is 0 (they have none).
enum class MapAlignmentMethod { kPositions, kPoses, kNone, kPointsSE2 };
// "positions", "poses", "none", "points-se2"
const char* MapAlignmentMethodName(MapAlignmentMethod method);

struct ComponentResult {
  int component = 0;
  size_t markers = 0;        // matched with ground truth
  size_t markers_total = 0;  // in the estimated map
  MapAlignmentMethod method = MapAlignmentMethod::kNone;
  Sim3Alignment alignment;  // scale 1
  double position_rmse_m = 0.0;
  double orientation_rmse_deg = 0.0;
};

struct MapEvalResult {
  size_t markers = 0;  // matched
  double position_rmse_m = 0.0;
  double orientation_rmse_deg = 0.0;
  std::vector<ComponentResult> components;        // by component number
  std::vector<MarkerError> per_marker;            // by component, then in the estimated map's order
  std::vector<MarkerKey> missing_in_estimate;     // in the ground truth only
  std::vector<MarkerKey> missing_in_groundtruth;  // in the estimate only
};

// RMS errors of the matched markers whose id matches a pattern, and of the others, from one
// evaluation (each marker keeps its component's alignment, fitted on all of its markers).
// E.g. warehouse-drone's load codes "^1/" against its floor codes.
struct GroupResult {
  std::string pattern;
  size_t markers = 0, markers_other = 0;
  double position_rmse_m = 0.0, orientation_rmse_deg = 0.0;              // ids matching
  double other_position_rmse_m = 0.0, other_orientation_rmse_deg = 0.0;  // the others
};

// `id_pattern`: ECMAScript regular expression searched in the id (std::regex_search);
// throws std::invalid_argument when it does not compile.
GroupResult EvaluateGroup(const MapEvalResult& result, const std::string& id_pattern);

// Throws std::invalid_argument if a map holds the same key twice, and std::runtime_error if
// no marker is in both maps.
MapEvalResult EvaluateMap(const MarkerMap& est, const MarkerMap& gt);

// What EvaluateMap would measure, predicted from an estimated map's own covariances, without
// ground truth: per component, the expected marker position RMS in the map's frame and after the
// rigid alignment ("positions" above). With p_i the centres, c their mean, S the joint covariance
// of the world position errors (from each marker's `covariance` and, when every free marker has
// one, the shared low-rank `covariance_factor`, mapping/map_covariance.h; without it the markers
// count as independent) and A_i = [I3, -[p_i - c]x] (3 x 6, the first-order effect of the
// alignment's translation and rotation on marker i), the alignment removes the projection of the
// errors on the span of A = [A_1; ...; A_N]:
//   E[RMS^2 aligned] = (trace(S) - trace((A^T A)^-1 A^T S A)) / N,   E[RMS^2] = trace(S) / N.
// Fixed markers (anchors) have no error. A component gets no prediction when a free marker has no
// covariance or its centres are nearly collinear (EvaluateMap then aligns by poses).
struct PredictedComponentError {
  int component = 0;
  size_t markers = 0;
  bool joint = false;          // the covariance factor was used (else independent markers)
  double rms_m = 0.0;          // in the map's frame (its gauge: anchors, priors or first frame)
  double aligned_rms_m = 0.0;  // after the rigid alignment
};
std::vector<PredictedComponentError> PredictMapError(const MarkerMap& map);
// The predicted aligned RMS of the whole map: the components' aligned_rms_m pooled by their
// marker counts, sqrt(sum n_c rms_c^2 / sum n_c); nullopt when no component has a prediction.
std::optional<double> PooledAlignedRms(const std::vector<PredictedComponentError>& components);

// The pose-based fit of the header comment; exposed for tests. Sizes equal and >= 1.
Sim3Alignment AlignByPoses(const std::vector<SE3d>& T_est_marker, const std::vector<SE3d>& T_gt_marker);

}  // namespace waymark::eval
