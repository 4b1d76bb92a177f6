#include "mapping/map_merge.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <map>
#include <set>

namespace waymark {
namespace {

bool PositiveDefinite(const Matrix6d& covariance) {
  if (!covariance.allFinite()) return false;
  const Eigen::LLT<Matrix6d> llt(0.5 * (covariance + covariance.transpose()));
  return llt.info() == Eigen::Success && llt.matrixL().toDenseMatrix().diagonal().minCoeff() > 1e-12;
}

// The map's codes as known markers (priors or fixed), then the survey's own others.
MarkerMap KnownMarkers(const MarkerMap& existing, const Dataset& survey) {
  MarkerMap known;
  for (MapMarker marker : existing.markers) {
    if (!marker.covariance || !PositiveDefinite(*marker.covariance)) {
      marker.covariance.reset();
      marker.fixed = true;
    }
    known.markers.push_back(marker);
  }
  if (survey.known_markers) {
    for (const MapMarker& marker : survey.known_markers->markers) {
      if (existing.Find(marker.key) == nullptr) known.markers.push_back(marker);
    }
  }
  return known;
}

// Renumbers the survey's components onto the map's (see the header comment).
void RenumberComponents(const MarkerMap& existing, MapBuildResult* result) {
  int next = 0;
  for (const MapMarker& m : existing.markers) next = std::max(next, m.component.value_or(0) + 1);
  std::map<int, int> number;
  for (const MapMarker& m : result->map.markers) {
    const MapMarker* old = existing.Find(m.key);
    if (old != nullptr && m.component) number.emplace(*m.component, old->component.value_or(0));
  }
  for (ComponentSummary& c : result->components) {
    if (number.count(c.component) == 0) number[c.component] = next++;
    c.component = number[c.component];
  }
  for (MapMarker& m : result->map.markers) {
    if (m.component) m.component = number[*m.component];
    if (const MapMarker* old = existing.Find(m.key)) m.fixed = old->fixed;  // held for the solve only
  }
}

}  // namespace

MapBuildResult MergeSurveyIntoMap(const MarkerMap& existing, const Dataset& survey,
                                  const MapBuildOptions& options) {
  Dataset merged = survey;
  merged.known_markers = KnownMarkers(existing, survey);
  MapBuildResult result = BuildMap(merged, options);
  RenumberComponents(existing, &result);
  size_t carried = 0;
  for (const MapMarker& old : existing.markers) {
    if (result.map.Find(old.key) != nullptr) continue;
    result.map.markers.push_back(old);
    ++carried;
  }
  result.notes.push_back("merge: " + std::to_string(existing.markers.size() - carried) +
                         " code(s) of the map " + "re-observed, " + std::to_string(carried) +
                         " carried over unchanged");
  return result;
}

}  // namespace waymark
