#include "core/detect_qr.h"

#include <algorithm>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <opencv2/objdetect.hpp>
#include <opencv2/wechat_qrcode.hpp>
#include <optional>

#include "core/detect_common.h"
#include "core/detect_refine.h"
#include "core/detect_zxing.h"

namespace waymark {
namespace {

// Crops larger than this (longer side, px) are not upscaled in pass 2.
constexpr int kMaxUpscaleSidePx = 480;

// Fraction of a side next to a finder pattern that the finder's outer ring covers in every
// version up to 3 (7 of 4 v + 17 modules: 0.33 at version 1, 0.24 at version 3); in larger
// versions the rest of the segment is the separator and format modules, rejected as
// outliers by the line fit.
constexpr double kFinderFraction = 0.24;
// Half window (px) of the edge search along the finders' outer edges: at least this, or
// a tenth of the side (zxing's fourth corner can be off by a few modules).
constexpr double kFinderWindowPx = 2.5;
// First refinement window, fraction of the shortest side: 0.74 module in version 1 (21
// modules), less in larger versions.
constexpr double kRefineWindowFraction = 0.035;

// The bottom-right corner from the symbol's own edges: the intersection of the outer edge
// of the top-right finder (right side, next to the top-right corner) and of the
// bottom-left finder (bottom side, next to the bottom-left corner). zxing places that
// corner from the alignment pattern, or, in version 1 (no alignment pattern), by
// completing the parallelogram of the three finders, a few pixels off under perspective.
// Keeps zxing's corner when an edge is not found or the corner would move more than a
// fifth of the shortest side.
void CornerFromFinderEdges(const cv::Mat& gray, MarkerObservation* obs) {
  Quad2d& c = obs->corners_px;
  double shortest = std::numeric_limits<double>::infinity();
  for (int i = 0; i < 4; ++i) shortest = std::min(shortest, (c[(i + 1) % 4] - c[i]).norm());
  const double window = std::min(std::max(kFinderWindowPx, 0.1 * shortest), shortest / 6.0);
  constexpr double kMinStep = 12.0;  // gray levels per px, as RefineOptions::min_step
  const std::optional<Line2d> right =
      FitSideSegment(gray, c[1], c[2], 0.02, kFinderFraction, window, kMinStep);
  const std::optional<Line2d> bottom =
      FitSideSegment(gray, c[2], c[3], 1.0 - kFinderFraction, 0.98, window, kMinStep);
  if (!right || !bottom || right->inlier_fraction < 0.5 || bottom->inlier_fraction < 0.5) return;
  const std::optional<Eigen::Vector2d> corner = IntersectLines(*right, *bottom);
  if (corner && (*corner - c[2]).norm() < 0.2 * shortest) c[2] = *corner;
}

// The corners from the symbol's edges: the fourth corner from the finders
// (CornerFromFinderEdges), then every side refined (core/detect_refine.h) with a first
// window of at most a module: the outermost row and column of a QR code hold data modules,
// and where one is light the next dark module inwards makes an edge one module inside,
// which a wider window would take for the side (a line of them can outvote the true side).
void RefineQrCorners(const cv::Mat& gray, MarkerObservation* obs) {
  RefineOptions options;
  options.search_px = 1.25;
  options.search_fraction = kRefineWindowFraction;
  MarkerObservation corrected = *obs;
  CornerFromFinderEdges(gray, &corrected);
  // A light-on-dark code has no light-outside edges: nothing refines, zxing's corners stay.
  std::optional<RefinedQuad> refined = RefineQuadCorners(gray, corrected.corners_px, options);
  if (!refined) refined = RefineQuadCorners(gray, obs->corners_px, options);
  obs->quality = 0.0;
  if (refined) {
    obs->corners_px = refined->corners_px;
    obs->quality = refined->inlier_fraction;
  }
}

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
    if (options_.refine_corners) {
      for (MarkerObservation& obs : found) RefineQrCorners(gray, &obs);
    }
    // Refined above (the quality is the refinement's inlier fraction, 0 if it failed).
    return FinishObservations(gray, found, /*refine_corners=*/false, options_.min_side_px);
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
