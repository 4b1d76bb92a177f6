// `waymark localize --live`'s input: JSON lines (odometry, velocities, detections, images;
// docs/formats.md "Localization input/output") fed to a LocalizeStream, one pose line per
// camera frame written to `out`. A malformed line is reported on `err` with its line number,
// counted and skipped: no line, however broken, stops the stream.
#pragma once

#include <iosfwd>
#include <memory>
#include <string>

#include "detect/detector.h"
#include "geometry/types.h"
#include "runner/run.h"

namespace waymark {

class LiveInput {
 public:
  // `out` receives the pose lines (flushed at once), `err` one line per malformed input line.
  LiveInput(const Dataset& dataset, const MarkerMap& map, const LocalizeRunOptions& options,
            std::ostream& out, std::ostream& err);

  // Reads every line of `in`, then flushes the stream (frames still waiting are answered).
  void Run(std::istream& in);
  // One input line (its number is counted here); a malformed one is reported and counted.
  void AddLine(std::string line);
  // Answers the frames still waiting and checks the map matches what was seen.
  void Finish();

  // "waymark localize --live: N lines, F frames (T tracking), M malformed lines skipped" and
  // the warnings, one per line.
  void PrintSummary(std::ostream& out) const;
  long malformed_lines() const { return malformed_; }
  long frames() const { return frames_; }

 private:
  void Reject(const std::string& message);
  void Write(const LocalizeStream::FrameOutput& output);
  void HandleLine(const std::string& line);
  void HandleImage(const std::string& camera, const std::string& path, double stamp_s);

  const Dataset& dataset_;
  const MarkerMap& map_;
  LocalizeRunOptions options_;
  std::ostream& out_;
  std::ostream& err_;
  PredictedRegionPolicy region_policy_;  // before stream_, whose frames it serves
  LocalizeStream stream_;
  std::unique_ptr<MarkerDetector> detector_;         // created at the first image line
  std::unique_ptr<MarkerDetector> region_detector_;  // the same without close-ups (regions)
  ReadWarnings read_warnings_;
  RealtimePacer pacer_;
  long line_number_ = 0, malformed_ = 0, frames_ = 0, tracking_ = 0;
  long images_ = 0, shed_images_ = 0, skipped_attempts_ = 0;  // image lines; those that shed work
  // Where the map says (runner/predicted_regions.h): images detected in the predicted regions
  // only and on the whole frame; their CPU time (ms, every thread of the process).
  long region_images_ = 0, whole_images_ = 0;
  double region_cpu_ms_ = 0.0, whole_cpu_ms_ = 0.0;
  double region_read_cpu_ms_ = 0.0, whole_read_cpu_ms_ = 0.0;  // of which decoding the image files
};

}  // namespace waymark
