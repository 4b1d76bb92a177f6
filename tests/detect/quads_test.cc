// Waymark's own candidate stage (detect/quads.h): DataMatrix L finders in every
// rotation and under perspective, with their corners and their orientation; solid-bordered
// quads where AprilTags are; nothing from blank, noise or filled boxes; a candidate read by
// libdmtx on its rectified patch.
#include "detect/quads.h"

#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/imgproc.hpp>

#include "detect/synthetic.h"

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
  const Quad2d square = {Eigen::Vector2d(margin - 0.5, margin - 0.5),
                         Eigen::Vector2d(margin + side - 0.5, margin - 0.5),
                         Eigen::Vector2d(margin + side - 0.5, margin + side - 0.5),
                         Eigen::Vector2d(margin - 0.5, margin + side - 0.5)};
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
}

TEST(DetectQuads, SmallAndLargeSymbolsAreCandidates) {
  for (const double side : {22.0, 40.0, 380.0}) {
    cv::Mat image = Canvas(1280, 960);
    const Quad2d truth = MakeQuad({640.0, 480.0}, side, 0.2);
    DrawSymbol(DataMatrixSymbol("S1"), truth, &image);
    cv::GaussianBlur(image, image, cv::Size(0, 0), 0.6);
    const auto candidates = DataMatrixCandidates(FindDarkQuads(image), 8);
    ASSERT_EQ(candidates.size(), 1u) << side;
    EXPECT_LT((candidates[0].corners_px[3] - truth[3]).norm(), std::max(2.0, 0.03 * side)) << side;
    const auto read = ReadDataMatrixCandidate(image, candidates[0]);
    ASSERT_EQ(read.size(), 1u) << side;
    EXPECT_EQ(read[0].key.id, "S1");
  }
}

// The L's legs count from 80 % dark: a blurred symbol found at a coarse level, where a
// module is a pixel or two, reads a leg 80-85 % dark (the recall bench's 62 px symbol at
// 1/4 resolution: 0.82 and 1.00). A leg under 80 % is no L.
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
  q.side_dark[3] = 0.78;
  EXPECT_TRUE(DataMatrixCandidates({q}, 4).empty());
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
  EXPECT_EQ(DataMatrixCandidates(quads, 8).size(), 1u);
  // One pixel changed far from the symbol: a new run (the same candidate).
  image.at<uint8_t>(5, 5) = 0;
  EXPECT_EQ(DataMatrixCandidates(FindDarkQuads(image), 8).size(), 1u);
  // The same pixels in another buffer: the same quads.
  const cv::Mat copy = image.clone();
  const auto again = FindDarkQuads(copy);
  ASSERT_EQ(again.size(), FindDarkQuads(image).size());
  cv::Mat blank = Canvas();
  EXPECT_TRUE(DataMatrixCandidates(FindDarkQuads(blank), 8).empty());
}

}  // namespace
}  // namespace waymark
