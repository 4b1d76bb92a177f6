// The large square ceiling marker of [Seki] (family `square`; Seki, Kawai, Hikizu, "Localization
// System for Indoor Mobile Robot Using Large Square-Shaped Reflective Marker", IJAT 15(2), 2021):
// retro-reflective tape laid as a square on the ceiling, one side solid, three dashed. It carries
// no ID: the solid side fixes its orientation, and where several squares hang in one map the pose
// prior tells them apart (IdentifySquare).
//
// Frame and corners (DESIGN.md): origin at the square's centre, z out of the taped face (towards
// the camera below, i.e. down for a ceiling marker), x right and y up as the square is seen from
// below with its solid side... wherever SquareTape::solid_side says (top by default). size_m is
// the side between the tape's centrelines; the corners are where the centrelines cross, in the
// usual order (MarkerCorners(size_m)): top-left, top-right, bottom-right, bottom-left.
//
// Tape: each side's strip is tape_width_m wide, centred on its centreline, and runs from corner to
// corner extended by tape_width_m / 2 at each end (so the strips close the corners). The solid side
// is one strip; a dashed side is n dashes of dash_m,
//   n = max(2, floor((L + gap_m) / (dash_m + gap_m))),  L = size_m + tape_width_m,
// the first and last flush with the strip's ends and the others spread evenly (actual gap
// (L - n dash_m) / (n - 1), which is >= gap_m).
//
// Detections of a square before identification carry the id kUnidentifiedSquareId and their
// corners "solid side first": corner 0 -> 1 is the solid side, then clockwise as seen from the
// camera looking at the taped face, as if the solid side were the top. SolidFirstToMarkerOrder
// turns them into the marker's own order for a given solid side.
#pragma once

#include <Eigen/Core>
#include <array>
#include <optional>
#include <string>
#include <vector>

#include "geometry/camera.h"
#include "geometry/pose.h"
#include "geometry/types.h"

namespace waymark {

// The id of a `square` detection whose square is not identified yet.
inline constexpr const char* kUnidentifiedSquareId = "*";

// "top", "right", "bottom", "left"; ParseSquareSide returns nullopt otherwise.
const char* SquareSideName(SquareSide side);
std::optional<SquareSide> ParseSquareSide(const std::string& name);

// The two corners (indices in MarkerCorners order) at the ends of a side, in order:
// top {0, 1}, right {1, 2}, bottom {2, 3}, left {3, 0}.
std::array<int, 2> SquareSideCorners(SquareSide side);

// True if the tape fits a square of side side_m: side_m > 0, 0 < tape_width_m <= side_m / 4,
// dash_m > 0, gap_m > 0 and room for two dashes with a gap (2 dash_m + gap_m <= side_m +
// tape_width_m); otherwise false with the reason in *why (when why != nullptr).
bool CheckSquareTape(const SquareTape& tape, double side_m, std::string* why);

// Number of dashes on a dashed side; *gap_m (if given) receives the actual gap between them.
int SquareDashCount(double side_m, const SquareTape& tape, double* gap_m = nullptr);

// An axis-aligned rectangle of tape in the marker frame (z = 0), metres.
struct TapeRect {
  Eigen::Vector2d min;
  Eigen::Vector2d max;
  bool Contains(const Eigen::Vector2d& p) const {
    return p.x() >= min.x() && p.x() <= max.x() && p.y() >= min.y() && p.y() <= max.y();
  }
};

// The tape as rectangles: the solid side first, then the dashes of the other three sides.
// Throws std::invalid_argument if CheckSquareTape fails.
std::vector<TapeRect> SquareTapeRects(double side_m, const SquareTape& tape);

// The tape of a map's square marker (its square_tape, or the defaults).
inline SquareTape TapeOf(const MapMarker& marker) { return marker.square_tape.value_or(SquareTape{}); }

// Corners given solid side first (see the header comment) in the order of a marker whose solid
// side is `solid_side`: marker corner k = solid_first[(k - side index) mod 4].
std::array<Eigen::Vector2d, 4> SolidFirstToMarkerOrder(const std::array<Eigen::Vector2d, 4>& solid_first,
                                                       SquareSide solid_side);

// Which square of a map a detection is. For every square of `map` with a pose, the corners it
// would show at the prior camera pose T_world_camera are predicted and compared with the
// detected ones (solid side first, put in that square's order); the detection is that square if
// its RMS corner distance is within gate_px and no other square's is (else nullopt: none fits,
// or two do and the prior cannot tell them apart).
struct SquareMatch {
  size_t index = 0;                           // into map.markers
  std::array<Eigen::Vector2d, 4> corners_px;  // in the square's own corner order
  double rms_px = 0.0;                        // its RMS corner distance
  double next_rms_px = 0.0;                   // the next best square's (+inf if none)
};
std::optional<SquareMatch> IdentifySquare(const MarkerMap& map, const Camera& camera,
                                          const SE3d& T_world_camera,
                                          const std::array<Eigen::Vector2d, 4>& solid_first_px,
                                          double gate_px);

}  // namespace waymark
