// DataMatrix detector on synthetic symbols from libdmtx's encoder drawn through known
// homographies: exact ids, docs/design.md corner order in all four rotations, sub-pixel
// corners, libdmtx's own corners (y-up origin converted), nothing on blank or noise.
#include "detect/datamatrix.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <string>
#include <vector>

#include "detect/detector.h"
#include "detect/quads.h"
#include "detect/synthetic.h"
#include "tests/detect/patch_test_util.h"

namespace waymark {
namespace {

cv::Mat Canvas(int width = 640, int height = 480) { return cv::Mat(height, width, CV_8U, cv::Scalar(190)); }

double MaxCornerError(const Quad2d& corners, const Quad2d& truth) {
  double worst = 0.0;
  for (int i = 0; i < 4; ++i) worst = std::max(worst, (corners[i] - truth[i]).norm());
  return worst;
}

TEST(DetectDataMatrix, FourRotationsGiveDesignOrderCorners) {
  auto detector = CreateDetector("datamatrix");
  const SymbolImage symbol = DataMatrixSymbol("A01");
  for (int r = 0; r < 4; ++r) {
    cv::Mat image = Canvas();
    const Quad2d truth = MakeQuad({321.2, 238.6}, 140.0, r * M_PI / 2 - 0.07);
    DrawSymbol(symbol, truth, &image);
    const auto found = detector->Detect(image);
    ASSERT_EQ(found.size(), 1u) << "rotation " << r;
    EXPECT_EQ(found[0].key.family, "datamatrix");
    EXPECT_EQ(found[0].key.id, "A01");
    EXPECT_LT(MaxCornerError(found[0].corners_px, truth), 0.15) << "rotation " << r;
  }
}

// A 1280x960 frame of gray 120 with a light card (225) at `card` under the DataMatrix symbol of
// `text` at `truth` (dark modules `dark`), blurred by `blur_px`.
cv::Mat SymbolOnACard(const std::string& text, const Quad2d& truth, const Quad2d& card, int dark,
                      double blur_px) {
  cv::Mat image = Canvas(1280, 960);
  cv::rectangle(image, cv::Rect(0, 0, 1280, 960), cv::Scalar(120), cv::FILLED);
  std::vector<cv::Point> polygon;
  for (const Eigen::Vector2d& c : card) polygon.emplace_back(int(c.x()), int(c.y()));
  cv::fillConvexPoly(image, polygon, cv::Scalar(225));
  DrawSymbol(DataMatrixSymbol(text), truth, &image, dark, 225);
  cv::GaussianBlur(image, image, cv::Size(0, 0), blur_px);
  return image;
}

// Large modules (10 x 10 symbols of 130-170 px: 13-17 px per module) on a light card: at full
// resolution the candidate stage's 15 px box spans about one module and the legs' insides are
// not darker than their local mean, at 1/4 the components break at clusters of dark modules;
// the 1/8 level sees each symbol whole. Read by the first pass alone (Waymark's candidates).
TEST(DetectDataMatrix, LargeModulesAreCandidates) {
  DetectorOptions options;
  options.second_pass = false;
  auto detector = CreateDetector("datamatrix", options);
  int read = 0, coarse = 0;
  for (int k = 0; k < 8; ++k) {
    const double side = 130.0 + 6.0 * k;
    const Eigen::Vector2d centre(400.0 + 40.0 * k, 300.0 + 30.0 * k);
    const std::string text = "D" + std::to_string(17 + 50 * k);
    const Quad2d truth = MakeQuad(centre, side, 0.15 * k - 0.5);
    const cv::Mat image = SymbolOnACard(text, truth, MakeQuad(centre, side * 1.6, 0.15 * k - 0.5), 40, 0.8);
    // The symbol whole at the 1/8 level.
    for (const DarkQuad& q : FindCoarseDarkQuads(image)) {
      if (q.scale == 0.125 && (QuadCenter(q.corners_px) - centre).norm() < 0.1 * side &&
          std::abs(QuadMeanSide(q.corners_px) / side - 1.0) < 0.15) {
        ++coarse;
        break;
      }
    }
    for (const MarkerObservation& obs : detector->Detect(image)) {
      if (obs.key.id != text) continue;
      ++read;
      EXPECT_LT(MaxCornerError(obs.corners_px, truth), 0.3) << text;
    }
  }
  EXPECT_GE(read, 7);
  EXPECT_GE(coarse, 5);  // 6 of 8 here; the others are read from another level's quad
}

// Large sharp symbols turned about 45 degrees (issue-scenario seed 3, frames 7, 22, 50:
// 70-165 px): at every level the L finder joins only the data modules near it, so its
// component's hull is the L's triangle, or that triangle with a short cut at a leg's end that
// the side-ratio bound turns away, and the hull gives no quad. The L found by its two dark
// legs (the far corner their parallelogram completion) is a candidate, read by the first pass.
TEST(DetectDataMatrix, LFoundByItsDarkLegsWhenTheHullGivesNoQuad) {
  DetectorOptions options;
  options.second_pass = false;
  auto detector = CreateDetector("datamatrix", options);
  int read = 0, tried = 0;
  for (int k = 0; k < 12; ++k) {
    const double side = 120.0 + 4.0 * k;
    const double angle = M_PI / 4 + 0.05 * (k % 3) + (k / 3) * M_PI / 2;
    const Eigen::Vector2d centre(400.0 + 40.0 * k, 300.0 + 30.0 * k);
    const std::string text = "D" + std::to_string(77 + 37 * k);
    const Quad2d truth = MakeQuad(centre, side, angle);
    const cv::Mat image = SymbolOnACard(text, truth, MakeQuad(centre, side * 1.5, angle), 35, 0.7);
    ++tried;
    for (const MarkerObservation& obs : detector->Detect(image)) {
      if (obs.key.id != text) continue;
      ++read;
      EXPECT_LT(MaxCornerError(obs.corners_px, truth), 0.3) << text;
    }
  }
  EXPECT_EQ(read, tried);
}

TEST(DetectDataMatrix, LibdmtxCornersAreInImageOrientation) {
  // libdmtx alone (its image origin is bottom-left, y up): corners must still come out
  // in y-down pixels and docs/design.md order, to within its grid-fit accuracy.
  const SymbolImage symbol = DataMatrixSymbol("libdmtx-7");
  for (int r = 0; r < 4; ++r) {
    cv::Mat image = Canvas(320, 240);
    const Quad2d truth = MakeQuad({160.0, 120.0}, 120.0, r * M_PI / 2 + 0.2);
    DrawSymbol(symbol, truth, &image);
    const auto found = ReadWithLibdmtx(image, std::numeric_limits<double>::infinity());
    ASSERT_EQ(found.size(), 1u) << "rotation " << r;
    EXPECT_EQ(found[0].key.id, "libdmtx-7");
    EXPECT_LT(MaxCornerError(found[0].corners_px, truth), 2.0) << "rotation " << r;
  }
}

TEST(DetectDataMatrix, PerspectiveBlurNoiseAndSeveralSymbols) {
  // Some of these rotations defeat zxing and need libdmtx (second pass).
  auto detector = CreateDetector("datamatrix");
  cv::Mat image = Canvas(1280, 960);
  std::vector<Quad2d> truths;
  for (int i = 0; i < 4; ++i) {
    truths.push_back(MakeQuad({300.0 + 600 * (i % 2), 250.0 + 450 * (i / 2)}, 120.0 + 20 * i, 0.5 * i, 0.85));
    DrawSymbol(DataMatrixSymbol("DM" + std::to_string(i)), truths.back(), &image);
  }
  cv::GaussianBlur(image, image, cv::Size(0, 0), 0.7);
  cv::Mat noise(image.size(), CV_8U);
  cv::RNG rng(3);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 6);
  image += noise;
  const auto found = detector->Detect(image);
  ASSERT_EQ(found.size(), 4u);
  for (const MarkerObservation& obs : found) {
    ASSERT_EQ(obs.key.id.substr(0, 2), "DM");
    const int i = std::stoi(obs.key.id.substr(2));
    EXPECT_LT(MaxCornerError(obs.corners_px, truths[i]), 0.3) << obs.key.id;
  }
}

TEST(DetectDataMatrix, CandidateStageReadsWhatZxingMisses) {
  // zxing 1.4 misses this symbol rotated by ~57 degrees in a candidate region's crop; the L
  // finder candidate, rectified upright and read by libdmtx, gives it without any second
  // pass (no scan of the frame or of a region).
  cv::Mat image = Canvas(480, 480);
  const Quad2d truth = MakeQuad({240.0, 240.0}, 180.0, 1.0);
  DrawSymbol(DataMatrixSymbol("DM3"), truth, &image);
  DetectorOptions first_only;
  first_only.second_pass = false;
  const auto found = CreateDetector("datamatrix", first_only)->Detect(image);
  ASSERT_EQ(found.size(), 1u);
  EXPECT_EQ(found[0].key.id, "DM3");
  EXPECT_LT(MaxCornerError(found[0].corners_px, truth), 0.15);
  DetectorOptions no_candidates;
  no_candidates.max_datamatrix_candidates = 0;
  no_candidates.second_pass = false;
  EXPECT_TRUE(CreateDetector("datamatrix", no_candidates)->Detect(image).empty());
}

// A candidate whose far sides took in part of the quiet zone (a hull joined to the card's
// edge) or whose sides stop short of the symbol: its patch fails the timing test or the
// decoders (on the recall bench; libdmtx reads these clean synthetic ones from either).
// RefitDataMatrixCandidate moves each side onto the symbol's outermost modules,
// and the refitted candidate reads.
TEST(DetectDataMatrix, RefitMovesCandidateSidesOntoTheSymbol) {
  // A light card a little larger than the symbol on a darker background.
  cv::Mat image = Canvas(320, 320);
  image.setTo(cv::Scalar(70));
  const Quad2d truth = MakeQuad({160.0, 158.0}, 84.0, 0.12);
  std::vector<cv::Point> card;
  for (const Eigen::Vector2d& c : MakeQuad({160.0, 158.0}, 84.0 * 1.8, 0.12))
    card.emplace_back(int(c.x()), int(c.y()));
  cv::fillConvexPoly(image, card, cv::Scalar(225));
  DrawSymbol(DataMatrixSymbol("REFIT-14"), truth, &image);
  cv::GaussianBlur(image, image, cv::Size(0, 0), 0.8);
  // Symbol-frame offsets of each corner (fractions of the side, x right and y down in the
  // upright symbol: TL, TR, BR, BL), the L's corner bottom-left.
  const Eigen::Vector2d u = (truth[1] - truth[0]) / 84.0, v = (truth[3] - truth[0]) / 84.0;
  const double too_large[4][2] = {{-0.02, -0.3}, {0.3, -0.3}, {0.3, 0.02}, {-0.02, 0.02}};
  const double too_small[4][2] = {{0.1, 0.1}, {-0.1, 0.1}, {-0.1, -0.1}, {0.1, -0.1}};
  for (const auto* offsets : {too_large, too_small}) {
    DataMatrixCandidate candidate;
    for (int i = 0; i < 4; ++i) {
      candidate.corners_px[i] = truth[i] + 84.0 * (offsets[i][0] * u + offsets[i][1] * v);
    }
    const std::optional<DataMatrixCandidate> refit = RefitDataMatrixCandidate(image, candidate);
    ASSERT_TRUE(refit.has_value());
    EXPECT_LT(MaxCornerError(refit->corners_px, truth), 2.0);
    const auto read = ReadDataMatrixCandidate(image, *refit);
    ASSERT_EQ(read.size(), 1u);
    EXPECT_EQ(read[0].key.id, "REFIT-14");
  }
  // Exact corners: no side moves, nothing to read again.
  DataMatrixCandidate exact;
  exact.corners_px = truth;
  EXPECT_FALSE(RefitDataMatrixCandidate(image, exact).has_value());
  // No symbol: nothing.
  DataMatrixCandidate blank;
  blank.corners_px = MakeQuad({60.0, 60.0}, 40.0, 0.0);
  EXPECT_FALSE(RefitDataMatrixCandidate(Canvas(320, 320), blank).has_value());
}

// The test before the decoders (DataMatrixTimingSideRuns >= 4: a side with at least the 4 dark
// timing modules of the shortest DataMatrix side): every symbol of a fixed-seed set passes
// (five sizes from 10 x 10 modules up, 30-180 px at 2.5 px per module or more, turned, under perspective,
// blurred, with noise, its candidate's corners up to 1.5 px off, the candidate a quarter turn off too);
// clutter with an L fails: the corner of a frame, a checkerboard in a frame's corner, an L with three dashes
// along its other sides (DataMatrixPatchPlausible's two runs pass it), text inside an L.
TEST(DetectDataMatrix, TimingSideRunsPassEverySymbolAndTurnAwayClutter) {
  cv::RNG rng(14);
  const std::string texts[] = {"A", "D4711", "WAYMARK-14", "aisle 12 shelf 7 bin 3",
                               "0123456789012345678901234567890123456789"};
  int tried = 0;
  for (const std::string& text : texts) {
    const SymbolImage symbol = DataMatrixSymbol(text);
    for (const double side : {30.0, 60.0, 110.0, 180.0}) {
      if (side < 2.5 * symbol.symbol.width) continue;  // under 2.5 px per module: no decoder reads it
      for (const double squeeze : {1.0, 0.7}) {
        cv::Mat image = Canvas(400, 400);
        const Quad2d truth = MakeQuad({200.0, 200.0}, side, rng.uniform(0.0, 2 * M_PI), squeeze);
        DrawSymbol(symbol, truth, &image, 30, 210);
        cv::GaussianBlur(image, image, cv::Size(0, 0), rng.uniform(0.5, 1.0));
        cv::Mat noise(image.size(), CV_8S);
        rng.fill(noise, cv::RNG::NORMAL, 0, 3);
        image.convertTo(image, CV_16S);
        cv::add(image, noise, image, cv::noArray(), CV_16S);
        image.convertTo(image, CV_8U);
        for (const int turn : {0, 1}) {
          DataMatrixCandidate candidate;
          for (int i = 0; i < 4; ++i) {
            candidate.corners_px[i] =
                truth[(i + turn) % 4] + Eigen::Vector2d(rng.uniform(-1.5, 1.5), rng.uniform(-1.5, 1.5));
          }
          EXPECT_TRUE(RectifyDataMatrixCandidate(image, candidate).has_value())
              << text << " side " << side << " turn " << turn;
          EXPECT_GE(DataMatrixTimingSideRuns(image, candidate.corners_px), 4)
              << text << " side " << side << " squeeze " << squeeze << " turn " << turn;
          ++tried;
        }
      }
    }
  }
  EXPECT_EQ(tried, 68);

  const int side = 60, margin = 18, size = side + 2 * margin;
  const Quad2d square = PatchSquare(margin, side);
  const cv::Mat frame = LFramePatch(margin, side);
  EXPECT_LT(DataMatrixTimingSideRuns(frame, square), 4);
  cv::Mat checker = frame.clone();
  for (int y = margin + 10; y < margin + side - 8; y += 8) {
    for (int x = margin + 8; x < margin + side - 10; x += 8) {
      if (((x + y) / 8) % 2 == 0) cv::rectangle(checker, cv::Rect(x, y, 8, 8), cv::Scalar(25), cv::FILLED);
    }
  }
  EXPECT_LT(DataMatrixTimingSideRuns(checker, square), 4);
  // Three dashes along the top and the right side, a mixed inside.
  cv::Mat dashed = checker.clone();
  AddThreeDashes(margin, side, &dashed);
  cv::GaussianBlur(dashed, dashed, cv::Size(0, 0), 0.7);
  int runs = 0;
  EXPECT_TRUE(DataMatrixPatchPlausible(dashed, margin, side, &runs));
  EXPECT_EQ(runs, 3);
  EXPECT_EQ(DataMatrixTimingSideRuns(dashed, square), 3);
  cv::Mat text = frame.clone();
  cv::putText(text, "EXIT", cv::Point(margin + 10, margin + 30), cv::FONT_HERSHEY_SIMPLEX, 0.5,
              cv::Scalar(25), 2);
  cv::putText(text, "B12", cv::Point(margin + 12, margin + 46), cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(25),
              2);
  EXPECT_LT(DataMatrixTimingSideRuns(text, square), 4);
  EXPECT_EQ(DataMatrixTimingSideRuns(cv::Mat(size, size, CV_8U, cv::Scalar(128)), square), 0);
}

// DataMatrixTimingSideRuns with `enough` (the detector asks only whether a side has 4 runs): the same
// answer to "at least `enough`?" as the full count for every `enough`, the full count itself when it
// is under `enough`, and never more than it, on symbols (turned, blurred, noisy) and on L-shaped clutter.
TEST(DetectDataMatrix, TimingSideRunsWithEnoughGiveTheSameAnswer) {
  cv::RNG rng(1410);
  std::vector<std::pair<cv::Mat, Quad2d>> cases;
  for (const std::string& text : {std::string("D4711"), std::string("aisle 12 shelf 7 bin 3")}) {
    const SymbolImage symbol = DataMatrixSymbol(text);
    for (const double side : {40.0, 90.0, 160.0}) {
      cv::Mat image = Canvas(320, 320);
      const Quad2d truth = MakeQuad({160.0, 160.0}, side, rng.uniform(0.0, 2 * M_PI), 0.8);
      DrawSymbol(symbol, truth, &image, 30, 210);
      cv::GaussianBlur(image, image, cv::Size(0, 0), 0.8);
      for (const int turn : {0, 1, 2}) {
        Quad2d corners;
        for (int i = 0; i < 4; ++i) corners[i] = truth[(i + turn) % 4];
        cases.emplace_back(image, corners);
      }
    }
  }
  // Clutter: an L and three dashes along the two other sides.
  const int side = 60, margin = 18, size = side + 2 * margin;
  const Quad2d square = PatchSquare(margin, side);
  cv::Mat clutter = LFramePatch(margin, side);
  AddThreeDashes(margin, side, &clutter);
  cases.emplace_back(clutter, square);
  cases.emplace_back(cv::Mat(size, size, CV_8U, cv::Scalar(128)), square);
  int stopped_early = 0;
  for (const auto& [image, corners] : cases) {
    const int full = DataMatrixTimingSideRuns(image, corners);
    for (int enough = 1; enough <= 12; ++enough) {
      const int runs = DataMatrixTimingSideRuns(image, corners, enough);
      EXPECT_EQ(runs >= enough, full >= enough) << "enough " << enough << " full " << full;
      EXPECT_LE(runs, full);
      if (full < enough) {
        EXPECT_EQ(runs, full);
      }
      stopped_early += runs < full;
    }
  }
  EXPECT_GT(stopped_early, 0);  // the early stop happened (the test can fail)
}

TEST(DetectDataMatrix, BlankNoiseAndBadInput) {
  auto detector = CreateDetector("datamatrix");
  EXPECT_TRUE(detector->Detect(Canvas()).empty());
  cv::Mat noise(480, 640, CV_8U);
  cv::RNG rng(11);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
  EXPECT_TRUE(detector->Detect(noise).empty());
  EXPECT_THROW(detector->Detect(cv::Mat()), std::invalid_argument);
  EXPECT_TRUE(detector->Detect(cv::Mat(2, 2, CV_8U, cv::Scalar(0))).empty());
  EXPECT_TRUE(ReadWithLibdmtx(cv::Mat(4, 4, CV_8U, cv::Scalar(0)), 10.0).empty());
}

}  // namespace
}  // namespace waymark
