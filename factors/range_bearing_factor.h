// Range and bearing of a point landmark seen from a planar robot (range_bearing.jsonl).
//
//   p_robot = R(theta)^T (l_world - t_world)          (the landmark in the robot frame, 2-D)
//   range   = |p_robot|,   bearing = atan2(p_robot_y, p_robot_x)
//   r = [(range - range_measured) / sigma_range,  wrap(bearing - bearing_measured) / sigma_bearing]
//
// T_world_robot = (t_world, theta) is the robot block, l_world the landmark's x, y in the world
// frame. The sensor is at the robot's origin with the robot's axes (x forward, y left); a
// measured elevation is applied by the caller (range_measured = range cos(elevation)).
// Parameter blocks (factors/pose_block.h, Euclidean):
//   T_world_robot [x y theta]
//   l_world       [x y]
// Returns false (Ceres rejects the step) when the landmark is within 1 mm of the robot's
// origin, where the bearing is undefined.
#pragma once

#include <ceres/autodiff_cost_function.h>

#include <cmath>
#include <stdexcept>
#include <string>

#include "factors/pose_block.h"
#include "util/format.h"

namespace waymark {

inline constexpr int kPointLandmark2Size = 2;

class RangeBearingFactor {
 public:
  // Throws std::invalid_argument unless the range is finite and positive, the bearing finite and
  // both sigmas finite and positive.
  RangeBearingFactor(double range_m, double bearing_rad, double sigma_range_m, double sigma_bearing_rad)
      : range_m_(range_m),
        bearing_rad_(bearing_rad),
        inv_sigma_range_(1.0 / sigma_range_m),
        inv_sigma_bearing_(1.0 / sigma_bearing_rad) {
    if (!std::isfinite(range_m) || !(range_m > 0.0) || !std::isfinite(bearing_rad) ||
        !std::isfinite(sigma_range_m) || !(sigma_range_m > 0.0) || !std::isfinite(sigma_bearing_rad) ||
        !(sigma_bearing_rad > 0.0)) {
      throw std::invalid_argument(
          "range-bearing factor: expected a positive range, a finite bearing and positive "
          "sigmas, got range " +
          FormatDouble(range_m) + ", bearing " + FormatDouble(bearing_rad) + ", sigmas " +
          FormatDouble(sigma_range_m) + ", " + FormatDouble(sigma_bearing_rad));
    }
  }

  template <typename T>
  bool operator()(const T* const T_world_robot, const T* const l_world, T* residuals) const {
    using std::atan2;
    using std::cos;
    using std::sin;
    using std::sqrt;
    const T dx = l_world[0] - T_world_robot[0];
    const T dy = l_world[1] - T_world_robot[1];
    const T c = cos(T_world_robot[2]), s = sin(T_world_robot[2]);
    const T px = c * dx + s * dy;
    const T py = -s * dx + c * dy;
    const T squared = px * px + py * py;
    if (squared < T(1e-6)) return false;
    residuals[0] = (sqrt(squared) - T(range_m_)) * T(inv_sigma_range_);
    residuals[1] = WrapAngleT(atan2(py, px) - T(bearing_rad_)) * T(inv_sigma_bearing_);
    return true;
  }

  static ceres::CostFunction* Create(double range_m, double bearing_rad, double sigma_range_m,
                                     double sigma_bearing_rad) {
    return new ceres::AutoDiffCostFunction<RangeBearingFactor, 2, kSE2BlockSize, kPointLandmark2Size>(
        new RangeBearingFactor(range_m, bearing_rad, sigma_range_m, sigma_bearing_rad));
  }

 private:
  const double range_m_;
  const double bearing_rad_;
  const double inv_sigma_range_;
  const double inv_sigma_bearing_;
};

// The same with the sensor's constant errors estimated (one block per robot):
//   r = [((1 + s_range) ((1 - c_depth) range + c_depth p_x) + b_range - range_measured) / sigma_range,
//        wrap((1 + k_bearing) bearing + b_bearing - bearing_measured) / sigma_bearing]
// b_range: a range offset (e.g. ranges to a cylinder's face, truth at its axis); b_bearing: the
// sensor's yaw on the robot; k_bearing: a bearing scale error (a camera whose focal length is
// off by a factor 1 / (1 + k) reads every bearing k times too large); c_depth: the share of the
// landmark's depth along the sensor's axis, p_x = range cos(bearing), in what the sensor reads as
// its range (a camera that ranges a code by its apparent size reads its depth: c_depth = 1);
// s_range: the range scale error at zero bearing. Blocks: T_world_robot [x y theta], l_world
// [x y], sensor [b_range b_bearing k_bearing c_depth s_range] (Euclidean; give it a weak prior,
// SensorBiasPrior, and hold the entries the caller does not estimate constant). With c_depth =
// s_range = 0 it is the distance model of the earlier 3-entry block.
inline constexpr int kRangeBearingSensorSize = 5;

// What the sensor reads as the range of a landmark at `range` and `bearing`, before its offset:
// (1 + s_range) ((1 - c_depth) range + c_depth range cos(bearing)); `sensor` is the block above.
template <typename T>
T SensedRange(const T& range, const T& bearing, const T* sensor) {
  using std::cos;
  return (T(1.0) + sensor[4]) * range * (T(1.0) - sensor[3] + sensor[3] * cos(bearing));
}

class BiasedRangeBearingFactor {
 public:
  BiasedRangeBearingFactor(double range_m, double bearing_rad, double sigma_range_m, double sigma_bearing_rad)
      : plain_(range_m, bearing_rad, sigma_range_m, sigma_bearing_rad),
        range_m_(range_m),
        bearing_rad_(bearing_rad),
        inv_sigma_range_(1.0 / sigma_range_m),
        inv_sigma_bearing_(1.0 / sigma_bearing_rad) {}

  template <typename T>
  bool operator()(const T* const T_world_robot, const T* const l_world, const T* const sensor,
                  T* residuals) const {
    if (!plain_(T_world_robot, l_world, residuals)) return false;
    // residuals[0] = (range - range_measured) / sigma; p_x / range = cos(bearing).
    const T range = residuals[0] / T(inv_sigma_range_) + T(range_m_);
    // residuals[1] = wrap(bearing - bearing_measured) / sigma: the bearing is
    // bearing_measured + that (wrapped to (-pi, pi] by the caller's atan2 and the wrap).
    const T bearing = WrapAngleT(residuals[1] / T(inv_sigma_bearing_) + T(bearing_rad_));
    residuals[0] = (SensedRange(range, bearing, sensor) + sensor[0] - T(range_m_)) * T(inv_sigma_range_);
    residuals[1] =
        WrapAngleT((T(1.0) + sensor[2]) * bearing + sensor[1] - T(bearing_rad_)) * T(inv_sigma_bearing_);
    return true;
  }

  static ceres::CostFunction* Create(double range_m, double bearing_rad, double sigma_range_m,
                                     double sigma_bearing_rad) {
    return new ceres::AutoDiffCostFunction<BiasedRangeBearingFactor, 2, kSE2BlockSize, kPointLandmark2Size,
                                           kRangeBearingSensorSize>(
        new BiasedRangeBearingFactor(range_m, bearing_rad, sigma_range_m, sigma_bearing_rad));
  }

 private:
  const RangeBearingFactor plain_;
  const double range_m_;
  const double bearing_rad_;
  const double inv_sigma_range_;
  const double inv_sigma_bearing_;
};

// The bearing part of BiasedRangeBearingFactor alone (1 residual, the same blocks): a sighting whose
// range is an outlier (a barcode's apparent size misread) and whose bearing is not.
class BiasedBearingFactor {
 public:
  BiasedBearingFactor(double range_m, double bearing_rad, double sigma_range_m, double sigma_bearing_rad)
      : biased_(range_m, bearing_rad, sigma_range_m, sigma_bearing_rad) {}

  template <typename T>
  bool operator()(const T* const T_world_robot, const T* const l_world, const T* const sensor,
                  T* residuals) const {
    T both[2];
    if (!biased_(T_world_robot, l_world, sensor, both)) return false;
    residuals[0] = both[1];
    return true;
  }

  static ceres::CostFunction* Create(double range_m, double bearing_rad, double sigma_range_m,
                                     double sigma_bearing_rad) {
    return new ceres::AutoDiffCostFunction<BiasedBearingFactor, 1, kSE2BlockSize, kPointLandmark2Size,
                                           kRangeBearingSensorSize>(
        new BiasedBearingFactor(range_m, bearing_rad, sigma_range_m, sigma_bearing_rad));
  }

 private:
  const BiasedRangeBearingFactor biased_;
};

// r = [b_range / sigma_range_m, b_bearing / sigma_bearing_rad, k_bearing / sigma_scale,
//      c_depth / sigma_depth, s_range / sigma_range_scale]: the weak prior that keeps an unexcited
// sensor error at 0 (an entry held constant by the caller gets any positive sigma).
struct SensorBiasPrior {
  SensorBiasPrior(double sigma_range_m, double sigma_bearing_rad, double sigma_scale,
                  double sigma_depth = 1.0, double sigma_range_scale = 1.0)
      : inv_{1.0 / sigma_range_m, 1.0 / sigma_bearing_rad, 1.0 / sigma_scale, 1.0 / sigma_depth,
             1.0 / sigma_range_scale} {}
  template <typename T>
  bool operator()(const T* const sensor, T* residuals) const {
    for (int i = 0; i < kRangeBearingSensorSize; ++i) residuals[i] = sensor[i] * T(inv_[i]);
    return true;
  }
  static ceres::CostFunction* Create(double sigma_range_m, double sigma_bearing_rad, double sigma_scale,
                                     double sigma_depth = 1.0, double sigma_range_scale = 1.0) {
    return new ceres::AutoDiffCostFunction<SensorBiasPrior, kRangeBearingSensorSize, kRangeBearingSensorSize>(
        new SensorBiasPrior(sigma_range_m, sigma_bearing_rad, sigma_scale, sigma_depth, sigma_range_scale));
  }
  const double inv_[kRangeBearingSensorSize];
};

}  // namespace waymark
