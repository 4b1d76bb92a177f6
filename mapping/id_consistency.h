// Identity check of the observations before initialization: finds views whose decoded id is
// inconsistent with the code's other views (a misdecoded id: code X read as code Y's id).
//
// Odometry drifts, but slowly: between two frames a and b of one odometry segment it is
// trusted to within a distance that grows with the path travelled between them. Each usable
// view o of a code gives the code's centre in the odometry frame,
//   p_o = T_odom_robot(frame_o) * T_robot_camera * t_camera_marker,   r_o = |t_camera_marker|,
// from the single-code pose (geometry/marker_pose.h; both IPPE solutions give nearly the same
// centre). Two views i, j of one code in one segment are consistent when
//   |p_i - p_j| <= base_gate_m + drift_per_m * |L_i - L_j| + range_fraction * (r_i + r_j),
// L = odometry path length from the segment's start to the view's frame. For each code and
// segment, support(i) = number of views consistent with i (itself included); the seed is the
// view of largest support. A view is inconsistent when it is not consistent with the seed and
// 2 * support(i) <= support(seed): a swapped id seen once against a code seen from several
// frames. When no two views agree (support(seed) = 1), all are inconsistent: a code never
// seen itself, only through swapped ids. A view is never set aside within its segment when it
// belongs to a visit of at least min_visit_views views: views linked along the path, each
// consistent with one of the visit_link_window views before it in path order. Between two
// visits of one code the odometry may have drifted by more than any fixed allowance (a VIO with
// 2 deg/m of yaw drift: metres after a loop), while within a visit it has not; a misdecoded id
// is a view or two at the wrong place, not a run of views that agree with each other.
// Across segments (a carry: odometry cannot compare
// positions) the views kept in one segment are inconsistent when they are a lone view and
// another segment's seed has support >= 3, or when another segment's seed has 8 times their
// seed's support. (A code revisited after a carry in a few frames only loses those views: a
// component wrongly split is reported, one wrongly joined through a swapped id is not.) Views in frames
// without odometry are not judged (the global solve's robust loss and outlier gate still see them).
#pragma once

#include <map>
#include <string>
#include <vector>

#include "geometry/camera.h"
#include "mapping/survey.h"

namespace waymark {

struct IdCheckOptions {
  double base_gate_m = 0.25;
  double drift_per_m = 0.05;         // odometry drift allowance per metre of path between views
  double range_fraction = 0.05;      // single-view centre error allowance, fraction of the range
  size_t max_reference_views = 200;  // support is counted against at most this many views
  int min_visit_views = 3;           // a visit of this many linked views is kept (header comment)
  size_t visit_link_window = 5;      // a view links to one of this many previous views (path order)
  bool Check(std::string* why) const;
};

// Indices (into survey.observations) of the inconsistent views, ascending.
std::vector<int> FindInconsistentIds(const Survey& survey, const std::map<std::string, Camera>& cameras,
                                     const IdCheckOptions& options = {});

// The survey without the observations in `removed` (indices into survey.observations); frames,
// markers and odometry are kept, observation indices renumbered.
Survey WithoutObservations(const Survey& survey, const std::vector<int>& removed);

}  // namespace waymark
