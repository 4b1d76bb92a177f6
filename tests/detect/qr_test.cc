// QR detector on synthetic codes drawn through known homographies (detect/synthetic.h):
// exact ids, corners in docs/design.md order within a sub-pixel bound, all four rotations,
// several codes per image, inverted codes, nothing on blank or noise images, and no crash
// on bad input.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <opencv2/imgproc.hpp>

#include "detect/detector.h"
#include "detect/qr_finder.h"
#include "detect/synthetic.h"

namespace waymark {
namespace {

cv::Mat Canvas(int width = 640, int height = 480) { return cv::Mat(height, width, CV_8U, cv::Scalar(180)); }

double MaxCornerError(const MarkerObservation& obs, const Quad2d& truth) {
  double worst = 0.0;
  for (int i = 0; i < 4; ++i) worst = std::max(worst, (obs.corners_px[i] - truth[i]).norm());
  return worst;
}

const MarkerObservation* FindId(const std::vector<MarkerObservation>& found, const std::string& id) {
  for (const MarkerObservation& o : found) {
    if (o.key.id == id) return &o;
  }
  return nullptr;
}

void AddNoise(double sigma, cv::Mat* image) {
  cv::RNG rng(42);
  cv::Mat noise(image->size(), CV_16S);
  rng.fill(noise, cv::RNG::NORMAL, 0, sigma);
  cv::Mat wide;
  image->convertTo(wide, CV_16S);
  wide += noise;
  wide.convertTo(*image, CV_8U);
}

TEST(DetectQr, FourRotationsGiveDesignOrderCorners) {
  auto detector = CreateDetector("qr");
  const SymbolImage symbol = QrSymbol("0/2/10");
  for (int r = 0; r < 4; ++r) {
    cv::Mat image = Canvas();
    const Quad2d truth = MakeQuad({320.3, 241.7}, 180.0, r * M_PI / 2 + 0.05);
    DrawSymbol(symbol, truth, &image);
    const auto found = detector->Detect(image);
    ASSERT_EQ(found.size(), 1u) << "rotation " << r;
    EXPECT_EQ(found[0].key.family, "qr");
    EXPECT_EQ(found[0].key.id, "0/2/10");
    EXPECT_LT(MaxCornerError(found[0], truth), 0.15) << "rotation " << r;
    ASSERT_TRUE(found[0].quality.has_value());
    EXPECT_GT(*found[0].quality, 0.3);
  }
}

TEST(DetectQr, PerspectiveBlurAndNoiseStaySubPixel) {
  auto detector = CreateDetector("qr");
  const SymbolImage symbol = QrSymbol("waymark:A01");
  cv::Mat image = Canvas();
  const Quad2d truth = MakeQuad({300.0, 250.0}, 150.0, -0.4, 0.8);
  DrawSymbol(symbol, truth, &image);
  cv::GaussianBlur(image, image, cv::Size(0, 0), 0.8);
  AddNoise(3.0, &image);
  const auto found = detector->Detect(image);
  ASSERT_EQ(found.size(), 1u);
  EXPECT_EQ(found[0].key.id, "waymark:A01");
  EXPECT_LT(MaxCornerError(found[0], truth), 0.25);
}

// Version 1 has no alignment pattern: the bottom-right corner has no finder of its own and
// comes from the symbol's edges (CornerFromFinderEdges in detect/qr.cc).
TEST(DetectQr, VersionOneFourthCornerUnderPerspective) {
  auto detector = CreateDetector("qr");
  const SymbolImage symbol = QrSymbol("0/2/1.5");  // 21 x 21 modules
  // Strong keystones, 120 .. 140 px wide: the bottom-right corner 15 px from the
  // parallelogram's. (zxing-cpp 1.4 reads these well by itself; its misplaced corner shows on
  // small rendered codes: bench/render_corner_bench.cc, 40 .. 46 px codes at 1.6 .. 2.4 m.)
  const std::vector<Quad2d> truths = {{Eigen::Vector2d(200.3, 150.6), Eigen::Vector2d(341.2, 171.4),
                                       Eigen::Vector2d(322.7, 296.1), Eigen::Vector2d(190.4, 291.8)},
                                      {Eigen::Vector2d(180.6, 160.2), Eigen::Vector2d(300.9, 140.3),
                                       Eigen::Vector2d(318.4, 280.7), Eigen::Vector2d(170.2, 300.5)}};
  for (size_t i = 0; i < truths.size(); ++i) {
    cv::Mat image = Canvas();
    DrawSymbol(symbol, truths[i], &image);
    cv::GaussianBlur(image, image, cv::Size(0, 0), 0.7);
    const auto found = detector->Detect(image);
    ASSERT_EQ(found.size(), 1u) << i;
    EXPECT_EQ(found[0].key.id, "0/2/1.5");
    EXPECT_LT(MaxCornerError(found[0], truths[i]), 0.15) << i;
    std::printf("keystone %zu: worst corner error %.3f px\n", i, MaxCornerError(found[0], truths[i]));
  }
}

TEST(DetectQr, SeveralCodesInOneBgrImage) {
  auto detector = CreateDetector("qr");
  cv::Mat image = Canvas(1280, 960);
  std::vector<Quad2d> truths;
  for (int i = 0; i < 4; ++i) {
    const Quad2d truth = MakeQuad({300.0 + 600 * (i % 2), 250.0 + 450 * (i / 2)}, 160.0 + 20 * i, 0.4 * i);
    DrawSymbol(QrSymbol("code-" + std::to_string(i)), truth, &image);
    truths.push_back(truth);
  }
  cv::Mat bgr;
  cv::cvtColor(image, bgr, cv::COLOR_GRAY2BGR);
  const auto found = detector->Detect(bgr);
  ASSERT_EQ(found.size(), 4u);
  for (int i = 0; i < 4; ++i) {
    const MarkerObservation* obs = FindId(found, "code-" + std::to_string(i));
    ASSERT_NE(obs, nullptr) << i;
    EXPECT_LT(MaxCornerError(*obs, truths[i]), 0.1) << i;
  }
}

TEST(DetectQr, InvertedCodeIsReadBySecondPass) {
  const SymbolImage symbol = QrSymbol("light-on-dark");
  cv::Mat image(480, 640, CV_8U, cv::Scalar(40));
  const Quad2d truth = MakeQuad({320.0, 240.0}, 200.0, 0.1);
  DrawSymbol(symbol, truth, &image, /*dark=*/235, /*light=*/20);
  DetectorOptions no_second;
  no_second.second_pass = false;
  EXPECT_TRUE(CreateDetector("qr", no_second)->Detect(image).empty());
  const auto found = CreateDetector("qr")->Detect(image);
  ASSERT_EQ(found.size(), 1u);
  EXPECT_EQ(found[0].key.id, "light-on-dark");
  EXPECT_LT((QuadCenter(found[0].corners_px) - QuadCenter(truth)).norm(), 2.0);
}

// A light-on-dark code, turned and blurred so that the finder search finds none of its
// finders in its region (it finds them in most such codes): the inverted crop still reads it.
TEST(DetectQr, InvertedCodeWithoutFindersIsRead) {
  const SymbolImage symbol = QrSymbol("light-on-dark/7");
  cv::Mat image(480, 640, CV_8U, cv::Scalar(40));
  const Quad2d truth = MakeQuad({321.3, 238.6}, 160.0, 0.8);
  DrawSymbol(symbol, truth, &image, /*dark=*/225, /*light=*/30);
  cv::GaussianBlur(image, image, cv::Size(0, 0), 1.0);
  EXPECT_TRUE(FindQrFinderPatterns(image, cv::Rect(201, 118, 240, 240)).empty());
  const auto found = CreateDetector("qr")->Detect(image);
  ASSERT_EQ(found.size(), 1u);
  EXPECT_EQ(found[0].key.id, "light-on-dark/7");
  EXPECT_LT((QuadCenter(found[0].corners_px) - QuadCenter(truth)).norm(), 2.0);
}

TEST(DetectQr, BlankAndNoiseImagesGiveNothing) {
  auto detector = CreateDetector("qr");
  EXPECT_TRUE(detector->Detect(Canvas()).empty());
  cv::Mat noise(480, 640, CV_8U);
  cv::RNG rng(7);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
  EXPECT_TRUE(detector->Detect(noise).empty());
}

TEST(DetectQr, BadInputThrowsOrGivesNothing) {
  auto detector = CreateDetector("qr");
  EXPECT_THROW(detector->Detect(cv::Mat()), std::invalid_argument);
  EXPECT_THROW(detector->Detect(cv::Mat(10, 10, CV_32F, cv::Scalar(0.5))), std::invalid_argument);
  EXPECT_TRUE(detector->Detect(cv::Mat(1, 1, CV_8U, cv::Scalar(0))).empty());
  EXPECT_TRUE(detector->Detect(cv::Mat(3, 2000, CV_8U, cv::Scalar(0))).empty());
  // A code cut by the image border is either not read or read with in-image corners.
  cv::Mat image = Canvas(200, 200);
  DrawSymbol(QrSymbol("cut"), MakeQuad({190.0, 100.0}, 120.0, 0.0), &image);
  for (const MarkerObservation& obs : detector->Detect(image)) {
    for (const auto& c : obs.corners_px) EXPECT_LE(c.x(), 199.5);
  }
}

}  // namespace
}  // namespace waymark
