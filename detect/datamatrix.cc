#include "detect/datamatrix.h"

#include <dmtx.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include <opencv2/imgproc.hpp>

#include "detect/common.h"
#include "detect/zxing.h"

namespace waymark {
namespace {

constexpr int kMaxUpscaleSidePx = 240;  // only small crops are upscaled
// libdmtx scans crops larger than this (longer side) at half resolution.
constexpr int kDmtxShrinkAbovePx = 320;
// libdmtx's timeout granularity is 1 ms; below this a scan is not worth starting.
constexpr double kMinDmtxTimeoutMs = 1.0;
// In the first round of pass 2 a region gets at least this much of the time left.
constexpr double kMinDmtxShareMs = 4.0;

// Corners of a decoded libdmtx region in y-down pixels of an image `height` rows tall
// scanned at 1/shrink resolution, docs/design.md order. Grid (0,0) is the L corner
// (bottom-left of the upright symbol). The refinement removes the sub-pixel offsets.
Quad2d DmtxCorners(const DmtxRegion& region, int height, int shrink) {
  static const double kGrid[4][2] = {{0.0, 1.0}, {1.0, 1.0}, {1.0, 0.0}, {0.0, 0.0}};
  Quad2d corners;
  for (int i = 0; i < 4; ++i) {
    DmtxVector2 grid{kGrid[i][0], kGrid[i][1]};
    DmtxVector2 raw;
    dmtxMatrix3VMultiply(&raw, &grid, const_cast<DmtxRegion&>(region).fit2raw);
    // Raw (shrunk) pixel centres sit at integers with row 0 at the bottom.
    corners[i] = Eigen::Vector2d(raw.X * shrink, (height - 1) - raw.Y * shrink);
  }
  return corners;
}

class DataMatrixDetector : public MarkerDetector {
 public:
  explicit DataMatrixDetector(const DetectorOptions& options) : options_(options) {}

  std::vector<std::string> Families() const override { return {kFamilyDataMatrix}; }

  std::vector<MarkerObservation> Detect(const cv::Mat& image) override {
    const FrameClock clock;
    const cv::Mat gray = ToGray8(image);
    const std::vector<cv::Rect> regions = SecondPassRegions(gray, options_.max_candidates);
    std::vector<MarkerObservation> found;
    const std::vector<CropAttempt> first = {
        [](const cv::Mat& crop) { return ReadWithZxing(crop, ZxingSymbology::kDataMatrix, ZxingPass{}); }};
    const double unlimited = std::numeric_limits<double>::infinity();
    RunSecondPass(gray, regions, first, clock, {unlimited, unlimited}, &found);
    if (options_.second_pass) {
      // Two rounds over the regions zxing left: first each gets an equal share of the time
      // left (so one slow region, e.g. clutter early in the list, cannot starve a code behind
      // it), then the regions still unread get whatever is left, in order.
      const FrameBudget budget{options_.time_budget_ms, options_.time_budget_with_codes_ms};
      int shares_left = static_cast<int>(std::count_if(regions.begin(), regions.end(), [&found](const cv::Rect& r) {
        return std::none_of(found.begin(), found.end(), [&r](const MarkerObservation& o) { return ObservationInside(o, r); });
      }));
      const auto libdmtx = [&clock, &budget, &found, &shares_left](const cv::Mat& crop, bool shared) {
        double left_ms = budget.For(found) - clock.ElapsedMs();
        if (shared) left_ms = std::min(left_ms, std::max(kMinDmtxShareMs, left_ms / std::max(1, shares_left--)));
        if (left_ms < kMinDmtxTimeoutMs) return std::vector<MarkerObservation>{};
        return ReadWithLibdmtx(crop, left_ms);
      };
      RunSecondPass(gray, regions,
                    {[&libdmtx](const cv::Mat& crop) { return libdmtx(crop, true); },
                     [](const cv::Mat& crop) { return ReadUpscaled(crop); }},
                    clock, budget, &found);
      RunSecondPass(gray, regions, {[&libdmtx](const cv::Mat& crop) { return libdmtx(crop, false); }}, clock, budget,
                    &found);
    }
    return FinishObservations(gray, found, options_.refine_corners, options_.min_side_px);
  }

 private:
  static std::vector<MarkerObservation> ReadUpscaled(const cv::Mat& crop) {
    if (std::max(crop.cols, crop.rows) > kMaxUpscaleSidePx) return {};
    cv::Mat big;
    cv::resize(crop, big, cv::Size(), 2.0, 2.0, cv::INTER_CUBIC);
    std::vector<MarkerObservation> found = ReadWithZxing(big, ZxingSymbology::kDataMatrix, ZxingPass{});
    MapFromCrop(cv::Point(0, 0), 2.0, &found);
    return found;
  }

  DetectorOptions options_;
};

// Owns libdmtx's objects for one scan.
struct DmtxScan {
  DmtxImage* image = nullptr;
  DmtxDecode* decode = nullptr;
  ~DmtxScan() {
    if (decode != nullptr) dmtxDecodeDestroy(&decode);
    if (image != nullptr) dmtxImageDestroy(&image);
  }
};

}  // namespace

std::vector<MarkerObservation> ReadWithLibdmtx(const cv::Mat& gray, double timeout_ms, int max_symbols) {
  CV_Assert(gray.type() == CV_8UC1);
  std::vector<MarkerObservation> out;
  if (gray.cols < 8 || gray.rows < 8) return out;
  DmtxScan scan;
  // libdmtx reads through a non-const pointer but does not write the pixels.
  scan.image = dmtxImageCreate(const_cast<unsigned char*>(gray.ptr<unsigned char>(0)), gray.cols, gray.rows,
                               DmtxPack8bppK);
  if (scan.image == nullptr) return out;
  dmtxImageSetProp(scan.image, DmtxPropRowPadBytes, static_cast<int>(gray.step[0]) - gray.cols);
  const int shrink = std::max(gray.cols, gray.rows) > kDmtxShrinkAbovePx ? 2 : 1;
  scan.decode = dmtxDecodeCreate(scan.image, shrink);
  if (scan.decode == nullptr) return out;
  DmtxTime deadline = dmtxTimeAdd(dmtxTimeNow(), static_cast<long>(std::ceil(timeout_ms)));
  while (DmtxRegion* region = dmtxRegionFindNext(scan.decode, &deadline)) {
    if (DmtxMessage* message = dmtxDecodeMatrixRegion(scan.decode, region, DmtxUndefined)) {
      MarkerObservation obs;
      obs.key.family = kFamilyDataMatrix;
      obs.key.id = TextToId(std::string(reinterpret_cast<const char*>(message->output), message->outputIdx));
      obs.corners_px = DmtxCorners(*region, gray.rows, shrink);
      out.push_back(std::move(obs));
      dmtxMessageDestroy(&message);
    }
    dmtxRegionDestroy(&region);
    if (static_cast<int>(out.size()) >= max_symbols) break;
  }
  return out;
}

std::unique_ptr<MarkerDetector> CreateDataMatrixDetector(const DetectorOptions& options) {
  return std::make_unique<DataMatrixDetector>(options);
}

}  // namespace waymark
