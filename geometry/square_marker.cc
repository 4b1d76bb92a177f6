#include "geometry/square_marker.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "util/format.h"

namespace waymark {
namespace {

constexpr SquareSide kSides[4] = {SquareSide::kTop, SquareSide::kRight, SquareSide::kBottom,
                                  SquareSide::kLeft};

int SideIndex(SquareSide side) { return static_cast<int>(side); }

bool Fail(std::string* why, const std::string& reason) {
  if (why != nullptr) *why = reason;
  return false;
}

}  // namespace

const char* SquareSideName(SquareSide side) {
  switch (side) {
    case SquareSide::kTop:
      return "top";
    case SquareSide::kRight:
      return "right";
    case SquareSide::kBottom:
      return "bottom";
    case SquareSide::kLeft:
      return "left";
  }
  return "unknown";
}

std::optional<SquareSide> ParseSquareSide(const std::string& name) {
  for (SquareSide side : kSides) {
    if (name == SquareSideName(side)) return side;
  }
  return std::nullopt;
}

std::array<int, 2> SquareSideCorners(SquareSide side) {
  const int i = SideIndex(side);
  return {i, (i + 1) % 4};
}

bool CheckSquareTape(const SquareTape& tape, double side_m, std::string* why) {
  if (!(std::isfinite(side_m) && side_m > 0.0))
    return Fail(why, "square side: expected > 0 m, got " + FormatDouble(side_m));
  if (!(std::isfinite(tape.tape_width_m) && tape.tape_width_m > 0.0 && tape.tape_width_m <= 0.25 * side_m)) {
    return Fail(why, "tape_width_m: expected > 0 and <= side / 4 (" + FormatDouble(0.25 * side_m) +
                         " m), got " + FormatDouble(tape.tape_width_m));
  }
  if (!(std::isfinite(tape.dash_m) && tape.dash_m > 0.0))
    return Fail(why, "dash_m: expected > 0, got " + FormatDouble(tape.dash_m));
  if (!(std::isfinite(tape.gap_m) && tape.gap_m > 0.0))
    return Fail(why, "gap_m: expected > 0, got " + FormatDouble(tape.gap_m));
  if (2.0 * tape.dash_m + tape.gap_m > side_m + tape.tape_width_m) {
    return Fail(why, "dash_m, gap_m: expected room for two dashes and a gap on a side of " +
                         FormatDouble(side_m + tape.tape_width_m) + " m");
  }
  if (SideIndex(tape.solid_side) < 0 || SideIndex(tape.solid_side) > 3)
    return Fail(why, "solid_side: not a side");
  return true;
}

int SquareDashCount(double side_m, const SquareTape& tape, double* gap_m) {
  const double length = side_m + tape.tape_width_m;
  const int n = std::max(2, static_cast<int>(std::floor((length + tape.gap_m) / (tape.dash_m + tape.gap_m))));
  if (gap_m != nullptr) *gap_m = (length - n * tape.dash_m) / (n - 1);
  return n;
}

std::vector<TapeRect> SquareTapeRects(double side_m, const SquareTape& tape) {
  std::string why;
  if (!CheckSquareTape(tape, side_m, &why)) throw std::invalid_argument("square marker: " + why);
  const double h = 0.5 * side_m, w = 0.5 * tape.tape_width_m, end = h + w;
  // A strip along side `s` between positions [a, b] measured along it from -end to +end.
  const auto strip = [h, w](SquareSide s, double a, double b) {
    switch (s) {
      case SquareSide::kTop:
        return TapeRect{{a, h - w}, {b, h + w}};
      case SquareSide::kBottom:
        return TapeRect{{a, -h - w}, {b, -h + w}};
      case SquareSide::kRight:
        return TapeRect{{h - w, a}, {h + w, b}};
      case SquareSide::kLeft:
        break;
    }
    return TapeRect{{-h - w, a}, {-h + w, b}};
  };
  std::vector<TapeRect> rects = {strip(tape.solid_side, -end, end)};
  double gap = 0.0;
  const int n = SquareDashCount(side_m, tape, &gap);
  for (SquareSide s : kSides) {
    if (s == tape.solid_side) continue;
    for (int i = 0; i < n; ++i) {
      const double a = -end + i * (tape.dash_m + gap);
      rects.push_back(strip(s, a, i + 1 == n ? end : a + tape.dash_m));
    }
  }
  return rects;
}

std::array<Eigen::Vector2d, 4> SolidFirstToMarkerOrder(const std::array<Eigen::Vector2d, 4>& solid_first,
                                                       SquareSide solid_side) {
  std::array<Eigen::Vector2d, 4> corners;
  const int s = SideIndex(solid_side);
  for (int k = 0; k < 4; ++k) corners[k] = solid_first[(k - s + 4) % 4];
  return corners;
}

std::optional<SquareMatch> IdentifySquare(const MarkerMap& map, const Camera& camera,
                                          const SE3d& T_world_camera,
                                          const std::array<Eigen::Vector2d, 4>& solid_first_px,
                                          double gate_px) {
  const SE3d T_camera_world = T_world_camera.inverse();
  constexpr double kInf = std::numeric_limits<double>::infinity();
  std::optional<SquareMatch> best;
  double next = kInf;
  for (size_t i = 0; i < map.markers.size(); ++i) {
    const MapMarker& marker = map.markers[i];
    if (marker.key.family != kFamilySquare || !marker.has_pose) continue;
    const std::array<Eigen::Vector2d, 4> corners =
        SolidFirstToMarkerOrder(solid_first_px, TapeOf(marker).solid_side);
    const std::array<Eigen::Vector3d, 4> object = MarkerCorners(marker.size_m);
    double sum_sq = 0.0;
    bool visible = true;
    for (int k = 0; k < 4 && visible; ++k) {
      const std::optional<Eigen::Vector2d> px =
          camera.Project(T_camera_world * (marker.T_world_marker * object[k]));
      if (!px)
        visible = false;
      else
        sum_sq += (*px - corners[k]).squaredNorm();
    }
    if (!visible) continue;
    const double rms = std::sqrt(0.25 * sum_sq);
    if (!best || rms < best->rms_px) {
      if (best) next = best->rms_px;
      best = SquareMatch{i, corners, rms, kInf};
    } else {
      next = std::min(next, rms);
    }
  }
  if (!best || !(best->rms_px <= gate_px) || next <= gate_px) return std::nullopt;
  best->next_rms_px = next;
  return best;
}

}  // namespace waymark
