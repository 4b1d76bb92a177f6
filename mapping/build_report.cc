#include "mapping/build_report.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <ostream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "geometry/pose.h"
#include "util/format.h"

namespace waymark {

namespace {

// Outliers counted by reason, then by code (the codes with most rejected views first).
void AppendOutlierTallies(const std::vector<RejectedObservation>& outliers, std::ostream& out) {
  if (outliers.empty()) return;
  const OutlierTally tally = TallyOutliers(outliers);
  for (const auto& [reason, n] : tally.by_reason) out << "  " << n << " x " << reason << "\n";
  const std::vector<std::pair<std::string, size_t>>& codes = tally.by_code;
  out << "  by code:";
  const size_t shown = std::min<size_t>(codes.size(), 12);
  for (size_t i = 0; i < shown; ++i) out << " " << codes[i].first << " (" << codes[i].second << ")";
  if (shown < codes.size()) out << " ... " << codes.size() - shown << " more codes";
  out << "\n";
}

}  // namespace

OutlierTally TallyOutliers(const std::vector<RejectedObservation>& outliers) {
  OutlierTally tally;
  std::map<std::string, size_t> by_reason, by_code;
  for (const RejectedObservation& o : outliers) {
    const std::string reason = o.reason.substr(0, o.reason.find(':'));
    ++by_reason[reason.rfind("id conflicts with ", 0) == 0
                    ? "id conflicts with a code mapped at the same place"
                    : reason];
    ++by_code[o.key.ToString()];
  }
  tally.by_reason.assign(by_reason.begin(), by_reason.end());
  tally.by_code.assign(by_code.begin(), by_code.end());
  std::stable_sort(tally.by_code.begin(), tally.by_code.end(),
                   [](const auto& a, const auto& b) { return a.second > b.second; });
  return tally;
}

std::string FormatOdometryCalibration(const MapBuildResult& result) {
  if (!result.odometry_calibration) return "";
  const Eigen::Vector3d& c = *result.odometry_calibration;
  const std::optional<Eigen::Matrix3d>& covariance = result.odometry_calibration_covariance;
  const auto sigma = [&](int i, double scale) {
    return covariance ? " +- " + FormatSignificant(scale * std::sqrt(std::max(0.0, (*covariance)(i, i))), 2)
                      : std::string();
  };
  std::ostringstream out;
  out << "odometry calibration (" << (result.odometry_calibration_given ? "given" : "estimated")
      << "): heading drift " << FormatSignificant(c[0] * 180.0 / M_PI, 3) << sigma(0, 180.0 / M_PI)
      << " deg/m, turn scale " << FormatSignificant(100.0 * c[1], 3) << sigma(1, 100.0)
      << " %, distance scale " << FormatSignificant(100.0 * c[2], 3) << sigma(2, 100.0) << " %";
  if (!result.odometry_calibration_given) {
    out << " (reuse for this robot: --odometry-calibration " << FormatSignificant(c[0], 6) << ","
        << FormatSignificant(c[1], 6) << "," << FormatSignificant(c[2], 6);
    if (covariance) {
      for (int i = 0; i < 3; ++i)
        out << "," << FormatSignificant(std::sqrt(std::max(0.0, (*covariance)(i, i))), 3);
    }
    out << ")";
  }
  return out.str();
}

std::string FormatCameraMounts(const MapBuildResult& result) {
  std::ostringstream out;
  const auto triple = [](const Eigen::Vector3d& v, double scale, int digits) {
    return "[" + FormatFixed(scale * v.x(), digits) + ", " + FormatFixed(scale * v.y(), digits) + ", " +
           FormatFixed(scale * v.z(), digits) + "]";
  };
  for (const CameraMountEstimate& mount : result.mounts) {
    const Eigen::Vector3d r = LogSO3(mount.estimated.rotation());
    out << "camera mount " << mount.camera << " (estimated): t "
        << triple(mount.estimated.translation(), 1.0, 4) << " m";
    if (mount.covariance) {
      const Vector6d sd = mount.covariance->diagonal().cwiseMax(0.0).cwiseSqrt();
      out << " +- " << triple(sd.tail<3>(), 1e3, 2) << " mm";
    }
    out << ", rotation vector " << triple(r, 180.0 / M_PI, 3) << " deg";
    if (mount.covariance) {
      const Vector6d sd = mount.covariance->diagonal().cwiseMax(0.0).cwiseSqrt();
      out << " +- " << triple(sd.head<3>(), 180.0 / M_PI, 3) << " deg";
    }
    out << "; moved " << FormatFixed(RotationAngleBetween(mount.estimated, mount.given) * 180.0 / M_PI, 3)
        << " deg, "
        << FormatFixed(1e3 * (mount.estimated.translation() - mount.given.translation()).norm(), 1)
        << " mm from the camera file\n";
  }
  for (const CameraWiggleSummary& w : result.wiggles) {
    out << "camera wiggle " << w.camera << " (each frame's pose off the mount, " << w.frames
        << " frames): RMS " << FormatFixed(w.rms_rad * 180.0 / M_PI, 3) << " deg, "
        << FormatFixed(1e3 * w.rms_m, 1) << " mm; max " << FormatFixed(w.max_rad * 180.0 / M_PI, 3)
        << " deg, " << FormatFixed(1e3 * w.max_m, 1) << " mm\n";
  }
  return out.str();
}

std::string FormatBuildSummary(const MapBuildResult& result) {
  std::ostringstream out;
  out << "map: " << result.map.markers.size() << " markers in " << result.components.size()
      << " component(s), " << result.frames << " frames, " << result.observations << " observations used\n";
  for (const ComponentSummary& c : result.components) {
    out << "  component " << c.component << ": " << c.markers << " markers, " << c.frames << " frames ("
        << c.trajectory_poses << " poses in its trajectory), gauge: " << c.gauge << "\n";
  }
  for (const CameraReprojection& r : result.reprojection) {
    out << "  reprojection " << r.camera << ": RMS " << FormatSignificant(r.rms_px, 4) << " px, median "
        << FormatSignificant(r.median_px, 4) << " px over " << r.observations << " observations\n";
  }
  out << "outliers rejected: " << result.outliers.size() << "\n";
  AppendOutlierTallies(result.outliers, out);
  const size_t shown = std::min<size_t>(result.outliers.size(), 10);
  for (size_t i = 0; i < shown; ++i) {
    const RejectedObservation& o = result.outliers[i];
    out << "  " << o.key.ToString() << " at t = " << FormatSignificant(o.stamp_s, 12) << " s (" << o.camera
        << "): " << o.reason;
    if (o.rms_px > 0.0) out << ", " << FormatSignificant(o.rms_px, 4) << " px";
    out << "\n";
  }
  if (shown < result.outliers.size()) out << "  ... and " << result.outliers.size() - shown << " more\n";
  out << "unmapped codes: " << result.unmapped.size() << "\n";
  for (const UnmappedMarker& u : result.unmapped) out << "  " << u.key.ToString() << ": " << u.reason << "\n";
  out << "time: init " << FormatSignificant(result.init_time_s, 3) << " s, solve "
      << FormatSignificant(result.solver_time_s, 3) << " s, covariance "
      << FormatSignificant(result.covariance_time_s, 3) << " s\n";
  if (!result.phases.empty()) out << "phases: " << FormatPhases(result.phases) << "\n";
  out << "solver: " << FormatSignificant(result.solver_time_s, 4) << " s, " << result.iterations
      << " iterations, cost " << FormatSignificant(result.initial_cost, 8) << " -> "
      << FormatSignificant(result.final_cost, 8) << ", " << result.termination << "\n";
  out << "covariance: " << (result.covariance_computed ? "computed" : "not computed") << "\n";
  if (result.odometry_calibration) out << FormatOdometryCalibration(result) << "\n";
  out << FormatCameraMounts(result);
  for (const std::string& note : result.notes) out << "note: " << note << "\n";
  return out.str();
}

}  // namespace waymark
