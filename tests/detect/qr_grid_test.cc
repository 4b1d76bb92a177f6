// The QR module grid and the sides fitted on dark outer modules (detect/qr_grid.h), on
// synthetic codes drawn through known homographies (detect/synthetic.h).
#include "detect/qr_grid.h"

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "detect/synthetic.h"

namespace waymark {
namespace {

cv::Mat Canvas() { return cv::Mat(480, 640, CV_8U, cv::Scalar(170)); }

double MaxCornerError(const Quad2d& a, const Quad2d& b) {
  double worst = 0.0;
  for (int i = 0; i < 4; ++i) worst = std::max(worst, (a[i] - b[i]).norm());
  return worst;
}

TEST(DetectQrGrid, ModuleCountFromTheTimingPatterns) {
  // Byte mode, error correction L: 17 bytes fit version 1, 26 need version 2, 60 version 4.
  for (const std::string text : {"0/2/10", "waymark-ceiling/12/0.7/3.5",
                                 "waymark:a-longer-payload/with/sixty/characters/0123456789ab"}) {
    const SymbolImage symbol = QrSymbol(text);
    cv::Mat image = Canvas();
    const Quad2d truth = MakeQuad({320.0, 240.0}, 4.0 * symbol.symbol.width, 0.3, 0.9);
    DrawSymbol(symbol, truth, &image);
    cv::GaussianBlur(image, image, cv::Size(0, 0), 0.7);
    const std::optional<QrGridEstimate> grid = EstimateQrGrid(image, truth);
    ASSERT_TRUE(grid.has_value()) << text;
    EXPECT_EQ(grid->modules, symbol.symbol.width) << text;
    EXPECT_GT(grid->timing_contrast, 0.6) << text;
    EXPECT_LT(grid->dark_level, 60.0);
    EXPECT_GT(grid->light_level, 190.0);
  }
}

TEST(DetectQrGrid, SidesFromDarkModulesRecoverCornersOffByHalfAModule) {
  const SymbolImage symbol = QrSymbol("waymark-ceiling/12/0.7/3.5");  // 25 modules
  cv::Mat image = Canvas();
  const Quad2d truth = MakeQuad({300.4, 250.7}, 75.0, -0.35, 0.9);  // 3 px per module
  DrawSymbol(symbol, truth, &image);
  cv::GaussianBlur(image, image, cv::Size(0, 0), 0.7);
  Quad2d start = truth;
  const Eigen::Vector2d offsets[4] = {{0.6, -0.5}, {-0.4, 0.7}, {1.1, 0.3}, {-0.5, -0.6}};
  for (int i = 0; i < 4; ++i) start[i] += offsets[i];
  const std::optional<QrGridEstimate> grid = EstimateQrGrid(image, start);
  ASSERT_TRUE(grid.has_value());
  EXPECT_EQ(grid->modules, 25);
  const std::optional<Quad2d> fitted = FitQrSidesOnDarkModules(image, start, *grid);
  ASSERT_TRUE(fitted.has_value());
  EXPECT_LT(MaxCornerError(*fitted, truth), 0.2);
}

TEST(DetectQrGrid, NothingWithoutACode) {
  const Quad2d quad = MakeQuad({320.0, 240.0}, 100.0, 0.0);
  EXPECT_FALSE(EstimateQrGrid(Canvas(), quad).has_value());
  EXPECT_FALSE(EstimateQrGrid(cv::Mat(), quad).has_value());
  cv::Mat noise(480, 640, CV_8U);
  cv::RNG rng(5);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
  EXPECT_FALSE(EstimateQrGrid(noise, quad).has_value());
  // A quad leaving the image samples nothing.
  EXPECT_FALSE(EstimateQrGrid(Canvas(), MakeQuad({630.0, 240.0}, 100.0, 0.0)).has_value());
  QrGridEstimate bad;
  bad.modules = 0;
  EXPECT_FALSE(FitQrSidesOnDarkModules(Canvas(), quad, bad).has_value());
}

}  // namespace
}  // namespace waymark
