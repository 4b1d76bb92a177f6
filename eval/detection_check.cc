#include "eval/detection_check.h"

#include <algorithm>
#include <array>
#include <map>
#include <string>
#include <utility>

#include "util/stats.h"

namespace waymark::eval {
namespace {

double ShortestSide(const std::array<Eigen::Vector2d, 4>& corners) {
  double side = (corners[0] - corners[3]).norm();
  for (int i = 0; i < 3; ++i) side = std::min(side, (corners[i + 1] - corners[i]).norm());
  return side;
}

double WorstCornerError(const MarkerObservation& found, const MarkerObservation& truth) {
  double worst = 0.0;
  for (int i = 0; i < 4; ++i) worst = std::max(worst, (found.corners_px[i] - truth.corners_px[i]).norm());
  return worst;
}

}  // namespace

long DetectionCheck::Gross() const {
  return std::count_if(worst_corner_px.begin(), worst_corner_px.end(),
                       [this](double e) { return e > options.gross_px; });
}

double DetectionCheck::MedianWorstCornerPx() const {
  return worst_corner_px.empty() ? 0.0 : Median(worst_corner_px);
}

void DetectionCheck::Add(const DetectionCheck& other) {
  codes_in_view += other.codes_in_view;
  read += other.read;
  worst_corner_px.insert(worst_corner_px.end(), other.worst_corner_px.begin(), other.worst_corner_px.end());
}

DetectionCheck CheckDetections(const std::vector<DetectionFrame>& detected,
                               const std::vector<DetectionFrame>& truth,
                               const DetectionCheckOptions& options) {
  std::map<std::pair<double, std::string>, const DetectionFrame*> by_frame;
  for (const DetectionFrame& frame : detected) by_frame[{frame.stamp_s, frame.camera}] = &frame;
  DetectionCheck check;
  check.options = options;
  for (const DetectionFrame& true_frame : truth) {
    const auto it = by_frame.find({true_frame.stamp_s, true_frame.camera});
    for (const MarkerObservation& code : true_frame.markers) {
      if (ShortestSide(code.corners_px) < options.min_side_px) continue;
      ++check.codes_in_view;
      if (it == by_frame.end()) continue;
      const auto& found = it->second->markers;
      const auto match = std::find_if(found.begin(), found.end(),
                                      [&](const MarkerObservation& m) { return m.key == code.key; });
      if (match == found.end()) continue;
      ++check.read;
      check.worst_corner_px.push_back(WorstCornerError(*match, code));
    }
  }
  return check;
}

}  // namespace waymark::eval
