// The dataset runner: drives a Localizer (online/localizer.h) with a dataset's odometry and
// camera frames (detections.jsonl, or its images through detect/detector.h), in time order, and
// collects the poses, the predictions, per-frame latency and counted warnings. `waymark
// localize` and `waymark demo` call RunLocalizer; the live mode of `waymark localize` feeds a
// LocalizeStream line by line.
//
// Time order. Odometry and frames are merged by stamp (each camera and the odometry keep their
// own order; on equal stamps odometry goes first). A frame waits until the odometry has reached
// its stamp, then the odometry pose is interpolated to the frame's instant, so the prediction
// lands exactly there:
//   T_odom_robot(t) = T_i * Exp(a * Log(T_i^-1 * T_j)),  a = (t - t_i) / (t_j - t_i),
// with Exp/Log of SE(3) (screw motion: exact for constant linear and angular velocity in the
// body frame; InterpolateScrew in geometry/pose.h). The Localizer then sees the increments T_i -> T(t) ->
// T_j, which compose to the recorded T_i^-1 T_j. A frame outside the odometry's time span is corrected
// without a prediction to its instant (counted warning). A dataset or stream without any
// odometry is no warning: the localizer's random walk predicts instead (online/localizer.h).
//
// Bad data never stops a run: codes absent from the map, frames or odometry whose time goes
// backwards, unreadable images are counted warnings. A map of another place (none of the codes
// detected in the first `map_check_frames` frames with codes, showing `map_check_codes`
// distinct codes, or in the whole run, is in the map) throws std::runtime_error, since every
// pose would be missing.
#pragma once

#include <chrono>
#include <deque>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "detect/detector.h"
#include "geometry/pose.h"
#include "geometry/types.h"
#include "online/localizer.h"
#include "runner/predicted_regions.h"

namespace waymark {

struct LocalizeRunOptions {
  LocalizerOptions localizer;         // DefaultLocalizerOptions(dataset) is the usual start
  bool detect_images = false;         // detect on images.csv instead of reading detections.jsonl
  std::vector<std::string> families;  // for images; empty: the map's families
  DetectorOptions detector;           // for images
  // Live image lines: detect in the regions where the localizer predicts mapped codes, on the
  // whole frame every N frames or when the track is not sure (runner/predicted_regions.h).
  PredictedRegionOptions predicted_regions;
  bool realtime = false;                             // pace the input by its timestamps (sleeps)
  std::function<void(const std::string&)> progress;  // "frame 120/1335, tracking 97.5 %"
  // A map of another place: once `map_check_frames` frames with codes showing at least
  // `map_check_codes` distinct codes were seen and none of them is in the map, the run stops
  // with an error (a robot starting in an unmapped corner sees few distinct codes).
  int map_check_frames = 30;
  int map_check_codes = 8;
  // Live streams: how long (in stamp time) a frame may wait for odometry beyond its stamp
  // before it is corrected without the interpolated prediction.
  double odometry_wait_s = 0.5;
  // Live streams: odometry is held this long (stamp time) behind the newest input before the
  // filter moves past it, so a camera frame that arrives after newer odometry, up to this late,
  // is still corrected at its own stamp (later than that: time going backwards, a warning).
  double late_frame_window_s = 0.2;
  // Odometry clock minus image clock (s), e.g. the survey's estimate that `waymark map build`
  // reports: an odometry sample stamped t is used at t - odometry_time_offset_s.
  double odometry_time_offset_s = 0.0;

  bool Check(std::string* why) const;
};

// What one frame's codes did (CorrectionOutcome counts).
struct FrameCounts {
  int accepted = 0;
  int gated = 0;    // above the chi-square gate (or predicted out of view)
  int unknown = 0;  // absent from the map
};
FrameCounts CountOutcomes(const FrameResult& result);

struct LocalizeRun {
  Trajectory trajectory;                  // poses while tracking, one per camera frame (one per stamp)
  Trajectory predicted;                   // Localizer::predicted_before_correction() (one per stamp)
  std::vector<PoseOutput> outputs;        // every frame, with status + covariance
  std::vector<std::string> cameras;       // outputs[i]'s camera
  std::vector<FrameCounts> frame_counts;  // outputs[i]'s corrections
  LocalizerCounters counters;
  std::vector<double> latency_ms;     // per frame: detection (if any) + odometry + update
  std::vector<std::string> warnings;  // "reason: count (first: example)"
  long frames_with_codes = 0;         // frames with at least one detected code
  long frames_with_map_codes = 0;     // frames with at least one code of the map
};

// LocalizerOptions for a dataset: motion model from dataset.yaml, OdometryNoise from its
// odometry_sigma (the default sigma otherwise), default pixel sigma from the cameras' (their
// largest; each camera's own pixel_sigma is used by the Localizer when set).
LocalizerOptions DefaultLocalizerOptions(const Dataset& dataset);

// Runs the whole dataset. Throws std::invalid_argument for unusable options or a dataset
// without cameras, a FormatError-like std::runtime_error for a map of another place.
LocalizeRun RunLocalizer(const Dataset& dataset, const MarkerMap& map, const LocalizeRunOptions& options);

// One line of poses.jsonl and of the live output (docs/formats.md, "Localization input/output"),
// without the newline:
//   {"t": 12.3, "camera": "cam0", "status": "tracking",
//    "T_world_robot": {"t": [x, y, z], "q_xyzw": [qx, qy, qz, qw]},
//    "covariance": [row-major, error state of online/ekf_state.h: x y yaw (planar, 9 numbers)
//                   or x y z yaw (free, 16 numbers)],
//    "accepted": 2, "gated": 0, "unknown": 0, "latency_ms": 0.41}
// T_world_robot and covariance only while tracking; latency_ms only when given.
std::string FormatPoseLine(const PoseOutput& pose, const std::string& camera, const FrameCounts& counts,
                           std::optional<double> latency_ms);

// The families to detect on images: `requested` when not empty, else the supported families
// of the map's codes, else qr, datamatrix and apriltag-36h11.
std::vector<std::string> DetectionFamilies(const MarkerMap& map, const std::vector<std::string>& requested);
// Reads one image (grayscale) and detects its codes into a DetectionFrame (image = path as
// given); nullopt with *why when the file cannot be read as an image.
std::optional<DetectionFrame> DetectImageFile(MarkerDetector& detector, const std::filesystem::path& file,
                                              double stamp_s, const std::string& camera, std::string* why);

// Counted warnings of a run: reason -> count and the first example.
class RunWarnings {
 public:
  void Add(const std::string& reason, const std::string& example);
  long Count(const std::string& reason) const;
  long Total() const;
  // "reason: count (first: example)" per reason.
  std::vector<std::string> Lines() const;

 private:
  std::map<std::string, std::pair<long, std::string>> counts_;
};

// Warning reasons (RunWarnings keys), also used by tests.
inline constexpr const char* kWarnOutsideOdometry = "frame outside the odometry's time span";
inline constexpr const char* kWarnUnknownCode = "detection of a code absent from the map";
inline constexpr const char* kWarnTimeBackwards = "input older than the last one processed (ignored)";
inline constexpr const char* kWarnInvalidInput = "invalid input (ignored)";
inline constexpr const char* kWarnUnknownCamera = "frame of a camera the dataset does not list (ignored)";
inline constexpr const char* kWarnImage = "image not readable (frame skipped)";
inline constexpr const char* kWarnNumerical = "numerical failure of a correction";

// The streaming core of RunLocalizer, also fed line by line by the live mode. Inputs must come
// in time order overall (frames may arrive before the odometry that passes their stamp: they
// wait for it). Each processed frame is reported through `on_frame` (in input order).
class LocalizeStream {
 public:
  struct FrameOutput {
    PoseOutput pose;
    std::string camera;
    FrameResult result;
    double latency_ms = 0.0;  // odometry + update (+ detection_ms passed with the frame)
  };

  LocalizeStream(const Dataset& dataset, const MarkerMap& map, const LocalizeRunOptions& options,
                 std::function<void(const FrameOutput&)> on_frame);
  ~LocalizeStream();

  // `stamp_s` on the odometry's clock (odometry_time_offset_s is subtracted here).
  void AddOdometry(double stamp_s, const SE3d& T_odom_robot);
  // Planar only: the robot moved with (v, omega) since the previous velocity sample ([Bach]'s
  // unicycle, the exact arc: turn a = omega dt, chord 2 v / omega sin(a / 2) at a / 2). The samples are
  // integrated into odometry poses T_odom_robot and go the odometry's way (interpolation to
  // the frame instants included). Odometry clock, like AddOdometry.
  void AddVelocity(double stamp_s, double v_mps, double omega_radps);
  // `detection_ms`: time already spent detecting the frame's codes (added to its latency).
  void AddFrame(const DetectionFrame& frame, double detection_ms = 0.0);
  // Processes every waiting frame (end of input).
  void Flush();

  const Localizer& localizer() const { return localizer_; }
  // Where the map's codes should appear in `camera`'s image at `stamp_s` (their predicted
  // corners, online/visibility.h): the localizer's state carried forward by the odometry received
  // up to that instant (on a copy: the stream itself is not moved). Empty without a track.
  std::vector<Vector8d> PredictedQuads(const std::string& camera, double stamp_s) const;
  const RunWarnings& warnings() const { return warnings_; }
  long frames_with_codes() const { return frames_with_codes_; }
  long frames_with_map_codes() const { return frames_with_map_codes_; }
  // Throws std::runtime_error when enough frames with codes (and distinct codes) were seen and
  // none had a code of the map (`at_end`: however few there were).
  void CheckMapMatches(bool at_end) const;

 private:
  struct Pending {
    DetectionFrame frame;
    double detection_ms = 0.0;
  };
  void Drain(bool flush);
  void FeedOdometryBefore(double stamp_s, bool inclusive);
  void ProcessFrame(const Pending& pending);
  void CountStatus(StepStatus status, const std::string& example);

  std::set<MarkerKey> map_keys_;
  LocalizeRunOptions options_;
  std::function<void(const FrameOutput&)> on_frame_;
  Localizer localizer_;
  bool dataset_has_odometry_ = false;  // dataset mode: the frames outside its span are warned of
  std::deque<Pending> pending_;
  std::deque<StampedSE3> odometry_;          // received, not yet fed
  std::optional<StampedSE3> last_odometry_;  // last recorded sample fed (interpolation base)
  std::optional<StampedSE3> velocity_pose_;  // AddVelocity: the integrated T_odom_robot
  bool seen_odometry_ = false;
  std::optional<double> latest_input_s_;  // largest stamp received (frames and odometry)
  std::set<MarkerKey> unknown_keys_;      // detected codes absent from the map
  RunWarnings warnings_;
  long frames_with_codes_ = 0;
  long frames_with_map_codes_ = 0;
};

// The longest wait --realtime makes for one gap between consecutive stamps: a recording
// paused for an hour (or a stamp jump from 0 to 1e6) is replayed with this pause instead.
inline constexpr double kMaxRealtimeGapS = 1.0;

// Sleeps so that inputs are released at the pace of their stamps (the first stamp is "now"),
// each gap between consecutive stamps waited for at most `max_gap_s` (the longer gaps are
// counted: shortened_gaps()). Stamps going backwards do not wait.
class RealtimePacer {
 public:
  explicit RealtimePacer(double max_gap_s = kMaxRealtimeGapS) : max_gap_s_(max_gap_s) {}
  void WaitFor(double stamp_s);
  long shortened_gaps() const { return shortened_gaps_; }
  // "--realtime: 2 stamp gaps longer than 1 s were waited as 1 s", or "" when none was.
  std::string Summary() const;

 private:
  double max_gap_s_;
  std::optional<std::chrono::steady_clock::time_point> target_wall_;  // when the last stamp was due
  double last_stamp_s_ = 0.0;
  long shortened_gaps_ = 0;
};

}  // namespace waymark
