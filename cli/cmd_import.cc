// `waymark import mrclam RUN_DIR --out DIR [--known-start]`: one Waymark dataset per robot of an
// UTIAS MRCLAM run (io/mrclam_io.h), and each robot's dead reckoning against its ground truth.
#include <iostream>
#include <stdexcept>
#include <string>
#include <vector>

#include "cli/args.h"
#include "cli/command.h"
#include "eval/trajectory_eval.h"
#include "geometry/types.h"
#include "io/dataset_io.h"
#include "io/mrclam_io.h"
#include "util/format.h"

namespace waymark::cli {
namespace {

constexpr const char* kUsage = R"(Usage:
  waymark import mrclam RUN_DIR --out DIR [--known-start]

Converts a run of the UTIAS MRCLAM dataset (Barcodes.dat, RobotN_Odometry.dat,
RobotN_Measurement.dat, RobotN_Groundtruth.dat, Landmark_Groundtruth.dat) into one Waymark
dataset per robot, DIR/robot1 ... DIR/robotN (docs/formats.md "MRCLAM import"):
odometry.tum integrated from the commanded velocities at their own stamps, range_bearing.jsonl
(landmark barcodes, and other robots' barcodes as robot sightings), groundtruth/trajectory.tum
and groundtruth/markers.json for evaluation only.

Barcodes in no list of Barcodes.dat (misreads), a robot's own barcode and measurements outside
the odometry's time span are dropped and counted. Prints per robot what was kept and dropped,
and its dead reckoning against the ground truth: ATE from the true start pose (no alignment)
and after an SE(2) alignment.

Options:
  --out DIR        output directory (created; DIR/robotN is written for every robot)
  --known-start    write each robot's true pose at its first odometry stamp as a start prior
                   (dataset.yaml start_prior); nothing else comes from the truth
)";

// Dead reckoning in the world frame: the odometry moved so that it starts at `T_world_start`.
Trajectory DeadReckoning(const Trajectory& odometry, const SE3d& T_world_start) {
  const SE3d T_world_odom = T_world_start * odometry.front().T.inverse();
  Trajectory world;
  world.reserve(odometry.size());
  for (const StampedSE3& pose : odometry) world.push_back({pose.stamp_s, T_world_odom * pose.T});
  return world;
}

void PrintDeadReckoning(const Dataset& dataset, std::ostream& out) {
  const Trajectory& gt = *dataset.groundtruth_trajectory;
  const std::optional<SE3d> T_world_start = InterpolateTrajectory(gt, dataset.odometry.front().stamp_s, 1.0);
  eval::TrajectoryEvalOptions options;
  options.max_dt_s = 0.02;  // ground truth at 100 Hz, odometry at ~67 Hz
  options.align = eval::AlignmentMode::kSE2;
  const Trajectory& odometry = dataset.odometry;
  std::string aligned_text;
  try {
    const eval::TrajectoryEvaluation aligned = eval::EvaluateTrajectory(gt, odometry, std::nullopt, options);
    aligned_text = FormatFixed(aligned.ate.translation_m.rmse, 3) + " m after SE(2) alignment (" +
                   std::to_string(aligned.ate.stamps_s.size()) + " poses)";
  } catch (const eval::DegenerateAlignmentError&) {
    aligned_text = "no SE(2) alignment (the robot did not move)";
  }
  out << "  dead reckoning ATE RMSE: ";
  if (T_world_start) {
    options.align = eval::AlignmentMode::kNone;
    const eval::TrajectoryEvaluation from_start =
        eval::EvaluateTrajectory(gt, DeadReckoning(odometry, *T_world_start), std::nullopt, options);
    out << FormatFixed(from_start.ate.translation_m.rmse, 3) << " m from the true start, ";
  }
  out << aligned_text << "\n";
}

int RunMrclam(const std::vector<std::string>& argv) {
  const Args args(argv, {"out"}, {"known-start"});
  if (args.Help()) {
    std::cout << kUsage;
    return 0;
  }
  args.ExpectPositionals(1, 1, "MRCLAM run directory RUN_DIR");
  const std::filesystem::path out_dir = args.Require("out");
  MrclamImportOptions options;
  options.known_start = args.Flag("known-start");
  const MrclamImport import = ImportMrclam(args.positionals()[0], options);
  // Everything is read and checked before the first file is written.
  for (const Dataset& dataset : import.robots) WriteDataset(out_dir / dataset.config.name, dataset);
  for (size_t i = 0; i < import.robots.size(); ++i) {
    const Dataset& dataset = import.robots[i];
    const MrclamRobotReport& report = import.reports[i];
    std::cout << report.name << ": " << report.odometry_samples << " velocity samples, " << report.frames
              << " measurement stamps, " << report.landmark_observations << " landmark observations, "
              << report.robot_sightings << " robot sightings\n"
              << "  rejected: " << report.misreads << " misread barcodes";
    std::string list;
    for (const auto& [barcode, count] : report.misread_barcodes)
      list += (list.empty() ? "" : ", ") + barcode + " x" + std::to_string(count);
    std::cout << (list.empty() ? "" : " (" + list + ")") << ", " << report.own_barcode << " own barcode, "
              << report.outside_odometry << " outside the odometry's span\n";
    PrintDeadReckoning(dataset, std::cout);
  }
  std::cout << "wrote " << import.robots.size() << " datasets to " << out_dir.string()
            << (options.known_start ? " (with start priors)" : "") << "\n";
  return 0;
}

const CommandRegistrar kRegistrar(Command{
    "import mrclam", "convert an UTIAS MRCLAM run into one dataset per robot", kUsage, RunMrclam});

}  // namespace
}  // namespace waymark::cli
