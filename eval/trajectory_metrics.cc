#include "eval/trajectory_metrics.h"

#include <cmath>
#include <sstream>
#include <stdexcept>

#include "util/check.h"

namespace waymark::eval {
namespace {

constexpr double kRadToDeg = 180.0 / M_PI;

void CheckPaired(const Trajectory& gt, const Trajectory& est, const char* what) {
  if (gt.size() != est.size()) {
    throw std::invalid_argument(std::string(what) + ": trajectories are not associated (sizes differ)");
  }
  if (gt.empty()) throw std::invalid_argument(std::string(what) + ": no pose pairs");
}

std::vector<std::pair<size_t, size_t>> ConsecutivePairs(const std::vector<size_t>& ids) {
  std::vector<std::pair<size_t, size_t>> pairs;
  for (size_t k = 1; k < ids.size(); ++k) pairs.emplace_back(ids[k - 1], ids[k]);
  return pairs;
}

}  // namespace

AteResult ComputeAte(const Trajectory& gt, const Trajectory& est) {
  CheckPaired(gt, est, "ATE");
  AteResult result;
  for (size_t i = 0; i < gt.size(); ++i) {
    result.stamps_s.push_back(gt[i].stamp_s);
    result.translation_errors_m.push_back((gt[i].T.translation() - est[i].T.translation()).norm());
    result.rotation_errors_deg.push_back(kRadToDeg * RotationAngleBetween(est[i].T, gt[i].T));
  }
  result.translation_m = ComputeStats(result.translation_errors_m);
  result.rotation_deg = ComputeStats(result.rotation_errors_deg);
  result.axes = ComputeAxisErrors(gt, est);
  return result;
}

AxisErrors ComputeAxisErrors(const Trajectory& gt, const Trajectory& est) {
  CheckPaired(gt, est, "per-axis errors");
  std::vector<double> x_m, y_m, z_m, yaw_deg;
  for (size_t i = 0; i < gt.size(); ++i) {
    const Eigen::Vector3d d = est[i].T.translation() - gt[i].T.translation();
    x_m.push_back(std::abs(d.x()));
    y_m.push_back(std::abs(d.y()));
    z_m.push_back(std::abs(d.z()));
    yaw_deg.push_back(kRadToDeg * std::abs(WrapAngle(est[i].T.yaw() - gt[i].T.yaw())));
  }
  return {ComputeStats(x_m), ComputeStats(y_m), ComputeStats(z_m), ComputeStats(yaw_deg)};
}

const char* RpeUnitName(RpeUnit unit) { return unit == RpeUnit::kFrames ? "frames" : "m"; }

RpeUnit ParseRpeUnit(const std::string& name) {
  if (name == "frames" || name == "f") return RpeUnit::kFrames;
  if (name == "m") return RpeUnit::kMetres;
  throw std::invalid_argument("RPE unit '" + name + "': expected frames or m");
}

bool RpeOptions::Check(std::string* why) const {
  WAYMARK_CHECK_OPTION(IsFinitePositive(delta), "RPE delta must be a positive number");
  WAYMARK_CHECK_OPTION(unit != RpeUnit::kFrames || delta == std::floor(delta),
                       "RPE delta in frames must be an integer");
  return true;
}

std::vector<std::pair<size_t, size_t>> RpeIndexPairs(const Trajectory& est, const RpeOptions& options) {
  std::vector<size_t> ids;
  if (options.unit == RpeUnit::kFrames) {
    const size_t step = static_cast<size_t>(options.delta);
    for (size_t i = 0; i < est.size(); i += step) ids.push_back(i);
    return ConsecutivePairs(ids);
  }
  double path_m = 0.0;
  for (size_t i = 0; i < est.size(); ++i) {
    if (i > 0) path_m += (est[i].T.translation() - est[i - 1].T.translation()).norm();
    if (path_m >= options.delta) {
      ids.push_back(i);
      path_m = 0.0;
    }
  }
  return ConsecutivePairs(ids);
}

RpeResult ComputeRpe(const Trajectory& gt, const Trajectory& est, const RpeOptions& options) {
  CheckPaired(gt, est, "RPE");
  std::string why;
  if (!options.Check(&why)) throw std::invalid_argument(why);
  RpeResult result;
  result.options = options;
  result.index_pairs = RpeIndexPairs(est, options);
  if (result.index_pairs.empty()) {
    std::ostringstream why_empty;
    why_empty << "RPE: delta " << options.delta << " " << RpeUnitName(options.unit)
              << " leaves no pose pair among " << est.size()
              << " associated poses; try a smaller --rpe-delta";
    throw std::runtime_error(why_empty.str());
  }
  for (const auto& [i, j] : result.index_pairs) {
    const SE3d Q = gt[i].T.inverse() * gt[j].T;
    const SE3d P = est[i].T.inverse() * est[j].T;
    const SE3d E = Q.inverse() * P;
    result.translation_errors_m.push_back(E.translation().norm());
    result.rotation_errors_deg.push_back(kRadToDeg * LogSO3(E.rotation()).norm());
  }
  result.translation_m = ComputeStats(result.translation_errors_m);
  result.rotation_deg = ComputeStats(result.rotation_errors_deg);
  return result;
}

PeTeResult ComputePeTe(const Trajectory& gt, const Trajectory& predicted) {
  CheckPaired(gt, predicted, "PE/TE");
  PeTeResult result;
  std::vector<double> errors_3d_m;
  for (size_t k = 0; k < gt.size(); ++k) {
    const Eigen::Vector3d d = predicted[k].T.translation() - gt[k].T.translation();
    result.stamps_s.push_back(gt[k].stamp_s);
    result.position_errors_m.push_back(d.head<2>().norm());
    errors_3d_m.push_back(d.norm());
    result.heading_errors_deg.push_back(kRadToDeg *
                                        std::abs(WrapAngle(predicted[k].T.yaw() - gt[k].T.yaw())));
  }
  result.position_m = ComputeStats(result.position_errors_m);
  result.position_3d_m = ComputeStats(errors_3d_m);
  result.heading_deg = ComputeStats(result.heading_errors_deg);
  return result;
}

}  // namespace waymark::eval
