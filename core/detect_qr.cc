#include "core/detect_qr.h"

#include <opencv2/imgproc.hpp>
#include <opencv2/objdetect.hpp>
#include <opencv2/wechat_qrcode.hpp>

#include "core/detect_common.h"
#include "core/detect_zxing.h"

namespace waymark {
namespace {

// Crops larger than this (longer side, px) are not upscaled in pass 2.
constexpr int kMaxUpscaleSidePx = 480;

class QrDetector : public MarkerDetector {
 public:
  explicit QrDetector(const DetectorOptions& options) : options_(options) {}

  std::vector<std::string> Families() const override { return {kFamilyQr}; }

  std::vector<MarkerObservation> Detect(const cv::Mat& image) override {
    const FrameClock clock;
    const cv::Mat gray = ToGray8(image);
    std::vector<MarkerObservation> found = ReadWithZxing(gray, ZxingSymbology::kQrCode, ZxingPass{});
    if (options_.second_pass) {
      const std::vector<CropAttempt> attempts = {
          [](const cv::Mat& crop) { return ReadInverted(crop); },
          [](const cv::Mat& crop) { return ReadUpscaled(crop); },
          [](const cv::Mat& crop) { return ReadGlobalHistogram(crop); },
          // WeChat costs milliseconds per crop: only for close-ups, where the crop is the
          // whole image (pass 1 and the cheap attempts read codes in larger frames).
          [this, full = gray.size()](const cv::Mat& crop) {
            return crop.size() == full ? ReadWeChat(crop) : std::vector<MarkerObservation>{};
          },
      };
      RunSecondPass(gray, SecondPassRegions(gray, options_.max_candidates), attempts, clock,
                    {options_.time_budget_ms, options_.time_budget_with_codes_ms}, &found);
    }
    return FinishObservations(gray, found, options_.refine_corners, options_.min_side_px);
  }

 private:
  static std::vector<MarkerObservation> ReadInverted(const cv::Mat& crop) {
    cv::Mat inverted;
    cv::bitwise_not(crop, inverted);
    return ReadWithZxing(inverted, ZxingSymbology::kQrCode, ZxingPass{});
  }

  static std::vector<MarkerObservation> ReadGlobalHistogram(const cv::Mat& crop) {
    ZxingPass pass;
    pass.local_average_binarizer = false;
    return ReadWithZxing(crop, ZxingSymbology::kQrCode, pass);
  }

  static std::vector<MarkerObservation> ReadUpscaled(const cv::Mat& crop) {
    if (std::max(crop.cols, crop.rows) > kMaxUpscaleSidePx) return {};
    cv::Mat big;
    cv::resize(crop, big, cv::Size(), 2.0, 2.0, cv::INTER_CUBIC);
    std::vector<MarkerObservation> found = ReadWithZxing(big, ZxingSymbology::kQrCode, ZxingPass{});
    MapFromCrop(cv::Point(0, 0), 2.0, &found);
    return found;
  }

  // WeChat decodes but, without its CNN detector, reports the whole crop as the
  // position; the corners come from cv::QRCodeDetector, accepted only for a single code.
  std::vector<MarkerObservation> ReadWeChat(const cv::Mat& crop) {
    const std::vector<std::string> texts = wechat_.detectAndDecode(crop);
    if (texts.size() != 1 || texts[0].empty()) return {};
    std::vector<cv::Point2f> corners;
    if (!corner_finder_.detect(crop, corners) || corners.size() != 4) return {};
    MarkerObservation obs;
    obs.key.family = kFamilyQr;
    obs.key.id = TextToId(texts[0]);
    for (int i = 0; i < 4; ++i) obs.corners_px[i] = Eigen::Vector2d(corners[i].x, corners[i].y);
    return {obs};
  }

  DetectorOptions options_;
  cv::wechat_qrcode::WeChatQRCode wechat_;
  cv::QRCodeDetector corner_finder_;
};

}  // namespace

std::unique_ptr<MarkerDetector> CreateQrDetector(const DetectorOptions& options) {
  return std::make_unique<QrDetector>(options);
}

}  // namespace waymark
