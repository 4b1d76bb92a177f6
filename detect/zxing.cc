// ZX_USE_UTF8 makes zxing-cpp 1.4's Result::text() return UTF-8 std::string.
#define ZX_USE_UTF8
#include "detect/zxing.h"

#include <ZXing/ReadBarcode.h>

#include <algorithm>
#include <cstdint>

namespace waymark {

bool IsValidUtf8(const std::string& text) {
  size_t i = 0;
  while (i < text.size()) {
    const unsigned char c = static_cast<unsigned char>(text[i]);
    int extra = 0;
    if (c < 0x80) {
      extra = 0;
    } else if ((c & 0xE0) == 0xC0 && c >= 0xC2) {
      extra = 1;
    } else if ((c & 0xF0) == 0xE0) {
      extra = 2;
    } else if ((c & 0xF8) == 0xF0 && c <= 0xF4) {
      extra = 3;
    } else {
      return false;
    }
    if (i + extra >= text.size() && extra > 0) return false;
    for (int k = 1; k <= extra; ++k) {
      if ((static_cast<unsigned char>(text[i + k]) & 0xC0) != 0x80) return false;
    }
    i += extra + 1;
  }
  return true;
}

std::string TextToId(const std::string& bytes) {
  if (IsValidUtf8(bytes)) return bytes;
  std::string out;
  out.reserve(bytes.size() * 2);
  for (const char ch : bytes) {
    const unsigned char c = static_cast<unsigned char>(ch);
    if (c < 0x80) {
      out.push_back(static_cast<char>(c));
    } else {
      out.push_back(static_cast<char>(0xC0 | (c >> 6)));
      out.push_back(static_cast<char>(0x80 | (c & 0x3F)));
    }
  }
  return out;
}

cv::Mat ZxingHybridBlackMask(const cv::Mat& gray, int min_dynamic_range) {
  CV_Assert(gray.type() == CV_8UC1 && gray.cols >= kZxingHybridMinSide && gray.rows >= kZxingHybridMinSide);
  constexpr int kBlock = 8;
  const int width = gray.cols, height = gray.rows;
  const int blocks_x = (width + kBlock - 1) / kBlock, blocks_y = (height + kBlock - 1) / kBlock;
  // Black point of every block, raster order (a low-contrast block reads its upper and left
  // neighbours').
  std::vector<int> black_point(static_cast<size_t>(blocks_x * blocks_y));
  const auto bp = [&black_point, blocks_x](int bx, int by) -> int& {
    return black_point[static_cast<size_t>(by * blocks_x + bx)];
  };
  std::vector<uint16_t> column_sum(static_cast<size_t>(width));
  std::vector<uint8_t> column_min(static_cast<size_t>(width)), column_max(static_cast<size_t>(width));
  for (int by = 0; by < blocks_y; ++by) {
    const int y0 = std::min(by * kBlock, height - kBlock);
    // Each column's sum, minimum and maximum over the band's 8 rows (loops the compiler
    // vectorizes), then each block's over its 8 columns.
    const uint8_t* first = gray.ptr<uint8_t>(y0);
    for (int x = 0; x < width; ++x) {
      column_sum[static_cast<size_t>(x)] = first[x];
      column_min[static_cast<size_t>(x)] = first[x];
      column_max[static_cast<size_t>(x)] = first[x];
    }
    for (int y = y0 + 1; y < y0 + kBlock; ++y) {
      const uint8_t* row = gray.ptr<uint8_t>(y);
      uint16_t* sum = column_sum.data();
      uint8_t* lo = column_min.data();
      uint8_t* hi = column_max.data();
      for (int x = 0; x < width; ++x) {
        sum[x] = static_cast<uint16_t>(sum[x] + row[x]);
        lo[x] = std::min(lo[x], row[x]);
        hi[x] = std::max(hi[x], row[x]);
      }
    }
    for (int bx = 0; bx < blocks_x; ++bx) {
      const int x0 = std::min(bx * kBlock, width - kBlock);
      int sum = 0, lo = 255, hi = 0;
      for (int x = x0; x < x0 + kBlock; ++x) {
        sum += column_sum[static_cast<size_t>(x)];
        lo = std::min<int>(lo, column_min[static_cast<size_t>(x)]);
        hi = std::max<int>(hi, column_max[static_cast<size_t>(x)]);
      }
      int point = sum / (kBlock * kBlock);
      if (hi - lo <= min_dynamic_range) {
        point = lo / 2;
        if (by > 0 && bx > 0) {
          const int neighbours = (bp(bx, by - 1) + 2 * bp(bx - 1, by) + bp(bx - 1, by - 1)) / 4;
          if (lo < neighbours) point = neighbours;
        }
      }
      bp(bx, by) = point;
    }
  }
  // Each pixel's block: the last one covering it (the pulled-back last block overwrites).
  const auto block_of = [](int p, int size, int blocks) {
    return p >= size - kBlock ? blocks - 1 : p / kBlock;
  };
  cv::Mat mask(height, width, CV_8UC1);
  std::vector<uint8_t> threshold_row(static_cast<size_t>(width));
  int row_block = -1;
  for (int y = 0; y < height; ++y) {
    const int by = block_of(y, height, blocks_y);
    if (by != row_block) {
      row_block = by;
      const int top = std::clamp(by, 2, blocks_y - 3);
      for (int bx = 0; bx < blocks_x; ++bx) {
        const int left = std::clamp(bx, 2, blocks_x - 3);
        int sum = 0;
        for (int dy = -2; dy <= 2; ++dy) {
          for (int dx = -2; dx <= 2; ++dx) sum += bp(left + dx, top + dy);
        }
        const uint8_t threshold = static_cast<uint8_t>(sum / 25);
        const bool last = bx == blocks_x - 1;
        const int x_begin = last ? width - kBlock : bx * kBlock;
        const int x_end = last ? width : std::min((bx + 1) * kBlock, width - kBlock);
        for (int x = x_begin; x < x_end; ++x) threshold_row[static_cast<size_t>(x)] = threshold;
      }
    }
    const uint8_t* in = gray.ptr<uint8_t>(y);
    const uint8_t* t = threshold_row.data();
    uint8_t* out = mask.ptr<uint8_t>(y);
    for (int x = 0; x < width; ++x) out[x] = in[x] <= t[x] ? 0 : 255;
  }
  return mask;
}

std::vector<MarkerObservation> ReadWithZxing(const cv::Mat& gray, ZxingSymbology symbology,
                                             const ZxingPass& pass) {
  CV_Assert(gray.type() == CV_8UC1);
  ZXing::DecodeHints hints;
  hints.setFormats(symbology == ZxingSymbology::kQrCode ? ZXing::BarcodeFormat::QRCode
                                                        : ZXing::BarcodeFormat::DataMatrix);
  hints.setTryHarder(pass.try_harder);
  hints.setTryRotate(false);     // 2-D finders are rotation invariant; rotation only costs time
  hints.setTryDownscale(false);  // one layer: the mask below is that layer's binarization
  hints.setIsPure(pass.pure);
  // The local-average binarization made here (ZxingHybridBlackMask, the same bits in a sixth
  // of the time) and handed over as black = 0 (zxing's BoolCast); images under its minimum side
  // are left to zxing, which binarizes them with its global histogram.
  const bool own_mask =
      pass.local_average_binarizer && gray.cols >= kZxingHybridMinSide && gray.rows >= kZxingHybridMinSide;
  const cv::Mat mask = own_mask ? ZxingHybridBlackMask(gray, pass.min_dynamic_range) : cv::Mat();
  hints.setBinarizer(own_mask                       ? ZXing::Binarizer::BoolCast
                     : pass.local_average_binarizer ? ZXing::Binarizer::LocalAverage
                                                    : ZXing::Binarizer::GlobalHistogram);
  const cv::Mat& image = own_mask ? mask : gray;
  const ZXing::ImageView view(image.data, image.cols, image.rows, ZXing::ImageFormat::Lum,
                              static_cast<int>(image.step[0]));
  const ZXing::Results results = ZXing::ReadBarcodes(view, hints);
  std::vector<MarkerObservation> out;
  for (const ZXing::Result& r : results) {
    if (!r.isValid()) continue;
    MarkerObservation obs;
    obs.key.family = symbology == ZxingSymbology::kQrCode ? kFamilyQr : kFamilyDataMatrix;
    obs.key.id = TextToId(r.text());
    const ZXing::Position& position = r.position();
    // zxing's integer corners count pixel edges (a symbol filling a WxH image spans
    // (0,0)..(W,H)); OpenCV's pixel centres are half a pixel further in.
    for (int i = 0; i < 4; ++i) obs.corners_px[i] = Eigen::Vector2d(position[i].x - 0.5, position[i].y - 0.5);
    out.push_back(std::move(obs));
  }
  return out;
}

}  // namespace waymark
