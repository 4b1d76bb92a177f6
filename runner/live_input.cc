#include "runner/live_input.h"

#include <chrono>
#include <iostream>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <vector>

#include "detect/common.h"
#include "io/detections_io.h"
#include "io/json_util.h"
#include "runner/image.h"
#include "util/format.h"

namespace waymark {

LiveInput::LiveInput(const Dataset& dataset, const MarkerMap& map, const LocalizeRunOptions& options,
                     std::ostream& out, std::ostream& err)
    : dataset_(dataset),
      map_(map),
      options_(options),
      out_(out),
      err_(err),
      region_policy_(options.predicted_regions),
      stream_(dataset, map, options, [this](const LocalizeStream::FrameOutput& output) { Write(output); }) {}

void LiveInput::Run(std::istream& in) {
  std::string line;
  while (std::getline(in, line)) AddLine(std::move(line));
  Finish();
}

void LiveInput::AddLine(std::string line) {
  ++line_number_;
  if (!line.empty() && line.back() == '\r') line.pop_back();
  if (line.find_first_not_of(" \t") == std::string::npos) return;
  try {
    HandleLine(line);
  } catch (const FormatError& e) {
    Reject(e.message());
  } catch (const std::invalid_argument& e) {
    Reject(e.what());
  }
}

void LiveInput::Finish() {
  stream_.Flush();
  stream_.CheckMapMatches(true);
}

void LiveInput::PrintSummary(std::ostream& out) const {
  out << "waymark localize --live: " << line_number_ << " lines, " << frames_ << " frames (" << tracking_
      << " tracking), " << malformed_ << " malformed lines skipped\n";
  if (images_ > 0) {
    out << "detection: " << images_ << " images, " << shed_images_ << " shed work under the "
        << options_.detector.live_budget_ms << " ms budget (" << skipped_attempts_
        << " second-pass attempts skipped)\n";
    const auto mean = [](double sum, long n) { return FormatFixed(n > 0 ? sum / n : 0.0, 2); };
    out << "detection: " << region_images_ << " images in the map's predicted regions only (CPU "
        << mean(region_cpu_ms_, region_images_) << " ms mean), " << whole_images_
        << " on the whole frame (CPU " << mean(whole_cpu_ms_, whole_images_) << " ms mean); all images: CPU "
        << mean(region_cpu_ms_ + whole_cpu_ms_, images_) << " ms mean\n";
    // The CPU above includes decoding the image files, which a camera's frames do not need.
    out << "detection: of which reading the image files: regions "
        << mean(region_read_cpu_ms_, region_images_) << " ms mean, whole frames "
        << mean(whole_read_cpu_ms_, whole_images_) << " ms mean; without it: regions "
        << mean(region_cpu_ms_ - region_read_cpu_ms_, region_images_) << " ms mean, whole frames "
        << mean(whole_cpu_ms_ - whole_read_cpu_ms_, whole_images_) << " ms mean; all images "
        << mean(region_cpu_ms_ + whole_cpu_ms_ - region_read_cpu_ms_ - whole_read_cpu_ms_, images_)
        << " ms mean\n";
  }
  for (const std::string& warning : stream_.warnings().Lines()) out << "warning: " << warning << "\n";
  if (!pacer_.Summary().empty()) out << "warning: " << pacer_.Summary() << "\n";
  for (const auto& [reason, count] : read_warnings_.counts)
    out << "warning: " << reason << ": " << count << "\n";
}

void LiveInput::Reject(const std::string& message) {
  ++malformed_;
  err_ << "waymark localize: stdin:" << line_number_ << ": " << message << "\n";
}

void LiveInput::Write(const LocalizeStream::FrameOutput& output) {
  ++frames_;
  tracking_ += output.pose.T_world_robot.has_value();
  out_ << FormatPoseLine(output.pose, output.camera, CountOutcomes(output.result), output.latency_ms) << "\n"
       << std::flush;
}

void LiveInput::HandleLine(const std::string& line) {
  // Syntax, numbers out of double range (1e400) and nesting: a FormatError, counted and skipped.
  const nlohmann::json object = ParseJsonLine(line, "stdin", line_number_);
  if (!object.is_object()) throw std::invalid_argument("expected a JSON object");
  const JsonSource source{"stdin", [this](const std::string&) { return std::optional<long>(line_number_); }};
  const double stamp_s = JsonNumber(source, *JsonMember(source, object, "", "t", true), "t");
  if (options_.realtime) pacer_.WaitFor(stamp_s);
  if (object.contains("T_odom_robot")) {
    JsonWarnUnknownKeys(source, object, "", {"t", "T_odom_robot"}, &read_warnings_);
    return stream_.AddOdometry(stamp_s, JsonPose(source, object["T_odom_robot"], "T_odom_robot"));
  }
  if (object.contains("v") || object.contains("omega")) {
    JsonWarnUnknownKeys(source, object, "", {"t", "v", "omega"}, &read_warnings_);
    const double v_mps = JsonNumber(source, *JsonMember(source, object, "", "v", true), "v");
    const double omega_radps = JsonNumber(source, *JsonMember(source, object, "", "omega", true), "omega");
    return stream_.AddVelocity(stamp_s, v_mps, omega_radps);
  }
  if (object.contains("markers")) {
    ReadWarnings warnings;
    std::vector<DetectionFrame> frames = ParseDetections(line, "stdin", &warnings, &dataset_.cameras);
    for (const auto& [reason, count] : warnings.counts) read_warnings_.counts[reason] += count;
    return stream_.AddFrame(frames.at(0));
  }
  if (object.contains("image")) {
    JsonWarnUnknownKeys(source, object, "", {"t", "camera", "image"}, &read_warnings_);
    const std::string camera = JsonString(source, *JsonMember(source, object, "", "camera", true), "camera");
    return HandleImage(camera, JsonString(source, object["image"], "image"), stamp_s);
  }
  throw std::invalid_argument(
      "expected an odometry line (T_odom_robot), a velocity line (v, omega), a detection line (markers) or "
      "an "
      "image line (image)");
}

void LiveInput::HandleImage(const std::string& camera, const std::string& path, double stamp_s) {
  if (!dataset_.cameras.count(camera))
    throw std::invalid_argument("camera: '" + camera + "' is not in the dataset");
  if (!detector_) {
    detector_ = CreateMultiDetector(DetectionFamilies(map_, options_.families), options_.detector);
    DetectorOptions regions = options_.detector;
    regions.close_up = false;  // a region is a crop of the frame, not a close-up photo
    region_detector_ = CreateMultiDetector(DetectionFamilies(map_, options_.families), regions);
  }
  const auto start = std::chrono::steady_clock::now();
  const double cpu_start = FrameClock::ProcessCpuMs();
  std::string why;
  const cv::Mat image = ReadImageFile(path, &why);
  if (image.empty()) throw std::invalid_argument(why);
  const double read_cpu_ms = FrameClock::ProcessCpuMs() - cpu_start;  // decoding the file
  DetectionFrame frame;
  frame.stamp_s = stamp_s;
  frame.camera = camera;
  frame.image = path;
  // Where the map says first (runner/predicted_regions.h): the codes the localizer puts in
  // this camera's view, each in its predicted region; the whole frame every N frames, when the
  // track is not sure, or when the regions gave nothing.
  const bool whole =
      region_policy_.WholeFrame(camera, stream_.localizer().tracking() == TrackingStatus::kTracking);
  int skipped = 0;
  if (whole) {
    frame.markers = detector_->Detect(image);
    skipped = detector_->SkippedAttempts();
  } else {
    const std::vector<PredictedRegion> regions =
        PredictedRegions(stream_.PredictedQuads(camera, stamp_s), image.size(), region_policy_.options());
    frame.markers = DetectInRegions(*region_detector_, image, regions, &skipped);
  }
  const double cpu_ms = FrameClock::ProcessCpuMs() - cpu_start;
  (whole ? whole_cpu_ms_ : region_cpu_ms_) += cpu_ms;
  (whole ? whole_read_cpu_ms_ : region_read_cpu_ms_) += read_cpu_ms;
  ++(whole ? whole_images_ : region_images_);
  ++images_;
  shed_images_ += skipped > 0;
  skipped_attempts_ += skipped;
  stream_.AddFrame(
      frame, std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
}

}  // namespace waymark
