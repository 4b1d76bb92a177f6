#include "runner/run.h"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/imgcodecs.hpp>
#include <set>
#include <sstream>
#include <stdexcept>
#include <thread>

#include "geometry/square_marker.h"
#include "io/util.h"
#include "runner/image.h"
#include "util/check.h"

namespace waymark {

namespace {

double ElapsedMs(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

std::string StampText(double stamp_s) { return "t=" + FormatDouble(stamp_s); }

}  // namespace

FrameCounts CountOutcomes(const FrameResult& result) {
  FrameCounts counts;
  for (const CorrectionResult& correction : result.corrections) {
    counts.accepted += correction.outcome == CorrectionOutcome::kAccepted;
    counts.gated += correction.outcome == CorrectionOutcome::kGated;
    counts.unknown += correction.outcome == CorrectionOutcome::kUnknownMarker;
  }
  return counts;
}

std::string FormatPoseLine(const PoseOutput& pose, const std::string& camera, const FrameCounts& counts,
                           std::optional<double> latency_ms) {
  const auto numbers = [](const auto& values) {
    std::string text = "[";
    for (Eigen::Index i = 0; i < values.size(); ++i) text += (i ? ", " : "") + FormatDouble(values(i));
    return text + "]";
  };
  std::string line = "{\"t\": " + FormatDouble(pose.stamp_s) + ", \"camera\": " + QuoteString(camera) +
                     ", \"status\": \"" + TrackingStatusName(pose.tracking) + "\"";
  if (pose.T_world_robot) {
    const SE3d& T = *pose.T_world_robot;
    line += ", \"T_world_robot\": {\"t\": " + numbers(T.translation()) +
            ", \"q_xyzw\": " + numbers(T.rotation().coeffs()) + "}";
  }
  if (pose.T_world_robot && pose.covariance) {
    const Eigen::MatrixXd row_major = pose.covariance->transpose();  // column-major storage of P^T
    line +=
        ", \"covariance\": " + numbers(Eigen::Map<const Eigen::VectorXd>(row_major.data(), row_major.size()));
  }
  line += ", \"accepted\": " + std::to_string(counts.accepted) +
          ", \"gated\": " + std::to_string(counts.gated) + ", \"unknown\": " + std::to_string(counts.unknown);
  if (latency_ms) line += ", \"latency_ms\": " + FormatDouble(std::round(*latency_ms * 1e3) / 1e3);
  return line + "}";
}

// ---- Warnings ----

void RunWarnings::Add(const std::string& reason, const std::string& example) {
  auto [it, inserted] = counts_.try_emplace(reason, 0, example);
  ++it->second.first;
}

long RunWarnings::Count(const std::string& reason) const {
  const auto it = counts_.find(reason);
  return it == counts_.end() ? 0 : it->second.first;
}

long RunWarnings::Total() const {
  long total = 0;
  for (const auto& [reason, count] : counts_) total += count.first;
  return total;
}

std::vector<std::string> RunWarnings::Lines() const {
  std::vector<std::string> lines;
  for (const auto& [reason, count] : counts_) {
    lines.push_back(reason + ": " + std::to_string(count.first) + " (first: " + count.second + ")");
  }
  return lines;
}

// ---- Options ----

bool LocalizeRunOptions::Check(std::string* why) const {
  WAYMARK_CHECK_OPTION(localizer.Check(why), nullptr);
  WAYMARK_CHECK_OPTION(map_check_frames >= 1 && map_check_codes >= 1,
                       "localize options: map_check_frames and map_check_codes must be >= 1");
  WAYMARK_CHECK_OPTION(IsFiniteAtLeast(odometry_wait_s, 0.0),
                       "localize options: odometry_wait_s must be finite and >= 0");
  WAYMARK_CHECK_OPTION(IsFiniteAtLeast(late_frame_window_s, 0.0),
                       "localize options: late_frame_window_s must be finite and >= 0");
  WAYMARK_CHECK_OPTION(std::isfinite(odometry_time_offset_s),
                       "localize options: odometry_time_offset_s must be finite");
  WAYMARK_CHECK_OPTION(!detect_images || detector.Check(why), nullptr);
  WAYMARK_CHECK_OPTION(predicted_regions.Check(why), nullptr);
  return true;
}

LocalizerOptions DefaultLocalizerOptions(const Dataset& dataset) {
  LocalizerOptions options;
  options.motion = dataset.config.motion;
  options.loose_noise = Eigen::VectorXd::Constant(StateDim(options.motion), 0.001);
  if (dataset.config.odometry_sigma) options.odometry.sigma = *dataset.config.odometry_sigma;
  std::optional<double> pixel_sigma_px;
  for (const auto& [name, camera] : dataset.cameras) {
    if (camera.pixel_sigma) pixel_sigma_px = std::max(pixel_sigma_px.value_or(0.0), *camera.pixel_sigma);
  }
  if (pixel_sigma_px && *pixel_sigma_px > 0.0) options.default_pixel_sigma_px = *pixel_sigma_px;
  return options;
}

std::vector<std::string> DetectionFamilies(const MarkerMap& map, const std::vector<std::string>& requested) {
  if (!requested.empty()) return requested;
  const std::vector<std::string> supported = SupportedFamilies();
  std::set<std::string> in_map;
  for (const MapMarker& marker : map.markers) {
    if (std::find(supported.begin(), supported.end(), marker.key.family) != supported.end())
      in_map.insert(marker.key.family);
  }
  if (in_map.empty()) return {kFamilyQr, kFamilyDataMatrix, "apriltag-36h11"};
  return {in_map.begin(), in_map.end()};
}

std::optional<DetectionFrame> DetectImageFile(MarkerDetector& detector, const std::filesystem::path& file,
                                              double stamp_s, const std::string& camera, std::string* why) {
  const cv::Mat image = ReadImageFile(file, why);
  if (image.empty()) return std::nullopt;
  DetectionFrame frame;
  frame.stamp_s = stamp_s;
  frame.camera = camera;
  frame.markers = detector.Detect(image);
  frame.image = file.string();
  return frame;
}

// ---- Streaming core ----

namespace {

std::vector<CameraInfo> CameraList(const Dataset& dataset) {
  std::vector<CameraInfo> cameras;
  for (const auto& [name, camera] : dataset.cameras) cameras.push_back(camera);
  return cameras;
}

}  // namespace

LocalizeStream::LocalizeStream(const Dataset& dataset, const MarkerMap& map,
                               const LocalizeRunOptions& options,
                               std::function<void(const FrameOutput&)> on_frame)
    : options_(options),
      on_frame_(std::move(on_frame)),
      localizer_(options.localizer, map, CameraList(dataset)),
      dataset_has_odometry_(!dataset.odometry.empty()) {
  std::string why;
  if (!options_.Check(&why)) throw std::invalid_argument(why);
  for (const MapMarker& marker : map.markers) {
    if (marker.has_pose) map_keys_.insert(marker.key);
  }
}

LocalizeStream::~LocalizeStream() = default;

void LocalizeStream::CountStatus(StepStatus status, const std::string& example) {
  switch (status) {
    case StepStatus::kOk:
      return;
    case StepStatus::kTimeWentBackwards:
      return warnings_.Add(kWarnTimeBackwards, example);
    case StepStatus::kInvalidInput:
      return warnings_.Add(kWarnInvalidInput, example);
    case StepStatus::kUnknownCamera:
      return warnings_.Add(kWarnUnknownCamera, example);
    case StepStatus::kNotPositiveDefinite:
    case StepStatus::kNonFiniteCovariance:
      return warnings_.Add(kWarnNumerical, example + ": " + StepStatusName(status));
  }
}

void LocalizeStream::AddOdometry(double odometry_stamp_s, const SE3d& T_odom_robot) {
  const double stamp_s = odometry_stamp_s - options_.odometry_time_offset_s;
  const std::string example = "odometry at " + StampText(stamp_s);
  if (!std::isfinite(stamp_s) || !T_odom_robot.IsFinite()) return warnings_.Add(kWarnInvalidInput, example);
  const std::optional<double> last_s =
      !odometry_.empty() ? std::optional<double>(odometry_.back().stamp_s)
                         : (last_odometry_ ? std::optional<double>(last_odometry_->stamp_s) : std::nullopt);
  if (last_s && stamp_s <= *last_s) return warnings_.Add(kWarnTimeBackwards, example);
  seen_odometry_ = true;
  latest_input_s_ = std::max(latest_input_s_.value_or(stamp_s), stamp_s);
  odometry_.push_back({stamp_s, T_odom_robot});
  Drain(false);
}

void LocalizeStream::AddVelocity(double stamp_s, double v_mps, double omega_radps) {
  const std::string example = "velocity at " + StampText(stamp_s);
  if (options_.localizer.motion != MotionModel::kPlanar || !std::isfinite(stamp_s) || !std::isfinite(v_mps) ||
      !std::isfinite(omega_radps)) {
    return warnings_.Add(kWarnInvalidInput, example + " (velocities need finite numbers and planar motion)");
  }
  if (!velocity_pose_) {
    velocity_pose_ = StampedSE3{stamp_s, SE3d()};
  } else {
    if (stamp_s <= velocity_pose_->stamp_s) return warnings_.Add(kWarnTimeBackwards, example);
    const double dt_s = stamp_s - velocity_pose_->stamp_s;
    const double a = omega_radps * dt_s;  // the arc's chord: 2 v / omega sin(a / 2) (v dt when straight)
    const double d = std::abs(a) > 1e-9 ? 2.0 * v_mps / omega_radps * std::sin(0.5 * a) : v_mps * dt_s;
    velocity_pose_ = StampedSE3{
        stamp_s, velocity_pose_->T * SE2d(d * std::cos(0.5 * a), d * std::sin(0.5 * a), a).ToSE3()};
  }
  AddOdometry(stamp_s, velocity_pose_->T);
}

void LocalizeStream::AddFrame(const DetectionFrame& frame, double detection_ms) {
  if (std::isfinite(frame.stamp_s))
    latest_input_s_ = std::max(latest_input_s_.value_or(frame.stamp_s), frame.stamp_s);
  pending_.push_back({frame, detection_ms});
  Drain(false);
}

void LocalizeStream::Flush() { Drain(true); }

void LocalizeStream::Drain(bool flush) {
  while (!pending_.empty()) {
    const double stamp_s = pending_.front().frame.stamp_s;
    const bool odometry_past = (!odometry_.empty() && odometry_.back().stamp_s >= stamp_s) ||
                               (last_odometry_ && last_odometry_->stamp_s >= stamp_s);
    const bool waited_enough = latest_input_s_ && *latest_input_s_ - stamp_s > options_.odometry_wait_s;
    if (!(flush || odometry_past || !seen_odometry_ || waited_enough || !std::isfinite(stamp_s))) break;
    const Pending pending = std::move(pending_.front());
    pending_.pop_front();
    ProcessFrame(pending);
  }
  if (!pending_.empty()) return;
  // Odometry within late_frame_window_s of the newest input waits (a late frame may still come).
  const double hold_from_s = flush || !latest_input_s_ ? std::numeric_limits<double>::infinity()
                                                       : *latest_input_s_ - options_.late_frame_window_s;
  FeedOdometryBefore(hold_from_s, true);
}

void LocalizeStream::FeedOdometryBefore(double stamp_s, bool inclusive) {
  while (!odometry_.empty() &&
         (odometry_.front().stamp_s < stamp_s || (inclusive && odometry_.front().stamp_s == stamp_s))) {
    const StampedSE3& sample = odometry_.front();
    CountStatus(localizer_.AddOdometry(sample.stamp_s, sample.T), "odometry at " + StampText(sample.stamp_s));
    last_odometry_ = sample;
    odometry_.pop_front();
  }
}

std::vector<Vector8d> LocalizeStream::PredictedQuads(const std::string& camera, double stamp_s) const {
  if (!localizer_.state().mean().allFinite() || localizer_.tracking() == TrackingStatus::kUninitialized)
    return {};
  Localizer ahead = localizer_;
  std::optional<StampedSE3> last = last_odometry_;
  for (const StampedSE3& sample : odometry_) {
    if (sample.stamp_s > stamp_s) {
      if (last && last->stamp_s < stamp_s) {
        const double a = (stamp_s - last->stamp_s) / (sample.stamp_s - last->stamp_s);
        ahead.AddOdometry(stamp_s, InterpolateScrew(last->T, sample.T, a));
      }
      break;
    }
    ahead.AddOdometry(sample.stamp_s, sample.T);
    last = sample;
  }
  // Codes near the image's border count too (the negative-evidence test leaves them out: a
  // miss there says little), and any chance of being in view is enough to look.
  VisibilityOptions visibility = options_.localizer.visibility;
  visibility.border_px = 0.0;
  visibility.min_in_view = 1e-3;
  std::vector<Vector8d> quads;
  for (const ExpectedCode& code : ahead.PredictCodesInView(camera, visibility)) quads.push_back(code.px);
  return quads;
}

// Brings the odometry to the frame's instant (interpolated between the recorded samples around
// it), then corrects with the frame's codes.
void LocalizeStream::ProcessFrame(const Pending& pending) {
  const auto start = std::chrono::steady_clock::now();
  const DetectionFrame& frame = pending.frame;
  const std::string example = frame.camera + " frame at " + StampText(frame.stamp_s);
  if (std::isfinite(frame.stamp_s)) {
    FeedOdometryBefore(frame.stamp_s, true);
    const bool at_sample = last_odometry_ && last_odometry_->stamp_s == frame.stamp_s;
    if (last_odometry_ && last_odometry_->stamp_s < frame.stamp_s && !odometry_.empty()) {
      const StampedSE3& next = odometry_.front();
      const double a = (frame.stamp_s - last_odometry_->stamp_s) / (next.stamp_s - last_odometry_->stamp_s);
      CountStatus(localizer_.AddOdometry(frame.stamp_s, InterpolateScrew(last_odometry_->T, next.T, a)),
                  "odometry interpolated to " + example);
    } else if (!at_sample && (seen_odometry_ || dataset_has_odometry_) &&
               (!last_odometry_ || (last_odometry_->stamp_s < frame.stamp_s && odometry_.empty()))) {
      warnings_.Add(kWarnOutsideOdometry, example);  // before the first sample or after the last
    }
  }
  bool has_map_code = false;
  for (const MarkerObservation& observation : frame.markers) {
    // A square not identified yet (id "*") is one of the map's squares, if it has any.
    const bool unidentified_square =
        observation.key.family == kFamilySquare && observation.key.id == kUnidentifiedSquareId;
    if (map_keys_.count(observation.key) ||
        (unidentified_square && std::any_of(map_keys_.begin(), map_keys_.end(), [](const MarkerKey& key) {
           return key.family == kFamilySquare;
         }))) {
      has_map_code = true;
    } else {
      warnings_.Add(kWarnUnknownCode, observation.key.ToString() + " in the " + example);
      unknown_keys_.insert(observation.key);
    }
  }
  FrameOutput output;
  output.camera = frame.camera;
  output.result = localizer_.AddDetections(frame);
  CountStatus(output.result.status, example);
  const bool rejected = output.result.status == StepStatus::kTimeWentBackwards ||
                        output.result.status == StepStatus::kInvalidInput ||
                        output.result.status == StepStatus::kUnknownCamera;
  if (rejected) {
    output.pose.stamp_s = frame.stamp_s;
    output.pose.tracking = localizer_.tracking();
  } else {
    output.pose = localizer_.Output();
    frames_with_codes_ += !frame.markers.empty();
    frames_with_map_codes_ += has_map_code;
  }
  output.latency_ms = pending.detection_ms + ElapsedMs(start);
  if (on_frame_) on_frame_(output);
  CheckMapMatches(false);
}

void LocalizeStream::CheckMapMatches(bool at_end) const {
  if (frames_with_map_codes_ > 0 || frames_with_codes_ == 0) return;
  if (!at_end && (frames_with_codes_ < options_.map_check_frames ||
                  static_cast<long>(unknown_keys_.size()) < options_.map_check_codes))
    return;
  std::ostringstream message;
  message << "none of the " << unknown_keys_.size() << " codes detected in " << frames_with_codes_
          << " frames is in the map (first: "
          << (unknown_keys_.empty() ? "?" : unknown_keys_.begin()->ToString())
          << "): is the map of another place?";
  throw std::runtime_error(message.str());
}

// ---- Pacing ----

void RealtimePacer::WaitFor(double stamp_s) {
  if (!std::isfinite(stamp_s)) return;
  if (!target_wall_) {
    target_wall_ = std::chrono::steady_clock::now();
    last_stamp_s_ = stamp_s;
    return;
  }
  double gap_s = stamp_s - last_stamp_s_;
  if (!(gap_s > 0.0)) return;
  last_stamp_s_ = stamp_s;
  if (gap_s > max_gap_s_) {
    gap_s = max_gap_s_;
    ++shortened_gaps_;
  }
  // Each due time follows the previous one (not the first): the capped gaps add up, and the
  // duration converted is at most max_gap_s, far from the clock's range.
  *target_wall_ +=
      std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(gap_s));
  if (*target_wall_ > std::chrono::steady_clock::now()) std::this_thread::sleep_until(*target_wall_);
}

std::string RealtimePacer::Summary() const {
  if (shortened_gaps_ == 0) return "";
  std::ostringstream text;
  text << "--realtime: " << shortened_gaps_ << " stamp gap" << (shortened_gaps_ == 1 ? "" : "s")
       << " longer than " << max_gap_s_ << " s " << (shortened_gaps_ == 1 ? "was" : "were") << " waited as "
       << max_gap_s_ << " s";
  return text.str();
}

}  // namespace waymark

// ---- Whole datasets ----

namespace waymark {

namespace {

// One input of a dataset: an odometry sample, a detections.jsonl frame or an images.csv row.
struct RunEvent {
  enum Kind { kOdometry, kDetections, kImage } kind;
  double stamp_s;
  size_t index;
};

// The streams to merge: odometry first (it wins ties), then one per camera, each in file order.
std::vector<std::vector<RunEvent>> BuildStreams(const Dataset& dataset, bool images,
                                                double odometry_offset_s) {
  std::vector<std::vector<RunEvent>> streams(1);
  for (size_t i = 0; i < dataset.odometry.size(); ++i)
    streams[0].push_back({RunEvent::kOdometry, dataset.odometry[i].stamp_s - odometry_offset_s, i});
  std::map<std::string, size_t> camera_stream;
  const auto stream_of = [&](const std::string& camera) -> std::vector<RunEvent>& {
    auto [it, inserted] = camera_stream.try_emplace(camera, streams.size());
    if (inserted) streams.emplace_back();
    return streams[it->second];
  };
  if (images) {
    for (size_t i = 0; i < dataset.images.size(); ++i)
      stream_of(dataset.images[i].camera).push_back({RunEvent::kImage, dataset.images[i].stamp_s, i});
  } else {
    for (size_t i = 0; i < dataset.detections.size(); ++i)
      stream_of(dataset.detections[i].camera)
          .push_back({RunEvent::kDetections, dataset.detections[i].stamp_s, i});
  }
  return streams;
}

// Merges the streams by the stamp at their heads (ties: the lower stream) and calls fn per event.
template <typename Fn>
void MergeStreams(const std::vector<std::vector<RunEvent>>& streams, Fn fn) {
  std::vector<size_t> next(streams.size(), 0);
  for (;;) {
    int best = -1;
    for (size_t s = 0; s < streams.size(); ++s) {
      if (next[s] >= streams[s].size()) continue;
      if (best < 0 || streams[s][next[s]].stamp_s < streams[best][next[best]].stamp_s)
        best = static_cast<int>(s);
    }
    if (best < 0) return;
    fn(streams[best][next[best]++]);
  }
}

void CheckRunInputs(const Dataset& dataset, const LocalizeRunOptions& options) {
  std::string why;
  if (!options.Check(&why)) throw std::invalid_argument(why);
  if (dataset.cameras.empty())
    throw std::invalid_argument("dataset " + dataset.dir.string() + " has no camera");
  if (options.detect_images && dataset.images.empty()) {
    throw std::invalid_argument("dataset " + dataset.dir.string() + ": no images (images.csv) to detect on");
  }
  if (!options.detect_images && dataset.detections.empty() && !dataset.images.empty()) {
    throw std::invalid_argument(
        "dataset " + dataset.dir.string() +
        ": no detections.jsonl, only images: detect on them (waymark localize --detect-images)");
  }
}

// Appends one frame's output to the run: every output, and the tracked pose (one per stamp:
// a later camera at the same instant replaces the earlier one, having seen more codes).
void CollectFrame(const LocalizeStream::FrameOutput& output, LocalizeRun* run) {
  run->outputs.push_back(output.pose);
  run->cameras.push_back(output.camera);
  run->latency_ms.push_back(output.latency_ms);
  run->frame_counts.push_back(CountOutcomes(output.result));
  if (!output.pose.T_world_robot) return;
  const StampedSE3 pose{output.pose.stamp_s, *output.pose.T_world_robot};
  if (!run->trajectory.empty() && run->trajectory.back().stamp_s == pose.stamp_s) {
    run->trajectory.back() = pose;
  } else if (run->trajectory.empty() || run->trajectory.back().stamp_s < pose.stamp_s) {
    run->trajectory.push_back(pose);
  }
}

// The predictions before correction, one per stamp (the first: before any camera corrected).
Trajectory OnePerStamp(const Trajectory& trajectory) {
  Trajectory result;
  for (const StampedSE3& pose : trajectory) {
    if (result.empty() || pose.stamp_s > result.back().stamp_s) result.push_back(pose);
  }
  return result;
}

}  // namespace

LocalizeRun RunLocalizer(const Dataset& dataset, const MarkerMap& map, const LocalizeRunOptions& options) {
  CheckRunInputs(dataset, options);
  LocalizeRun run;
  LocalizeStream stream(dataset, map, options,
                        [&run](const LocalizeStream::FrameOutput& output) { CollectFrame(output, &run); });
  std::unique_ptr<MarkerDetector> detector;
  if (options.detect_images)
    detector = CreateMultiDetector(DetectionFamilies(map, options.families), options.detector);
  const std::vector<std::vector<RunEvent>> streams =
      BuildStreams(dataset, options.detect_images, options.odometry_time_offset_s);
  size_t total_frames = 0, frames = 0;
  for (size_t s = 1; s < streams.size(); ++s) total_frames += streams[s].size();
  RealtimePacer pacer;
  RunWarnings image_warnings;
  MergeStreams(streams, [&](const RunEvent& event) {
    if (options.realtime) pacer.WaitFor(event.stamp_s);
    if (event.kind == RunEvent::kOdometry) {
      const StampedSE3& sample = dataset.odometry[event.index];
      return stream.AddOdometry(sample.stamp_s, sample.T);
    }
    if (event.kind == RunEvent::kDetections) {
      stream.AddFrame(dataset.detections[event.index]);
    } else {
      const ImageEntry& entry = dataset.images[event.index];
      const auto start = std::chrono::steady_clock::now();
      std::string why;
      const std::optional<DetectionFrame> frame =
          DetectImageFile(*detector, dataset.dir / entry.path, entry.stamp_s, entry.camera, &why);
      if (frame) {
        stream.AddFrame(*frame, ElapsedMs(start));
      } else {
        image_warnings.Add(kWarnImage, why);
      }
    }
    if (options.progress && ++frames % 50 == 0) {
      options.progress("frame " + std::to_string(frames) + "/" + std::to_string(total_frames));
    }
  });
  stream.Flush();
  stream.CheckMapMatches(true);
  run.counters = stream.localizer().counters();
  run.predicted = OnePerStamp(stream.localizer().predicted_before_correction());
  run.warnings = stream.warnings().Lines();
  for (const std::string& line : image_warnings.Lines()) run.warnings.push_back(line);
  if (stream.frames_with_codes() == 0) run.warnings.push_back("no code detected in the whole run");
  if (!pacer.Summary().empty()) run.warnings.push_back(pacer.Summary());
  run.frames_with_codes = stream.frames_with_codes();
  run.frames_with_map_codes = stream.frames_with_map_codes();
  return run;
}

}  // namespace waymark
