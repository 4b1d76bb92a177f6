// zxing-cpp behind Waymark's types (detect/zxing.h): the local-average binarization made by
// Waymark (ZxingHybridBlackMask) is zxing-cpp 1.4's HybridBinarizer bit for bit, and
// ReadWithZxing, which hands that mask to zxing, reads what zxing reads on its own.
#define ZX_USE_UTF8
#include "detect/zxing.h"

#include <ZXing/ReadBarcode.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <opencv2/imgproc.hpp>
#include <string>

#include "detect/common.h"
#include "detect/synthetic.h"

namespace waymark {
namespace {

// The binarization written as zxing-cpp 1.4's HybridBinarizer states it, block by block in
// raster order, every block's 64 pixels written (a pulled-back last block overwrites its
// neighbour's): the slow, literal form that the row-wise ZxingHybridBlackMask must equal.
cv::Mat LiteralHybridMask(const cv::Mat& gray, int min_dynamic_range = 24) {
  const int w = gray.cols, h = gray.rows, bw = (w + 7) / 8, bh = (h + 7) / 8;
  cv::Mat_<int> bp(bh, bw);
  for (int by = 0; by < bh; ++by) {
    for (int bx = 0; bx < bw; ++bx) {
      const int x0 = std::min(bx * 8, w - 8), y0 = std::min(by * 8, h - 8);
      int sum = 0, lo = 255, hi = 0;
      for (int y = y0; y < y0 + 8; ++y) {
        for (int x = x0; x < x0 + 8; ++x) {
          const int v = gray.at<uint8_t>(y, x);
          sum += v;
          lo = std::min(lo, v);
          hi = std::max(hi, v);
        }
      }
      int point = sum / 64;
      if (hi - lo <= min_dynamic_range) {
        point = lo / 2;
        if (by > 0 && bx > 0) {
          const int n = (bp(by - 1, bx) + 2 * bp(by, bx - 1) + bp(by - 1, bx - 1)) / 4;
          if (lo < n) point = n;
        }
      }
      bp(by, bx) = point;
    }
  }
  cv::Mat mask(h, w, CV_8UC1, cv::Scalar(128));
  for (int by = 0; by < bh; ++by) {
    for (int bx = 0; bx < bw; ++bx) {
      const int left = std::clamp(bx, 2, bw - 3), top = std::clamp(by, 2, bh - 3);
      int sum = 0;
      for (int dy = -2; dy <= 2; ++dy) {
        for (int dx = -2; dx <= 2; ++dx) sum += bp(top + dy, left + dx);
      }
      const int threshold = sum / 25;
      const int x0 = std::min(bx * 8, w - 8), y0 = std::min(by * 8, h - 8);
      for (int y = y0; y < y0 + 8; ++y) {
        for (int x = x0; x < x0 + 8; ++x)
          mask.at<uint8_t>(y, x) = gray.at<uint8_t>(y, x) <= threshold ? 0 : 255;
      }
    }
  }
  return mask;
}

// Flat patches of random levels (low-contrast blocks take the min / 2 and neighbour rules),
// soft gradients, sharp random rectangles and a little noise.
cv::Mat TestImage(int width, int height, uint64_t seed) {
  cv::RNG rng(seed);
  cv::Mat image(height, width, CV_8UC1, cv::Scalar(rng.uniform(60, 220)));
  for (int k = 0; k < 12; ++k) {
    const int x = rng.uniform(0, width), y = rng.uniform(0, height);
    const cv::Rect box(x, y, rng.uniform(3, std::max(4, width / 2)), rng.uniform(3, std::max(4, height / 2)));
    cv::rectangle(image, box, cv::Scalar(rng.uniform(0, 256)), cv::FILLED);
  }
  cv::Mat noise(height, width, CV_8UC1);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 6);
  image += noise;
  return image;
}

TEST(ZxingHybridBlackMask, EqualsTheLiteralBlockByBlockBinarization) {
  // Sizes at the minimum, off the 8-pixel grid each way, and a camera frame.
  const cv::Size sizes[] = {{40, 40}, {41, 40}, {40, 47}, {57, 123}, {333, 41}, {255, 257}, {1280, 960}};
  uint64_t seed = 1;
  int dark = 0, light = 0;
  for (const cv::Size& size : sizes) {
    for (int trial = 0; trial < 3; ++trial, ++seed) {
      const cv::Mat image = TestImage(size.width, size.height, seed);
      const cv::Mat expected = LiteralHybridMask(image);
      const cv::Mat mask = ZxingHybridBlackMask(image);
      ASSERT_EQ(mask.size(), image.size());
      EXPECT_EQ(cv::countNonZero(mask != expected), 0) << size << " seed " << seed;
      dark += cv::countNonZero(mask == 0);
      light += cv::countNonZero(mask == 255);
    }
  }
  // Both kinds of pixel occur (the test is not passed by all-light masks).
  EXPECT_GT(dark, 10000);
  EXPECT_GT(light, 10000);
}

// A wider flat-block range (for noisy whole frames) is the same rule with another number, and on a
// flat frame under noise of 8 gray levels it leaves the flat area light where zxing's 24 makes
// speckle of about half of it.
TEST(ZxingHybridBlackMask, WiderFlatRangeKeepsNoiseLight) {
  for (const int range : {24, 40, 56}) {
    const cv::Mat image = TestImage(333, 257, 40 + range);
    EXPECT_EQ(cv::countNonZero(ZxingHybridBlackMask(image, range) != LiteralHybridMask(image, range)), 0)
        << range;
  }
  cv::Mat flat(480, 640, CV_8UC1, cv::Scalar(150));
  cv::RNG rng(9);
  AddSensorNoise(rng, 8.0, &flat);
  const double pixels = static_cast<double>(flat.total());
  EXPECT_GT(cv::countNonZero(ZxingHybridBlackMask(flat) == 0) / pixels, 0.3);
  EXPECT_LT(
      cv::countNonZero(ZxingHybridBlackMask(flat, NoiseAwareThreshold(24, NoiseSigma(flat), 7.0)) == 0) /
          pixels,
      0.01);
}

TEST(ZxingHybridBlackMask, TakesARegionOfInterestWithItsStride) {
  const cv::Mat image = TestImage(300, 200, 7);
  const cv::Mat roi = image(cv::Rect(13, 9, 170, 101));
  ASSERT_FALSE(roi.isContinuous());
  EXPECT_EQ(cv::countNonZero(ZxingHybridBlackMask(roi) != LiteralHybridMask(roi.clone())), 0);
}

TEST(ZxingHybridBlackMask, RefusesImagesUnderTheMinimumSide) {
  EXPECT_THROW(ZxingHybridBlackMask(cv::Mat(39, 100, CV_8UC1, cv::Scalar(0))), cv::Exception);
  EXPECT_THROW(ZxingHybridBlackMask(cv::Mat(100, 100, CV_8UC3, cv::Scalar(0))), cv::Exception);
}

// zxing's own reading of `gray` with its local-average binarizer.
std::vector<std::string> ZxingOwnTexts(const cv::Mat& gray, ZXing::BarcodeFormat format) {
  ZXing::DecodeHints hints;
  hints.setFormats(format);
  hints.setBinarizer(ZXing::Binarizer::LocalAverage);
  hints.setTryHarder(true);
  hints.setTryRotate(false);
  const ZXing::ImageView view(gray.data, gray.cols, gray.rows, ZXing::ImageFormat::Lum,
                              static_cast<int>(gray.step[0]));
  std::vector<std::string> texts;
  for (const ZXing::Result& r : ZXing::ReadBarcodes(view, hints)) texts.push_back(r.text());
  std::sort(texts.begin(), texts.end());
  return texts;
}

TEST(ReadWithZxing, ReadsWhatZxingReadsWithItsOwnBinarizer) {
  // Codes of both symbologies at several sizes and tilts on a gradient with clutter, some
  // small enough that a few fail: every image must give the same texts both ways.
  int read = 0, images = 0;
  for (int k = 0; k < 12; ++k) {
    cv::Mat canvas(480, 640, CV_8UC1);
    for (int y = 0; y < canvas.rows; ++y) canvas.row(y).setTo(cv::Scalar(120 + y / 6));
    cv::rectangle(canvas, cv::Rect(20 + 7 * k, 300, 180, 60), cv::Scalar(40), cv::FILLED);
    const double side = 30.0 + 14.0 * k;
    const Quad2d qr = MakeQuad({200.0, 170.0}, side, 0.11 * k, 1.0 - 0.02 * k);
    const Quad2d dm = MakeQuad({470.0, 200.0}, 40.0 + 8.0 * k, -0.07 * k);
    DrawSymbol(QrSymbol("zx-" + std::to_string(k)), qr, &canvas);
    DrawSymbol(DataMatrixSymbol("dm-" + std::to_string(k)), dm, &canvas);
    cv::GaussianBlur(canvas, canvas, cv::Size(0, 0), 0.6 + 0.05 * k);
    for (const auto& [symbology, format] :
         {std::pair{ZxingSymbology::kQrCode, ZXing::BarcodeFormat::QRCode},
          std::pair{ZxingSymbology::kDataMatrix, ZXing::BarcodeFormat::DataMatrix}}) {
      std::vector<std::string> ours;
      for (const MarkerObservation& obs : ReadWithZxing(canvas, symbology, ZxingPass{}))
        ours.push_back(obs.key.id);
      std::sort(ours.begin(), ours.end());
      EXPECT_EQ(ours, ZxingOwnTexts(canvas, format)) << "image " << k;
      read += static_cast<int>(ours.size());
      ++images;
    }
  }
  // Most codes are read (19 of 24 at this commit): the comparison is not of empty lists.
  EXPECT_GE(read, images / 2);
}

}  // namespace
}  // namespace waymark
