// Helpers shared by the code detectors (detect/detector.h): image conversion, the checks
// every reported quad must pass, candidate regions for second passes, and the work bound of
// a frame.
// Pixel convention: the centre of pixel (c, r) is at (c, r) (OpenCV).
#pragma once

#include <Eigen/Core>
#include <array>
#include <deque>
#include <functional>
#include <future>
#include <mutex>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "geometry/types.h"

namespace waymark {

using Quad2d = std::array<Eigen::Vector2d, 4>;

// An 8-bit single-channel view or copy of `image` (gray, BGR, BGRA; 16-bit is scaled by
// 1/256). Throws std::invalid_argument for an empty image or another pixel type.
cv::Mat ToGray8(const cv::Mat& image);

// The standard deviation (gray levels) of the white sensor noise on `gray` (8-bit, one
// channel), robustly: the median of |I(x + 1, y) - I(x, y)| over every fourth row (read
// between the integer levels) divided by 0.6745 sqrt(2). Edges and texture are the minority
// of neighbouring pairs on a camera frame and barely move the median; a frame that is mostly
// fine texture reads noisier than it is. 0 for an image under two pixels wide. Computed once
// per image for the families of one frame (PerImageCache, below).
double NoiseSigma(const cv::Mat& gray);

// The whole-frame binarizations' allowance for that noise: a threshold of `base` gray levels
// that grows with the noise once `levels_per_sigma` noise sigmas exceed it:
// max(base, round(levels_per_sigma noise_sigma)). With the factors the callers use, the recall
// bench's frames (noise 1.5-3.5 gray levels) keep `base`; at twice and three times that noise
// the fixed thresholds made speckle of most of a flat frame, and a frame cost 2 and 3 times as
// much (docs/detection.md).
int NoiseAwareThreshold(int base, double noise_sigma, double levels_per_sigma);

// True if the quad can be reported: finite corners inside [-0.5, w-0.5] x [-0.5, h-0.5],
// every side at least `min_side_px`, strictly convex, and clockwise on screen (x right,
// y down), which is docs/design.md's order top-left, top-right, bottom-right, bottom-left seen
// from the printed side. Otherwise false with the reason in *why (if given).
bool QuadIsValid(const Quad2d& corners_px, const cv::Size& image_size, double min_side_px,
                 std::string* why = nullptr);

Eigen::Vector2d QuadCenter(const Quad2d& corners_px);
double QuadMeanSide(const Quad2d& corners_px);

// std::lround(x) (halves away from zero) for finite |x| < 2^52, without the library call (the
// DataMatrix patch tests round every sample's coordinates: 4 % of a DataMatrix-only frame's
// instructions went into lround). x - trunc(x) is exact there, so the result is lround's bit for bit.
inline long RoundHalfAwayFromZero(double x) {
  const long t = static_cast<long>(x);
  const double fraction = x - static_cast<double>(t);
  return x >= 0.0 ? t + (fraction >= 0.5 ? 1 : 0) : t - (fraction <= -0.5 ? 1 : 0);
}

// Rotates the corner order by `steps` positions: out[i] = in[(i + steps) mod 4].
Quad2d RotateCorners(const Quad2d& corners_px, int steps);

// True if `a` and `b` are the same code seen twice: same key and centres closer than half
// the smaller mean side.
bool SameDetection(const MarkerObservation& a, const MarkerObservation& b);

// Appends the observations of `found` that are not already in `all` (SameDetection).
void AppendUnique(const std::vector<MarkerObservation>& found, std::vector<MarkerObservation>* all);

// True if a code of `found` (any key) has its centre within half its own mean side of `centre_px`,
// or has `centre_px` inside its quad: that place is already read.
bool AnyObservationAt(const std::vector<MarkerObservation>& found, const Eigen::Vector2d& centre_px);

// Candidate regions that may hold a 2-D code ([George]: Canny edges, dilation, the
// bounding box of every blob contour, nested ones included, scored by size, aspect ratio,
// fill, edge density, contrast and not touching the image border), best first, padded by a quiet-zone margin
// and clipped to the image. Regions are searched on a copy downscaled to at most `work_width_px` wide.
struct CandidateOptions {
  int work_width_px = 640;
  double min_side_px = 16.0;         // in full-resolution pixels
  double preferred_side_px = 100.0;  // smaller boxes score proportionally less
  double max_aspect = 4.0;           // longer / shorter side of the box
  double min_edge_density = 0.06;    // Canny pixels / box area (at work resolution)
  double margin_fraction = 0.25;     // padding added on each side, fraction of the box side
  int max_regions = 16;
};
struct CandidateRegion {
  cv::Rect rect;  // full-resolution pixels
  double score = 0.0;
};
std::vector<CandidateRegion> FindCodeCandidates(const cv::Mat& gray, const CandidateOptions& options);

// True if the centre of `obs` lies inside `rect`.
bool ObservationInside(const MarkerObservation& obs, const cv::Rect& rect);

// Maps the corners of observations found in a crop (at `scale` times the crop's
// resolution) back to full-image pixels: p = p_crop / scale + offset, with the pixel-centre
// convention kept (scaling is about pixel edges: (p + 0.5) / scale - 0.5).
void MapFromCrop(const cv::Point& offset, double scale, std::vector<MarkerObservation>* observations);

// True when `size` may be a close-up whose code fills the image (at most 640x480 pixels): the
// second passes then try the whole image as a region of its own, and QR tries OpenCV's WeChat
// decoder on it.
inline bool MayBeCloseUp(const cv::Size& size) { return size.area() <= 640 * 480; }

// The regions a second pass tries: the whole image when it MayBeCloseUp and `close_up`
// (DetectorOptions::close_up: the code may fill it, leaving no blob boundary), then
// FindCodeCandidates.
std::vector<cv::Rect> SecondPassRegions(const cv::Mat& gray, int max_candidates, bool close_up = true);

// One way of decoding a crop: returns observations with corners in crop pixels.
using CropAttempt = std::function<std::vector<MarkerObservation>(const cv::Mat& crop)>;

// What a frame's second passes may still do. Offline (live_budget_ms == 0) every attempt
// runs and no clock is read: the work is bounded by the callers' counts (regions,
// candidates), so the result depends on the image alone. Live (live_budget_ms > 0): once
// the frame has taken live_budget_ms of wall-clock time, Allow() returns false and counts
// the attempt as skipped.
//
// It also carries the codes other families have read in the frame
// (MarkerDetector::ReadByOthers): the passes skip their candidates there.
class FrameWork {
 public:
  // `read_by_others`: the codes other families have read in the frame (MarkerDetector::
  // ReadByOthers); it must outlive this.
  FrameWork(double live_budget_ms, const std::vector<MarkerObservation>& read_by_others);
  // True if the next attempt may run; false (and one more skipped attempt) if not.
  bool Allow();
  // Wall-clock milliseconds left in a live frame; infinity offline.
  double LeftMs() const;
  int skipped() const { return skipped_; }
  // Codes of other families already read.
  const std::vector<MarkerObservation>& read_by_others() const { return *read_by_others_; }
  // True if `centre_px` is at a code of `found` or of another family (AnyObservationAt).
  bool IsRead(const std::vector<MarkerObservation>& found, const Eigen::Vector2d& centre_px) const;
  // True if `region` is mostly one code of `found` or of another family (RegionIsMostlyOneCode).
  bool RegionIsRead(const cv::Rect& region, const std::vector<MarkerObservation>& found) const;

 private:
  double budget_ms_;
  const std::vector<MarkerObservation>* read_by_others_;
  double start_ms_ = 0.0;
  int skipped_ = 0;
};

// True if `region` is mostly one code of `codes`: a code's centre inside it, and the code's
// bounding box at least 0.3 of the region (a candidate region pads its blob by a quarter
// side, so a lone code covers about 0.44 of it); or the region's centre inside a code's quad
// and at least 0.75 of the region inside the code's bounding box (a blob of the code's own
// modules: no other code can be there).
bool RegionIsMostlyOneCode(const cv::Rect& region, const std::vector<MarkerObservation>& codes);

// For each region holding no code of `found` yet and not mostly one code read already
// (work->RegionIsRead), runs `attempts` in order on the crop until one decodes something
// (appended to *found in full-image pixels); every attempt asks work->Allow() first.
void RunSecondPass(const cv::Mat& gray, const std::vector<cv::Rect>& regions,
                   const std::vector<CropAttempt>& attempts, FrameWork* work,
                   std::vector<MarkerObservation>* found);

// The last step of every detector: refines each quad (if options.refine_corners; the
// quality is the refinement's inlier fraction, 0 when it fails and the decoder's
// corners are kept), drops invalid quads (QuadIsValid) and duplicates.
std::vector<MarkerObservation> FinishObservations(const cv::Mat& gray,
                                                  const std::vector<MarkerObservation>& raw,
                                                  bool refine_corners, double min_side_px);
// FinishObservations in its two steps (FinishObservations(g, raw, r, m) ==
// KeepValidObservations(g, RefineObservations(g, raw, r), m)), so that a detector run in two
// stages (MarkerDetector::DetectFirstPass) refines each quad once.
std::vector<MarkerObservation> RefineObservations(const cv::Mat& gray,
                                                  const std::vector<MarkerObservation>& raw,
                                                  bool refine_corners);
std::vector<MarkerObservation> KeepValidObservations(const cv::Mat& gray,
                                                     const std::vector<MarkerObservation>& refined,
                                                     double min_side_px);

// What a detector keeps between MarkerDetector::DetectFirstPass and DetectSecondPasses: the
// image (gray), the first pass's reads before refinement (`raw`) and the same reads refined
// (`refined`, one per raw read, in order; the second passes only append to `raw`).
struct StagedDetection {
  bool started = false;
  cv::Mat gray;
  std::vector<MarkerObservation> raw;
  std::vector<MarkerObservation> refined;
  // The first pass's reads followed by `more` (the second passes' reads), refined; each read
  // of the first pass is refined once. `refine` refines one read in place.
  template <typename Refine>
  std::vector<MarkerObservation> RefinedWith(const std::vector<MarkerObservation>& raw_after,
                                             Refine refine) const {
    std::vector<MarkerObservation> out = refined;
    for (size_t i = raw.size(); i < raw_after.size(); ++i) {
      MarkerObservation obs = raw_after[i];
      refine(&obs);
      out.push_back(obs);
    }
    return out;
  }
  // The second stage's result: RefinedWith(raw_after, refine) as KeepValidObservations keeps it.
  template <typename Refine>
  std::vector<MarkerObservation> KeptRefinedWith(const std::vector<MarkerObservation>& raw_after,
                                                 Refine refine, double min_side_px) const {
    return KeepValidObservations(gray, RefinedWith(raw_after, refine), min_side_px);
  }
  // Throws std::logic_error unless DetectFirstPass ran.
  void CheckStarted() const;
};

// A 64-bit hash of an 8-bit single-channel image's size and pixels (four interleaved
// multiply-xor lanes over 8-byte words, then the tail; about 0.05 ms for 1280x960).
uint64_t PixelHash(const cv::Mat& gray);

// While a scope is alive, PixelHash of its image (the same pixel buffer, size, type and row
// step) returns the hash the scope computed once: the families of a multi-family detector share
// one image whose pixels do not change during a call, and each PerImageCache lookup hashed the
// whole frame again (about 8 per frame). Scopes may nest and live on several threads at once.
// The caller must not change the image's pixels while its scope is alive.
class PixelHashScope {
 public:
  explicit PixelHashScope(const cv::Mat& gray);
  ~PixelHashScope();
  PixelHashScope(const PixelHashScope&) = delete;
  PixelHashScope& operator=(const PixelHashScope&) = delete;

 private:
  size_t id_;
};

// Whole-frame work shared by the families of one frame (the candidate stage, the candidate
// regions), also when a multi-family detector runs them on several threads at once: the
// first call for an image's pixels (and `key`, a parameter of the computation) computes the
// value, every other call with the same pixels and key, before, during or after it, gets that
// value (a concurrent caller waits for it). The last kEntries results are kept, keyed by the
// image's size, `key` and PixelHash, so a value is always what a new computation on these
// pixels would give: a buffer drawn on after a first run is seen anew. Thread-safe.
template <typename T>
class PerImageCache {
 public:
  static constexpr size_t kEntries = 4;
  T Get(const cv::Mat& gray, double key, const std::function<T()>& compute) {
    const uint64_t hash = PixelHash(gray);
    std::shared_future<T> value;
    std::promise<T> promise;
    bool mine = false;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      for (const Entry& e : entries_) {
        if (e.size == gray.size() && e.key == key && e.hash == hash) value = e.value;
      }
      if (!value.valid()) {
        value = promise.get_future().share();
        entries_.push_back({gray.size(), key, hash, value});
        if (entries_.size() > kEntries) entries_.pop_front();
        mine = true;
      }
    }
    if (mine) {
      try {
        promise.set_value(compute());
      } catch (...) {
        promise.set_exception(std::current_exception());
      }
    }
    return value.get();
  }

 private:
  struct Entry {
    cv::Size size;
    double key = 0.0;
    uint64_t hash = 0;
    std::shared_future<T> value;
  };
  std::mutex mutex_;
  std::deque<Entry> entries_;
};

// CPU time of the calling thread since construction, in milliseconds (benchmarks).
class FrameClock {
 public:
  FrameClock() : start_ms_(ThreadCpuMs()) {}
  double ElapsedMs() const { return ThreadCpuMs() - start_ms_; }
  static double ThreadCpuMs();
  // CPU time of the whole process (every thread), in milliseconds.
  static double ProcessCpuMs();

 private:
  double start_ms_;
};

}  // namespace waymark
