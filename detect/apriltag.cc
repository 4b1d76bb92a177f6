#include "detect/apriltag.h"

#include <apriltag/apriltag.h>
#include <apriltag/tag16h5.h>
#include <apriltag/tag25h9.h>
#include <apriltag/tag36h10.h>
#include <apriltag/tag36h11.h>
#include <apriltag/tagCircle21h7.h>
#include <apriltag/tagCircle49h12.h>
#include <apriltag/tagCustom48h12.h>
#include <apriltag/tagStandard41h12.h>
#include <apriltag/tagStandard52h13.h>

#include <algorithm>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "detect/common.h"
#include "detect/quads.h"

namespace waymark {
namespace {

constexpr int kMinImageSidePx = 32;
// libapriltag looks for quads in crops of the solid-bordered quads of the shared candidate
// stage (detect/quads.h: where a black border around mixed bits is), each at the decimation
// that leaves the quad's shortest side about this many pixels (at least 1, at most
// apriltag_decimate): the whole frame at decimation 4 lost tags 44-94 px wide (11-23
// decimated pixels), and decimation 1 everywhere costs several times as much.
constexpr double kCropDecimatedSidePx = 32.0;
constexpr double kCropMarginFraction = 0.3;  // of the quad's box, each side
constexpr int kMaxQuadCrops = 24;
// Then the whole frame at apriltag_decimate (8 by default), for tags at no such quad (a
// broken border, a tag larger than the candidate stage's coarsest level sees whole). Both
// ignore tiles whose gray levels span less than this (libapriltag's min_white_black_diff,
// default 5): on cluttered, noisy frames most of the whole frame's time went into clusters of
// such faint edges. A tag's border against its white ring spans far more, even at a fifth of
// full exposure. (The crops kept the default until issue 14's sixth round: with 15 they read
// the same tags on the recall bench's six 150-frame runs, 8 % fewer AprilTag instructions.)
constexpr int kMinTileContrast = 15;
// The whole frame's decimated image is blurred first (libapriltag's quad_sigma, applied after
// the decimation, which subsamples and so keeps the sensor noise at full strength): on the
// recall bench's noisy frames without clutter (issue-plain), that pass cost 1.9 ms on an empty
// frame and 1.3 ms on one with codes, most of it in quads of noise; blurred by 0.8 px, 0.26 and
// 0.40 ms (on cluttered frames 1.0 instead of 1.2 ms), and it reads the same tags or more (a tag with a dark
// bar across its border: 7 of 16 instead of 6, in tests/detect/apriltag_test.cc). The crops keep
// apriltag_blur_sigma: blurred, they read the same tags in no less time and with other corners.
constexpr double kWholeFrameSigma = 0.8;
// The whole frame's tile contrast also grows with the frame's sensor noise once 2.5 noise
// sigmas exceed kMinTileContrast (NoiseAwareThreshold; the bench's noise, at most 3.5 gray
// levels, keeps 15): the blur leaves about half the noise, whose tiles of 16 decimated pixels
// span 3-4 of its sigmas.
constexpr double kTileContrastPerSigma = 2.5;

struct FamilyEntry {
  const char* name;  // after "apriltag-"
  apriltag_family_t* (*create)();
  void (*destroy)(apriltag_family_t*);
};

const FamilyEntry kFamilies[] = {
    {"16h5", tag16h5_create, tag16h5_destroy},
    {"25h9", tag25h9_create, tag25h9_destroy},
    {"36h10", tag36h10_create, tag36h10_destroy},
    {"36h11", tag36h11_create, tag36h11_destroy},
    {"circle21h7", tagCircle21h7_create, tagCircle21h7_destroy},
    {"circle49h12", tagCircle49h12_create, tagCircle49h12_destroy},
    {"custom48h12", tagCustom48h12_create, tagCustom48h12_destroy},
    {"standard41h12", tagStandard41h12_create, tagStandard41h12_destroy},
    {"standard52h13", tagStandard52h13_create, tagStandard52h13_destroy},
};

const FamilyEntry* FindFamily(const std::string& family) {
  const std::string prefix = kFamilyAprilTagPrefix;
  if (family.compare(0, prefix.size(), prefix) != 0) return nullptr;
  const std::string name = family.substr(prefix.size());
  for (const FamilyEntry& entry : kFamilies) {
    if (name == entry.name) return &entry;
  }
  return nullptr;
}

class AprilTagDetector : public MarkerDetector {
 public:
  AprilTagDetector(const std::string& family, const FamilyEntry& entry, const DetectorOptions& options)
      : family_(family), entry_(entry), options_(options) {
    tag_family_ = entry_.create();
    whole_frame_ = apriltag_detector_create();
    apriltag_detector_add_family_bits(whole_frame_, tag_family_, options.apriltag_max_bits_corrected);
    whole_frame_->quad_decimate = static_cast<float>(options.apriltag_decimate);
    whole_frame_->quad_sigma = static_cast<float>(kWholeFrameSigma);
    whole_frame_->nthreads = 1;  // threads: the multi-family detector's (detect/detector.h)
    whole_frame_->refine_edges = true;
    whole_frame_->qtp.min_white_black_diff = kMinTileContrast;
    crops_ = apriltag_detector_create();
    apriltag_detector_add_family_bits(crops_, tag_family_, options.apriltag_max_bits_corrected);
    crops_->quad_decimate = 1.0f;  // set per crop
    crops_->quad_sigma = static_cast<float>(options.apriltag_blur_sigma);
    crops_->nthreads = 1;
    crops_->refine_edges = true;
    crops_->qtp.min_white_black_diff = kMinTileContrast;
  }
  ~AprilTagDetector() override {
    apriltag_detector_destroy(crops_);
    apriltag_detector_destroy(whole_frame_);
    entry_.destroy(tag_family_);
  }
  AprilTagDetector(const AprilTagDetector&) = delete;
  AprilTagDetector& operator=(const AprilTagDetector&) = delete;

  std::vector<std::string> Families() const override { return {family_}; }
  int SkippedAttempts() const override { return skipped_; }

  std::vector<MarkerObservation> Detect(const cv::Mat& image) override {
    const cv::Mat gray = ToGray8(image);
    const std::vector<MarkerObservation> raw = FirstPass(gray);
    skipped_ = 0;
    return Finish(gray, RefineObservations(gray, raw, Refines()));
  }

  std::vector<MarkerObservation> DetectFirstPass(const cv::Mat& image) override {
    staged_.gray = ToGray8(image);
    staged_.raw = FirstPass(staged_.gray);
    staged_.refined = RefineObservations(staged_.gray, staged_.raw, Refines());
    staged_.started = true;
    skipped_ = 0;
    return Finish(staged_.gray, staged_.refined);
  }

  // Every pass runs in the first stage (the quad crops and the whole frame at a coarse
  // decimation are both cheaper than the full-resolution second pass they replace): the
  // second stage has nothing left to add.
  std::vector<MarkerObservation> DetectSecondPasses() override {
    staged_.CheckStarted();
    skipped_ = 0;
    return Finish(staged_.gray, staged_.refined);
  }

 private:
  bool Refines() const { return options_.refine_corners && !tag_family_->reversed_border; }

  // libapriltag 3.3 crashes on images only a few pixels across once decimated (e.g.
  // 2000x3 at decimate 2, 8x8 at 4); no tag fits in them anyway.
  static bool TooSmall(const cv::Size& size, double decimate) {
    const double min_side_px = std::max<double>(kMinImageSidePx, 8.0 * decimate);
    return size.width < min_side_px || size.height < min_side_px;
  }

  // Unrefined reads: crops of the solid-bordered quads (best first, at most kMaxQuadCrops), each
  // at a decimation chosen by its size, then the whole frame at apriltag_decimate; a tag is
  // kept once (a whole-frame read at a tag already read is dropped: at decimation 8 a 67 px tag
  // was read with one bit corrected and its corners 2-3 px off, which the refinement rejects).
  std::vector<MarkerObservation> FirstPass(const cv::Mat& gray) {
    std::vector<MarkerObservation> raw;
    const cv::Rect frame(0, 0, gray.cols, gray.rows);
    for (const Quad2d& quad : SolidBorderQuads(FindDarkQuads(gray, options_.min_side_px),
                                               std::numeric_limits<double>::infinity(), kMaxQuadCrops)) {
      // A tag read already, or another family's code (a QR code's quad often has three
      // solid sides).
      if (AnyObservationAt(raw, QuadCenter(quad)) || AnyObservationAt(ReadByOthers(), QuadCenter(quad)))
        continue;
      double shortest = std::numeric_limits<double>::infinity();
      for (int j = 0; j < 4; ++j) shortest = std::min(shortest, (quad[(j + 1) % 4] - quad[j]).norm());
      const int decimate = std::clamp(static_cast<int>(shortest / kCropDecimatedSidePx), 1,
                                      std::max(1, static_cast<int>(options_.apriltag_decimate)));
      std::vector<cv::Point2f> points;
      for (const Eigen::Vector2d& c : quad) points.emplace_back(float(c.x()), float(c.y()));
      cv::Rect box = cv::boundingRect(points);
      const int margin =
          static_cast<int>(std::ceil(kCropMarginFraction * std::max(box.width, box.height))) + 2;
      box = cv::Rect(box.x - margin, box.y - margin, box.width + 2 * margin, box.height + 2 * margin) & frame;
      if (TooSmall(box.size(), decimate)) continue;
      crops_->quad_decimate = static_cast<float>(decimate);
      for (const MarkerObservation& obs : Run(crops_, gray(box), box.tl())) {
        const bool seen = std::any_of(raw.begin(), raw.end(),
                                      [&obs](const MarkerObservation& o) { return SameDetection(o, obs); });
        if (!seen) raw.push_back(obs);
      }
    }
    if (!TooSmall(gray.size(), options_.apriltag_decimate)) {
      whole_frame_->qtp.min_white_black_diff =
          NoiseAwareThreshold(kMinTileContrast, NoiseSigma(gray), kTileContrastPerSigma);
      for (const MarkerObservation& obs : Run(whole_frame_, gray, cv::Point(0, 0))) {
        if (!AnyObservationAt(raw, QuadCenter(obs.corners_px))) raw.push_back(obs);
      }
    }
    return raw;
  }

  // The refined reads (RefineObservations) checked and, when refined, those whose border the
  // refinement did not find dropped.
  std::vector<MarkerObservation> Finish(const cv::Mat& gray,
                                        const std::vector<MarkerObservation>& refined) const {
    const bool refine = Refines();
    std::vector<MarkerObservation> out = KeepValidObservations(gray, refined, options_.min_side_px);
    if (refine) {
      // A tag whose border the refinement cannot find where libapriltag put it (quality 0)
      // has corners that are not the border's: a dark bar across the border joins it, and
      // libapriltag's quad follows the bar (11.8 px off in the recall bench). Bad corners
      // are worse than a missed tag: it is dropped.
      out.erase(std::remove_if(out.begin(), out.end(),
                               [](const MarkerObservation& o) { return o.quality.value_or(0.0) <= 0.0; }),
                out.end());
    }
    return out;
  }

  // libapriltag on `gray` (a view into the frame at `offset`): corners in frame pixels,
  // DESIGN.md order, OpenCV's pixel centres. The frame is never written: libapriltag 3.3 blurs
  // (quad_sigma > 0) or sharpens (< 0) the image it is given in place when it does not decimate
  // it (quad_decimate <= 1), which would change the pixels the other families read at the same
  // time on other threads, this family's later crops and the corner refinement; it gets a copy then.
  std::vector<MarkerObservation> Run(apriltag_detector_t* detector, const cv::Mat& gray,
                                     const cv::Point& offset) {
    const bool writes_image = detector->quad_sigma != 0.0f && !(detector->quad_decimate > 1.0f);
    const cv::Mat pixels = writes_image ? gray.clone() : gray;
    image_u8_t view{pixels.cols, pixels.rows, static_cast<int32_t>(pixels.step[0]),
                    const_cast<uint8_t*>(pixels.data)};
    zarray_t* detections = apriltag_detector_detect(detector, &view);
    std::vector<MarkerObservation> out;
    for (int i = 0; i < zarray_size(detections); ++i) {
      apriltag_detection_t* det = nullptr;
      zarray_get(detections, i, &det);
      MarkerObservation obs;
      obs.key = {family_, std::to_string(det->id)};
      for (int k = 0; k < 4; ++k) {
        obs.corners_px[k] =
            Eigen::Vector2d(det->p[3 - k][0] - 0.5 + offset.x, det->p[3 - k][1] - 0.5 + offset.y);
      }
      out.push_back(obs);
    }
    apriltag_detections_destroy(detections);
    return out;
  }

  std::string family_;
  FamilyEntry entry_;
  DetectorOptions options_;
  apriltag_family_t* tag_family_ = nullptr;
  apriltag_detector_t* whole_frame_ = nullptr;  // quad_decimate apriltag_decimate
  apriltag_detector_t* crops_ = nullptr;        // quad_decimate set per crop
  int skipped_ = 0;
  StagedDetection staged_;
};

}  // namespace

std::vector<std::string> AprilTagFamilyNames() {
  std::vector<std::string> names;
  for (const FamilyEntry& entry : kFamilies) names.push_back(entry.name);
  return names;
}

cv::Mat AprilTagModuleImage(const std::string& family, int id, cv::Rect* symbol) {
  const FamilyEntry* entry = FindFamily(family);
  if (entry == nullptr) throw std::invalid_argument("unknown AprilTag family '" + family + "'");
  apriltag_family_t* tags = entry->create();
  if (id < 0 || static_cast<uint32_t>(id) >= tags->ncodes) {
    entry->destroy(tags);
    throw std::invalid_argument(family + ": no tag " + std::to_string(id));
  }
  const int total = tags->total_width;
  // As libapriltag draws it: black, a one-module white ring (the quiet zone around the
  // black border, or for reversed-border families the border itself), white bits.
  const int white_width = tags->width_at_border + (tags->reversed_border ? 0 : 2);
  const int white_start = (total - white_width) / 2;
  const int white_end = white_start + white_width - 1;
  const int start = (total - tags->width_at_border) / 2;
  cv::Mat modules(total, total, CV_8U, cv::Scalar(0));
  for (int k = white_start; k <= white_end; ++k) {
    modules.at<uint8_t>(white_start, k) = modules.at<uint8_t>(white_end, k) = 255;
    modules.at<uint8_t>(k, white_start) = modules.at<uint8_t>(k, white_end) = 255;
  }
  const uint64_t code = tags->codes[id];
  for (uint32_t i = 0; i < tags->nbits; ++i) {
    if (((code >> (tags->nbits - 1 - i)) & 1u) == 0) continue;
    // Bit positions are relative to the border square and may be negative (stored as
    // uint32_t) for bits outside a reversed border.
    const int x = static_cast<int32_t>(tags->bit_x[i]) + start;
    const int y = static_cast<int32_t>(tags->bit_y[i]) + start;
    if (x >= 0 && y >= 0 && x < total && y < total) modules.at<uint8_t>(y, x) = 255;
  }
  *symbol = cv::Rect(start, start, tags->width_at_border, tags->width_at_border);
  entry->destroy(tags);
  return modules;
}

std::unique_ptr<MarkerDetector> CreateAprilTagDetector(const std::string& family,
                                                       const DetectorOptions& options) {
  const FamilyEntry* entry = FindFamily(family);
  if (entry == nullptr) throw std::invalid_argument("unknown AprilTag family '" + family + "'");
  return std::make_unique<AprilTagDetector>(family, *entry, options);
}

}  // namespace waymark
