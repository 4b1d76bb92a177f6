// The online localizer: an EKF on the robot pose against a known map of codes, fed with
// odometry (or velocities) and with the codes each camera sees. State and equations:
// online/ekf_state.h (P, boxplus, update), online/motion_model.h (F, G, Qu),
// online/marker_measurement.h (H, R of both corrections).
//
// Corrections, each gated by NIS <= ChiSquareQuantile(gate_probability, dof):
//   kLoosePose     [Bach]'s baseline: the code's single-image pose composed with the map is
//                  the measurement, H = I, fixed noise `loose_noise` (dof 3 planar, 4 free).
//   kSingleFrame   no filter: every camera frame on its own, the robust PnP of the robot over
//                  all of the frame's codes at once (geometry/robot_pnp.h), started from each
//                  code's single-image pose (planar: its corner fit); the start whose fit keeps
//                  the most codes inside the gate wins. Codes outside the gate are counted as
//                  gated; a frame without a code inside it has no pose. The covariance is the
//                  fit's (J^T J)^-1 (the map taken as exact). The baseline of issue 13 ("a
//                  single-frame fit"), and a mode for robots with no motion input at all.
//   kTightCorners  ours: the four corners' pixels, H through the camera Jacobian, noise
//                  sigma_px^2 I8, the marker's map error considered (Schmidt, ekf_state.h;
//                  MapUncertainty below) (dof 8), applied as an
//                  iterated EKF (EkfState::UpdateIterated): after metres without a code the
//                  prior is off by tens of pixels and one linearization leaves the mean biased
//                  while P shrinks (NEES spikes of 10^3-10^4 in the Monte-Carlo test).
//
// Life cycle (TrackingStatus, reported with every output; a pose only while kTracking):
//   kUninitialized -> kTracking: the first unambiguous code of the map with a single-image pose
//     initializes the mean (RobotPoseFromCode) and P (single-image covariance + map covariance).
//     Planar robots start instead from the corner fit (PlanarPoseFromCorners): the state's
//     (x, y, theta) that best fits the code's four corners with the robot level, by Gauss-Newton
//     from the single-image pose. The single-image attitude of a small code seen head-on is off
//     by degrees, and through the range it moves the implied robot position by range x tilt
//     (ceiling codes 40 px wide at 1.85 m: starts 0.4-0.7 m off); the known level removes that.
//     With A = (H^T H)^-1 H^T at the fit, P = sigma_px^2 A A^T + A J_m Sigma_m J_m^T A^T and the
//     cross-covariance with the marker's map error C_m = -A J_m Sigma_m. Both IPPE solutions of
//     an ambiguous code fit to the same planar pose when the level decides between them: such
//     a code initializes too. The relocalization hypotheses and the contradiction test use the
//     same fit (the loose baseline keeps [Bach]'s single-image pose).
//   kTracking -> kSuspect: a frame whose codes were all gated out and one of whose codes
//     contradicts the track: every single-image robot pose of that code (both IPPE solutions
//     when ambiguous) is farther from the state than agree_trans_m + 3 sigma_position or
//     agree_rot_rad + 3 sigma_yaw (a gated code that agrees with the track, e.g. a few bad
//     corner pixels, is not a contradiction). No pose is output while suspect; the filter keeps
//     predicting and keeps correcting with every code that passes its gate.
//   kTracking -> kSuspect, negative information (online/visibility.h): codes the predicted
//     pose puts in view (weighted by P(in view) under P and the detection rate learned on this
//     run) that are not detected raise S, a decaying CUSUM of log P(frame | pose wrong) /
//     P(frame | pose right) with a blind-camera state per camera; S >= visibility.suspect_llr
//     makes the track suspect, S >= visibility.lost_llr makes it lost. This catches a robot
//     carried away before it sees any code.
//   kSuspect -> kTracking: a code of a later frame passes the gate (a misdecoded id or a flip
//     seen once, a blinded camera: a false alarm, counted in suspect_cleared) and S is below
//     suspect_llr after it (a code seen where predicted lowers S by about -log q).
//   kTracking/kSuspect -> kLost: `lost_after_rejected_frames` frames in a row whose every code
//     was gated out, S >= visibility.lost_llr, the position sigma above
//     `max_position_sigma_m`, or a non-finite P.
//   Relocalization (kSuspect or kLost -> kTracking, a restart from the latest sighting): the
//     gated or lost-time codes give single-code robot-pose hypotheses (both IPPE solutions of
//     an ambiguous code), chained while each agrees with one of the previous sighting's
//     (within agree_trans_m / agree_rot_rad after moving the older one by the odometry since;
//     two codes of one frame chain too). A chain restarts the filter once it holds
//       1 sighting   when lost and the latest code is "clear": unambiguous (IPPE), reprojection
//                    RMS <= clear_max_rms_sigmas * sigma_px over its own four corners, and
//                    nearer than clear_max_range_sizes code sizes;
//       1 sighting   when suspect with S >= suspect_llr (codes expected and not seen already
//                    say the pose is wrong) and the latest code is clear;
//       2 sightings  when suspect otherwise and the latest code is clear: a first code that
//                    contradicts a track whose expected codes were seen is confirmed by its
//                    next sighting (or another code), so one misdecoded id never moves a
//                    healthy filter;
//       relocalize_after_agreeing sightings otherwise (ambiguous, poorly fitting or far codes).
//   Frames whose codes are gated while suspect are decided at the end of the frame: a code that
//   passes the gate in the same frame keeps the track.
// Without odometry (no odometry or velocity input has come yet: a hand-held camera, a humanoid
// that gives none, [Kang]): each frame first predicts that the robot stayed where it was, with a
// random walk whose sigma grows with the time dt since the previous input,
//   sigma_trans = without_odometry.speed_mps * dt (per axis),  sigma_yaw = without_odometry.turn_radps * dt,
// (F = I, G = I, Qu = diag(sigma^2)), so that the corners of a robot that moved since are not
// gated against an overconfident prior; a long gap grows sigma past max_position_sigma_m (lost).
// The tight mode then corrects with the frame's robust PnP over all its codes (the fit of
// kSingleFrame, its start chosen nearest the state) as one measurement of the state:
//   z = the fit's (x, y, theta) or (x, y, z, yaw),  H = I,  R = the fit's (J^T J)^-1,
// gated like the loose update (dof 3 or 4); the free model takes its roll and pitch from the
// fit. A rig of several cameras adds the mount's uncertainty to R: with the camera at lever
// arm l from the robot's origin, position sigma_m^2 + (sigma_rad |l|)^2 per axis and heading
// sigma_rad^2 (camera_mount_sigma_*). The test of codes expected in view and not seen
// (online/visibility.h) is off without odometry: a random walk does not predict where the
// robot went, so a code it "expects" says nothing when missed; a wrong track shows instead as
// frame fits outside the gate (lost after lost_after_rejected_frames of them). Linearizing each code at the
// predicted pose, as with odometry, fails here: after a second without codes the prior is off by decimetres
// and radians (the corners are gated), there is no odometry attitude, and a hand-held camera tilts by degrees
// between frames. The fit holds the map as exact (no Schmidt term). The first start takes the fit too, when
// it keeps two codes or an unambiguous one. The fit dominates when its covariance R is at most
// without_odometry.fit_dominance times the prior P in every direction (generalized eigenvalues
// of (R, P)): the state is then reset to the fit (x = z, P = R) after the gated update instead of
// keeping the fused mean. The random walk's mean says the robot stayed where it was; a camera
// that moves steadily is then a few millimetres off it at every frame, a lag the fused mean
// carries (tagslam-test16 and 17: 0.11 and 0.15 mm from TagSLAM's per-frame fit where the frame's
// own fit is at 0.03 and 0.01 mm). The prior still gates the fit and picks between an ambiguous
// code's two solutions; a fit of one far code (tagslam-test10) does not dominate and is fused.
// Codes absent from the map are counted and ignored. Inputs older
// than the last one processed are rejected (StepStatus::kTimeWentBackwards) and change nothing.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "geometry/camera.h"
#include "geometry/pose.h"
#include "geometry/robot_pnp.h"
#include "geometry/types.h"
#include "online/code_sighting.h"
#include "online/ekf_state.h"
#include "online/marker_measurement.h"
#include "online/motion_model.h"
#include "online/status.h"
#include "online/visibility.h"

namespace waymark {

enum class CorrectionMode { kLoosePose, kTightCorners, kSingleFrame };
// Where the free model takes roll and pitch from (ekf_state.h).
enum class AttitudeSource { kOdometry, kMarker };
// How the tight update treats a marker's map covariance Sigma_m:
//   kConsider  Schmidt: the marker error is one draw shared by all its sightings; the state
//              keeps its correlation with it (ekf_state.h). Consistent with a learned map.
//   kInNoise   folded into R = sigma_px^2 I8 + J_m Sigma_m J_m^T at every sighting, as if each
//              sighting saw a new draw (overconfident after repeated sightings).
//   kIgnore    the map taken as exact.
enum class MapUncertainty { kConsider, kInNoise, kIgnore };

// The random walk that replaces the odometry while there is none (header comment above).
struct MotionWithoutOdometry {
  double speed_mps = 1.0;   // sigma of the translation per second, per axis
  double turn_radps = 2.0;  // sigma of the heading per second
  // The fit dominates (header comment) when every generalized eigenvalue of its covariance R
  // against the prior P (R v = lambda P v) is at most this: the prior would then move the fused
  // pose by at most lambda / (1 + lambda) of the innovation in any direction. 0 turns it off.
  double fit_dominance = 0.1;
};

// True when every generalized eigenvalue of (fit_covariance, prior) is <= max_ratio (false when
// the prior is not positive definite or max_ratio <= 0).
bool FitDominates(const Eigen::MatrixXd& prior, const Eigen::MatrixXd& fit_covariance, double max_ratio);

struct LocalizerOptions {
  MotionModel motion = MotionModel::kPlanar;
  CorrectionMode mode = CorrectionMode::kTightCorners;
  AttitudeSource attitude_source = AttitudeSource::kOdometry;
  OdometryNoise odometry;
  // Used only until the first odometry or velocity input (header comment).
  MotionWithoutOdometry without_odometry;
  // Rigs of several cameras, without odometry: how far each camera's pose at a frame may be off
  // its T_robot_camera (calibration error, cameras that are not exactly synchronized), per axis;
  // added to the frame fit's noise so that two cameras' fits of one instant agree within it.
  double camera_mount_sigma_rad = 0.005;
  double camera_mount_sigma_m = 0.005;
  double gate_probability = 0.997;      // chi-square gate of every correction
  int tight_iterations = 5;             // iterated EKF steps of the corner update (1: plain EKF)
  double default_pixel_sigma_px = 1.0;  // when CameraInfo::pixel_sigma is absent
  // [Bach]'s fixed G: variances of [x y theta] (planar) or [x y z yaw] (free).
  Eigen::VectorXd loose_noise = Eigen::Vector3d::Constant(0.001);
  int lost_after_rejected_frames = 3;
  int relocalize_after_agreeing = 3;
  double agree_trans_m = 0.2;
  double agree_rot_rad = 0.2;
  double max_position_sigma_m = 2.0;
  double clear_max_rms_sigmas = 3.0;    // a clear code: reprojection RMS <= this * sigma_px
  double clear_max_range_sizes = 40.0;  // and range <= this * size_m (4 m for a 10 cm code)
  MarkerPoseOptions marker_pose;        // single-image poses computed by AddDetections
  MapUncertainty map_uncertainty = MapUncertainty::kConsider;
  int max_considered_markers = 16;  // kConsider: markers whose correlation is kept (most recent)
  // Codes the map puts in view but not detected (online/visibility.h; life cycle above).
  VisibilityOptions visibility;
  // The robot's pose at its first odometry sample (at its first input without odometry),
  // roughly: moved with the odometry, it stands in for the track until the first start, to tell
  // apart squares that look alike (family `square`, no ids; IdentifySquare's 100 px gate: within
  // about 0.5 m and 15 deg under [Seki]'s 2 m squares).
  std::optional<SE3d> start_pose;

  bool Check(std::string* why) const;

  // Special members out of line (localizer.cc): GCC 12 reports a false -Wuse-after-free on the
  // inlined destruction of loose_noise in callers that build options by value.
  LocalizerOptions() = default;
  LocalizerOptions(const LocalizerOptions&) = default;
  LocalizerOptions(LocalizerOptions&&) = default;
  LocalizerOptions& operator=(const LocalizerOptions&) = default;
  LocalizerOptions& operator=(LocalizerOptions&&) = default;
  ~LocalizerOptions();
};

// Everything one camera saw at one instant.
struct CameraFrame {
  double stamp_s = 0.0;
  std::string camera;
  std::vector<CodeSighting> sightings;
};

enum class CorrectionOutcome {
  kAccepted,       // used to correct the state
  kGated,          // NIS above the gate, or (tight) predicted out of view: ignored, kept as a
                   // relocalization hypothesis
  kUnknownMarker,  // not in the map: counted and ignored
  kNotUsable,      // no single-image pose (loose mode, initialization) or S not PD
  kInitialized,    // started (or restarted) the filter
  kHypothesis,     // lost or uninitialized: only collected as a relocalization hypothesis
};

struct CorrectionResult {
  MarkerKey key;
  StepStatus status = StepStatus::kOk;  // a numerical failure of this correction, if any
  CorrectionOutcome outcome = CorrectionOutcome::kNotUsable;
  double nis = 0.0;
  double gate = 0.0;           // NIS threshold used
  Eigen::VectorXd innovation;  // z [-] h(x) before the update
};

struct FrameResult {
  StepStatus status = StepStatus::kOk;
  TrackingStatus tracking = TrackingStatus::kUninitialized;  // after the frame
  std::vector<CorrectionResult> corrections;
};

// The localizer's answer at one instant: a pose only when tracking.
struct PoseOutput {
  double stamp_s = 0.0;
  TrackingStatus tracking = TrackingStatus::kUninitialized;
  std::optional<SE3d> T_world_robot;
  std::optional<Eigen::MatrixXd> covariance;  // error state of ekf_state.h
};

struct LocalizerCounters {
  long frames = 0;
  long accepted = 0;
  long gated = 0;
  long unknown_markers = 0;
  long not_usable = 0;
  long initializations = 0;  // first start and every relocalization
  long times_lost = 0;
  long times_suspect = 0;            // kTracking -> kSuspect
  long suspect_cleared = 0;          // kSuspect -> kTracking without a restart (false alarms)
  long suspect_by_missed_codes = 0;  // of times_suspect: by the negative-evidence test
  long lost_by_missed_codes = 0;     // of times_lost: likewise
  // Of times_lost, the other reasons (life cycle above): lost_after_rejected_frames frames in a
  // row whose codes were all gated; the position sigma above max_position_sigma_m (no code for
  // too long); a numerical failure (non-finite covariance).
  long lost_by_gated_frames = 0;
  long lost_by_uncertainty = 0;
  long lost_by_numerical_failure = 0;
  long frame_fits_taken = 0;  // without odometry: frame fits that dominated the prior (header comment)
  long expected_codes = 0;    // codes predicted in view (online/visibility.h)
  long expected_missed = 0;   // of those, not detected
  long rejected_inputs = 0;   // time going backwards, invalid input, unknown camera
};

class Localizer {
 public:
  // Throws std::invalid_argument when options.Check fails or a camera is listed twice.
  Localizer(LocalizerOptions options, MarkerMap map, const std::vector<CameraInfo>& cameras);

  // Starts tracking from a pose known before any code (a robot set down at a known place, as
  // AMCL's initial pose): mean T_world_robot (level for planar), covariance of the error state
  // (ekf_state.h: x y yaw planar, x y z yaw free). kInvalidInput (nothing changes) for a
  // covariance of the wrong size, not finite or not positive definite; kTimeWentBackwards for a
  // stamp older than the last input. Counts as an initialization.
  StepStatus InitializeAt(double stamp_s, const SE3d& T_world_robot, const Eigen::MatrixXd& covariance);
  // Odometry pose T_odom_robot at stamp_s; only increments between calls are used.
  StepStatus AddOdometry(double stamp_s, const SE3d& T_odom_robot);
  // Planar only: the robot moved with (v, omega) since the previous input ([Bach], eq. 5).
  StepStatus AddVelocity(double stamp_s, double v_mps, double omega_radps);
  // Corrects with every code of the frame, in order.
  FrameResult AddFrame(const CameraFrame& frame);
  // The same from raw detections: single-image poses are computed (MakeCodeSighting, with the
  // map's code sizes) only for the codes that need one: initialization, the loose update,
  // relocalization hypotheses, kMarker attitude. Codes absent from the map are counted.
  FrameResult AddDetections(const DetectionFrame& detections);

  PoseOutput Output() const;
  // The map's codes the current state puts in `camera`'s view (online/visibility.h, step 1),
  // for a detector that looks where the map says first (the live loop, runner/
  // predicted_regions.h), under `visibility` (by default the localizer's own options: the
  // negative-evidence test's). Empty without a track, or for a camera not in the dataset.
  std::vector<ExpectedCode> PredictCodesInView(const std::string& camera,
                                               const std::optional<VisibilityOptions>& visibility = {}) const;
  TrackingStatus tracking() const { return tracking_; }
  const EkfState& state() const { return state_; }
  const LocalizerCounters& counters() const { return counters_; }
  // S of the negative-evidence test after the last frame (online/visibility.h).
  double missed_codes_llr() const { return negative_.llr(); }
  // Free model: the odometry frame's estimated tilt (online/motion_model.h).
  const OdometryTilt& odometry_tilt() const { return odometry_tilt_; }
  // The pose predicted just before each frame that corrected the state ([Bach]'s PE/TE):
  // one entry per such frame, stamped with the frame.
  const Trajectory& predicted_before_correction() const { return predicted_before_correction_; }

 private:
  // A code gated while tracking or suspect, kept for the decision at the end of its frame.
  struct GatedSighting {
    const Camera* camera;
    const MapMarker* marker;
    CodeSighting sighting;  // solved
  };

  StepStatus Accept(double stamp_s);  // time check
  StepStatus ApplyPrediction(const MotionPrediction& prediction, const SE3d& increment);
  CorrectionResult ProcessSighting(const Camera& camera, const CodeSighting& sighting);
  CorrectionResult CorrectTight(const Camera& camera, const MapMarker& marker, const CodeSighting& sighting);
  CorrectionResult CorrectLoose(const Camera& camera, const MapMarker& marker, const CodeSighting& sighting);
  void FinishCorrection(const UpdateResult& update, CorrectionResult* result);
  // `sighting` when solved, else its solved copy in *storage.
  const CodeSighting& Solved(const Camera& camera, const MapMarker& marker, const CodeSighting& sighting,
                             CodeSighting* storage) const;
  // The robot pose implied by solution i of a sighting.
  SE3d CodeHypothesis(const Camera& camera, const MapMarker& marker, const CodeSighting& sighting,
                      size_t i) const;
  // Planar motion: the robot pose fitted to the sighting's four corners from solution i (header
  // comment), with its covariance and C_m; nullopt for free motion, when a corner leaves the
  // camera's front, the fit does not converge, or its residual fails the gate.
  std::optional<CodeRobotPose> PlanarPoseFromCorners(const Camera& camera, const MapMarker& marker,
                                                     const CodeSighting& sighting, size_t i) const;
  // The robot pose solution i implies for initialization and relocalization: the planar corner
  // fit when there is one, else CodeHypothesis.
  SE3d RestartPose(const Camera& camera, const MapMarker& marker, const CodeSighting& sighting,
                   size_t i) const;
  // Planar: the sighting is ambiguous but its solutions fit to one pose (header comment).
  bool PlanarResolvesAmbiguity(const Camera& camera, const MapMarker& marker,
                               const CodeSighting& sighting) const;
  bool IsClear(const Camera& camera, const MapMarker& marker, const CodeSighting& sighting) const;
  // True when every solution of the (solved) sighting is far from the track (header comment).
  bool Contradicts(const Camera& camera, const MapMarker& marker, const CodeSighting& sighting) const;
  // Translation and rotation distance between two robot poses in the state's coordinates.
  std::pair<double, double> Distance(const SE3d& a, const SE3d& b) const;
  // Adds a (solved) sighting to the relocalization chain; true if it restarted the filter.
  bool OfferHypothesis(const Camera& camera, const MapMarker& marker, const CodeSighting& sighting);
  // End of a frame while tracking or suspect: the state change its outcomes and S (the
  // negative-evidence test after the frame) call for.
  void FinishFrame(int accepted, double llr);
  // Feeds the frame's expected codes and their outcomes to the negative-evidence test; S after.
  double TestExpectedCodes(const CameraFrame& frame, const std::vector<ExpectedCode>& expected,
                           const FrameResult& result, bool learn);
  // Restarts from solution i of a sighting (an ambiguous code's second solution borrows the
  // first one's covariance: the two are near each other, which is what makes them ambiguous).
  bool Initialize(const Camera& camera, const MapMarker& marker, const CodeSighting& sighting, size_t i = 0);
  enum class LostReason { kGatedFrames, kUncertainty, kMissedCodes, kNumerical };
  void SetLost(LostReason reason);
  void CheckUncertainty();
  // Without odometry: the random-walk prediction over dt seconds (header comment).
  void PredictWithoutOdometry(double dt_s);
  // The frame's known codes as PnP views (corner pixels of `frame` are referenced, not copied).
  std::vector<PnpView> FrameViews(const Camera& camera, const CameraFrame& frame) const;
  // The robust PnP of the robot over all of a frame's known codes (kSingleFrame, header
  // comment); nullopt when no code fits inside the gate.
  struct FrameFit {
    std::vector<PnpView> views;     // the frame's known codes, in the frame's order
    std::vector<bool> unambiguous;  // per view: its single-image pose is unambiguous
    std::vector<bool> inliers;      // per view: inside the gate at the fit
    SE3d T_world_robot;
    Eigen::MatrixXd covariance;  // of the state's error, from the inliers
  };
  std::optional<FrameFit> FitFrame(const Camera& camera, const CameraFrame& frame) const;
  // One CorrectionResult per code of the frame: unknown codes counted here, every known one
  // (with its index among the frame's known codes) filled in by `report`.
  void ReportFrameCodes(
      const CameraFrame& frame, FrameResult* result,
      const std::function<void(const CodeSighting&, const MapMarker&, size_t, CorrectionResult*)>& report);
  // Sets the state to the fit (a start when there was no track) and reports every code.
  bool StartFromFit(const FrameFit& fit, const CameraFrame& frame, FrameResult* result);
  // Without odometry: the frame's fit as one measurement of the pose (header comment).
  void CorrectWithFrameFit(const Camera& camera, const CameraFrame& frame, FrameResult* result);
  // kSingleFrame: the frame's pose on its own (header comment).
  void FitSingleFrame(const Camera& camera, const CameraFrame& frame, FrameResult* result);
  // Free model, kOdometry: a used code's attitude refines the odometry frame's tilt.
  void UpdateOdometryTilt(const Camera& camera, const MapMarker& marker, const CodeSighting& sighting);
  bool HasTrack() const {
    return tracking_ == TrackingStatus::kTracking || tracking_ == TrackingStatus::kSuspect;
  }

  LocalizerOptions options_;
  MarkerMap map_;
  std::map<std::string, Camera> cameras_;
  EkfState state_;
  TrackingStatus tracking_ = TrackingStatus::kUninitialized;
  LocalizerCounters counters_;
  Trajectory predicted_before_correction_;
  std::optional<double> last_stamp_s_;
  std::optional<SE3d> last_T_odom_robot_;
  std::optional<double> last_odometry_stamp_s_;  // stamp of last_T_odom_robot_ (random-walk terms)
  bool had_motion_input_ = false;                // an odometry or velocity input came: no random walk
  std::optional<SE3d> first_T_odom_robot_;       // for options_.start_pose
  int rejected_frames_in_a_row_ = 0;
  // Relocalization: the latest sighting's robot poses (both solutions of an ambiguous code),
  // moved with the odometry, each with the length of the chain of agreeing sightings it ends.
  struct Hypothesis {
    SE3d T_world_robot;
    int agreeing = 1;
  };
  std::vector<Hypothesis> hypotheses_;
  std::vector<GatedSighting> gated_;  // this frame's gated codes (AddFrame)
  double gate_loose_ = 0.0;           // chi-square quantiles of gate_probability
  OdometryTilt odometry_tilt_;        // free model: the odometry frame's tilt (online/motion_model.h)
  double gate_tight_ = 0.0;
  NegativeEvidenceTest negative_;
  CodeIndex code_index_;                         // of map_ (indices: a copied Localizer stays valid)
  std::map<std::string, NearCodes> near_codes_;  // per camera
  std::optional<int> component_;                 // the map component the track is in (the last code used)
};

}  // namespace waymark
