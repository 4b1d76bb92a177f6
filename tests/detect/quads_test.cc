// Waymark's own candidate stage (detect/quads.h): DataMatrix L finders in every
// rotation and under perspective, with their corners and their orientation; solid-bordered
// quads where AprilTags are; nothing from blank, noise or filled boxes; a candidate read by
// libdmtx on its rectified patch.
#include "detect/quads.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "detect/synthetic.h"
#include "tests/detect/patch_test_util.h"

namespace waymark {
namespace {

cv::Mat Canvas(int width = 640, int height = 480) { return cv::Mat(height, width, CV_8U, cv::Scalar(200)); }

double MaxCornerError(const Quad2d& a, const Quad2d& b) {
  double worst = 0.0;
  for (int i = 0; i < 4; ++i) worst = std::max(worst, (a[i] - b[i]).norm());
  return worst;
}

TEST(DetectQuads, DataMatrixCandidateInEveryRotationWithItsOrientation) {
  const SymbolImage symbol = DataMatrixSymbol("Q7");
  for (int r = 0; r < 4; ++r) {
    for (const double squeeze : {1.0, 0.7}) {
      cv::Mat image = Canvas();
      const Quad2d truth = MakeQuad({320.0, 240.0}, 90.0, r * M_PI / 2 + 0.3, squeeze);
      DrawSymbol(symbol, truth, &image);
      cv::GaussianBlur(image, image, cv::Size(0, 0), 0.7);
      const auto candidates = DataMatrixCandidates(FindDarkQuads(image), 8);
      ASSERT_GE(candidates.size(), 1u) << "rotation " << r << " squeeze " << squeeze;  // best first
      // The L's three corners come from the hull (a pixel at the level it was found at); the
      // fourth, where the hull
      // cuts across the timing pattern's corner, can be a few modules off: the decoder finds
      // the symbol in the patch's quiet zone all the same.
      for (int k : {0, 2, 3}) {
        EXPECT_LT((candidates[0].corners_px[k] - truth[k]).norm(), 3.0)
            << "rotation " << r << " corner " << k;
      }
      EXPECT_LT((candidates[0].corners_px[1] - truth[1]).norm(), 0.35 * QuadMeanSide(truth))
          << "rotation " << r;
      const auto read = ReadDataMatrixCandidate(image, candidates[0]);
      ASSERT_EQ(read.size(), 1u) << "rotation " << r << " squeeze " << squeeze;
      EXPECT_EQ(read[0].key.id, "Q7");
      EXPECT_LT(MaxCornerError(read[0].corners_px, truth), 2.0) << "rotation " << r;  // libdmtx's fit
    }
  }
}

// The test before the decoders: a symbol's patch passes, also dim (contrast 40) and blurred;
// an even inside (light or dark) or no contrast fails.
TEST(DetectQuads, DataMatrixPatchPlausibleTurnsAwayClutter) {
  const int side = 60, margin = 18, size = side + 2 * margin;
  const Quad2d square = PatchSquare(margin, side);
  const SymbolImage symbol = DataMatrixSymbol("P1");
  const auto patch_with = [&](int dark, int light) {
    cv::Mat patch(size, size, CV_8U, cv::Scalar(light));
    DrawSymbol(symbol, square, &patch, dark, light);
    return patch;
  };
  EXPECT_TRUE(DataMatrixPatchPlausible(patch_with(20, 235), margin, side));
  cv::Mat dim = patch_with(90, 130);
  cv::GaussianBlur(dim, dim, cv::Size(0, 0), 1.0);
  EXPECT_TRUE(DataMatrixPatchPlausible(dim, margin, side));
  // An L around an even inside (the corner of a frame).
  cv::Mat frame(size, size, CV_8U, cv::Scalar(235));
  cv::rectangle(frame, cv::Rect(margin, margin, 6, side), cv::Scalar(20), cv::FILLED);
  cv::rectangle(frame, cv::Rect(margin, margin + side - 6, side, 6), cv::Scalar(20), cv::FILLED);
  EXPECT_FALSE(DataMatrixPatchPlausible(frame, margin, side));
  // An L around a filled box.
  cv::Mat filled = frame.clone();
  cv::rectangle(filled, cv::Rect(margin, margin, side, side), cv::Scalar(20), cv::FILLED);
  EXPECT_FALSE(DataMatrixPatchPlausible(filled, margin, side));
  // No contrast.
  EXPECT_FALSE(DataMatrixPatchPlausible(cv::Mat(size, size, CV_8U, cv::Scalar(128)), margin, side));
  // A mixed inside without a timing pattern: an L and a checkerboard inside a light band
  // along the top and right sides (text or a picture in a frame's corner).
  cv::Mat checker = frame.clone();
  for (int y = margin + 10; y < margin + side - 8; y += 8) {
    for (int x = margin + 8; x < margin + side - 10; x += 8) {
      if (((x + y) / 8) % 2 == 0) cv::rectangle(checker, cv::Rect(x, y, 8, 8), cv::Scalar(20), cv::FILLED);
    }
  }
  int runs = -1;
  EXPECT_FALSE(DataMatrixPatchPlausible(checker, margin, side, &runs));
  EXPECT_LT(runs, 2);
  // The symbol's timing pattern: "P1" is 10 x 10 modules, 5 dark along each timing side.
  EXPECT_TRUE(DataMatrixPatchPlausible(patch_with(20, 235), margin, side, &runs));
  EXPECT_GE(runs, 4);
  // A quarter turn off (the L top-left): still a symbol.
  cv::Mat turned;
  cv::rotate(patch_with(20, 235), turned, cv::ROTATE_90_CLOCKWISE);
  EXPECT_TRUE(DataMatrixPatchPlausible(turned, margin, side));
}

TEST(DetectQuads, QuietZoneOutsideTheLegs) {
  const int side = 60, margin = 18, size = side + 2 * margin;
  const Quad2d square = PatchSquare(margin, side);
  cv::Mat patch(size, size, CV_8U, cv::Scalar(235));
  DrawSymbol(DataMatrixSymbol("P1"), square, &patch, 20, 235);
  cv::GaussianBlur(patch, patch, cv::Size(0, 0), 0.8);
  EXPECT_LE(DataMatrixQuietZoneDark(patch, margin, side), 0.1);
  // The candidate's legs 3 px inside the symbol's (its corners a few pixels off): the leg's edge
  // is found on the profile, the quiet zone is still there.
  EXPECT_LE(DataMatrixQuietZoneDark(patch, margin + 3, side - 3), 0.1);
  // A dark area joined to the left leg (an L-shaped part of a larger dark thing).
  cv::Mat joined = patch.clone();
  cv::rectangle(joined, cv::Rect(0, 0, margin, size), cv::Scalar(20), cv::FILLED);
  EXPECT_GT(DataMatrixQuietZoneDark(joined, margin, side), 0.9);
  // A dark area a pixel below the bottom leg, wider than the profile reaches (an L-shaped
  // corner of a picture on a dark band). A bar within the profile's reach counts as the leg
  // (the candidate's legs may be a few pixels off).
  cv::Mat barred = patch.clone();
  cv::rectangle(barred, cv::Rect(0, margin + side + 1, size, size), cv::Scalar(20), cv::FILLED);
  EXPECT_GT(DataMatrixQuietZoneDark(barred, margin, side), 0.9);
  EXPECT_EQ(DataMatrixQuietZoneDark(cv::Mat(size, size, CV_8U, cv::Scalar(128)), margin, side), 1.0);
}

TEST(DetectQuads, SmallAndLargeSymbolsAreCandidates) {
  for (const double side : {22.0, 40.0, 380.0}) {
    cv::Mat image = Canvas(1280, 960);
    const Quad2d truth = MakeQuad({640.0, 480.0}, side, 0.2);
    DrawSymbol(DataMatrixSymbol("S1"), truth, &image);
    cv::GaussianBlur(image, image, cv::Size(0, 0), 0.6);
    const auto candidates = DataMatrixCandidates(FindDarkQuads(image), 8);
    // The symbol first; parts of it (an L alone of a few modules) may follow, nothing elsewhere.
    ASSERT_GE(candidates.size(), 1u) << side;
    for (const DataMatrixCandidate& c : candidates) {
      EXPECT_LT((QuadCenter(c.corners_px) - QuadCenter(truth)).norm(), 0.75 * side) << side;
    }
    EXPECT_LT((candidates[0].corners_px[3] - truth[3]).norm(), std::max(2.0, 0.03 * side)) << side;
    const auto read = ReadDataMatrixCandidate(image, candidates[0]);
    ASSERT_EQ(read.size(), 1u) << side;
    EXPECT_EQ(read[0].key.id, "S1");
  }
}

// Under sensor noise of 8 gray levels (a dim camera) the darkness threshold grows with the
// frame's noise (NoiseSigma, NoiseAwareThreshold: 16 instead of 7 at full resolution, which
// keeps the speckle that cost time out of the components): the symbol is still the first
// candidate and is read, and the noise makes no quads of its own.
TEST(DetectQuads, NoisyFrameKeepsTheSymbolAndFewQuads) {
  cv::Mat image = Canvas(1280, 960);
  const Quad2d truth = MakeQuad({500.0, 420.0}, 90.0, 0.3, 0.85);
  DrawSymbol(DataMatrixSymbol("N8"), truth, &image, 40, 210);
  cv::GaussianBlur(image, image, cv::Size(0, 0), 0.7);
  cv::RNG rng(8);
  AddSensorNoise(rng, 8.0, &image);
  const std::vector<DarkQuad> quads = FindDarkQuads(image);
  EXPECT_LT(quads.size(), 30u);
  const auto candidates = DataMatrixCandidates(quads, 8);
  ASSERT_GE(candidates.size(), 1u);
  EXPECT_LT((QuadCenter(candidates[0].corners_px) - QuadCenter(truth)).norm(), 5.0);
  const auto read = ReadDataMatrixCandidate(image, candidates[0]);
  ASSERT_EQ(read.size(), 1u);
  EXPECT_EQ(read[0].key.id, "N8");
}

// The L's legs count from 80 % dark: a blurred symbol found at a coarse level, where a
// module is a pixel or two, reads a leg 80-85 % dark (the recall bench's 62 px symbol at
// 1/4 resolution: 0.82 and 1.00). A leg of 75-80 % makes an L alone (ranked after the L with
// its timing pattern), under 75 % no L.
TEST(DetectQuads, BlurredLegAtACoarseLevelStillMakesAnL) {
  DarkQuad q;
  q.corners_px = {Eigen::Vector2d(100, 100), Eigen::Vector2d(160, 100), Eigen::Vector2d(160, 160),
                  Eigen::Vector2d(100, 160)};
  q.side_dark = {0.5, 0.55, 1.0, 0.82};  // top, right dashed; bottom, left the L
  q.side_runs = {5, 4, 1, 1};
  q.scale = 0.25;
  q.interior_spread = 0.5;  // a symbol's varied inside (DataMatrix candidates need >= 0.3)
  const std::vector<DataMatrixCandidate> candidates = DataMatrixCandidates({q}, 4);
  ASSERT_EQ(candidates.size(), 1u);
  // The L's corner (bottom-left of the quad) is the upright symbol's bottom-left.
  EXPECT_LT((candidates[0].corners_px[3] - Eigen::Vector2d(100, 160)).norm(), 1e-9);
  const double full_score = candidates[0].score;
  q.side_dark[3] = 0.78;
  const std::vector<DataMatrixCandidate> alone = DataMatrixCandidates({q}, 4);
  ASSERT_EQ(alone.size(), 1u);
  EXPECT_LT(alone[0].score, 0.6 * full_score);
  q.side_dark[3] = 0.7;
  EXPECT_TRUE(DataMatrixCandidates({q}, 4).empty());
}

// An L alone: light modules near the far corner leave the component's hull well inside the
// timing pattern, so the hull's two other sides cross the quiet zone (issue-scenario misses
// of 47-135 px). The far corner is the L's parallelogram completion; such a candidate ranks
// after every L with its timing pattern. Four solid sides (an AprilTag's border) make no L.
TEST(DetectQuads, LAloneCandidateCompletesTheParallelogram) {
  DarkQuad cut;  // the L's corner at (100, 160); the hull cuts from (160, 160) to (130, 100)
  cut.corners_px = {Eigen::Vector2d(100, 100), Eigen::Vector2d(130, 100), Eigen::Vector2d(160, 160),
                    Eigen::Vector2d(100, 160)};
  cut.side_dark = {0.6, 0.1, 0.95, 1.0};  // top dashed, the cut light, bottom and left the L
  cut.side_runs = {3, 1, 1, 1};
  cut.interior_spread = 0.6;
  DarkQuad full;  // an L with its timing pattern elsewhere
  full.corners_px = {Eigen::Vector2d(300, 100), Eigen::Vector2d(360, 100), Eigen::Vector2d(360, 160),
                     Eigen::Vector2d(300, 160)};
  full.side_dark = {0.5, 0.5, 0.9, 0.9};
  full.side_runs = {4, 4, 1, 1};
  full.interior_spread = 0.6;
  const std::vector<DataMatrixCandidate> candidates = DataMatrixCandidates({cut, full}, 4);
  ASSERT_EQ(candidates.size(), 2u);
  EXPECT_LT((candidates[0].corners_px[3] - Eigen::Vector2d(300, 160)).norm(), 1e-9);  // full first
  const Quad2d expected = {Eigen::Vector2d(100, 100), Eigen::Vector2d(160, 100), Eigen::Vector2d(160, 160),
                           Eigen::Vector2d(100, 160)};
  EXPECT_LT(MaxCornerError(candidates[1].corners_px, expected), 1e-9);
  cut.side_dark = {0.9, 0.9, 0.95, 1.0};  // four solid sides
  EXPECT_TRUE(DataMatrixCandidates({cut}, 4).empty());
}

// A dark component whose hull is an L's square with its far corner cut by two sides (a
// DataMatrix symbol whose light modules near the far corner leave the hull well short of
// it): five corners, the cut is not the shortest side, so the hull's quad (shortest side
// removed) is not the square. The L's parallelogram completion is one more dark quad, marked
// (for DataMatrix candidates only: never an AprilTag border).
TEST(DetectQuads, LCompletionQuadWhenTheHullIsCutDeep) {
  for (int r = 0; r < 4; ++r) {
    cv::Mat image = Canvas();
    // Clockwise from the L's corner: (100, 300), up the left leg, the cut, down to the bottom leg.
    const Eigen::Vector2d centre(150, 250);
    const std::vector<Eigen::Vector2d> shape = {Eigen::Vector2d(100, 300), Eigen::Vector2d(100, 200),
                                                Eigen::Vector2d(140, 200), Eigen::Vector2d(200, 260),
                                                Eigen::Vector2d(200, 300)};
    const Quad2d square = {Eigen::Vector2d(100, 200), Eigen::Vector2d(200, 200), Eigen::Vector2d(200, 300),
                           Eigen::Vector2d(100, 300)};
    const auto turn = [&](const Eigen::Vector2d& p) -> Eigen::Vector2d {  // r quarter turns, then moved
      Eigen::Vector2d d = p - centre;
      for (int k = 0; k < r; ++k) d = Eigen::Vector2d(-d.y(), d.x());
      return Eigen::Vector2d(320, 240) + d;
    };
    std::vector<cv::Point> polygon;
    for (const Eigen::Vector2d& p : shape) {
      const Eigen::Vector2d q = turn(p);
      polygon.emplace_back(static_cast<int>(q.x()), static_cast<int>(q.y()));
    }
    cv::fillConvexPoly(image, polygon, cv::Scalar(30));
    const std::vector<DarkQuad> quads = FindDarkQuads(image);
    int completions = 0;
    for (const DarkQuad& q : quads) {
      if (!q.l_completion) continue;
      ++completions;
      double worst = 1e9;  // the quad's corners against the turned square's, in any rotation
      for (int k = 0; k < 4; ++k) {
        double e = 0.0;
        for (int i = 0; i < 4; ++i) e = std::max(e, (q.corners_px[(i + k) % 4] - turn(square[i])).norm());
        worst = std::min(worst, e);
      }
      EXPECT_LT(worst, 4.0) << "rotation " << r;  // a pixel of the level it was found at (1/4)
    }
    EXPECT_GE(completions, 1) << "rotation " << r;
    EXPECT_TRUE(SolidBorderQuads(quads, 400.0, 16).empty()) << "rotation " << r;
  }
  // A square has no L completion.
  cv::Mat image = Canvas();
  cv::rectangle(image, cv::Rect(100, 100, 80, 80), cv::Scalar(30), cv::FILLED);
  for (const DarkQuad& q : FindDarkQuads(image)) EXPECT_FALSE(q.l_completion);
}

// An L whose hull gives no quad: the L with lone dark modules inside (its hull's polygon a
// triangle), and with a block joined inside one leg's end too (a triangle with a short cut,
// turned away by the side-ratio bound). The L found by its two dark legs is a marked quad
// (DataMatrix only), the far corner the legs' parallelogram completion.
TEST(DetectQuads, LQuadFromDarkLegsWhenTheHullIsATriangle) {
  for (const int shape : {0, 1}) {  // 0: lone modules, 1: and a joined block
    const bool block = shape == 1;
    for (int r = 0; r < 8; ++r) {
      cv::Mat image = Canvas();
      const Eigen::Vector2d centre(320, 240);
      const double angle = r * M_PI / 4 + 0.1;
      const auto turn = [&](double x, double y) -> cv::Point {  // square coordinates -> image
        const double c = std::cos(angle), s = std::sin(angle);
        return cv::Point(static_cast<int>(std::lround(centre.x() + c * x - s * y)),
                         static_cast<int>(std::lround(centre.y() + s * x + c * y)));
      };
      // The square (-60, -60)..(60, 60); the L's corner bottom-left, its legs 12 px wide.
      const auto fill = [&](double x0, double y0, double x1, double y1) {
        const std::vector<cv::Point> poly = {turn(x0, y0), turn(x1, y0), turn(x1, y1), turn(x0, y1)};
        cv::fillConvexPoly(image, poly, cv::Scalar(30));
      };
      fill(-60, -60, -48, 60);
      fill(-60, 48, 60, 60);
      if (block) fill(-48, -60, -24, -36);
      for (const double c : {-22.0, 4.0, 28.0}) fill(c - 6, c - 6, c + 6, c + 6);  // across the triangle
      const std::vector<DarkQuad> quads = FindDarkQuads(image);
      double best = 1e9;
      for (const DarkQuad& q : quads) {
        if (!q.l_completion) continue;
        for (int k = 0; k < 4; ++k) {
          double e = 0.0;
          const double xs[4] = {-60, 60, 60, -60}, ys[4] = {-60, -60, 60, 60};
          for (int i = 0; i < 4; ++i) {
            const cv::Point p = turn(xs[i], ys[i]);
            e = std::max(e, (q.corners_px[(i + k) % 4] - Eigen::Vector2d(p.x, p.y)).norm());
          }
          best = std::min(best, e);
        }
      }
      EXPECT_LT(best, 5.0) << "angle " << r << " shape " << shape;  // a pixel or two of its level
      EXPECT_TRUE(SolidBorderQuads(quads, 400.0, 16).empty()) << "angle " << r << " shape " << shape;
    }
  }
}

// A symbol inside a larger L-shaped quad at the same place (the dark background around its
// card, ranked first) keeps its own candidate; the same symbol found at two levels (about one
// size) is one candidate.
TEST(DetectQuads, CandidateInsideALargerLIsNoDuplicate) {
  const auto quad_at = [](double half, double dark) {
    DarkQuad q;
    q.corners_px = {Eigen::Vector2d(200 - half, 200 - half), Eigen::Vector2d(200 + half, 200 - half),
                    Eigen::Vector2d(200 + half, 200 + half), Eigen::Vector2d(200 - half, 200 + half)};
    q.side_dark = {0.5, 0.5, dark, dark};
    q.side_runs = {4, 4, 1, 1};
    q.interior_spread = 0.6;
    return q;
  };
  EXPECT_EQ(DataMatrixCandidates({quad_at(45, 0.95), quad_at(26, 0.9)}, 4).size(), 2u);
  EXPECT_EQ(DataMatrixCandidates({quad_at(28, 0.95), quad_at(26, 0.9)}, 4).size(), 1u);
}

TEST(DetectQuads, AprilTagBorderIsASolidQuadAndFilledBoxesAreNot) {
  cv::Mat image = Canvas();
  const Quad2d tag = MakeQuad({200.0, 240.0}, 60.0, 0.4, 0.8);
  DrawSymbol(AprilTagSymbol("apriltag-36h11", 5), tag, &image);
  cv::rectangle(image, cv::Rect(400, 200, 80, 80), cv::Scalar(30), cv::FILLED);  // a filled box
  cv::rectangle(image, cv::Rect(520, 60, 60, 60), cv::Scalar(30), 6);            // an empty frame
  const auto quads = FindDarkQuads(image);
  const auto solid = SolidBorderQuads(quads, 200.0, 8);
  ASSERT_EQ(solid.size(), 1u);
  EXPECT_LT(MaxCornerError(solid[0], tag), 2.0);
  EXPECT_TRUE(DataMatrixCandidates(quads, 8).empty());
  EXPECT_TRUE(SolidBorderQuads(quads, 40.0, 8).empty());  // larger than the limit
}

TEST(DetectQuads, BlankNoiseAndTextGiveNoCandidate) {
  EXPECT_TRUE(DataMatrixCandidates(FindDarkQuads(Canvas()), 8).empty());
  cv::Mat noise(480, 640, CV_8U);
  cv::RNG rng(4);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
  EXPECT_TRUE(DataMatrixCandidates(FindDarkQuads(noise), 8).empty());
  cv::Mat text = Canvas();
  for (int i = 0; i < 8; ++i) {
    cv::putText(text, "EXIT 12 aisle B L7", cv::Point(20, 50 + 55 * i), cv::FONT_HERSHEY_SIMPLEX,
                1.0 + 0.2 * i, cv::Scalar(20), 2);
  }
  for (const DataMatrixCandidate& c : DataMatrixCandidates(FindDarkQuads(text), 8)) {
    EXPECT_TRUE(ReadDataMatrixCandidate(text, c).empty());
  }
  EXPECT_TRUE(FindDarkQuads(cv::Mat(8, 8, CV_8U, cv::Scalar(0))).empty());
  EXPECT_TRUE(DataMatrixCandidates(FindDarkQuads(Canvas()), 0).empty());
}

TEST(DetectQuads, SharedRunFollowsThePixelsNotTheBuffer) {
  // The same buffer, drawn on after a first run: the second run sees the new pixels.
  cv::Mat image = Canvas();
  EXPECT_TRUE(DataMatrixCandidates(FindDarkQuads(image), 8).empty());
  DrawSymbol(DataMatrixSymbol("Q7"), MakeQuad({320.0, 240.0}, 90.0, 0.3), &image);
  cv::GaussianBlur(image, image, cv::Size(0, 0), 0.7);
  const auto quads = FindDarkQuads(image);
  const size_t count = DataMatrixCandidates(quads, 8).size();  // the symbol and parts of it
  EXPECT_GE(count, 1u);
  // One pixel changed far from the symbol: a new run (the same candidates).
  image.at<uint8_t>(5, 5) = 0;
  EXPECT_EQ(DataMatrixCandidates(FindDarkQuads(image), 8).size(), count);
  // The same pixels in another buffer: the same quads.
  const cv::Mat copy = image.clone();
  const auto again = FindDarkQuads(copy);
  ASSERT_EQ(again.size(), FindDarkQuads(image).size());
  cv::Mat blank = Canvas();
  EXPECT_TRUE(DataMatrixCandidates(FindDarkQuads(blank), 8).empty());
}

}  // namespace
}  // namespace waymark
