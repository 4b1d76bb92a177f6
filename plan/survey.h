// The survey's poses for plan/route.h: the dataset localized against the map with the online
// localizer (runner/run.h, the options `waymark localize` uses), one SurveyPose per camera
// instant while tracking, with the codes of the map detected at that instant by any camera and
// the map component the pose is in (that of the last code seen: each component of a map has its
// own world frame, so a route uses the poses of one component only).
#pragma once

#include <vector>

#include "geometry/types.h"
#include "plan/route.h"

namespace waymark::plan {

// Throws std::invalid_argument for a survey that is not planar or has no odometry, and what
// RunLocalizer throws (a map of another place).
std::vector<SurveyPose> LocalizeSurvey(const Dataset& survey, const MarkerMap& map);

// The odometry noise the survey's localizer used (for RouteOptions::odometry).
OdometryNoise SurveyOdometryNoise(const Dataset& survey);

}  // namespace waymark::plan
