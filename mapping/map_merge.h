// Merging a new survey into an existing map.
//
// The existing map's codes become known markers of the survey: a code with a covariance enters
// the optimization as an SE(3) pose prior with that covariance (factors/pose_prior_se3_factor.h,
// the right perturbation of map.json), a code without one (or with one that is not positive
// definite) is held fixed. The survey's own markers.json entries are kept for codes the map does
// not hold. The survey is then mapped as by BuildMap (mapping/map_builder.h), so the codes it
// re-observes are updated, new codes are added in the map's frame, and codes of the map the
// survey does not see are carried over unchanged.
// Components: a component of the survey that holds a code of the map takes that code's component
// number; other components get numbers after the map's largest.
#pragma once

#include "geometry/types.h"
#include "mapping/map_builder.h"

namespace waymark {

// Throws like BuildMap.
MapBuildResult MergeSurveyIntoMap(const MarkerMap& existing, const Dataset& survey,
                                  const MapBuildOptions& options = {});

}  // namespace waymark
