// Tests of geometry/square_marker.h: the tape's layout, the checks on its parameters, the corner
// order, and telling several squares of one map apart by the pose prior.
#include "geometry/square_marker.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>

#include "tests/test_cameras.h"

namespace waymark {
namespace {

using ::testing::HasSubstr;

// Tape area covered by the rectangles (union), by sampling a fine grid.
double CoveredArea(const std::vector<TapeRect>& rects, double extent, double step) {
  int inside = 0;
  for (double y = -extent; y <= extent; y += step) {
    for (double x = -extent; x <= extent; x += step) {
      for (const TapeRect& r : rects) {
        if (r.Contains(Eigen::Vector2d(x, y))) {
          ++inside;
          break;
        }
      }
    }
  }
  return inside * step * step;
}

TEST(SquareMarkerTest, PaperSquareLayout) {
  const SquareTape tape;  // 50 mm tape, solid top, 100 mm dashes and gaps
  // L = 2.05 m: floor((2.05 + 0.1) / 0.2) = 10 dashes, gap (2.05 - 1.0) / 9 = 0.1167 m.
  double gap = 0.0;
  EXPECT_EQ(SquareDashCount(2.0, tape, &gap), 10);
  EXPECT_NEAR(gap, 1.05 / 9.0, 1e-12);
  const std::vector<TapeRect> rects = SquareTapeRects(2.0, tape);
  ASSERT_EQ(rects.size(), 1u + 3u * 10u);
  // The solid side: the top strip, centred on y = 1, from corner to corner plus w/2.
  EXPECT_EQ(rects[0].min, Eigen::Vector2d(-1.025, 0.975));
  EXPECT_EQ(rects[0].max, Eigen::Vector2d(1.025, 1.025));
  // Dashes flush with both ends of each dashed side, inside its strip.
  for (size_t i = 1; i < rects.size(); ++i) {
    const Eigen::Vector2d size = rects[i].max - rects[i].min;
    EXPECT_NEAR(std::min(size.x(), size.y()), 0.05, 1e-12) << i;
    EXPECT_NEAR(std::max(size.x(), size.y()), 0.10, 1e-12) << i;
    EXPECT_LE(rects[i].max.cwiseAbs().maxCoeff(), 1.025 + 1e-12);
  }
  // Area: solid 2.05 x 0.05, three sides of 10 dashes 0.1 x 0.05, minus the four corner squares
  // where two strips overlap.
  const double expected = 2.05 * 0.05 + 3 * 10 * 0.1 * 0.05 - 4 * 0.05 * 0.05;
  EXPECT_NEAR(CoveredArea(rects, 1.1, 0.0025), expected, 0.01 * expected);
  // The corners are the centrelines' crossings: on the tape, at MarkerCorners(2).
  for (const Eigen::Vector3d& corner : MarkerCorners(2.0)) {
    int covering = 0;
    for (const TapeRect& r : rects) covering += r.Contains(corner.head<2>()) ? 1 : 0;
    EXPECT_GE(covering, 2) << corner.transpose();
  }
}

TEST(SquareMarkerTest, SolidSideIsWhereTheTapeSays) {
  for (SquareSide side : {SquareSide::kTop, SquareSide::kRight, SquareSide::kBottom, SquareSide::kLeft}) {
    SquareTape tape;
    tape.solid_side = side;
    const std::vector<TapeRect> rects = SquareTapeRects(2.0, tape);
    const std::array<int, 2> ends = SquareSideCorners(side);
    const std::array<Eigen::Vector3d, 4> corners = MarkerCorners(2.0);
    // The solid strip contains the whole centreline between the side's two corners.
    for (double f = 0.0; f <= 1.0; f += 0.01) {
      const Eigen::Vector3d p = (1.0 - f) * corners[ends[0]] + f * corners[ends[1]];
      EXPECT_TRUE(rects[0].Contains(p.head<2>())) << SquareSideName(side) << " " << f;
    }
    EXPECT_EQ(ParseSquareSide(SquareSideName(side)), side);
  }
  EXPECT_FALSE(ParseSquareSide("up").has_value());
  EXPECT_EQ(SquareSideCorners(SquareSide::kLeft), (std::array<int, 2>{3, 0}));
}

TEST(SquareMarkerTest, CheckNamesTheBadParameter) {
  std::string why;
  EXPECT_TRUE(CheckSquareTape(SquareTape{}, 2.0, &why));
  SquareTape tape;
  tape.tape_width_m = 0.6;
  EXPECT_FALSE(CheckSquareTape(tape, 2.0, &why));
  EXPECT_THAT(why, HasSubstr("tape_width_m: expected > 0 and <= side / 4"));
  tape = SquareTape{};
  tape.dash_m = 0.0;
  EXPECT_FALSE(CheckSquareTape(tape, 2.0, &why));
  EXPECT_THAT(why, HasSubstr("dash_m: expected > 0"));
  tape = SquareTape{};
  tape.gap_m = std::nan("");
  EXPECT_FALSE(CheckSquareTape(tape, 2.0, &why));
  EXPECT_THAT(why, HasSubstr("gap_m: expected > 0"));
  tape = SquareTape{};
  tape.dash_m = 1.0;
  EXPECT_FALSE(CheckSquareTape(tape, 2.0, &why));
  EXPECT_THAT(why, HasSubstr("room for two dashes"));
  EXPECT_FALSE(CheckSquareTape(SquareTape{}, -1.0, &why));
  EXPECT_THAT(why, HasSubstr("square side: expected > 0 m"));
  EXPECT_THROW(SquareTapeRects(0.1, SquareTape{}), std::invalid_argument);
}

TEST(SquareMarkerTest, SolidFirstToMarkerOrder) {
  const std::array<Eigen::Vector2d, 4> solid_first = {Eigen::Vector2d(0, 0), Eigen::Vector2d(1, 0),
                                                      Eigen::Vector2d(2, 0), Eigen::Vector2d(3, 0)};
  EXPECT_EQ(SolidFirstToMarkerOrder(solid_first, SquareSide::kTop), solid_first);
  // Solid right: the solid side runs from marker corner 1 to 2.
  const std::array<Eigen::Vector2d, 4> right = SolidFirstToMarkerOrder(solid_first, SquareSide::kRight);
  EXPECT_EQ(right[1], solid_first[0]);
  EXPECT_EQ(right[2], solid_first[1]);
  EXPECT_EQ(right[0], solid_first[3]);
  const std::array<Eigen::Vector2d, 4> left = SolidFirstToMarkerOrder(solid_first, SquareSide::kLeft);
  EXPECT_EQ(left[3], solid_first[0]);
  EXPECT_EQ(left[0], solid_first[1]);
}

// Two 2 m squares on a 2 m high ceiling, 4 m apart, seen by [Seki]'s upward fisheye.
MarkerMap TwoSquares() {
  MarkerMap map;
  // Face down (z towards the floor): rotate 180 degrees about x.
  const Eigen::Quaterniond face_down(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()));
  for (int i = 0; i < 2; ++i) {
    MapMarker marker;
    marker.key = {kFamilySquare, i == 0 ? "A" : "B"};
    marker.size_m = 2.0;
    marker.T_world_marker = SE3d(face_down, Eigen::Vector3d(4.0 * i, 0.0, 2.3));
    if (i == 1) marker.square_tape = SquareTape{0.05, SquareSide::kRight, 0.1, 0.1};
    map.markers.push_back(marker);
  }
  MapMarker qr;
  qr.key = {kFamilyQr, "A"};
  qr.size_m = 0.1;
  map.markers.push_back(qr);
  return map;
}

// The camera 0.3 m above the floor looking up, at (x, y), heading yaw.
SE3d UpwardCamera(double x, double y, double yaw) {
  const Eigen::Quaterniond up(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()));  // optical axis = world z
  return SE3d(up, Eigen::Vector3d(x, y, 0.3));
}

// What a detector would report: the square's corners at the true pose, solid side first.
std::array<Eigen::Vector2d, 4> SolidFirst(const MapMarker& marker, const Camera& camera,
                                          const SE3d& T_world_camera) {
  std::array<Eigen::Vector2d, 4> px;
  const std::array<Eigen::Vector3d, 4> object = MarkerCorners(marker.size_m);
  for (int k = 0; k < 4; ++k)
    px[k] = *camera.Project(T_world_camera.inverse() * (marker.T_world_marker * object[k]));
  const int s = static_cast<int>(TapeOf(marker).solid_side);
  std::array<Eigen::Vector2d, 4> solid_first;
  for (int k = 0; k < 4; ++k) solid_first[k] = px[(k + s) % 4];
  return solid_first;
}

TEST(SquareMarkerTest, IdentifySquareByThePosePrior) {
  const MarkerMap map = TwoSquares();
  const Camera camera(testing::Seed002EquisolidInfo());
  for (int which = 0; which < 2; ++which) {
    const SE3d T_true = UpwardCamera(4.0 * which + 0.5, -0.7, 0.4);
    const std::array<Eigen::Vector2d, 4> detected = SolidFirst(map.markers[which], camera, T_true);
    // A prior 10 cm and 2 degrees off still picks the right square, in its own corner order.
    const SE3d T_prior = UpwardCamera(4.0 * which + 0.6, -0.75, 0.4 + 2.0 * M_PI / 180.0);
    const std::optional<SquareMatch> match = IdentifySquare(map, camera, T_prior, detected, 30.0);
    const std::optional<SquareMatch> loose = IdentifySquare(map, camera, T_prior, detected, 1e9);
    ASSERT_TRUE(match.has_value()) << which << " " << (loose ? loose->rms_px : -1.0);
    EXPECT_EQ(match->index, static_cast<size_t>(which));
    EXPECT_LT(match->rms_px, 30.0);
    EXPECT_GT(match->next_rms_px, 30.0);
    const std::array<Eigen::Vector3d, 4> object = MarkerCorners(2.0);
    for (int k = 0; k < 4; ++k) {
      const Eigen::Vector2d expected =
          *camera.Project(T_true.inverse() * (map.markers[which].T_world_marker * object[k]));
      EXPECT_LE((match->corners_px[k] - expected).norm(), 1e-9) << which << " corner " << k;
    }
  }
  // A prior midway between the squares fits neither within 30 px.
  const std::array<Eigen::Vector2d, 4> detected =
      SolidFirst(map.markers[0], camera, UpwardCamera(0.0, 0.0, 0.0));
  EXPECT_FALSE(IdentifySquare(map, camera, UpwardCamera(2.0, 0.0, 0.0), detected, 30.0).has_value());
  // A gate so wide that both squares fit: ambiguous, refused.
  EXPECT_FALSE(IdentifySquare(map, camera, UpwardCamera(0.0, 0.0, 0.0), detected, 1e4).has_value());
}

}  // namespace
}  // namespace waymark
