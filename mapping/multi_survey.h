// Several surveys as one (`waymark map build D1 D2 ...` with the code families of
// mapping/map_builder.h): the datasets are laid end to end in time and built as one survey, tied
// through the codes they share, and the smoothed trajectory is split back per dataset.
//
// Dataset k's stamps (odometry, detections, images) are shifted by offset_k so that it starts
// gap_s after the previous one ends; gap_s exceeds the ingest's max_odometry_gap_s, so the
// odometry is split there (mapping/survey.h) and no increment joins two surveys. Cameras are
// renamed "<dataset>.<camera>" (each survey keeps its own calibration). markers.json entries are
// merged (the same key twice must be the same entry). motion, default_marker_size_m,
// odometry_sigma and payload must agree where set.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "geometry/types.h"

namespace waymark {

struct SurveyPart {
  std::string name;
  double offset_s = 0.0;              // combined stamp = own stamp + offset_s
  double begin_s = 0.0, end_s = 0.0;  // combined stamps of the part's first and last sample
};

struct CombinedSurvey {
  Dataset dataset;
  std::vector<SurveyPart> parts;
};

// Throws std::runtime_error when the datasets disagree (see the header) or two have one name.
CombinedSurvey CombineSurveys(const std::vector<const Dataset*>& datasets, double gap_s);

// The poses of `trajectory` (combined stamps) that fall in each part, back at their own stamps.
std::map<std::string, Trajectory> SplitTrajectory(const CombinedSurvey& combined,
                                                  const Trajectory& trajectory);

}  // namespace waymark
