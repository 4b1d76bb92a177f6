// `waymark dataset info DIR`: validates a dataset directory (io/dataset_io.h) and prints a
// summary to stdout. Warnings counted while reading are summarized on stdout; their first
// messages go to stderr. Bad input: one line on stderr naming the file (and line), exit 1.
#include <iostream>
#include <stdexcept>
#include <string>
#include <vector>

#include "cli/args.h"
#include "cli/command.h"
#include "geometry/types.h"
#include "io/dataset_io.h"
#include "util/format.h"

namespace waymark::cli {
namespace {

constexpr const char* kUsage = R"(Usage:
  waymark dataset info DIR [--strict]

Reads every file of the dataset directory DIR (dataset.yaml, cameras/*.yaml, odometry,
detections, images.csv, markers.json, groundtruth/, reference/; docs/formats.md), checks
them and their cross-references, and prints a summary to stdout: name, motion, cameras,
frames and detections per family, distinct and known markers, odometry (poses, time span,
path length), images, ground truth and reference, and the warnings counted.

Exit status: 0 when the dataset is valid, 1 on the first error (one line on stderr naming
the file and line).

Options:
  --strict   also exit 1 when warnings were counted (rejected detections, unknown keys,
             missing images, markers without a size)
)";

// "297 poses over 29.599 s, 1 markers", or "absent".
std::string TruthText(const std::optional<Trajectory>& trajectory, const std::optional<MarkerMap>& map) {
  if (!trajectory && !map) return "absent";
  std::string text = "trajectory ";
  if (trajectory) {
    text += std::to_string(trajectory->size()) + " poses";
    if (trajectory->size() > 1)
      text += " over " + FormatFixed(trajectory->back().stamp_s - trajectory->front().stamp_s, 3) + " s";
  } else {
    text += "absent";
  }
  return text + ", markers " + (map ? std::to_string(map->markers.size()) : std::string("absent"));
}

void PrintSummary(const Dataset& dataset, std::ostream& out) {
  const DatasetConfig& config = dataset.config;
  const DatasetSummary summary = SummarizeDataset(dataset);
  out << "dataset: " << config.name << " (" << dataset.dir.string() << ")\n"
      << "motion: " << (config.motion == MotionModel::kPlanar ? "planar" : "free") << "\n"
      << "cameras: " << dataset.cameras.size() << "\n";
  for (const std::string& name : config.cameras) {
    const CameraInfo& camera = dataset.cameras.at(name);
    out << "  " << name << ": " << CameraModelName(camera.model) << " " << camera.width << "x"
        << camera.height << "\n";
  }
  if (dataset.has_detections_file) {
    out << "frames: " << summary.frames << " (" << config.detections_file << ")\n"
        << "detections: " << summary.detections;
    std::string families;
    for (const auto& [family, count] : summary.detections_per_family) {
      families += (families.empty() ? "" : ", ") + family + ": " + std::to_string(count);
    }
    out << (families.empty() ? "" : " (" + families + ")") << "\n"
        << "distinct markers: " << summary.distinct_markers << "\n";
  } else {
    out << "frames: none (no " << config.detections_file << ")\n";
  }
  out << "known markers: "
      << (dataset.known_markers ? std::to_string(summary.known_markers) + " (" + config.markers_file + ")"
                                : "none")
      << "\n";
  if (dataset.has_odometry_file) {
    out << "odometry: " << summary.odometry_poses << " poses, " << FormatFixed(summary.odometry_span_s, 3)
        << " s, path " << FormatFixed(summary.odometry_path_length_m, 3) << " m (" << config.odometry_file
        << ")\n";
  } else {
    out << "odometry: none\n";
  }
  if (dataset.has_range_bearing_file) {
    long landmarks = 0, robots = 0;
    for (const RangeBearingFrame& frame : dataset.range_bearing) {
      landmarks += static_cast<long>(frame.landmarks.size());
      robots += static_cast<long>(frame.robots.size());
    }
    out << "range-bearing: " << dataset.range_bearing.size() << " stamps, " << landmarks
        << " landmark observations, " << robots << " robot sightings (" << config.range_bearing_file << ")\n";
  }
  if (config.start_prior) {
    const SE2d T = SE2d::FromSE3(config.start_prior->T_world_robot);
    out << "start prior: x " << FormatFixed(T.x(), 3) << " m, y " << FormatFixed(T.y(), 3) << " m, yaw "
        << FormatFixed(T.theta(), 3) << " rad (sigma " << FormatDouble(config.start_prior->sigma_m) << " m, "
        << FormatDouble(config.start_prior->sigma_rad) << " rad)\n";
  }
  out << "images: "
      << (dataset.has_images_file ? std::to_string(dataset.images.size()) + " (" + config.images_file + ")"
                                  : "none")
      << "\n";
  out << "ground truth: " << TruthText(dataset.groundtruth_trajectory, dataset.groundtruth_markers) << "\n";
  out << "reference: " << TruthText(dataset.reference_trajectory, dataset.reference_markers) << "\n";
  out << "warnings: " << dataset.warnings.Total();
  std::string reasons;
  for (const auto& [reason, count] : dataset.warnings.counts) {
    reasons += (reasons.empty() ? "" : ", ") + reason + ": " + std::to_string(count);
  }
  out << (reasons.empty() ? "" : " (" + reasons + ")") << "\n";
}

int RunInfo(const std::vector<std::string>& argv) {
  const Args args(argv, {}, {"strict"});
  if (args.Help()) {
    std::cout << kUsage;
    return 0;
  }
  args.ExpectPositionals(1, 1, "dataset directory DIR");
  const Dataset dataset = LoadDataset(args.positionals()[0]);
  PrintSummary(dataset, std::cout);
  for (const std::string& message : dataset.warnings.first_messages)
    std::cerr << "warning: " << message << "\n";
  if (dataset.warnings.Total() > static_cast<long>(dataset.warnings.first_messages.size())) {
    std::cerr << "warning: ... "
              << dataset.warnings.Total() - static_cast<long>(dataset.warnings.first_messages.size())
              << " more\n";
  }
  if (args.Flag("strict") && dataset.warnings.Total() > 0) {
    std::cerr << "waymark dataset: error: " << dataset.warnings.Total() << " warnings with --strict\n";
    return 1;
  }
  return 0;
}

int RunDataset(const std::vector<std::string>& args) {
  if (args.empty())
    throw std::invalid_argument("missing verb (expected `waymark dataset info DIR`; see --help)");
  const std::string& verb = args[0];
  const std::vector<std::string> rest(args.begin() + 1, args.end());
  if (verb == "info") return RunInfo(rest);
  throw std::invalid_argument("unknown verb '" + verb + "' (expected info; see --help)");
}

const CommandRegistrar kRegistrar(Command{"dataset", "validate a dataset directory and summarize it (info)",
                                          kUsage, RunDataset});

}  // namespace
}  // namespace waymark::cli
