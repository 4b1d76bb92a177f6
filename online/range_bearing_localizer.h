// EKF localization of a planar robot against a map of point landmarks from range-bearing
// observations (range_bearing.jsonl; mapping/range_bearing_map.h builds such maps).
//
// State x = [x, y, theta, k, s_turn, s_dist, b_range, b_bearing, s_range, k_bearing, c_depth, s_robot, f]:
// T_world_robot, the odometry's constant errors (heading drift k in rad/m, turn scale, distance scale; as
// factors/calibrated_odometry_factor.h, to first order), the sensor's constant range and
// bearing offsets (as BiasedRangeBearingFactor) and the range scale error common to a frame's
// landmarks (noise.range_scale_sigma, a first-order Gauss-Markov process of correlation time
// tau = noise.range_scale_time_s) and the sensor's bearing scale error k_bearing (as
// BiasedRangeBearingFactor) and c_depth, the share of a range that is the landmark's depth along
// the sensor's axis p_x = r cos(beta) rather than its distance r (a camera that ranges a code from
// its apparent size measures its depth: c_depth = 1 reads a landmark at 0.5 rad 12 % short) and
// s_robot, the sensor's constant range scale error (the build's s_range per dataset), covariance P
// (12 x 12, the same order); the calibration, the offsets, k_bearing, c_depth and s_robot start at
// their *_mean with calibration_sigma, sensor_bias_sigma, bearing_scale_sigma, depth_share_sigma and
// range_scale_state_sigma (the last two 0 by default: held at their mean, 0) and have no process
// noise (a sigma of 0 holds its entry); s_range starts at 0 with variance range_scale_sigma^2.
// SensorPriorFromMap sets the means and sigmas from the map's range_bearing_sensor (the spread of
// the mapped robots' values: a robot of the same fleet), which bounds the odometry calibration to
// what the fleet's robots showed instead of a weak constant prior. Predict with an odometry increment M =
// (t_M, theta_M) in the robot frame, s = |t_M|:
//   t_C = (1 + s_dist) t_M,  theta_C = (1 + s_turn + f) theta_M + k s   (the corrected increment; f the
//   turn scale's fast fluctuation, a Gauss-Markov process: f' = phi_f f, phi_f = exp(-dt / tau_f), variance
//   turn_fluctuation_sigma^2 (1 - phi_f^2) added; F[2, 12] = theta_M, F[12, 12] = phi_f)
//   x' = [t + R(theta) t_C, theta + theta_C, c' = m + phi_c (c - m) for c = (k, s_turn, s_dist), b_range,
//         b_bearing, phi s_range, k_bearing, c_depth, s_robot]
//   F  = d x'/d x = I12 with F[0:2, 2] = [-(R t_C)_y, (R t_C)_x], F[0:2, 5] = R(theta) t_M,
//        F[2, 3] = s, F[2, 4] = theta_M, F[8, 8] = phi = exp(-dt / tau) (dt: the increment's duration),
//        F[3+i, 3+i] = phi_c,i = exp(-dt / calibration_time_s[i]) (1 for a constant entry)
//   G  = d x'/d M (pose rows) = blockdiag(R(theta), 1)
//   P' = F P F^T + G Q G^T,  Q = diag(q_t (d + d0), q_t (d + d0), q_r (|theta_M| + c_d d + th0)), d = |t_M|
//   (the random walk of mapping/range_bearing_map.h, d0 = 1 mm, th0 = 1 mrad), and
//   q_s = range_scale_sigma^2 (1 - phi^2) on s_range, and calibration_sigma[i]^2 (1 - phi_c,i^2) on
//   calibration entry i when calibration_time_s[i] > 0 (a first-order Gauss-Markov process about the
//   prior's mean m = calibration_mean: odometry whose turn and distance scales vary with the floor,
//   the load and the wheels' slip; 0: a constant, the default).
// Update with a landmark l (2-D; the map's position, or as the augmented state holds it, below):
//   d = l - t, q = |d|^2, r = sqrt(q), beta = wrap(atan2(d_y, d_x) - theta),
//   p_x = cos(theta) d_x + sin(theta) d_y, p_y = -sin(theta) d_x + cos(theta) d_y (the landmark in
//   the robot frame), rho = (1 - c_depth) r + c_depth p_x,
//   h(x) = [(1 + s_range + s_robot) rho + b_range, wrap((1 + k_bearing) beta + b_bearing)]
//   H = [[(1 + s_range + s_robot) ((1 - c_depth) [-d_x/r, -d_y/r, 0] + c_depth [-cos(theta), -sin(theta),
//   p_y]),
//         0 0 0, 1, 0, rho, 0, (1 + s_range + s_robot) (p_x - r), rho],
//        [(1 + k_bearing) [d_y/q, -d_x/q, -1], 0 0 0, 0, 1, 0, beta, 0, 0]], H_l = -H[:, 0:2],  y = [range -
//        h_0, wrap(bearing - h_1)],  S = H P H^T + R (the augmented form below),
//   R = diag(sigma_w^2, sigma_bearing^2), sigma_w^2 = max(sigma_range(range)^2 - (range_scale_sigma
//   range)^2, range_a_m^2) (the range variance less its common part; an observation's own sigma as given)
//   gate: y^T S^-1 y <= gate_chi2 (2 dof), else the observation is a gross outlier (counted);
//   K = P H^T S^-1 (LLT), x += K y, P = (I - K H) P (I - K H)^T + K R' K^T (Joseph), symmetrized.
//   Iterated (options update_iterations, relocalization_iterations > 1): x_{i+1} = x_prior + K_i (z -
//   h(x_i) - H_i (x_prior - x_i)), H_i and K_i at x_i (Gauss-Newton on the prior and the sighting),
//   P from the last H_i and K_i; the gate on the first linearization.
// The map's landmark errors (map_uncertainty). A landmark's map error eps_l = l_true - l_map is one
// draw that every sighting of it shares, and the landmarks' errors are correlated (map.json
// position_covariance and position_covariance_factor, mapping/range_bearing_map.h; in memory
// MapMarker::position_covariance and the translation rows 3, 4 of MapMarker::covariance_factor):
//   eps_l = F_l xi + eta_l,  xi ~ N(0, I_k) common to all landmarks,  eta_l ~ N(0, D_l),
//   D_l = Sigma_l - F_l F_l^T  (Sigma_l the 2 x 2 position covariance; without a factor k = 0, D_l =
//   Sigma_l),
// kEstimate and kConsider augment the state with xi (k entries, from the start, N(0, I)) and with
// eta_l of every landmark seen (2 entries, added at its first sighting with mean 0, covariance D_l
// and no correlation; at most max_landmark_states landmarks, the least recently seen one dropped
// (marginalized) for a new one: a landmark dropped and seen again starts afresh). The update uses
// the landmark at l = l_map + F_l xi + eta_l:
//   H_aug = [H, H_l F_l, H_l (at eta_l's entries), 0 elsewhere],  H_l = dh/dl = -H[:, 0:2],
//   S = H_aug P_aug H_aug^T + R,  K = P_aug H_aug^T S^-1,
//   P_aug = P_aug - K (H_aug P_aug) - (H_aug P_aug)^T K^T + K S K^T   (the Joseph form, expanded).
// kEstimate updates xi and eta too (the map is refined by the robot's own sightings); kConsider
// (Schmidt) zeroes their rows of K, so their mean stays 0 and their own covariance stays the map's,
// while their correlation with the robot's state is kept. Either way a repeated sighting of a
// landmark does not count its map error as new information. kInNoise (the earlier behaviour) adds
// H_l Sigma_l H_l^T to R at every sighting (each sighting's map error independent); kIgnore takes
// the map as exact. Prediction: F_aug = blockdiag(F, I), the noise on the robot's state only.
// A landmark absent from the map (an unknown or misread code) is rejected and counted.
// Lost: the position's largest standard deviation exceeds lost_sigma_m, or lost_rejections
// observations in a row failed the gate (then P is inflated to reacquire_sigma_m /
// reacquire_sigma_rad so that the gate can accept again); the track is regained after
// regain_updates accepted updates in a row with the position's sigma below lost_sigma_m. No pose
// is output while lost.
#pragma once

#include <Eigen/Core>
#include <map>
#include <optional>
#include <string>
#include <utility>

#include "geometry/pose.h"
#include "geometry/types.h"

namespace waymark {

// Why a noise model is unusable ("" when fine).
std::string CheckRangeBearingNoise(const RangeBearingNoise& noise);

enum class RangeBearingMapUncertainty { kEstimate, kConsider, kInNoise, kIgnore };
// "estimate", "consider", "in-noise", "ignore"; nullopt for other names.
std::optional<RangeBearingMapUncertainty> ParseRangeBearingMapUncertainty(const std::string& name);

struct RangeBearingLocalizerOptions {
  RangeBearingNoise noise;
  double gate_chi2 = 13.8155;  // 2 dof, 99.9 %
  double lost_sigma_m = 0.5;
  int lost_rejections = 10;
  double reacquire_sigma_m = 1.0;
  double reacquire_sigma_rad = 0.3;
  int regain_updates = 3;
  // The calibration's start and its sigmas: k (rad/m), turn scale, distance scale.
  Eigen::Vector3d calibration_mean = Eigen::Vector3d::Zero();
  Eigen::Vector3d calibration_sigma = Eigen::Vector3d(0.05, 0.2, 0.2);
  // The calibration's correlation time (s) per entry: > 0 makes the entry a first-order
  // Gauss-Markov process about calibration_mean with stationary sigma calibration_sigma (an entry
  // no sighting observes relaxes to its prior instead of keeping a confident wrong value); 0
  // (default): constant, as before.
  Eigen::Vector3d calibration_time_s = Eigen::Vector3d::Zero();
  // The turn scale's fast fluctuation f (state 12) about the robot's own constant turn scale: a
  // first-order Gauss-Markov process of stationary sigma turn_fluctuation_sigma and correlation
  // time turn_fluctuation_time_s (both > 0 to use it; else f is held at 0, as before).
  double turn_fluctuation_sigma = 0.0;
  double turn_fluctuation_time_s = 0.0;
  // The sensor's range offset (m) and bearing offset (rad) at the start, and their sigmas.
  Eigen::Vector2d sensor_bias_mean = Eigen::Vector2d::Zero();
  Eigen::Vector2d sensor_bias_sigma = Eigen::Vector2d(0.2, 0.05);
  // The sensor's bearing scale error at the start, and its sigma.
  double bearing_scale_mean = 0.0;
  double bearing_scale_sigma = 0.1;
  // The sensor's depth share c_depth at its start, and its sigma; 0 (default) holds c_depth at its
  // mean (0: ranges taken as distances); 1 is weak (a camera that ranges codes by their apparent size).
  double depth_share_mean = 0.0;
  double depth_share_sigma = 0.0;
  // The sensor's constant range scale error s_robot at its start, and its sigma (0: held).
  double range_scale_mean = 0.0;
  double range_scale_state_sigma = 0.0;
  RangeBearingMapUncertainty map_uncertainty = RangeBearingMapUncertainty::kEstimate;
  int max_landmark_states = 64;  // eta_l blocks kept (kEstimate, kConsider)
  // The variance factor k (> 0) of the reported pose covariance: RunRangeBearingLocalizer outputs
  // k P. Scaling Q, R and P0 alike by k leaves the gain and the estimate unchanged and P scaled by
  // k; the gate and the lost test stay on the unscaled S and P (the innovations are consistent
  // unscaled: the factor is for the slow, systematic errors they cannot reveal). The map build's
  // leave-one-out calibration (map.json range_bearing_sensor online_variance_factor) sets it.
  double variance_factor = 1.0;
  // The update's Gauss-Newton iterations (the iterated EKF): each relinearizes h at the updated
  // state, x = x_prior + K_i (z - h(x_i) - H_i (x_prior - x_i)), until the pose moves by less than
  // 1e-9 (m, rad) or the count is spent; P from the last linearization; the gate still uses the
  // prediction's. update_iterations while tracking (1: the EKF, linearized once at the
  // prediction); relocalization_iterations while lost (P inflated to the reacquire sigmas, or the
  // position's sigma above lost_sigma_m: a prior so wide that h is far from linear over it, where
  // one linearization can land a confident wrong pose and regain the track there). Both 1 by
  // default (the EKF as before; docs/accuracy.md, MRCLAM, has what 10 while lost does).
  int update_iterations = 1;
  int relocalization_iterations = 1;
  bool Check(std::string* why) const;
};

// The odometry calibration of factors/calibrated_odometry_factor.h (the map build's, map.json's:
// theta_C = (theta_M - k s) / (1 + turn scale), t_C = t_M / (1 + distance scale)) in this filter's
// form (theta_C = (1 + s_turn) theta_M + k s, t_C = (1 + s_dist) t_M) and back (the same map both
// ways): s_turn = -turn / (1 + turn), k = -k_build / (1 + turn), s_dist = -dist / (1 + dist).
Eigen::Vector3d ConvertOdometryCalibration(const Eigen::Vector3d& c);
// Its derivative, for a sigma: |d converted / d c| per entry (k's from its own entry).
Eigen::Vector3d ConvertOdometryCalibrationSigma(const Eigen::Vector3d& c, const Eigen::Vector3d& sigma);

// The means and sigmas of the odometry calibration and of the sensor's offsets, scales and depth
// share from a map's range_bearing_sensor prior (mapping/range_bearing_map.h: the mapped robots'
// mean and spread; the calibration converted to this filter's form); the depth share and robot
// range scale are held at 0 for a distance-model map.
void SensorPriorFromMap(const RangeBearingSensorModel& model, RangeBearingLocalizerOptions* options);

enum class RangeBearingUpdate { kAccepted, kUnknownLandmark, kGated, kDegenerate };

class RangeBearingLocalizer {
 public:
  // Throws std::invalid_argument for bad options or a covariance that is not SPD.
  RangeBearingLocalizer(const MarkerMap& map, const RangeBearingLocalizerOptions& options,
                        const SE2d& T_world_start, const Eigen::Matrix3d& start_covariance);

  // dt_s: the increment's duration (for the range scale's correlation; 0 = none elapsed).
  void Predict(const SE2d& T_a_b, double dt_s = 0.0);
  RangeBearingUpdate Update(const RangeBearingObservation& observation);

  SE2d pose() const { return SE2d(x_[0], x_[1], x_[2]); }
  Eigen::Matrix3d covariance() const { return P_.topLeftCorner<3, 3>(); }  // of the pose
  Eigen::Vector3d calibration() const { return x_.segment<3>(3); }
  Eigen::Matrix3d calibration_covariance() const { return P_.block<3, 3>(3, 3); }
  Eigen::Vector2d sensor_bias() const { return x_.segment<2>(6); }
  double range_scale() const { return x_[8]; }
  double bearing_scale() const { return x_[9]; }
  double depth_share() const { return x_[10]; }
  double robot_range_scale() const { return x_[11]; }
  double turn_fluctuation() const { return x_[12]; }
  // The augmented state: k (xi) and the landmarks' eta blocks held now.
  int map_modes() const { return k_; }
  int landmark_states() const { return static_cast<int>(slots_.size()); }
  // The landmark's position as the filter holds it now (l_map + F_l xi + eta_l; the map's under
  // kConsider, kInNoise, kIgnore); nullopt for a landmark absent from the map.
  std::optional<Eigen::Vector2d> LandmarkPosition(const MarkerKey& key) const;
  bool lost() const { return lost_; }
  // The mean of y^T S^-1 y over the accepted updates (0 before the first).
  double mean_nis() const { return accepted_nis_count_ > 0 ? accepted_nis_sum_ / accepted_nis_count_ : 0.0; }
  // Counts: accepted, unknown, gated, degenerate, became lost, regained.
  const std::map<std::string, long>& counts() const { return counts_; }

  // Exposed for the Jacobian tests.
  static constexpr int kStateSize = 13;
  using Vector6 = Eigen::Matrix<double, kStateSize, 1>;  // the state (name kept from 6 states)
  using Matrix6 = Eigen::Matrix<double, kStateSize, kStateSize>;
  // phi: the range scale's exp(-dt / tau); calibration_phi: the calibration's per entry (1: constant),
  // each entry relaxing to calibration_mean: c' = m + phi_c (c - m), after the increment used c.
  // turn_phi: the turn fluctuation's exp(-dt / tau_f).
  static Vector6 PredictState(const Vector6& x, const SE2d& T_a_b, double phi = 1.0,
                              const Eigen::Vector3d& calibration_phi = Eigen::Vector3d::Ones(),
                              const Eigen::Vector3d& calibration_mean = Eigen::Vector3d::Zero(),
                              double turn_phi = 1.0);
  static Matrix6 PredictJacobian(const Vector6& x, const SE2d& T_a_b, double phi = 1.0,
                                 const Eigen::Vector3d& calibration_phi = Eigen::Vector3d::Ones(),
                                 double turn_phi = 1.0);
  // The discrete Gauss-Markov transition of an entry over dt_s: phi = exp(-dt / tau) and the
  // variance it adds, sigma^2 (1 - phi^2) (so that a stationary variance sigma^2 stays); tau <= 0:
  // constant (phi 1, no variance).
  static std::pair<double, double> GaussMarkovStep(double sigma, double tau_s, double dt_s);
  // h(x) of the whole state (range with its scale and offset, bearing with its offset) and d h / d x.
  static Eigen::Vector2d MeasureState(const Vector6& x, const Eigen::Vector2d& l_world);
  static Eigen::Matrix<double, 2, kStateSize> MeasureStateJacobian(const Vector6& x,
                                                                   const Eigen::Vector2d& l_world);
  // d h / d l of MeasureState (the landmark's world position).
  static Eigen::Matrix2d MeasureLandmarkJacobian(const Vector6& x, const Eigen::Vector2d& l_world);
  static Eigen::Vector2d Measure(const Eigen::Vector3d& x, const Eigen::Vector2d& l_world);
  static Eigen::Matrix<double, 2, 3> MeasureJacobian(const Eigen::Vector3d& x,
                                                     const Eigen::Vector2d& l_world);

 private:
  void CheckLost();

  struct Landmark {
    Eigen::Vector2d l_map;
    std::optional<Eigen::Matrix2d> sigma;         // the map's marginal covariance
    Eigen::Matrix2d D = Eigen::Matrix2d::Zero();  // sigma - F F^T
    Eigen::Matrix<double, 2, Eigen::Dynamic> F;   // 2 x k (zero without a factor)
  };
  struct Slot {
    int index = 0;  // first entry of eta_l in x_
    long last_used = 0;
  };
  bool Augmented() const {
    return options_.map_uncertainty == RangeBearingMapUncertainty::kEstimate ||
           options_.map_uncertainty == RangeBearingMapUncertainty::kConsider;
  }
  // Adds eta_l of `key` to the state (dropping the least recently used one when full); -1 when
  // the landmark has no covariance.
  int SlotOf(const MarkerKey& key, const Landmark& landmark);
  // The landmark's position in `state` (this filter's layout): l_map + F xi + eta (eta at `slot`,
  // < 0: none) under kEstimate, l_map otherwise.
  Eigen::Vector2d LandmarkIn(const Landmark& landmark, int slot, const Eigen::VectorXd& state) const;
  void DropSlot(const MarkerKey& key);

  RangeBearingLocalizerOptions options_;
  std::map<MarkerKey, Landmark> landmarks_;
  int k_ = 0;  // columns of the map's factor (xi's entries at kStateSize ..)
  std::map<MarkerKey, Slot> slots_;
  long updates_ = 0;
  Eigen::VectorXd x_;  // [robot state (kStateSize), xi (k_), eta blocks]
  Eigen::MatrixXd P_;
  bool lost_ = false;
  int rejections_in_row_ = 0;
  int accepted_in_row_ = 0;
  std::map<std::string, long> counts_;
  double accepted_nis_sum_ = 0.0;
  long accepted_nis_count_ = 0;
};

}  // namespace waymark
