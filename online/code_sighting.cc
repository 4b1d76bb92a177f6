#include "online/code_sighting.h"

#include <stdexcept>

namespace waymark {

CodeSighting MakeCodeSighting(const Camera& camera, const MarkerObservation& observation, double size_m,
                              const MarkerPoseOptions& options, std::string* why) {
  CodeSighting sighting;
  sighting.observation = observation;
  MarkerPoseEstimate estimate;
  try {
    estimate = EstimateMarkerPose(observation.corners_px, size_m, camera, options);
  } catch (const std::runtime_error& error) {
    if (why) *why = error.what();
    return sighting;
  }
  for (const MarkerPoseSolution& solution : estimate.solutions)
    sighting.T_camera_marker.push_back(solution.T_camera_marker);
  if (!sighting.T_camera_marker.empty() && estimate.covariance.allFinite())
    sighting.covariance = estimate.covariance;
  sighting.ambiguous = estimate.ambiguous;
  if (!estimate.solutions.empty()) sighting.rms_px = estimate.best().rms_px;
  return sighting;
}

}  // namespace waymark
