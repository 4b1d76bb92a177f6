#include "detect/synthetic.h"

#include <dmtx.h>

#include <algorithm>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/objdetect.hpp>
#include <stdexcept>

#include "detect/apriltag.h"

namespace waymark {
namespace {

// Bounding box of the dark modules: the symbol for QR and DataMatrix, whose finders
// reach all four sides.
cv::Rect DarkExtent(const cv::Mat& modules) {
  cv::Mat dark = modules < 128;
  std::vector<cv::Point> points;
  cv::findNonZero(dark, points);
  if (points.empty()) throw std::runtime_error("synthetic symbol: no dark module");
  return cv::boundingRect(points);
}

struct DmtxEncoder {
  DmtxEncode* encode = dmtxEncodeCreate();
  ~DmtxEncoder() {
    if (encode != nullptr) dmtxEncodeDestroy(&encode);
  }
};

}  // namespace

SymbolImage QrSymbol(const std::string& text) {
  cv::QRCodeEncoder::Params params;
  params.correction_level = cv::QRCodeEncoder::CORRECT_LEVEL_L;
  params.mode = cv::QRCodeEncoder::MODE_BYTE;
  cv::Mat modules;
  cv::QRCodeEncoder::create(params)->encode(text, modules);
  if (modules.empty()) throw std::runtime_error("QrSymbol: cv::QRCodeEncoder failed for '" + text + "'");
  cv::Mat padded;
  cv::copyMakeBorder(modules, padded, 2, 2, 2, 2, cv::BORDER_CONSTANT, cv::Scalar(255));
  return {padded, DarkExtent(padded)};
}

SymbolImage DataMatrixSymbol(const std::string& text) {
  DmtxEncoder encoder;
  if (encoder.encode == nullptr) throw std::runtime_error("DataMatrixSymbol: dmtxEncodeCreate failed");
  dmtxEncodeSetProp(encoder.encode, DmtxPropModuleSize, 1);
  dmtxEncodeSetProp(encoder.encode, DmtxPropMarginSize, 2);
  dmtxEncodeSetProp(encoder.encode, DmtxPropSizeRequest, DmtxSymbolSquareAuto);
  std::string data = text;
  if (dmtxEncodeDataMatrix(encoder.encode, static_cast<int>(data.size()),
                           reinterpret_cast<unsigned char*>(data.data())) == DmtxFail) {
    throw std::runtime_error("DataMatrixSymbol: libdmtx failed to encode '" + text + "'");
  }
  DmtxImage* image = encoder.encode->image;
  const int width = dmtxImageGetProp(image, DmtxPropWidth);
  const int height = dmtxImageGetProp(image, DmtxPropHeight);
  cv::Mat modules(height, width, CV_8U);
  for (int row = 0; row < height; ++row) {
    for (int col = 0; col < width; ++col) {
      int value = 0;
      // libdmtx addresses pixels with y up from the bottom row.
      dmtxImageGetPixelValue(image, col, height - 1 - row, 0, &value);
      modules.at<uint8_t>(row, col) = value < 128 ? 0 : 255;
    }
  }
  const cv::Rect symbol = DarkExtent(modules);
  // Upright DataMatrix: the solid L finder is the left column and the bottom row.
  const cv::Mat left = modules(cv::Rect(symbol.x, symbol.y, 1, symbol.height));
  const cv::Mat bottom = modules(cv::Rect(symbol.x, symbol.y + symbol.height - 1, symbol.width, 1));
  if (cv::countNonZero(left) != 0 || cv::countNonZero(bottom) != 0) {
    throw std::runtime_error("DataMatrixSymbol: L finder not at the left and bottom");
  }
  return {modules, symbol};
}

SymbolImage AprilTagSymbol(const std::string& family, int id) {
  SymbolImage out;
  out.modules = AprilTagModuleImage(family, id, &out.symbol);
  return out;
}

void DrawSymbol(const SymbolImage& symbol, const Quad2d& corners_px, cv::Mat* canvas, int dark, int light) {
  CV_Assert(canvas->type() == CV_8UC1);
  // Homography from module coordinates (module (c, r) covers [c, c+1) x [r, r+1)) to
  // pixel coordinates.
  const cv::Rect& s = symbol.symbol;
  const std::vector<cv::Point2f> src = {{float(s.x), float(s.y)},
                                        {float(s.x + s.width), float(s.y)},
                                        {float(s.x + s.width), float(s.y + s.height)},
                                        {float(s.x), float(s.y + s.height)}};
  std::vector<cv::Point2f> dst;
  for (const Eigen::Vector2d& c : corners_px) dst.emplace_back(float(c.x()), float(c.y()));
  const cv::Mat H = cv::getPerspectiveTransform(src, dst);
  const cv::Mat H_inv = H.inv();
  // Pixel bounding box of the whole module image.
  const std::vector<cv::Point2f> outline = {{0.f, 0.f},
                                            {float(symbol.modules.cols), 0.f},
                                            {float(symbol.modules.cols), float(symbol.modules.rows)},
                                            {0.f, float(symbol.modules.rows)}};
  std::vector<cv::Point2f> outline_px;
  cv::perspectiveTransform(outline, outline_px, H);
  const cv::Rect box = cv::boundingRect(outline_px) & cv::Rect(0, 0, canvas->cols, canvas->rows);
  constexpr int kSub = 4;
  for (int y = box.y; y < box.y + box.height; ++y) {
    for (int x = box.x; x < box.x + box.width; ++x) {
      double sum = 0.0;
      int inside = 0;
      for (int k = 0; k < kSub * kSub; ++k) {
        const double px = x - 0.5 + (k % kSub + 0.5) / kSub;
        const double py = y - 0.5 + (k / kSub + 0.5) / kSub;
        const double* h = H_inv.ptr<double>(0);
        const double w = h[6] * px + h[7] * py + h[8];
        const double u = (h[0] * px + h[1] * py + h[2]) / w;
        const double v = (h[3] * px + h[4] * py + h[5]) / w;
        const int c = static_cast<int>(std::floor(u));
        const int r = static_cast<int>(std::floor(v));
        if (c < 0 || r < 0 || c >= symbol.modules.cols || r >= symbol.modules.rows) continue;
        sum += symbol.modules.at<uint8_t>(r, c) < 128 ? dark : light;
        ++inside;
      }
      if (inside == 0) continue;
      const double background = canvas->at<uint8_t>(y, x);
      const double value = (sum + (kSub * kSub - inside) * background) / (kSub * kSub);
      canvas->at<uint8_t>(y, x) = cv::saturate_cast<uint8_t>(value);
    }
  }
}

void AddSensorNoise(cv::RNG& rng, double sigma, cv::Mat* image) {
  CV_Assert(image != nullptr && image->type() == CV_8UC1);
  cv::Mat noise(image->size(), CV_16S), wide;
  rng.fill(noise, cv::RNG::NORMAL, 0, sigma);
  image->convertTo(wide, CV_16S);
  wide += noise;
  wide.convertTo(*image, CV_8U);
}

Quad2d MakeQuad(const Eigen::Vector2d& center_px, double side_px, double angle_rad, double squeeze) {
  const double h = 0.5 * side_px;
  // Unit square corners in docs/design.md order on screen (y down); the right side scaled.
  const Eigen::Vector2d local[4] = {{-h, -h}, {h, -h * squeeze}, {h, h * squeeze}, {-h, h}};
  const double c = std::cos(angle_rad);
  const double s = std::sin(angle_rad);
  Quad2d quad;
  for (int i = 0; i < 4; ++i) {
    quad[i] =
        center_px + Eigen::Vector2d(c * local[i].x() - s * local[i].y(), s * local[i].x() + c * local[i].y());
  }
  return quad;
}

}  // namespace waymark
