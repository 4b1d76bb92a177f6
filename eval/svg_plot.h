// A hand-written SVG figure of an evaluation (no plotting dependency):
//   top panel   top view (x right, y up, equal axis scales, metres) of the ground-truth
//               trajectory, the aligned estimate, and the markers: true (squares) and
//               estimated (crosses, joined to their true pose by a thin line);
//   bottom panel translation error against time since the first stamp: ATE per pair, PE at each
//               correction instant (dots) when predicted poses were given.
// All coordinates are in the ground truth's world frame.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "eval/map_metrics.h"
#include "eval/trajectory_eval.h"
#include "geometry/types.h"

namespace waymark::eval {

struct PlotMarker {
  std::string label;  // MarkerKey::ToString()
  std::optional<Eigen::Vector3d> p_true;
  std::optional<Eigen::Vector3d> p_est;  // already in the ground truth's frame
};

struct PlotInput {
  const TrajectoryEvaluation* trajectory = nullptr;  // may be null (map-only figure)
  std::vector<PlotMarker> markers;
  std::string title;
};

// Markers of an estimated map (moved by `alignment` into the ground truth's frame) and of a
// true map, matched by key. Either map may be null.
std::vector<PlotMarker> PlotMarkersFromMaps(const MarkerMap* est, const Sim3Alignment& alignment,
                                            const MarkerMap* truth);

// Likewise, with each estimated marker moved by its own component's alignment.
std::vector<PlotMarker> PlotMarkersFromMapEval(const MarkerMap& est, const MarkerMap& truth,
                                               const MapEvalResult& result);

// The SVG document. Throws std::invalid_argument when there is nothing to draw.
std::string RenderSvg(const PlotInput& input);

}  // namespace waymark::eval
