#include "geometry/unicycle.h"

#include <cmath>
#include <stdexcept>

namespace waymark {

SE2d IntegrateArc(const SE2d& T_start, double v_mps, double w_radps, double dt_s) {
  const double theta = T_start.theta();
  const double dtheta = w_radps * dt_s;
  double x = T_start.x(), y = T_start.y();
  if (std::abs(dtheta) > 1e-9) {
    const double radius = v_mps / w_radps;
    x += radius * (std::sin(theta + dtheta) - std::sin(theta));
    y -= radius * (std::cos(theta + dtheta) - std::cos(theta));
  } else {
    x += v_mps * dt_s * std::cos(theta);
    y += v_mps * dt_s * std::sin(theta);
  }
  return SE2d(x, y, theta + dtheta);
}

Trajectory IntegrateVelocities(const std::vector<VelocitySample>& samples, const SE2d& T_odom_start) {
  Trajectory trajectory;
  trajectory.reserve(samples.size());
  SE2d T_odom_robot = T_odom_start;
  for (size_t i = 0; i < samples.size(); ++i) {
    if (i > 0) {
      const double dt_s = samples[i].stamp_s - samples[i - 1].stamp_s;
      if (!(dt_s >= 0.0)) throw std::invalid_argument("IntegrateVelocities: stamps decrease");
      T_odom_robot = IntegrateArc(T_odom_robot, samples[i - 1].v_mps, samples[i - 1].w_radps, dt_s);
    }
    trajectory.push_back({samples[i].stamp_s, T_odom_robot.ToSE3()});
  }
  return trajectory;
}

}  // namespace waymark
