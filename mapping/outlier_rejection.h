// Outlier rejection of a map build (mapping/map_builder.h, stage 3): which observations enter
// the global problem, duplicated codes (one id printed twice in one place), and the corner gate.
#pragma once

#include <utility>
#include <vector>

#include "geometry/pose.h"
#include "mapping/global_problem.h"
#include "mapping/initializer.h"
#include "mapping/map_builder.h"
#include "mapping/survey.h"

namespace waymark {

// Observations usable in the optimization: a usable single view, both ends placed.
std::vector<int> UsableObservations(const Survey& survey, const Initialization& init, MapBuildResult* result);

// The pairs (i, j), i < j, of `markers` whose centres are within `gate_m` in x, in lexicographic
// order: a sweep over the markers sorted by x, linear in the survey where all pairs are not.
std::vector<std::pair<size_t, size_t>> NearbyPairs(const std::vector<SE3d>& T_world_marker, double gate_m);

// Two distinct codes of one component mapped at one place (centres closer than half the
// larger code's size, faces within 60 degrees) cannot both be right: one is another code read
// under a wrong id (the same code misdecoded alike in several frames, which the id check cannot
// see). The code with fewer observations loses them, reported. Returns the observations kept.
std::vector<int> RemoveDuplicateCodes(const Survey& survey, const Initialization& init,
                                      const GlobalProblem& problem, const std::vector<int>& active,
                                      MapBuildResult* result);

// Drops the observations above the outlier gate, then codes seen in fewer than min_frames
// frames; reports both in result->outliers / unmapped. Returns the observations kept.
std::vector<int> RejectOutliers(const Survey& survey, const GlobalProblem& problem,
                                const std::vector<int>& active, const MapBuildOptions& options,
                                MapBuildResult* result);
}  // namespace waymark
