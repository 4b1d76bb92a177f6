// ZX_USE_UTF8 makes zxing-cpp 1.4's Result::text() return UTF-8 std::string.
#define ZX_USE_UTF8
#include "detect/zxing.h"

#include <ZXing/ReadBarcode.h>

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

std::vector<MarkerObservation> ReadWithZxing(const cv::Mat& gray, ZxingSymbology symbology,
                                             const ZxingPass& pass) {
  CV_Assert(gray.type() == CV_8UC1);
  ZXing::DecodeHints hints;
  hints.setFormats(symbology == ZxingSymbology::kQrCode ? ZXing::BarcodeFormat::QRCode
                                                        : ZXing::BarcodeFormat::DataMatrix);
  hints.setBinarizer(pass.local_average_binarizer ? ZXing::Binarizer::LocalAverage
                                                  : ZXing::Binarizer::GlobalHistogram);
  hints.setTryHarder(pass.try_harder);
  hints.setTryRotate(false);  // 2-D finders are rotation invariant; rotation only costs time
  hints.setTryDownscale(pass.try_downscale);
  hints.setIsPure(pass.pure);
  const ZXing::ImageView view(gray.data, gray.cols, gray.rows, ZXing::ImageFormat::Lum,
                              static_cast<int>(gray.step[0]));
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
