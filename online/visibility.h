// Negative information for the localizer: codes the map says a camera should see now, and a
// sequential test on whether they were seen. Between a kidnapping (the robot carried; the
// odometry does not see it) and the first code seen after it, the only evidence that the track
// is wrong is what is NOT seen: codes the predicted pose puts squarely in view that the detector
// does not report.
//
// 1. Expected codes (PredictExpectedCodes), per camera frame, from the predicted state:
//      in front     every corner at depth > 0 (camera frame), centre within max_range_m
//      facing       angle between the code's z axis and the ray code -> camera <= max_angle_deg
//      readable     apparent size s = sqrt(area of the predicted quad) >= min_code_px
//      in view      P(in view) = P_u P_v, the chance that the quad shifted by the predicted
//                   centroid's error stays inside the image with border_px margin:
//                     P_u = Phi(slack_right / sigma_u) - Phi(-slack_left / sigma_u)
//                   (slack = distance of the extreme corner to the margin, negative outside),
//                   Sigma_centre = H_c P H_c^T + J_c Sigma_marker,t J_c^T of the code centre's
//                   pixel (H_c as in online/marker_measurement.h, for the centre; J_c on the
//                   marker's translation error). A code at the edge of view under a wide
//                   covariance has a small P(in view), hence little weight.
//    The map holds no walls: occlusion by unknown geometry is left to the learned rate below.
//
// 2. Detection probability p_d, learned online from the run's own hits and misses on expected
//    codes while the track is trusted (DetectionModel). Per camera, per cell (apparent size x
//    viewing angle bins), a Beta(1, 1) prior and exponentially forgotten counts:
//      p_cell = (hits + 1) / (trials + 2),
//    times a per-code ratio of its hits to the hits its cells predicted (a code hidden by a
//    pillar from where the robot passes is learned as such; misses where p_cell is small, e.g.
//    far away, barely count):
//      p_code = p_cell (hits_code + k) / (sum over its trials of p_cell + k),  k = code_prior_trials,
//    and capped at max_detection_probability (misses are not independent in practice). Each
//    trial counts with weight P(in view) (1 - P(camera blind | frame)). Codes with p_code below
//    min_detection_probability are no evidence (a fresh cell's prior 0.5 included).
//
// 3. Sequential test (NegativeEvidenceTest). Per camera frame, with outcomes o_i in {hit: the
//    code passed the gate; occupied: some detection of the frame lies on its predicted quad (a
//    misread id, a gated sighting): no evidence; miss}, and v_i = P(in view), p_i = p_code:
//      H_right: the camera is blind (covered, glare, blur) with probability b (a two-state
//               Markov chain per camera: P(blind onset) = blind_onset_probability per frame,
//               P(stays blind) = blind_stay_probability); when seeing, hit_i ~ Bernoulli(v_i p_i).
//               A frame with any detection proves the camera is not blind.
//        P(O | right) = b- [no detection] + (1 - b-) prod_hit (v_i p_i) prod_miss (1 - v_i p_i),
//        b- = rho b + eps (1 - b)   (forward algorithm; b = the posterior after the frame)
//      H_wrong: the codes are not where predicted: a miss is certain, a hit has probability q
//               (hit_probability_if_wrong), for an accepted code that was not expected too.
//        llr_k = log P(O | wrong) - log P(O | right)
//      S_k = max(0, exp(-dt / decay_time_s) S_{k-1} + llr_k)        (CUSUM with decay)
//    A camera's misses cost H_right at most about -log(eps) before its blindness explains them,
//    plus -log(rho) per further frame: a covered camera makes the track suspect but only
//    several cameras (or a long time) make it lost. The localizer (online/localizer.h) moves
//    kTracking -> kSuspect at S >= suspect_llr and -> kLost at S >= lost_llr.
#pragma once

#include <Eigen/Core>
#include <array>
#include <map>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "geometry/camera.h"
#include "geometry/types.h"
#include "online/ekf_state.h"
#include "online/marker_measurement.h"

namespace waymark {

struct VisibilityOptions {
  bool enabled = true;          // false: no negative information (the localizer as before)
  double min_code_px = 12.0;    // smaller codes are never expected
  double max_range_m = 20.0;    // farther codes are never expected (cheap pre-filter)
  double max_angle_deg = 75.0;  // codes seen more obliquely are never expected
  double border_px = 4.0;       // the quad must stay this far inside the image
  double min_in_view = 0.05;    // P(in view) below this: not expected
  double max_detection_probability = 0.9;
  // Codes whose learned p_code is below this are no evidence (they still teach the model): a
  // cell that straddles the detector's limit (range, blur) averages codes read and not read.
  double min_detection_probability = 0.6;
  double forget_trials = 500.0;  // memory of the per-cell counts (effective trials)
  double code_prior_trials = 4.0;
  double blind_onset_probability = 0.005;   // per camera frame
  double blind_stay_probability = 0.95;     // per camera frame (mean blind spell 20 frames)
  double hit_probability_if_wrong = 0.001;  // a code passing the gate where a wrong pose predicts it
  double decay_time_s = 10.0;
  double learn_below_llr = 2.0;  // p_d learns only while S is below this (the track trusted)
  double suspect_llr = 3.5;
  double lost_llr = 9.0;

  bool Check(std::string* why) const;
};

// A code the predicted state puts in a camera's view.
struct ExpectedCode {
  const MapMarker* marker = nullptr;
  Vector8d px = Vector8d::Zero();  // predicted corners
  double in_view = 0.0;            // P(in view) under the state's covariance
  double size_px = 0.0;            // sqrt of the predicted quad's area
  double cos_angle = 1.0;          // between the code's normal and the ray to the camera
};

// The map's codes with a pose, laid out for the per-frame scan (centres and normals side by
// side, not inside the large MapMarker), each with its index in map.markers.
class CodeIndex {
 public:
  explicit CodeIndex(const MarkerMap& map);
  struct Entry {
    Eigen::Vector3d centre_world;
    Eigen::Vector3d normal_world;  // the code's z axis
    double size_m = 0.0;
    size_t marker_index = 0;
  };
  const std::vector<Entry>& entries() const { return entries_; }
  // Indices of the entries whose centre lies within radius_m of point_world.
  std::vector<size_t> Near(const Eigen::Vector3d& point_world, double radius_m) const;
  double max_size_m() const { return max_size_m_; }

 private:
  std::vector<Entry> entries_;
  double max_size_m_ = 0.0;
};

// The codes one camera can possibly expect, kept between frames: every code within
// R = min(max_range_m, max_size_m f / min_code_px) of the camera (farther ones are smaller than
// min_code_px) plus kRescanM, rescanned once the camera moved kRescanM from the last scan, so the
// per-frame test visits a few codes instead of the whole map.
class NearCodes {
 public:
  static constexpr double kRescanM = 1.0;
  const std::vector<size_t>& Around(const CodeIndex& codes, const Camera& camera,
                                    const Eigen::Vector3d& camera_world, const VisibilityOptions& options);

 private:
  std::optional<Eigen::Vector3d> scan_point_world_;
  std::vector<size_t> near_;
};

// The codes of `map` (indexed by `codes`, built from it) that `camera` should see from the
// state's mean (header, step 1), in map order. With `component`, only the codes of that
// component of the map (each has its own world frame).
// `near` (optional): only these entries of `codes` (NearCodes::Around).
std::vector<ExpectedCode> PredictExpectedCodes(const EkfState& state, const Camera& camera,
                                               const MarkerMap& map, const CodeIndex& codes,
                                               const VisibilityOptions& options,
                                               std::optional<int> component = std::nullopt,
                                               const std::vector<size_t>* near = nullptr);

// True when the detected quad's centre lies on the expected code's predicted quad, grown by
// half its size (a misread or gated sighting of that code).
bool CoversExpected(const ExpectedCode& expected, const std::array<Eigen::Vector2d, 4>& corners_px);

enum class ExpectedOutcome { kHit, kOccupied, kMissed };

// Learned detection probabilities (header, step 2). Codes are told apart by the address of
// their MapMarker, which must outlive the model (the localizer's own map).
class DetectionModel {
 public:
  explicit DetectionModel(const VisibilityOptions& options) : options_(options) {}
  double Probability(const std::string& camera, const ExpectedCode& code) const;
  // One trial of weight `weight` in [0, 1].
  void Learn(const std::string& camera, const ExpectedCode& code, bool hit, double weight);

 private:
  static constexpr int kSizeBins = 8, kAngleBins = 4;
  struct Counts {
    double hits = 0.0, trials = 0.0;
  };
  struct CameraCounts {
    std::array<Counts, kSizeBins * kAngleBins> cells;
    std::unordered_map<const MapMarker*, Counts> codes;  // hits, and hits the cells predicted
  };
  static int Cell(const ExpectedCode& code);
  static double CellProbability(const CameraCounts& counts, const ExpectedCode& code);
  VisibilityOptions options_;
  std::map<std::string, CameraCounts> cameras_;
};

// The sequential test (header, step 3).
class NegativeEvidenceTest {
 public:
  explicit NegativeEvidenceTest(const VisibilityOptions& options) : options_(options), model_(options) {}

  // One camera frame: `expected` with their `outcomes`, `unexpected_hits` accepted codes that
  // were not expected, `any_detection` whether the frame reported any code. `learn`: the
  // frame may teach p_d. Returns S after the frame.
  double AddFrame(double stamp_s, const std::string& camera, const std::vector<ExpectedCode>& expected,
                  const std::vector<ExpectedOutcome>& outcomes, int unexpected_hits, bool any_detection,
                  bool learn);
  // After a (re)initialization: S = 0, no camera believed blind. The learned p_d is kept.
  void Restart();
  double llr() const { return llr_; }
  double blind_probability(const std::string& camera) const;
  const DetectionModel& model() const { return model_; }

 private:
  VisibilityOptions options_;
  DetectionModel model_;
  std::map<std::string, double> blind_;  // posterior P(blind) per camera after its last frame
  double llr_ = 0.0;
  double last_stamp_s_ = 0.0;
  bool has_stamp_ = false;
};

}  // namespace waymark
