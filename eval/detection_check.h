// Detections checked against exact corners (a rendered dataset's groundtruth/corners.jsonl,
// docs/sim.md): of the codes in view whose shortest side is at least min_side_px, how many were
// read with their id in the same image; of those, the worst of a code's four corner errors, and
// how many are off by more than gross_px (a corner refinement gone wrong).
#pragma once

#include <vector>

#include "geometry/types.h"

namespace waymark::eval {

struct DetectionCheckOptions {
  double min_side_px = 20.0;
  double gross_px = 2.0;
};

struct DetectionCheck {
  DetectionCheckOptions options;
  long codes_in_view = 0;
  long read = 0;
  std::vector<double> worst_corner_px;  // per code read

  // Codes read whose worst corner is off by more than options.gross_px.
  long Gross() const;
  // The median of worst_corner_px (util/stats.h); 0 when no code was read.
  double MedianWorstCornerPx() const;
  // Pools another check made with the same options.
  void Add(const DetectionCheck& other);
};

// Frames are matched by (stamp, camera), codes by key.
DetectionCheck CheckDetections(const std::vector<DetectionFrame>& detected,
                               const std::vector<DetectionFrame>& truth,
                               const DetectionCheckOptions& options = {});

}  // namespace waymark::eval
