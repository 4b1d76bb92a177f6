#include "runner/predicted_regions.h"

#include <algorithm>
#include <cmath>

#include "detect/common.h"
#include "util/check.h"

namespace waymark {

bool PredictedRegionOptions::Check(std::string* why) const {
  WAYMARK_CHECK_OPTION(full_frame_every >= 1, "full_frame_every must be >= 1");
  WAYMARK_CHECK_OPTION(margin_fraction >= 0.0 && std::isfinite(margin_fraction),
                       "margin_fraction must be >= 0");
  WAYMARK_CHECK_OPTION(min_margin_px >= 0.0 && std::isfinite(min_margin_px), "min_margin_px must be >= 0");
  return true;
}

std::vector<PredictedRegion> PredictedRegions(const std::vector<Vector8d>& quads_px,
                                              const cv::Size& image_size,
                                              const PredictedRegionOptions& options) {
  const cv::Rect image(0, 0, image_size.width, image_size.height);
  std::vector<PredictedRegion> boxes;
  for (const Vector8d& px : quads_px) {
    double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
    bool finite = true;
    for (int k = 0; k < 4; ++k) {
      const double x = px[2 * k], y = px[2 * k + 1];
      finite = finite && std::isfinite(x) && std::isfinite(y);
      x0 = std::min(x0, x);
      y0 = std::min(y0, y);
      x1 = std::max(x1, x);
      y1 = std::max(y1, y);
    }
    if (!finite) continue;
    const double margin =
        std::max(options.min_margin_px, options.margin_fraction * std::max(x1 - x0, y1 - y0));
    // Clamped before the conversion to int (a prediction far off the image).
    const auto clamp = [](double v, int hi) { return static_cast<int>(std::clamp(v, -1.0, hi + 1.0)); };
    const cv::Rect box(cv::Point(clamp(std::floor(x0 - margin), image_size.width),
                                 clamp(std::floor(y0 - margin), image_size.height)),
                       cv::Point(clamp(std::ceil(x1 + margin) + 1, image_size.width),
                                 clamp(std::ceil(y1 + margin) + 1, image_size.height)));
    const cv::Rect clipped = box & image;
    if (clipped.area() > 0) boxes.push_back({clipped, 1});
  }
  // Overlapping boxes merged (repeatedly: a union can reach a third box).
  for (bool merged = true; merged;) {
    merged = false;
    for (size_t i = 0; i < boxes.size() && !merged; ++i) {
      for (size_t j = i + 1; j < boxes.size() && !merged; ++j) {
        if ((boxes[i].rect & boxes[j].rect).area() > 0) {
          boxes[i].rect |= boxes[j].rect;
          boxes[i].codes += boxes[j].codes;
          boxes.erase(boxes.begin() + static_cast<std::ptrdiff_t>(j));
          merged = true;
        }
      }
    }
  }
  return boxes;
}

std::vector<MarkerObservation> DetectInRegions(MarkerDetector& detector, const cv::Mat& image,
                                               const std::vector<PredictedRegion>& regions, int* skipped) {
  std::vector<MarkerObservation> all;
  for (const PredictedRegion& region : regions) {
    const cv::Mat crop = image(region.rect);
    std::vector<MarkerObservation> found = detector.DetectFirstPass(crop);
    if (skipped != nullptr) *skipped += detector.SkippedAttempts();
    if (static_cast<int>(found.size()) < region.codes) {
      found = detector.DetectSecondPasses();  // the first pass is not run again
      if (skipped != nullptr) *skipped += detector.SkippedAttempts();
    }
    MapFromCrop(region.rect.tl(), 1.0, &found);
    AppendUnique(found, &all);
  }
  return all;
}

bool PredictedRegionPolicy::WholeFrame(const std::string& camera, bool tracking) {
  const auto it = since_whole_.find(camera);
  const bool whole = it == since_whole_.end() || !tracking || it->second + 1 >= options_.full_frame_every;
  since_whole_[camera] = whole ? 0 : it->second + 1;
  return whole;
}

}  // namespace waymark
