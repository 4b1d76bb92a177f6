// Placement of the local maps (mapping/local_maps.h) at any scale: a pose graph over the maps,
// solved in two stages, with the odometry's systematic errors estimated in the first.
//
// Why two stages. Wheel odometry drifts mostly through constant errors: unequal wheel radii
// bend a straight run into an arc (the sim's corridor: 0.19 deg per metre, 190 degrees round a
// 1 km loop). Composed along the survey, the maps' start values are then hundreds of metres off
// at the end of a long loop, and the link that closes it (a code seen at both ends) is
// thousands of sigmas off: a robust solve ignores it and a plain one may wrap the heading the
// wrong way. Links between maps close together along the odometry, on the other hand, are
// nearly right whatever the drift. So:
//
// Chains and instances. Maps that follow one another by odometry form a chain (LocalMap::chain,
// path_m: odometry path length along it). The maps holding a code, in time order, are cut into
// instances of the code: a new instance starts when the next map is in another chain or more
// than near_path_m of path after the instance's last map. One instance is the code seen over a
// short stretch of odometry, whatever the drift; two instances of one code are a loop closure.
//
// Stage 1 (instances apart). Nodes: T_world_ref of every map and T_world_code of every
// instance (SE(3) blocks; planar surveys are planarized at the end, their odometry holds roll,
// pitch and height), c = [k_rad_per_m, turn_scale, distance_scale] shared by the odometry.
// Factors:
//   odometry links: r = S BoxMinus(C(M, c), T_world_refA^-1 T_world_refB)
//                   (factors/calibrated_odometry_factor.h; the links' summed odometry covariance,
//                   floored at odometry_floor_m / _rad);
//   sightings:      r = S BoxMinus(T_ref_code, T_world_ref^-1 T_world_code)
//                   (factors/odometry_se3_factor.h with the code as frame b; T_ref_code and its
//                   covariance from the map's fusion, times kUnstablePenalty^2 or
//                   kAmbiguousPenalty^2 like RankingSigma), Cauchy loss of scale 3;
//   prior:          r = c / calibration_sigma.
// A code seen from several maps of one instance measures their relative pose (all its codes
// together, with their full covariances), hence the odometry's heading against the images: this
// estimates k and turn_scale. Groups: maps joined by odometry or by an instance; the first map of
// each is held constant. Start: maps composed along their odometry links, instances from their
// most certain sighting. After it, a sighting is an inlier when r^T r <= inlier_chi2.
//
// Heading-drift search. Codes seen close together along the odometry say little about its
// heading drift k (a code's own orientation is good to a degree or so), so a long loop can
// still be off by more than half a turn after stage 1, where no local solve can close it. The
// loop's closures can: for every chain with two instances of one code, its maps are re-composed
// from their stage-1 increments with an extra drift dk (BendChain below) for dk on a grid over
// +-search_max_rad_per_m (step search_step_rad / chain length, then ten times finer around the
// best points), and the dk with the least
//   sum over closures of min(e^2, T^2) / (T / search_truncation_m)^2 + (dk / search_sigma_rad_per_m)^2,
//   e^2 = |p_first - p_later|^2 + (L angle(R_first, R_later))^2,
//   T = max(search_truncation_m, gate_m + gate_per_m d)   (d: path between the two instances)
// is kept (ties: the smaller |dk|); k += dk. The prior term matters: a loop bent by whole extra
// turns can pass near its start again (1 km corridor: 0.72 deg/m off, 1.5 m short; a 1.4 km
// one, 500 x 200 m: two extra turns close within 0.7 m), while the right bend misses by the
// metres that stage 1's other errors leave, which grow with the loop (a corner's turn error
// swings the whole next leg). T is stage 2's gate for the pair: a fixed 5 m made the right bend
// of a 1.4 km loop (more than 5 m off) cost as much as any other, and the prior then chose a
// wrong one or none; scaled so, loops under 90 m keep 5 m and a 1 m sigma, and the coarse step
// (which moves a closure by at most search_step_rad times the loop's extent) stays inside the
// basin.
//
// Stage 2 (closures). Groups are placed relative to each other along a maximum-quality spanning
// forest of the instance pairs of one code in two groups (quality 1 / sigma as RankingSigma over
// both), each group moved rigidly. Every other instance is compared with its code's first
// instance at these poses: with E = T_world_first^-1 T_world_instance and d = |path difference|
// of their first maps (0 in different chains),
//   |t_E| <= gate_m + gate_per_m * d   and   angle(E) <= gate_rad + gate_rad_per_m * d
// merges it into the first (forest pairs merge too); the others stay apart. Then everything is
// solved again from there with the sightings that were inliers of stage 1 under the plain
// squared loss (a true closure must pull the whole loop shut, many sigmas, which a robust loss
// refuses) and the others robust; the first map of each component is held constant, and so is
// c (stage 1's, with the search's dk): a closure or two give three equations, which c's three
// entries would fit exactly whatever the truth (1 km corridor: turn scale 0.08 against a true
// 0.005, codes 7.3 m RMS off; held: 1.9 m). The global solve estimates c again from every corner.
//
// A known c (LocalMapGraphOptions::given_calibration, e.g. an earlier survey's estimate for the
// same robot) is held at its value in both stages, and the heading-drift search is skipped; with
// given_calibration_sigma it is the mean of the prior instead (sigma per entry), and the search
// runs as usual.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "geometry/pose.h"
#include "mapping/local_maps.h"

namespace waymark {

struct LocalMapGraphOptions {
  double near_path_m = 20.0;
  double search_max_rad_per_m = 0.02;     // heading-drift search range (+-), rad per metre
  double search_step_rad = 0.05;          // its step, as heading change over the chain
  double search_truncation_m = 5.0;       // closure mismatch above this counts as this (at least;
                                          // wider for long closures, header comment)
  double search_sigma_rad_per_m = 0.002;  // how far stage 1's k may be off (search prior)
  double inlier_chi2 = 36.0;              // sighting inlier gate after stage 1 (6 whitened residuals)
  double gate_m = 0.5;
  double gate_per_m = 0.05;
  double gate_rad = 0.2;
  double gate_rad_per_m = 0.002;
  double calibration_sigma = 0.05;                         // prior on every entry of c
  std::optional<Eigen::Vector3d> given_calibration;        // c held at this (header comment),
  std::optional<Eigen::Vector3d> given_calibration_sigma;  // or its prior's mean with this sigma
  double odometry_floor_m = 1e-3;
  double odometry_floor_rad = 1e-4;
  int max_iterations = 50;
  bool CalibrationHeld() const { return given_calibration && !given_calibration_sigma; }
  bool Check(std::string* why) const;
};

struct LocalMapGraph {
  std::vector<SE3d> T_world_ref;                                   // per map
  Eigen::Vector3d odometry_calibration = Eigen::Vector3d::Zero();  // c of the header comment
  int groups = 0;                                                  // after stage 1
  int instances = 0;                                               // code instances (nodes of stage 1)
  int sightings = 0;
  int outlying_sightings = 0;  // above inlier_chi2 after stage 1
  int closures_accepted = 0;   // instances merged into their code's first one
  int closures_rejected = 0;
  // Instance pairs considered for stage 2's placement forest: per code, the best instance of
  // each group joined to the code's best one, so at most the number of instances.
  int placement_candidates = 0;
};

// The header comment's two stages; `links` as FindLocalMapLinks gives them (only the odometry
// links are used: the codes enter as sightings). Throws std::runtime_error on bad options.
LocalMapGraph SolveLocalMapGraph(const std::vector<LocalMap>& maps, const std::vector<LocalMapLink>& links,
                                 bool planar, const LocalMapGraphOptions& options = {});

// One line for the build summary: groups, instances, closures, the estimated odometry calibration.
std::string DescribeLocalMapGraph(const LocalMapGraph& graph);

}  // namespace waymark
