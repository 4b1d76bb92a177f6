// One code seen in one image, as the localizer consumes it: the detected corners plus the
// code's single-image pose solutions (geometry/marker_pose.h), which initialization, the loosely
// coupled update and relocalization need. The tightly coupled update uses only the corners, so
// Localizer::AddDetections leaves the pose unsolved (`solved` false) and the localizer solves
// it only when one of those needs it.
#pragma once

#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "geometry/camera.h"
#include "geometry/marker_pose.h"
#include "geometry/pose.h"
#include "geometry/types.h"

namespace waymark {

struct CodeSighting {
  MarkerObservation observation;
  std::vector<SE3d> T_camera_marker;   // best first (IPPE gives two); empty when unavailable
  std::optional<Matrix6d> covariance;  // of T_camera_marker[0], right perturbation
  bool ambiguous = false;              // the two solutions fit about equally well
  bool solved = true;                  // false: the pose fields above were not computed yet
  double rms_px = std::numeric_limits<double>::infinity();  // reprojection RMS of solution 0
};

// Runs EstimateMarkerPose on the observation. When the estimator rejects the corners
// (degenerate quad, code seen from behind, outside the field of view) the sighting keeps its
// corners but has no pose, and `why` (if given) receives the estimator's message.
CodeSighting MakeCodeSighting(const Camera& camera, const MarkerObservation& observation, double size_m,
                              const MarkerPoseOptions& options = {}, std::string* why = nullptr);

}  // namespace waymark
