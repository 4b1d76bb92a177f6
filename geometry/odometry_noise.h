// The random-walk terms of dataset.yaml's odometry_sigma (OdometrySigma, geometry/types.h;
// docs/mapping.md, "Odometry noise models"): between two instants T seconds and L metres of
// path apart, on every axis,
//   translation variance  trans_per_sqrt_s^2 T + trans_per_sqrt_m^2 L
//   rotation variance     rot_per_sqrt_s^2 T + rot_per_sqrt_m^2 L
// They add over any split of a stretch, so the map build's links between frames
// (factors/odometry_covariance.h, mapping/survey.h) and the localizer's per-sample predictions
// (online/motion_model.h) state the same drift whatever the odometry or frame rate.
#pragma once

#include <cmath>
#include <stdexcept>

#include "geometry/types.h"
#include "util/format.h"

namespace waymark {

struct OdometryWalkVariance {
  double translation = 0.0;  // m^2 per axis
  double rotation = 0.0;     // rad^2 per axis
};

// Throws std::invalid_argument when a random-walk term is negative or not finite.
inline void CheckRandomWalkTerms(const OdometrySigma& sigma) {
  for (const double v :
       {sigma.trans_per_sqrt_s, sigma.rot_per_sqrt_s, sigma.trans_per_sqrt_m, sigma.rot_per_sqrt_m}) {
    if (!(std::isfinite(v) && v >= 0.0))
      throw std::invalid_argument("odometry_sigma: the random-walk terms must be finite and >= 0");
  }
}

// The variances over duration_s seconds and path_m metres (header comment). Throws
// std::invalid_argument on a bad term (CheckRandomWalkTerms) or a negative or non-finite
// duration or path.
inline OdometryWalkVariance OdometryRandomWalk(const OdometrySigma& sigma, double duration_s, double path_m) {
  CheckRandomWalkTerms(sigma);
  if (!(std::isfinite(duration_s) && duration_s >= 0.0 && std::isfinite(path_m) && path_m >= 0.0)) {
    throw std::invalid_argument("odometry random walk: duration and path must be finite and >= 0, got " +
                                FormatDouble(duration_s) + " s and " + FormatDouble(path_m) + " m");
  }
  return {sigma.trans_per_sqrt_s * sigma.trans_per_sqrt_s * duration_s +
              sigma.trans_per_sqrt_m * sigma.trans_per_sqrt_m * path_m,
          sigma.rot_per_sqrt_s * sigma.rot_per_sqrt_s * duration_s +
              sigma.rot_per_sqrt_m * sigma.rot_per_sqrt_m * path_m};
}

}  // namespace waymark
