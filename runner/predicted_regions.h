// The live loop looks where the map says first (issue 14): the localizer predicts which mapped
// codes are in a camera's view (Localizer::PredictCodesInView) and where; while the track is
// kTracking the detector runs on those regions only (none predicted: nothing to detect), and on
// the whole frame every `full_frame_every`-th frame of the camera and whenever the track is not
// kTracking (uninitialized, suspect, lost). A mapped code the prediction misses is found at the
// next whole frame; codes expected and not found make the track suspect (online/visibility.h),
// which brings the whole frame back at once.
#pragma once

#include <map>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "detect/detector.h"
#include "online/visibility.h"

namespace waymark {

struct PredictedRegionOptions {
  // 1: every frame on the whole image (no prediction used).
  int full_frame_every = 10;
  // Each predicted quad's bounding box is grown by this fraction of its larger side on every
  // side, and by at least min_margin_px (the prediction's error, the quiet zone the decoders and
  // the corner refinement need).
  double margin_fraction = 0.5;
  double min_margin_px = 24.0;

  bool Check(std::string* why) const;
};

// A region to detect in and the number of predicted codes it holds.
struct PredictedRegion {
  cv::Rect rect;
  int codes = 0;
  bool operator==(const PredictedRegion& o) const { return rect == o.rect && codes == o.codes; }
};

// The regions to detect in: each predicted quad's bounding box (corners x0 y0 ... x3 y3, as
// ExpectedCode::px) grown by the margin, clipped to the image; boxes that overlap are merged
// into their union (one detection per region, a code never cut in two), in the order given.
// Boxes entirely outside the image, and quads with a non-finite corner, are dropped.
std::vector<PredictedRegion> PredictedRegions(const std::vector<Vector8d>& quads_px,
                                              const cv::Size& image_size,
                                              const PredictedRegionOptions& options);

// Runs the first pass of `detector` (MarkerDetector::DetectFirstPass) on each region of
// `image`, and its second passes (DetectSecondPasses, continuing from the first pass's reads,
// which are not made again) on a region where it found fewer codes than were predicted there;
// returns the codes in full-image pixels (duplicates dropped; a code found by two regions is
// reported once). A region whose codes the first passes read costs no second pass. `skipped`
// (optional) adds the attempts skipped under the detector's live budget.
std::vector<MarkerObservation> DetectInRegions(MarkerDetector& detector, const cv::Mat& image,
                                               const std::vector<PredictedRegion>& regions,
                                               int* skipped = nullptr);

// Per camera: whether the next frame is detected on the whole image or in the predicted
// regions, and the counts the live summary reports.
class PredictedRegionPolicy {
 public:
  explicit PredictedRegionPolicy(const PredictedRegionOptions& options) : options_(options) {}
  // True if this camera's next frame must be detected on the whole image: its first frame, every
  // full_frame_every-th, and any frame while the track is not kTracking (`tracking` false).
  bool WholeFrame(const std::string& camera, bool tracking);
  const PredictedRegionOptions& options() const { return options_; }

 private:
  PredictedRegionOptions options_;
  std::map<std::string, long> since_whole_;  // frames since the camera's last whole-frame pass
};

}  // namespace waymark
