// The UTIAS MRCLAM dataset (Leung, Halpern, Barfoot, Liu, IJRR 2011; docs/references.md [Leung])
// into Waymark datasets, one per robot (docs/formats.md "MRCLAM import").
//
// A run directory holds whitespace-separated tables with '#' comment lines (CRLF allowed):
//   Barcodes.dat               subject barcode            (subjects 1-5 robots, 6-20 landmarks)
//   RobotN_Odometry.dat        time v w                   commanded velocities (m/s, rad/s)
//   RobotN_Measurement.dat     time barcode range bearing (the second column is a barcode number)
//   RobotN_Groundtruth.dat     time x y theta             Vicon, evaluation only
//   Landmark_Groundtruth.dat   subject x y sx sy          Vicon, evaluation only
// The robots are the subjects N of Barcodes.dat with a RobotN_Odometry.dat; every other subject
// of Barcodes.dat is a landmark. Nothing but ground truth files (and the start prior with
// known_start) comes from the truth.
//
// Per robot (dataset name robotN, motion planar, no camera):
//   odometry.tum        the velocities integrated at their own stamps (geometry/unicycle.h) from
//                       the identity; odometry_sigma is the model of ImportMrclam's options;
//   range_bearing.jsonl one line per measurement stamp: landmark barcodes as family "barcode",
//                       id the barcode number; another robot's barcode as a robot sighting;
//                       barcodes in no list (misreads) and the robot's own barcode dropped and
//                       counted; measurements outside the odometry's span dropped and counted;
//   groundtruth/trajectory.tum, groundtruth/markers.json (landmarks as point landmarks, z = 0);
//   start_prior (known_start only): the true pose at the first odometry stamp, interpolated.
// Errors: FormatError naming the file and line ("Robot2_Odometry.dat:17: expected 3 numbers
// (time v w), got 2"), a missing file, stamps that decrease, a barcode or subject listed twice.
#pragma once

#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "geometry/types.h"

namespace waymark {

// One table of numbers: rows of exactly `columns` finite numbers; '#' lines and blank lines
// skipped. `what` names the columns in errors ("time v w").
struct MrclamRow {
  long line = 0;
  std::vector<double> values;
};
std::vector<MrclamRow> ParseMrclamTable(const std::string& text, const std::filesystem::path& path,
                                        size_t columns, const std::string& what);

struct MrclamImportOptions {
  bool known_start = false;
  // The start prior's sigmas (Vicon is good to about 1 mm; these allow for the clock sync of
  // about 1 ms and the interpolation).
  double start_sigma_m = 0.01;
  double start_sigma_rad = 0.01;
  // A-priori odometry noise written to dataset.yaml (per increment of the ~67 Hz stream); the
  // range-bearing map build re-estimates the odometry's noise from its residuals.
  OdometrySigma odometry_sigma{0.05, 0.05};
};

struct MrclamRobotReport {
  std::string name;
  size_t odometry_samples = 0;
  size_t frames = 0;  // lines of range_bearing.jsonl
  size_t landmark_observations = 0;
  size_t robot_sightings = 0;
  size_t misreads = 0;          // barcodes in no list
  size_t own_barcode = 0;       // the robot's own barcode (a misread too)
  size_t outside_odometry = 0;  // measurements before the first or after the last odometry stamp
  std::map<std::string, size_t> misread_barcodes;  // barcode -> count
};

struct MrclamImport {
  std::vector<Dataset> robots;  // robot1, robot2, ... (dir unset)
  std::vector<MrclamRobotReport> reports;
};

// Reads the whole run; throws FormatError on the first malformed file.
MrclamImport ImportMrclam(const std::filesystem::path& run_dir, const MrclamImportOptions& options);

}  // namespace waymark
