// QR candidates from finder patterns and their rectified reading (detect/qr_finder.h),
// on synthetic codes drawn through known homographies (detect/synthetic.h): finder
// centres and code corners where the symbol puts them, docs/design.md order in every rotation,
// small and oblique codes that zxing-cpp misses on the whole frame read after
// rectification, and nothing from images without codes or from bad input.
#include "detect/qr_finder.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <opencv2/imgproc.hpp>

#include "detect/detector.h"
#include "detect/quads.h"
#include "detect/synthetic.h"
#include "detect/zxing.h"

namespace waymark {
namespace {

cv::Mat Canvas(int width = 640, int height = 480) { return cv::Mat(height, width, CV_8U, cv::Scalar(170)); }

// Where the module coordinates (u, v) of an n-module symbol (0..n across, pixel edges of
// the symbol) land when its outer corners are `corners_px`.
Eigen::Vector2d SymbolPoint(const Quad2d& corners_px, int n, double u, double v) {
  const std::vector<cv::Point2f> src = {{0.f, 0.f}, {float(n), 0.f}, {float(n), float(n)}, {0.f, float(n)}};
  std::vector<cv::Point2f> dst;
  for (const Eigen::Vector2d& c : corners_px) dst.emplace_back(c.x(), c.y());
  const cv::Matx33d H(cv::getPerspectiveTransform(src, dst));
  const cv::Vec3d p = H * cv::Vec3d(u, v, 1.0);
  return {p[0] / p[2], p[1] / p[2]};
}

double MaxCornerError(const Quad2d& a, const Quad2d& b) {
  double worst = 0.0;
  for (int i = 0; i < 4; ++i) worst = std::max(worst, (a[i] - b[i]).norm());
  return worst;
}

const cv::Rect kWhole(0, 0, 640, 480);

// The default options (pass 2 is bounded by counts, not by time).
DetectorOptions Generous() { return DetectorOptions{}; }

TEST(DetectQrFinder, ThreeFindersAtTheSymbolsFinderCentres) {
  const SymbolImage symbol = QrSymbol("0/2/10");
  const int n = symbol.symbol.width;  // 21 modules
  cv::Mat image = Canvas();
  const Quad2d truth = MakeQuad({320.3, 241.7}, 150.0, 0.3);
  DrawSymbol(symbol, truth, &image);
  cv::GaussianBlur(image, image, cv::Size(0, 0), 0.7);
  const std::vector<QrFinderPattern> finders = FindQrFinderPatterns(image, kWhole);
  ASSERT_EQ(finders.size(), 3u);
  const Eigen::Vector2d expected[3] = {SymbolPoint(truth, n, 3.5, 3.5), SymbolPoint(truth, n, n - 3.5, 3.5),
                                       SymbolPoint(truth, n, 3.5, n - 3.5)};
  for (const Eigen::Vector2d& e : expected) {
    double nearest = 1e9;
    for (const QrFinderPattern& f : finders) nearest = std::min(nearest, (f.centre_px - e).norm());
    EXPECT_LT(nearest, 0.5);
  }
  const double module_px = 150.0 / n;
  for (const QrFinderPattern& f : finders) EXPECT_NEAR(f.width_px, 7.0 * module_px, 1.5 * module_px);
}

// Under sensor noise of 10 gray levels, where the binarization's offset grows with the frame's
// noise (10 instead of 4: fewer specks to trace), the three finders are still found, at their
// centres, and nothing else.
TEST(DetectQrFinder, ThreeFindersUnderHeavyNoise) {
  const SymbolImage symbol = QrSymbol("0/2/10");
  const int n = symbol.symbol.width;
  cv::Mat image = Canvas();
  const Quad2d truth = MakeQuad({320.3, 241.7}, 150.0, 0.3);
  DrawSymbol(symbol, truth, &image);
  cv::GaussianBlur(image, image, cv::Size(0, 0), 0.7);
  cv::RNG rng(10);
  AddSensorNoise(rng, 10.0, &image);
  const std::vector<QrFinderPattern> finders = FindQrFinderPatterns(image, kWhole);
  ASSERT_EQ(finders.size(), 3u);
  for (const Eigen::Vector2d& e : {SymbolPoint(truth, n, 3.5, 3.5), SymbolPoint(truth, n, n - 3.5, 3.5),
                                   SymbolPoint(truth, n, 3.5, n - 3.5)}) {
    double nearest = 1e9;
    for (const QrFinderPattern& f : finders) nearest = std::min(nearest, (f.centre_px - e).norm());
    EXPECT_LT(nearest, 1.0);
  }
}

TEST(DetectQrFinder, CandidateCornersInDesignOrderInEveryRotation) {
  const SymbolImage symbol = QrSymbol("waymark:A01");
  for (int r = 0; r < 4; ++r) {
    cv::Mat image = Canvas();
    const Quad2d truth = MakeQuad({310.0, 250.0}, 140.0, r * M_PI / 2 + 0.2, 0.85);
    DrawSymbol(symbol, truth, &image);
    const std::vector<QrCandidate> candidates =
        GroupQrFinders(FindQrFinderPatterns(image, kWhole), image.size());
    ASSERT_EQ(candidates.size(), 1u) << "rotation " << r;
    // Coarse (contour corners; the fourth from the finders' edges): well within a module.
    EXPECT_LT(MaxCornerError(candidates[0].corners_px, truth), 0.5 * 140.0 / 21.0) << "rotation " << r;
    EXPECT_GT(candidates[0].module_px, 0.5 * 140.0 / 21.0);
  }
}

// A version-2 code of 1.7 px per module under a 0.7 px blur (the ceiling codes of the
// ceiling-grid scenario): zxing-cpp does not read it on the frame, nor in a crop upscaled 2x
// with its global binarizer; resampled upright at 4 px per module and sharpened, it does.
TEST(DetectQrFinder, SmallBlurredCodeIsReadRectified) {
  const SymbolImage symbol = QrSymbol("waymark-ceiling/12/0.7/3.5");
  ASSERT_EQ(symbol.symbol.width, 25);
  cv::Mat image = Canvas();
  const Quad2d truth = MakeQuad({301.4, 180.6}, 42.5, 0.06);
  DrawSymbol(symbol, truth, &image, 90, 200);
  cv::GaussianBlur(image, image, cv::Size(0, 0), 0.7);
  std::printf("zxing on the whole frame: %zu codes\n",
              ReadWithZxing(image, ZxingSymbology::kQrCode, ZxingPass{}).size());
  const cv::Rect region(265, 145, 72, 72);
  const std::vector<QrCandidate> candidates =
      GroupQrFinders(FindQrFinderPatterns(image, region), image.size());
  ASSERT_EQ(candidates.size(), 1u);
  const std::vector<MarkerObservation> read = ReadRectifiedQr(image, candidates[0]);
  ASSERT_EQ(read.size(), 1u);
  EXPECT_EQ(read[0].key.id, "waymark-ceiling/12/0.7/3.5");
  EXPECT_LT(MaxCornerError(read[0].corners_px, truth), 1.0);
  // The detector finds it too, with refined corners.
  const std::vector<MarkerObservation> found = CreateDetector("qr", Generous())->Detect(image);
  ASSERT_EQ(found.size(), 1u);
  EXPECT_EQ(found[0].key.id, "waymark-ceiling/12/0.7/3.5");
  EXPECT_LT(MaxCornerError(found[0].corners_px, truth), 0.5);
}

// Version 1 turned 45-60 degrees away (the corner bench's 65 px codes at 45 deg): zxing's
// grid from the finders' parallelogram misses the data; the rectified code is read.
TEST(DetectQrFinder, ObliqueVersionOneCodeIsRead) {
  const SymbolImage symbol = QrSymbol("0/5/2.5");
  ASSERT_EQ(symbol.symbol.width, 21);
  cv::Mat image = Canvas(1280, 960);
  const Quad2d truth = {Eigen::Vector2d(600.2, 400.7), Eigen::Vector2d(641.9, 392.3),
                        Eigen::Vector2d(642.4, 470.1), Eigen::Vector2d(600.8, 467.5)};
  DrawSymbol(symbol, truth, &image);
  cv::GaussianBlur(image, image, cv::Size(0, 0), 0.7);
  std::printf("zxing on the whole frame: %zu codes\n",
              ReadWithZxing(image, ZxingSymbology::kQrCode, ZxingPass{}).size());
  const std::vector<MarkerObservation> found = CreateDetector("qr", Generous())->Detect(image);
  ASSERT_EQ(found.size(), 1u);
  EXPECT_EQ(found[0].key.id, "0/5/2.5");
  EXPECT_LT(MaxCornerError(found[0].corners_px, truth), 0.5);
}

// A finder whose dark ring touches other dark pixels (a bar, or under blur the data modules):
// the ring's outline is no square, but the light ring inside it still closes around the
// centre, and the finder is found by its hole.
TEST(DetectQrFinder, FinderFoundByItsHoleWhenItsRingTouchesADarkBar) {
  const SymbolImage symbol = QrSymbol("0/2/10");
  const int n = symbol.symbol.width;  // 21 modules
  cv::Mat image = Canvas();
  const Quad2d truth = MakeQuad({320.0, 240.0}, 147.0, 0.0);  // 7 px per module, axis-aligned
  DrawSymbol(symbol, truth, &image);
  // A bar from the left reaching 2 px into the top-left finder's ring.
  const Eigen::Vector2d ring = SymbolPoint(truth, n, 0.0, 3.5);
  cv::rectangle(image, cv::Point(int(ring.x()) - 60, int(ring.y()) - 8),
                cv::Point(int(ring.x()) + 2, int(ring.y()) + 8), cv::Scalar(30), cv::FILLED);
  cv::GaussianBlur(image, image, cv::Size(0, 0), 0.7);
  const std::vector<QrFinderPattern> finders = FindQrFinderPatterns(image, kWhole);
  ASSERT_EQ(finders.size(), 3u);
  double nearest = 1e9;
  const Eigen::Vector2d top_left = SymbolPoint(truth, n, 3.5, 3.5);
  for (const QrFinderPattern& f : finders) {
    if ((f.centre_px - top_left).norm() < nearest) {
      nearest = (f.centre_px - top_left).norm();
      EXPECT_NEAR(f.width_px, 7.0 * 7.0, 0.2 * 7.0 * 7.0);
    }
  }
  EXPECT_LT(nearest, 0.5);
  ASSERT_EQ(GroupQrFinders(finders, image.size()).size(), 1u);
}

// The image of a square of side `side_px` (head-on) tilted by `tilt_deg` about an in-plane
// axis at `axis_rad`, seen by a pinhole camera of focal length 1000 px at 1000 units.
Quad2d TiltedSquare(const Eigen::Vector2d& centre, double side_px, double roll_rad, double tilt_deg,
                    double axis_rad) {
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(tilt_deg * M_PI / 180.0, Eigen::Vector3d(std::cos(axis_rad), std::sin(axis_rad), 0.0))
          .toRotationMatrix() *
      Eigen::AngleAxisd(roll_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const double h = 0.5 * side_px;
  const Eigen::Vector3d local[4] = {{-h, -h, 0}, {h, -h, 0}, {h, h, 0}, {-h, h, 0}};
  Quad2d quad;
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector3d p = R * local[i] + Eigen::Vector3d(0, 0, 1000.0);
    quad[i] = centre + 1000.0 * Eigen::Vector2d(p.x() / p.z(), p.y() / p.z());
  }
  return quad;
}

// A small tilted version-1 code (2.1 px per module across its short side) among boxes and
// frames, as the recall bench's clutter: the dark-quad stage gives it as a candidate (the
// few candidate regions need not hold it), the boxes give none, and the detector reads it
// with sub-pixel corners.
TEST(DetectQrFinder, SmallTiltedCodeAmongBoxesIsACandidateFromDarkQuads) {
  cv::Mat image = Canvas(1280, 960);
  cv::RNG rng(7);
  for (int i = 0; i < 40; ++i) {
    const cv::Rect box(rng.uniform(0, 1200), rng.uniform(0, 900), rng.uniform(15, 120), rng.uniform(15, 120));
    if ((box & cv::Rect(560, 380, 160, 160)).area() > 0) continue;
    cv::rectangle(image, box, cv::Scalar(rng.uniform(20, 80)), rng.uniform(0, 2) ? cv::FILLED : 3);
  }
  const SymbolImage symbol = QrSymbol("r/235/12.5");
  ASSERT_EQ(symbol.symbol.width, 21);
  const Quad2d truth = TiltedSquare({640.0, 460.0}, 58.0, 0.4, 40.0, 1.1);
  DrawSymbol({cv::Mat(1, 1, CV_8U, cv::Scalar(255)), cv::Rect(0, 0, 1, 1)},
             TiltedSquare({640.0, 460.0}, 87.0, 0.4, 40.0, 1.1), &image, 20, 225);
  DrawSymbol(symbol, truth, &image, 30, 225);
  cv::GaussianBlur(image, image, cv::Size(0, 0), 0.7);
  const std::vector<QrCandidate> candidates = QrCandidatesFromQuads(image, FindDarkQuads(image, 6.0));
  ASSERT_EQ(candidates.size(), 1u);
  EXPECT_LT((QuadCenter(candidates[0].corners_px) - QuadCenter(truth)).norm(), 0.2 * QuadMeanSide(truth));
  const std::vector<MarkerObservation> found = CreateDetector("qr", Generous())->Detect(image);
  ASSERT_EQ(found.size(), 1u);
  EXPECT_EQ(found[0].key.id, "r/235/12.5");
  EXPECT_LT(MaxCornerError(found[0].corners_px, truth), 0.3);
}

// The contours are traced only in windows around rows and columns that cross a finder's
// middle (KeepFinderWindows in qr_finder.cc): the finders of a small, blurred code in every
// rotation, head on and foreshortened to 0.55, on a noisy, shaded background (a field of
// noise specks that the windows leave out) are all found where the symbol puts them.
// A square of side `side` foreshortened to `squeeze` across (a code turned away about its
// vertical axis), then rotated by `angle` on screen.
Quad2d ForeshortenedQuad(const Eigen::Vector2d& centre, double side, double angle, double squeeze) {
  const double h = 0.5 * side, c = std::cos(angle), s = std::sin(angle);
  const Eigen::Vector2d local[4] = {
      {-h * squeeze, -h}, {h * squeeze, -h}, {h * squeeze, h}, {-h * squeeze, h}};
  Quad2d quad;
  for (int i = 0; i < 4; ++i) {
    quad[i] =
        centre + Eigen::Vector2d(c * local[i].x() - s * local[i].y(), s * local[i].x() + c * local[i].y());
  }
  return quad;
}

TEST(DetectQrFinder, FindersFoundInEveryRotationOnNoise) {
  const SymbolImage symbol = QrSymbol("r/42/12.5");
  const int n = symbol.symbol.width;
  for (const double squeeze : {1.0, 0.55}) {
    for (int step = 0; step < 12; ++step) {
      cv::Mat image = Canvas();
      for (int y = 0; y < image.rows; ++y) image.row(y).setTo(cv::Scalar(120 + y / 8));
      const Quad2d truth = ForeshortenedQuad({321.3, 238.6}, 84.0, step * M_PI / 12 + 0.05, squeeze);
      DrawSymbol(symbol, truth, &image);
      cv::GaussianBlur(image, image, cv::Size(0, 0), 0.7);
      cv::Mat noise(image.size(), CV_16S);
      cv::RNG rng(step + 1);
      rng.fill(noise, cv::RNG::NORMAL, 0, 5);
      image.convertTo(image, CV_16S);
      image += noise;
      image.convertTo(image, CV_8U);
      const std::vector<QrFinderPattern> finders = FindQrFinderPatterns(image, kWhole);
      const Eigen::Vector2d expected[3] = {SymbolPoint(truth, n, 3.5, 3.5),
                                           SymbolPoint(truth, n, n - 3.5, 3.5),
                                           SymbolPoint(truth, n, 3.5, n - 3.5)};
      for (const Eigen::Vector2d& e : expected) {
        double nearest = 1e9;
        for (const QrFinderPattern& f : finders) nearest = std::min(nearest, (f.centre_px - e).norm());
        EXPECT_LT(nearest, 1.0) << "squeeze " << squeeze << " angle step " << step;
      }
    }
  }
}

// A small oblique code whose third finder the search misses (blurred into its data modules:
// recall bench issue seed 13 frame 127): the two found complete the triple with the third
// found where they put it, whichever of the three is lost (the pair adjacent, either one the
// corner finder, or on the diagonal), in every rotation; the corners are as good as the three
// finders' (coarse: the reader refines them) and the candidate reads.
TEST(DetectQrFinder, PairCompletedWhicheverFinderIsLost) {
  const SymbolImage symbol = QrSymbol("r/228/12.5");
  const int n = symbol.symbol.width;
  const double module_px = 48.0 / n;
  int completed = 0;
  for (int step = 0; step < 4; ++step) {
    cv::Mat image = Canvas();
    const Quad2d truth = ForeshortenedQuad({321.3, 238.6}, 48.0, step * M_PI / 2 + 0.3, 0.65);
    DrawSymbol(symbol, truth, &image);
    cv::GaussianBlur(image, image, cv::Size(0, 0), 0.6);
    // A small code's box, as the detector searches it (upscaled).
    const std::vector<QrFinderPattern> finders = FindQrFinderPatterns(image, cv::Rect(281, 198, 80, 80));
    ASSERT_EQ(finders.size(), 3u) << "rotation " << step;
    const std::vector<QrCandidate> whole = GroupQrFinders(finders, image.size());
    ASSERT_EQ(whole.size(), 1u) << "rotation " << step;
    const double whole_error = MaxCornerError(whole[0].corners_px, truth);
    for (int lost = 0; lost < 3; ++lost) {
      std::vector<QrFinderPattern> pair;
      for (int i = 0; i < 3; ++i) {
        if (i != lost) pair.push_back(finders[i]);
      }
      const std::vector<QrCandidate> candidates =
          QrCandidatesFromFinderPairs(image, pair, {}, kMaxPairFinderWidthPx);
      ASSERT_EQ(candidates.size(), 1u) << "rotation " << step << " lost " << lost;
      EXPECT_LT(MaxCornerError(candidates[0].corners_px, truth), whole_error + 0.5 * module_px)
          << "rotation " << step << " lost " << lost;
      const std::vector<MarkerObservation> read = ReadRectifiedQr(image, candidates[0]);
      ASSERT_EQ(read.size(), 1u) << "rotation " << step << " lost " << lost;
      EXPECT_EQ(read[0].key.id, "r/228/12.5");
      ++completed;
    }
  }
  EXPECT_EQ(completed, 12);
}

// Pairs are only formed from finders outside every triple, of similar widths, and need the
// third finder's pattern in the image where they put it.
TEST(DetectQrFinder, NoPairCompletionWithoutItsEvidence) {
  const SymbolImage symbol = QrSymbol("r/228/12.5");
  cv::Mat image = Canvas();
  DrawSymbol(symbol, MakeQuad({320.0, 240.0}, 48.0, 0.2), &image);
  const std::vector<QrFinderPattern> finders = FindQrFinderPatterns(image, kWhole);
  ASSERT_EQ(finders.size(), 3u);
  const std::vector<QrCandidate> triples = GroupQrFinders(finders, image.size());
  ASSERT_EQ(triples.size(), 1u);
  EXPECT_TRUE(QrCandidatesFromFinderPairs(image, finders, triples, kMaxPairFinderWidthPx).empty());
  // The same pair: completed; not with no image, with finders wider than allowed, or with one
  // finder twice as wide as the other.
  const std::vector<QrFinderPattern> pair = {finders[0], finders[1]};
  EXPECT_FALSE(QrCandidatesFromFinderPairs(image, pair, {}, kMaxPairFinderWidthPx).empty());
  EXPECT_TRUE(QrCandidatesFromFinderPairs(cv::Mat(), pair, {}, kMaxPairFinderWidthPx).empty());
  EXPECT_TRUE(QrCandidatesFromFinderPairs(image, pair, {}, 0.5 * pair[0].width_px).empty());
  std::vector<QrFinderPattern> uneven = pair;
  uneven[1].width_px *= 2.0;
  EXPECT_TRUE(QrCandidatesFromFinderPairs(image, uneven, {}, 100.0).empty());
  // Two finder-like squares with nothing where a third would be.
  cv::Mat two = Canvas();
  for (const int x : {200, 330}) {
    cv::rectangle(two, cv::Rect(x, 200, 21, 21), cv::Scalar(20), cv::FILLED);
    cv::rectangle(two, cv::Rect(x + 3, 203, 15, 15), cv::Scalar(230), cv::FILLED);
    cv::rectangle(two, cv::Rect(x + 6, 206, 9, 9), cv::Scalar(20), cv::FILLED);
  }
  const std::vector<QrFinderPattern> squares = FindQrFinderPatterns(two, kWhole);
  ASSERT_EQ(squares.size(), 2u);
  EXPECT_TRUE(QrCandidatesFromFinderPairs(two, squares, {}, kMaxPairFinderWidthPx).empty());
}

// The rectified read's evidence (RectifiedQrFinderContrast, resampled on the three finders'
// patches only since issue 14's tenth speed round): codes of 21 modules at 2.9-6.7 px per module,
// turned and foreshortened, blurred, score well above 0 and read; the same layout of three
// solid dark squares (a filled box is no finder: its light ring is dark), of three thick dark
// frames round small light boxes (light where the centre is dark, dark where the ring is
// light) score at most 0, and a quad over noise little; none reads.
TEST(DetectQrFinder, RectifiedFinderContrastTellsCodesFromClutter) {
  int k = 0;
  for (const double side : {60.0, 90.0, 140.0}) {
    for (const double squeeze : {1.0, 0.85}) {
      const SymbolImage symbol = QrSymbol("r/" + std::to_string(300 + k) + "/12.5");
      cv::Mat image = Canvas();
      DrawSymbol(symbol, MakeQuad({320.0, 240.0}, side, 0.3 + 0.7 * k, squeeze), &image);
      cv::GaussianBlur(image, image, cv::Size(0, 0), 0.7);
      const std::vector<QrCandidate> candidates =
          GroupQrFinders(FindQrFinderPatterns(image, kWhole), image.size());
      ASSERT_EQ(candidates.size(), 1u) << side << " " << squeeze;
      EXPECT_GT(RectifiedQrFinderContrast(image, candidates[0]), 20.0) << side << " " << squeeze;
      EXPECT_EQ(ReadRectifiedQr(image, candidates[0]).size(), 1u) << side << " " << squeeze;
      ++k;
    }
  }
  // Clutter at a code's corners: 21 modules of 4 px, the three 7-module blocks at 260..288
  // and 320..348.
  QrCandidate candidate;
  candidate.corners_px = {Eigen::Vector2d(259.5, 199.5), Eigen::Vector2d(343.5, 199.5),
                          Eigen::Vector2d(343.5, 283.5), Eigen::Vector2d(259.5, 283.5)};
  candidate.module_px = 4.0;
  for (const bool frames : {false, true}) {
    cv::Mat boxes = Canvas();
    for (const cv::Point& at : {cv::Point(260, 200), cv::Point(316, 200), cv::Point(260, 256)}) {
      cv::rectangle(boxes, cv::Rect(at, cv::Size(28, 28)), cv::Scalar(20), cv::FILLED);
      if (frames)
        cv::rectangle(boxes, cv::Rect(at + cv::Point(8, 8), cv::Size(12, 12)), cv::Scalar(230), cv::FILLED);
    }
    cv::GaussianBlur(boxes, boxes, cv::Size(0, 0), 0.7);
    EXPECT_LE(RectifiedQrFinderContrast(boxes, candidate), 0.0) << frames;
    EXPECT_TRUE(ReadRectifiedQr(boxes, candidate).empty()) << frames;
  }
  cv::Mat noise(480, 640, CV_8U);
  cv::RNG rng(5);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
  EXPECT_LT(RectifiedQrFinderContrast(noise, candidate), 10.0);
  EXPECT_TRUE(ReadRectifiedQr(noise, candidate).empty());
  // Bad input.
  EXPECT_EQ(RectifiedQrFinderContrast(cv::Mat(), candidate), -std::numeric_limits<double>::infinity());
  QrCandidate degenerate = candidate;
  degenerate.module_px = 0.0;
  EXPECT_EQ(RectifiedQrFinderContrast(Canvas(), degenerate), -std::numeric_limits<double>::infinity());
}

TEST(DetectQrFinder, NoCandidateWithoutThreeFinders) {
  // Blank, noise, and two finder-like squares (a code needs three).
  EXPECT_TRUE(FindQrFinderPatterns(Canvas(), kWhole).empty());
  cv::Mat noise(480, 640, CV_8U);
  cv::RNG rng(3);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
  EXPECT_TRUE(GroupQrFinders(FindQrFinderPatterns(noise, kWhole), noise.size()).empty());
  cv::Mat two = Canvas();
  for (const int x : {200, 400}) {
    cv::rectangle(two, cv::Rect(x, 200, 70, 70), cv::Scalar(20), cv::FILLED);
    cv::rectangle(two, cv::Rect(x + 10, 210, 50, 50), cv::Scalar(230), cv::FILLED);
    cv::rectangle(two, cv::Rect(x + 20, 220, 30, 30), cv::Scalar(20), cv::FILLED);
  }
  EXPECT_EQ(FindQrFinderPatterns(two, kWhole).size(), 2u);
  EXPECT_TRUE(GroupQrFinders(FindQrFinderPatterns(two, kWhole), two.size()).empty());
}

TEST(DetectQrFinder, BadInputGivesNothing) {
  EXPECT_TRUE(FindQrFinderPatterns(cv::Mat(), kWhole).empty());
  EXPECT_TRUE(FindQrFinderPatterns(cv::Mat(480, 640, CV_32F, cv::Scalar(0.5)), kWhole).empty());
  EXPECT_TRUE(FindQrFinderPatterns(Canvas(), cv::Rect(700, 500, 50, 50)).empty());  // outside
  EXPECT_TRUE(FindQrFinderPatterns(Canvas(), cv::Rect(10, 10, 8, 8)).empty());      // tiny
  QrCandidate degenerate;
  degenerate.corners_px = MakeQuad({320.0, 240.0}, 60.0, 0.0);
  EXPECT_TRUE(ReadRectifiedQr(Canvas(), degenerate).empty());  // module_px = 0
  degenerate.module_px = 2.0;
  EXPECT_TRUE(ReadRectifiedQr(cv::Mat(), degenerate).empty());
  EXPECT_TRUE(ReadRectifiedQr(Canvas(), degenerate).empty());  // nothing there
}

}  // namespace
}  // namespace waymark
