// Where to put the codes before they are installed (`waymark plan-codes`): candidate layouts on
// a floor plan's walls (plan/floor_plan.h), each judged by the error the map build and the online
// localizer would have on the survey path, predicted with the build's own covariance machinery.
//
// A layout is one code size z (of the plan's sizes) and one spacing s: on each face of each wall,
// codes at s/2 + k s from the wall's start (at least margin_m + z from both ends, the simulator's
// corridor rule), at code_height_m, facing out of that face. Codes no camera of the rig sees in
// at least two frames along the path are dropped (sim/world.h's visibility: range, angle, image,
// walls occluding). The first `anchors` codes kept are given as known (the gauge).
//
// Prediction of a layout: a survey along the path is simulated without noise (odometry equal to
// the path, corners exactly projected, pixel_sigma_px on every corner, frames at camera_hz) and
// built with `waymark map build`'s BuildMap (mapping/map_builder.h). Its marker covariances are
// the inverse of the Gauss-Newton information at the truth, which is what the build predicts for
// its own map on a real survey of that layout. Then
//   map error      the expected marker position RMS after the rigid alignment that `waymark eval
//                  --map` fits (eval/map_metrics.h PredictMapError, pooled): what a sim survey
//                  of the layout should measure;
//   online error   the localizer (runner/run.h, the options `waymark localize` uses) run on the
//                  same noise-free survey against the predicted map taken as exact
//                  (MapUncertainty::kIgnore): the RMS over its frames of the position sigma
//                  sqrt(P_xx + P_yy) of the pose relative to the map. Routes and goals are given in
//                  the map's frame, so the map's own frame error (the gauge drift, 2-3 times its
//                  aligned error in a 40 m loop) moves them with the robot; it is judged by the
//                  map criterion. (With the map's error considered, the filter's sigma is about
//                  the map's unaligned error: 21.7 mm for the default corridor.)
// A layout meets a target E when both are at most E, the map is one component and the localizer
// tracks at least 95 % of the frames from its first code on. Codes the build leaves unmapped are
// dropped from the layout (`unmapped` counts them).
//
// Search: for each size, the spacings from the sparsest to the densest; the first layout that
// meets E is that size's fewest codes (denser layouts of the same size have more codes). The
// chosen layout is the one with the fewest codes over all sizes (ties: the smaller size).
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "geometry/types.h"
#include "plan/floor_plan.h"

namespace waymark::plan {

struct PlacementOptions {
  double target_m = 0.01;
  std::vector<double> spacings_m = {4.0, 2.8, 2.0, 1.4, 1.0, 0.7, 0.5, 0.35, 0.25};
  std::function<void(const std::string&)> progress;  // one line per layout evaluated

  bool Check(std::string* why) const;
};

// Along the path, per metre driven.
struct MetrePrediction {
  double from_m = 0.0;
  int codes_in_view = 0;            // distinct codes seen in this metre
  double online_max_sigma_m = 0.0;  // largest predicted position sigma
  double map_sigma_m = 0.0;         // RMS position sigma of those codes in the map
};

struct LayoutPrediction {
  double size_m = 0.0;
  double spacing_m = 0.0;
  MarkerMap markers;  // the planned codes: planned poses, predicted covariances, anchors fixed
  std::optional<double> map_rms_m;
  double online_rms_m = 0.0;
  double online_max_m = 0.0;
  double tracked_fraction = 0.0;  // of the frames from the first tracked one on
  int components = 0;
  int unmapped = 0;
  bool meets = false;
  std::vector<MetrePrediction> per_metre;
  double path_length_m = 0.0;
};

struct PlacementResult {
  std::vector<LayoutPrediction> tried;  // in the order evaluated
  int chosen = -1;                      // index into tried; -1: no layout meets the target
};

// Throws std::invalid_argument when a path pose lies outside the walls' bounding box or a step
// of the path crosses a wall (naming the pose), or the path has fewer than two poses.
void CheckPath(const FloorPlan& plan, const Trajectory& path);

// The layout of one size and spacing, predicted.
LayoutPrediction PredictLayout(const FloorPlan& plan, const Trajectory& path, double size_m,
                               double spacing_m);

PlacementResult PlanCodes(const FloorPlan& plan, const Trajectory& path, const PlacementOptions& options);

}  // namespace waymark::plan
