#include "io/mrclam_io.h"

#include <cmath>
#include <set>
#include <sstream>

#include "geometry/unicycle.h"
#include "io/util.h"
#include "util/format.h"

namespace waymark {
namespace {

namespace fs = std::filesystem;
constexpr double kPi = 3.14159265358979323846;

std::vector<MrclamRow> ReadTable(const fs::path& path, size_t columns, const std::string& what) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec))
    throw FormatError(path, "missing file (expected columns: " + what + ")");
  return ParseMrclamTable(ReadTextFile(path), path, columns, what);
}

long AsInteger(const fs::path& path, const MrclamRow& row, size_t column, const std::string& name) {
  const double value = row.values[column];
  if (value != std::floor(value) || std::abs(value) > 1e9) {
    throw FormatError(path, row.line, name + ": expected an integer, got " + FormatDouble(value));
  }
  return static_cast<long>(value);
}

void CheckNonDecreasing(const fs::path& path, const std::vector<MrclamRow>& rows) {
  for (size_t i = 1; i < rows.size(); ++i) {
    if (rows[i].values[0] < rows[i - 1].values[0]) {
      throw FormatError(path, rows[i].line,
                        "time: expected non-decreasing stamps, got " + FormatDouble(rows[i].values[0]) +
                            " after " + FormatDouble(rows[i - 1].values[0]));
    }
  }
}

Trajectory ReadGroundtruth(const fs::path& path) {
  const std::vector<MrclamRow> rows = ReadTable(path, 4, "time x y theta");
  CheckNonDecreasing(path, rows);
  Trajectory trajectory;
  for (const MrclamRow& row : rows) {
    if (!trajectory.empty() && row.values[0] == trajectory.back().stamp_s) continue;  // a repeated stamp
    trajectory.push_back({row.values[0], SE2d(row.values[1], row.values[2], row.values[3]).ToSE3()});
  }
  if (trajectory.empty()) throw FormatError(path, "no poses");
  return trajectory;
}

std::string RobotName(long subject) { return "robot" + std::to_string(subject); }

}  // namespace

std::vector<MrclamRow> ParseMrclamTable(const std::string& text, const fs::path& path, size_t columns,
                                        const std::string& what) {
  std::vector<MrclamRow> rows;
  ForEachLine(text, [&](long line_number, std::string_view line) {
    const size_t first = line.find_first_not_of(" \t");
    if (first == std::string_view::npos || line[first] == '#') return;
    std::istringstream in{std::string(line)};
    MrclamRow row;
    row.line = line_number;
    std::string token;
    while (in >> token) {
      const std::optional<double> value = ParseFiniteDouble(token);
      if (!value) {
        throw FormatError(
            path, line_number,
            "expected " + std::to_string(columns) + " numbers (" + what + "), got '" + token + "'");
      }
      row.values.push_back(*value);
    }
    if (row.values.size() != columns) {
      throw FormatError(path, line_number,
                        "expected " + std::to_string(columns) + " numbers (" + what + "), got " +
                            std::to_string(row.values.size()));
    }
    rows.push_back(std::move(row));
  });
  return rows;
}

MrclamImport ImportMrclam(const fs::path& run_dir, const MrclamImportOptions& options) {
  std::error_code ec;
  if (!fs::is_directory(run_dir, ec)) throw FormatError(run_dir, "not a directory (expected an MRCLAM run)");
  // Barcodes: subject -> barcode, both unique.
  const fs::path barcodes_path = run_dir / "Barcodes.dat";
  std::map<long, long> barcode_of_subject;
  std::map<long, long> subject_of_barcode;
  for (const MrclamRow& row : ReadTable(barcodes_path, 2, "subject barcode")) {
    const long subject = AsInteger(barcodes_path, row, 0, "subject");
    const long barcode = AsInteger(barcodes_path, row, 1, "barcode");
    if (!barcode_of_subject.emplace(subject, barcode).second)
      throw FormatError(barcodes_path, row.line, "subject " + std::to_string(subject) + " listed twice");
    if (!subject_of_barcode.emplace(barcode, subject).second)
      throw FormatError(barcodes_path, row.line, "barcode " + std::to_string(barcode) + " listed twice");
  }
  if (barcode_of_subject.empty()) throw FormatError(barcodes_path, "no subjects");
  std::set<long> robots;
  for (const auto& [subject, barcode] : barcode_of_subject) {
    if (fs::exists(run_dir / ("Robot" + std::to_string(subject) + "_Odometry.dat"), ec))
      robots.insert(subject);
  }
  if (robots.empty()) throw FormatError(run_dir, "no RobotN_Odometry.dat for any subject N of Barcodes.dat");

  // Landmark truth (evaluation only): subject x y sx sy.
  const fs::path landmarks_path = run_dir / "Landmark_Groundtruth.dat";
  MarkerMap landmarks_truth;
  for (const MrclamRow& row : ReadTable(landmarks_path, 5, "subject x y sx sy")) {
    const long subject = AsInteger(landmarks_path, row, 0, "subject");
    const auto it = barcode_of_subject.find(subject);
    if (it == barcode_of_subject.end() || robots.count(subject)) {
      throw FormatError(landmarks_path, row.line,
                        "subject " + std::to_string(subject) + " is not a landmark of Barcodes.dat");
    }
    MapMarker marker;
    marker.is_point = true;
    marker.key = {kFamilyBarcode, std::to_string(it->second)};
    if (landmarks_truth.Find(marker.key))
      throw FormatError(landmarks_path, row.line, "subject " + std::to_string(subject) + " listed twice");
    marker.T_world_marker =
        SE3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(row.values[1], row.values[2], 0.0));
    Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
    covariance(0, 0) = row.values[3] * row.values[3];
    covariance(1, 1) = row.values[4] * row.values[4];
    marker.position_covariance = covariance;
    landmarks_truth.markers.push_back(marker);
  }

  MrclamImport result;
  for (const long subject : robots) {
    const std::string prefix = "Robot" + std::to_string(subject) + "_";
    MrclamRobotReport report;
    report.name = RobotName(subject);
    Dataset dataset;
    dataset.config.name = report.name;
    dataset.config.motion = MotionModel::kPlanar;
    dataset.config.odometry_sigma = options.odometry_sigma;

    const fs::path odometry_path = run_dir / (prefix + "Odometry.dat");
    const std::vector<MrclamRow> odometry_rows = ReadTable(odometry_path, 3, "time v w");
    CheckNonDecreasing(odometry_path, odometry_rows);
    if (odometry_rows.size() < 2) throw FormatError(odometry_path, "expected at least 2 velocity samples");
    std::vector<VelocitySample> samples;
    for (const MrclamRow& row : odometry_rows)
      samples.push_back({row.values[0], row.values[1], row.values[2]});
    Trajectory odometry = IntegrateVelocities(samples);
    // Equal stamps give equal poses: keep one (TUM stamps of a trajectory increase).
    Trajectory unique;
    for (const StampedSE3& pose : odometry) {
      if (!unique.empty() && pose.stamp_s == unique.back().stamp_s) {
        unique.back() = pose;
      } else {
        unique.push_back(pose);
      }
    }
    dataset.odometry = std::move(unique);
    dataset.has_odometry_file = true;
    report.odometry_samples = odometry_rows.size();
    const double t_first = dataset.odometry.front().stamp_s, t_last = dataset.odometry.back().stamp_s;

    const fs::path measurement_path = run_dir / (prefix + "Measurement.dat");
    const std::vector<MrclamRow> measurements = ReadTable(measurement_path, 4, "time barcode range bearing");
    CheckNonDecreasing(measurement_path, measurements);
    for (const MrclamRow& row : measurements) {
      const double stamp_s = row.values[0];
      const long barcode = AsInteger(measurement_path, row, 1, "barcode");
      const double range_m = row.values[2], bearing_rad = row.values[3];
      if (!(range_m > 0.0)) {
        throw FormatError(measurement_path, row.line,
                          "range: expected a positive range, got " + FormatDouble(range_m));
      }
      if (std::abs(bearing_rad) > kPi) {
        throw FormatError(measurement_path, row.line,
                          "bearing: expected an angle within +-pi, got " + FormatDouble(bearing_rad));
      }
      const auto it = subject_of_barcode.find(barcode);
      if (it == subject_of_barcode.end()) {
        ++report.misreads;
        ++report.misread_barcodes[std::to_string(barcode)];
        continue;
      }
      if (it->second == subject) {
        ++report.own_barcode;
        continue;
      }
      if (stamp_s < t_first || stamp_s > t_last) {
        ++report.outside_odometry;
        continue;
      }
      if (dataset.range_bearing.empty() || dataset.range_bearing.back().stamp_s != stamp_s) {
        dataset.range_bearing.push_back({stamp_s, {}, {}});
      }
      RangeBearingFrame& frame = dataset.range_bearing.back();
      if (robots.count(it->second)) {
        frame.robots.push_back({RobotName(it->second), std::to_string(barcode), range_m, bearing_rad});
        ++report.robot_sightings;
      } else {
        RangeBearingObservation obs;
        obs.key = {kFamilyBarcode, std::to_string(barcode)};
        obs.range_m = range_m;
        obs.bearing_rad = bearing_rad;
        frame.landmarks.push_back(obs);
        ++report.landmark_observations;
      }
    }
    dataset.has_range_bearing_file = true;
    report.frames = dataset.range_bearing.size();

    const fs::path truth_path = run_dir / (prefix + "Groundtruth.dat");
    dataset.groundtruth_trajectory = ReadGroundtruth(truth_path);
    dataset.groundtruth_markers = landmarks_truth;
    if (options.known_start) {
      const std::optional<SE3d> T_world_start =
          InterpolateTrajectory(*dataset.groundtruth_trajectory, t_first, 1.0);
      if (!T_world_start) {
        throw FormatError(truth_path, "no ground-truth pose within 1 s around the first odometry stamp " +
                                          FormatDouble(t_first) + " (needed by --known-start)");
      }
      dataset.config.start_prior = StartPrior{*T_world_start, options.start_sigma_m, options.start_sigma_rad};
    }
    result.robots.push_back(std::move(dataset));
    result.reports.push_back(std::move(report));
  }
  return result;
}

}  // namespace waymark
