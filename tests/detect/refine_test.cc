// Edge estimators of detect/refine.h on synthetic blurred edges with known position:
// an isolated step, a thin dark bar (a QR finder's 1-module ring), and the side-segment
// line fit used for the QR fourth corner.
#include "detect/refine.h"

#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/imgproc.hpp>
#include <utility>
#include <vector>

#include "detect/synthetic.h"

namespace waymark {
namespace {

double Phi(double u) { return 0.5 * std::erfc(-u / std::sqrt(2.0)); }

// A 64x64 image of a straight edge through `point` with outward normal (cos a, sin a):
// light `light` outside, a dark (15) bar of width `bar_px` inside, light again beyond it;
// Gaussian blur `sigma_px`, each pixel the mean of 8x8 samples, rounded and clipped to
// [0, 255] (light > 255 saturates the outside as an over-exposed quiet zone does).
cv::Mat EdgeImage(const Eigen::Vector2d& point, double angle_rad, double sigma_px, double light,
                  double bar_px) {
  const Eigen::Vector2d n(std::cos(angle_rad), std::sin(angle_rad));
  cv::Mat image(64, 64, CV_8U);
  for (int r = 0; r < image.rows; ++r) {
    for (int c = 0; c < image.cols; ++c) {
      double sum = 0.0;
      for (int i = 0; i < 8; ++i) {
        for (int j = 0; j < 8; ++j) {
          const Eigen::Vector2d q(c - 0.5 + (i + 0.5) / 8.0, r - 0.5 + (j + 0.5) / 8.0);
          const double d = (q - point).dot(n);  // outward distance from the edge
          sum += light - (light - 15.0) * (Phi(-d / sigma_px) - Phi((-d - bar_px) / sigma_px));
        }
      }
      image.at<uint8_t>(r, c) = cv::saturate_cast<uint8_t>(std::round(sum / 64.0));
    }
  }
  return image;
}

struct Bias {
  double centroid_px = 0.0;  // FindOuterEdge
  double model_px = 0.0;     // FitEdgeModel from it
  int fitted = 0;
};

// Mean signed error (outward positive) of both estimators over 21 profiles along the edge,
// each started 0.3 px off the edge.
Bias MeasureBias(double sigma_px, double light, double bar_px) {
  const Eigen::Vector2d point(32.3, 31.7);
  const double angle_rad = 0.3;
  const cv::Mat image = EdgeImage(point, angle_rad, sigma_px, light, bar_px);
  const Eigen::Vector2d n(std::cos(angle_rad), std::sin(angle_rad));
  const Eigen::Vector2d along(-n.y(), n.x());
  Bias bias;
  int found = 0;
  for (int k = -10; k <= 10; ++k) {
    const Eigen::Vector2d p = point + 0.7 * k * along + 0.3 * n;
    const std::optional<EdgeHit> hit = FindOuterEdge(image, p, n, 1.25, 12.0);
    if (!hit) continue;
    ++found;
    bias.centroid_px += hit->offset_px + 0.3;
    if (const std::optional<double> e = FitEdgeModel(image, p, n, hit->offset_px)) {
      ++bias.fitted;
      bias.model_px += *e + 0.3;
    }
  }
  EXPECT_EQ(found, 21);
  bias.centroid_px /= std::max(found, 1);
  bias.model_px /= std::max(bias.fitted, 1);
  return bias;
}

TEST(DetectRefine, IsolatedStepIsUnbiased) {
  for (const double sigma_px : {0.7, 1.0}) {
    const Bias bias = MeasureBias(sigma_px, 190.0, 100.0);
    EXPECT_LT(std::abs(bias.centroid_px), 0.03) << sigma_px;
    EXPECT_LT(std::abs(bias.model_px), 0.03) << sigma_px;
  }
}

// A 1-module ring of 1.9 .. 2.3 px (a 40 .. 48 px version-1 QR code): the centroid of the
// derivative is pulled outwards by the ring's inner edge (measured +0.13 .. +0.43 px); the
// bar model fit removes it.
TEST(DetectRefine, ThinDarkBarIsLocatedByTheModelFit) {
  for (const double bar_px : {1.9, 2.3}) {
    for (const double sigma_px : {0.7, 1.0}) {
      const Bias bias = MeasureBias(sigma_px, 190.0, bar_px);
      EXPECT_GT(bias.centroid_px, 0.1) << bar_px << " " << sigma_px;  // the bias the fit removes
      EXPECT_EQ(bias.fitted, 21) << bar_px << " " << sigma_px;
      EXPECT_LT(std::abs(bias.model_px), 0.05) << bar_px << " " << sigma_px;
    }
  }
}

// Dark square [10, 50]^2 on light, blurred: each side's edge is known exactly.
cv::Mat SquareImage() {
  cv::Mat image(64, 64, CV_8U);
  for (int r = 0; r < 64; ++r) {
    for (int c = 0; c < 64; ++c) {
      const double inside =
          (Phi((c - 10.0) / 0.7) - Phi((c - 50.0) / 0.7)) * (Phi((r - 10.0) / 0.7) - Phi((r - 50.0) / 0.7));
      image.at<uint8_t>(r, c) = cv::saturate_cast<uint8_t>(std::round(200.0 - 185.0 * inside));
    }
  }
  return image;
}

TEST(DetectRefine, SideSegmentsGiveTheFourthCorner) {
  const cv::Mat image = SquareImage();
  // Corners TL, TR, BR, BL (clockwise on screen); the bottom-right one 2.5 px off, as zxing
  // places it on a version-1 QR code.
  const Eigen::Vector2d tr(50, 10), br(47.5, 48.0), bl(10, 50);
  const std::optional<Line2d> right = FitSideSegment(image, tr, br, 0.05, 0.3, 3.0, 12.0);
  const std::optional<Line2d> bottom = FitSideSegment(image, br, bl, 0.7, 0.95, 3.0, 12.0);
  ASSERT_TRUE(right && bottom);
  EXPECT_GT(right->inlier_fraction, 0.9);
  const std::optional<Eigen::Vector2d> corner = IntersectLines(*right, *bottom);
  ASSERT_TRUE(corner);
  EXPECT_LT((*corner - Eigen::Vector2d(50.0, 50.0)).norm(), 0.1);
}

TEST(DetectRefine, DegenerateInputGivesNothing) {
  const Line2d a{Eigen::Vector2d(0, 0), Eigen::Vector2d(1, 0), 1.0};
  const Line2d b{Eigen::Vector2d(0, 1), Eigen::Vector2d(1, 0.01).normalized(), 1.0};
  EXPECT_FALSE(IntersectLines(a, b));  // nearly parallel
  const cv::Mat flat(64, 64, CV_8U, cv::Scalar(128));
  EXPECT_FALSE(FitSideSegment(flat, {10, 10}, {50, 10}, 0.1, 0.9, 3.0, 12.0));
  EXPECT_FALSE(FitSideSegment(cv::Mat(), {10, 10}, {50, 10}, 0.1, 0.9, 3.0, 12.0));
  EXPECT_FALSE(FitSideSegment(SquareImage(), {10, 10}, {50, 10}, 0.5, 0.4, 3.0, 12.0));
  EXPECT_FALSE(FindOuterEdge(flat, {32, 32}, {1, 0}, 2.0, 12.0));
  // A profile leaving the image.
  EXPECT_FALSE(FitEdgeModel(SquareImage(), {1.0, 30.0}, {-1, 0}, 0.0));
}

// A window of more than 64 samples (FindOuterEdge's profile then leaves its stack buffer)
// finds the same edge: the top side of the square, 10 px outwards of the start; a window
// reaching out of the image gives nothing.
TEST(DetectRefine, WideWindowFindsTheOuterEdge) {
  const cv::Mat image = SquareImage();
  const std::optional<EdgeHit> wide = FindOuterEdge(image, {30.0, 20.0}, {0.0, -1.0}, 12.0, 12.0);
  const std::optional<EdgeHit> narrow = FindOuterEdge(image, {30.0, 10.5}, {0.0, -1.0}, 2.0, 12.0);
  ASSERT_TRUE(wide && narrow);
  EXPECT_NEAR(wide->offset_px, 10.0, 0.05);
  EXPECT_NEAR(wide->offset_px - 9.5, narrow->offset_px, 1e-9);
  EXPECT_FALSE(FindOuterEdge(image, {30.0, 20.0}, {0.0, -1.0}, -3.0, 12.0));  // no window
  // The window's ends at rows 40 and 0 (inside), then at 40.5 and -0.5 (its last sample out).
  const std::optional<EdgeHit> to_border = FindOuterEdge(image, {30.0, 20.0}, {0.0, -1.0}, 19.5, 12.0);
  ASSERT_TRUE(to_border);
  EXPECT_NEAR(to_border->offset_px, 10.0, 0.05);
  EXPECT_FALSE(FindOuterEdge(image, {30.0, 20.0}, {0.0, -1.0}, 20.0, 12.0));
}

// A saturated quiet zone (every outside pixel 255) leaves the bar model's light level
// undetermined: the first estimate comes back unchanged, though a thin bar is there.
TEST(DetectRefine, ClippedProfileKeepsTheFirstEstimate) {
  const Eigen::Vector2d point(32.3, 31.7), n(std::cos(0.3), std::sin(0.3));
  const cv::Mat image = EdgeImage(point, 0.3, 0.7, 300.0, 2.0);
  const Eigen::Vector2d p = point + 0.3 * n;
  const std::optional<EdgeHit> hit = FindOuterEdge(image, p, n, 1.25, 12.0);
  ASSERT_TRUE(hit);
  const std::optional<double> e = FitEdgeModel(image, p, n, hit->offset_px);
  ASSERT_TRUE(e);
  EXPECT_EQ(*e, hit->offset_px);
  // Unsaturated, the same bar is fitted and the estimate moves.
  const cv::Mat unclipped = EdgeImage(point, 0.3, 0.7, 190.0, 2.0);
  const std::optional<EdgeHit> hit2 = FindOuterEdge(unclipped, p, n, 1.25, 12.0);
  ASSERT_TRUE(hit2);
  const std::optional<double> e2 = FitEdgeModel(unclipped, p, n, hit2->offset_px);
  ASSERT_TRUE(e2);
  EXPECT_NE(*e2, hit2->offset_px);
}

// FitEdgeThroughBoth gives bit for bit the lines of FitEdgeThrough with and without the model.
TEST(DetectRefine, BothLinesEqualTheTwoFits) {
  const Eigen::Vector2d point(32.3, 31.7), n(std::cos(0.3), std::sin(0.3)), along(-n.y(), n.x());
  const cv::Mat image = EdgeImage(point, 0.3, 0.8, 190.0, 2.1);
  std::vector<Eigen::Vector2d> points;
  for (int k = -10; k <= 10; ++k) points.push_back(point + 0.9 * k * along + 0.4 * n);
  const EdgeLinePair both = FitEdgeThroughBoth(image, points, n, 1.5, 12.0);
  const std::optional<Line2d> modelled = FitEdgeThrough(image, points, n, 1.5, 12.0, true);
  const std::optional<Line2d> centroid = FitEdgeThrough(image, points, n, 1.5, 12.0, false);
  ASSERT_TRUE(both.modelled && both.centroid && modelled && centroid);
  for (const auto& [a, b] : {std::pair(*both.modelled, *modelled), std::pair(*both.centroid, *centroid)}) {
    EXPECT_EQ(a.point, b.point);
    EXPECT_EQ(a.direction, b.direction);
    EXPECT_EQ(a.inlier_fraction, b.inlier_fraction);
  }
  // The model moves the line (a thin bar): the two differ.
  EXPECT_NE(both.modelled->point, both.centroid->point);
  const EdgeLinePair none = FitEdgeThroughBoth(cv::Mat(), points, n, 1.5, 12.0);
  EXPECT_FALSE(none.modelled || none.centroid);
}

// A dim code (the recall bench's low light: the frame at 0.15-0.3 of its exposure, a border
// contrast of about 30 gray levels under noise): its edge steps over 1 px are under the
// usual minimum (12), which scales down with the border's contrast; the corners come out
// within a tenth of a pixel, from a start a pixel off.
TEST(DetectRefine, DimCodeIsRefined) {
  const SymbolImage symbol = AprilTagSymbol("apriltag-36h11", 7);
  cv::Mat image(200, 200, CV_8U, cv::Scalar(120));
  const Quad2d truth = MakeQuad({101.3, 98.6}, 90.0, 0.35, 0.9);
  DrawSymbol(symbol, truth, &image, 20, 210);  // a light ring round the border ...
  image.convertTo(image, CV_8U, 0.12);         // ... at 0.12 of the exposure: 2 .. 25
  cv::GaussianBlur(image, image, cv::Size(0, 0), 0.8);
  cv::RNG rng(5);
  AddSensorNoise(rng, 1.0, &image);
  Quad2d start = truth;
  for (int i = 0; i < 4; ++i) start[i] += Eigen::Vector2d(i % 2 ? 0.8 : -0.7, i < 2 ? 0.6 : -0.9);
  const std::optional<RefinedQuad> refined = RefineQuadCorners(image, start);
  ASSERT_TRUE(refined.has_value());
  for (int i = 0; i < 4; ++i) EXPECT_LT((refined->corners_px[i] - truth[i]).norm(), 0.1) << "corner " << i;
}

}  // namespace
}  // namespace waymark
