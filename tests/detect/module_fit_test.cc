// The photometric fit of a symbol's module grid (detect/module_fit.h), on synthetic codes
// drawn through known homographies (detect/synthetic.h).
#include "detect/module_fit.h"

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "detect/qr_grid.h"
#include "detect/synthetic.h"

namespace waymark {
namespace {

double MaxCornerError(const Quad2d& a, const Quad2d& b) {
  double worst = 0.0;
  for (int i = 0; i < 4; ++i) worst = std::max(worst, (a[i] - b[i]).norm());
  return worst;
}

// The dark modules of `symbol` without its quiet zone, row-major.
std::vector<uint8_t> DarkModules(const SymbolImage& symbol) {
  std::vector<uint8_t> dark;
  for (int v = 0; v < symbol.symbol.height; ++v) {
    for (int u = 0; u < symbol.symbol.width; ++u) {
      dark.push_back(symbol.modules.at<uint8_t>(symbol.symbol.y + v, symbol.symbol.x + u) == 0 ? 1 : 0);
    }
  }
  return dark;
}

// A small code (about 2 px per module) under blur and noise, with a lighting gradient.
cv::Mat Render(const SymbolImage& symbol, const Quad2d& corners, double blur_px, uint64_t seed) {
  cv::Mat image(480, 640, CV_8U, cv::Scalar(180));
  DrawSymbol(symbol, corners, &image, 40, 200);
  cv::GaussianBlur(image, image, cv::Size(0, 0), blur_px);
  cv::Mat ramp(image.size(), CV_16S);
  for (int r = 0; r < ramp.rows; ++r) {
    for (int c = 0; c < ramp.cols; ++c) ramp.at<int16_t>(r, c) = static_cast<int16_t>((c - 320) / 40);
  }
  cv::Mat noise(image.size(), CV_16S);
  cv::RNG rng(seed);
  rng.fill(noise, cv::RNG::NORMAL, 0.0, 3.0);
  cv::Mat sum;
  image.convertTo(sum, CV_16S);
  sum += ramp + noise;
  sum.convertTo(image, CV_8U);
  return image;
}

TEST(DetectModuleFit, SmallCodeCornersFromEveryModuleEdge) {
  // Version 1 (21 modules) at 42-45 px: the corners of the side fits are 0.1-0.3 px out here.
  // (No axis-aligned case: DrawSymbol's 4 x 4 supersampling puts an axis-aligned edge up to
  // 1/8 px off along its whole length, a limit of the renderer, not of the fit.)
  const SymbolImage symbol = QrSymbol("0/2/10");
  ASSERT_EQ(symbol.symbol.width, 21);
  const std::vector<uint8_t> dark = DarkModules(symbol);
  int case_index = 0;
  for (const double blur : {0.5, 0.8, 1.0}) {
    for (const double angle : {0.1, 0.4, -1.1}) {
      const Quad2d truth = MakeQuad({310.3 + 7 * case_index, 242.6}, 42.0 + case_index % 4, angle, 0.85);
      const cv::Mat image = Render(symbol, truth, blur, 100 + case_index);
      ++case_index;
      // Start 0.3 px outwards along every diagonal, as the side fits leave small codes.
      Quad2d start = truth;
      const Eigen::Vector2d centre = QuadCenter(truth);
      for (Eigen::Vector2d& c : start) c += 0.3 * (c - centre).normalized();
      const std::optional<ModuleFit> fit = FitModuleGrid(image, start, 21, dark);
      ASSERT_TRUE(fit.has_value()) << "blur " << blur << " angle " << angle;
      EXPECT_LT(MaxCornerError(fit->corners_px, truth), 0.06) << "blur " << blur << " angle " << angle;
      EXPECT_NEAR(fit->contrast, 160.0, 25.0);
      EXPECT_LT(fit->residual_rms, fit->start_rms);
    }
  }
}

TEST(DetectModuleFit, ModulesSampledFromTheImageServeAsWell) {
  const SymbolImage symbol = QrSymbol("waymark-ceiling/12/0.7/3.5");  // 25 modules
  const Quad2d truth = MakeQuad({300.4, 250.7}, 55.0, -0.35, 0.9);
  const cv::Mat image = Render(symbol, truth, 0.8, 7);
  Quad2d start = truth;
  const Eigen::Vector2d offsets[4] = {{0.3, -0.2}, {-0.2, 0.3}, {0.4, 0.1}, {-0.2, -0.3}};
  for (int i = 0; i < 4; ++i) start[i] += offsets[i];
  const std::optional<QrGridEstimate> grid = EstimateQrGrid(image, start);
  ASSERT_TRUE(grid.has_value());
  const std::vector<uint8_t> sampled = SampleQrModules(image, start, *grid);
  ASSERT_EQ(sampled.size(), 25u * 25u);
  const std::optional<ModuleFit> fit = FitModuleGrid(image, start, 25, sampled);
  ASSERT_TRUE(fit.has_value());
  EXPECT_LT(MaxCornerError(fit->corners_px, truth), 0.08);
}

TEST(DetectModuleFit, NothingForBadInput) {
  const SymbolImage symbol = QrSymbol("0/2/10");
  const std::vector<uint8_t> dark = DarkModules(symbol);
  const Quad2d truth = MakeQuad({320.0, 240.0}, 44.0, 0.2);
  const cv::Mat image = Render(symbol, truth, 0.8, 1);
  EXPECT_FALSE(FitModuleGrid(cv::Mat(), truth, 21, dark).has_value());
  EXPECT_FALSE(FitModuleGrid(image, truth, 25, dark).has_value());  // pattern of another size
  cv::Mat color;
  cv::cvtColor(image, color, cv::COLOR_GRAY2BGR);
  EXPECT_FALSE(FitModuleGrid(color, truth, 21, dark).has_value());
  // Partly outside the image.
  EXPECT_FALSE(FitModuleGrid(image, MakeQuad({10.0, 240.0}, 44.0, 0.2), 21, dark).has_value());
  // Degenerate corners: all on one line, or all on one point.
  const Quad2d line = {Eigen::Vector2d(300, 240), Eigen::Vector2d(320, 240), Eigen::Vector2d(340, 240),
                       Eigen::Vector2d(360, 240)};
  EXPECT_FALSE(FitModuleGrid(image, line, 21, dark).has_value());
  const Quad2d point = {Eigen::Vector2d(320, 240), Eigen::Vector2d(320, 240), Eigen::Vector2d(320, 240),
                        Eigen::Vector2d(320, 240)};
  EXPECT_FALSE(FitModuleGrid(image, point, 21, dark).has_value());
  // Started far off (a whole code's width): no crash; if anything, not a fit that moved that far.
  const Quad2d far = MakeQuad({364.0, 240.0}, 44.0, 0.2);
  EXPECT_FALSE(FitModuleGrid(image, far, 21, dark).has_value());
  // An empty image: no contrast to fit.
  const cv::Mat blank(480, 640, CV_8U, cv::Scalar(128));
  EXPECT_FALSE(FitModuleGrid(blank, truth, 21, dark).has_value());
}

TEST(DetectModuleFit, AWrongPatternDoesNotPassForTheCode) {
  // Another code's modules at this code's place: the fit must not report a good match.
  const SymbolImage symbol = QrSymbol("0/2/10");
  const SymbolImage other = QrSymbol("9/9/99");
  const Quad2d truth = MakeQuad({320.0, 240.0}, 44.0, 0.2);
  const cv::Mat image = Render(symbol, truth, 0.8, 3);
  const std::optional<ModuleFit> right = FitModuleGrid(image, truth, 21, DarkModules(symbol));
  const std::optional<ModuleFit> wrong = FitModuleGrid(image, truth, 21, DarkModules(other));
  ASSERT_TRUE(right.has_value());
  if (wrong) {
    EXPECT_GT(wrong->residual_rms, 2.0 * right->residual_rms);
  }
}

}  // namespace
}  // namespace waymark
