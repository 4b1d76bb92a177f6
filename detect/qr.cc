#include "detect/qr.h"

#include <algorithm>
#include <functional>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <opencv2/objdetect.hpp>
#include <opencv2/wechat_qrcode.hpp>
#include <optional>

#include "detect/common.h"
#include "detect/module_fit.h"
#include "detect/qr_finder.h"
#include "detect/qr_grid.h"
#include "detect/qr_modules.h"
#include "detect/quads.h"
#include "detect/refine.h"
#include "detect/zxing.h"

namespace waymark {
namespace {

// Crops larger than this (longer side, px) are not upscaled in pass 2.
constexpr int kMaxUpscaleSidePx = 480;
// The whole frame's zxing read: a block is flat (no black point of its own) while its range is
// at most zxing's 24 gray levels or this many noise sigmas of the frame (NoiseAwareThreshold):
// 64 pixels of noise alone span about 5 sigmas, so above 3.4 gray levels of noise a fixed 24
// turned flat areas into speckle.
constexpr double kMinDynamicRangePerSigma = 7.0;

// Small-code boxes searched for finders per frame (ReadSmallCodeQuads).
constexpr int kMaxSmallCodeBoxes = 16;
// A finder triple belongs to a small-code quad when its centre is within this fraction of the
// quad's side of the quad's (an oblique code's coarse outline can be a module or two off).
constexpr double kSmallCodeCentreFraction = 0.5;
// Quads up to this side (px) with no finder triple are read as module grids from their own
// corners (larger codes have finders the search finds: 7 modules of at least 2.4 px).
constexpr double kMaxUnorientedSidePx = 50.0;
// ... at most this many per frame (each is up to eight contrast evaluations, two grid fits
// and their decodes; most such quads of a cluttered frame are no code).
constexpr int kMaxUnorientedReads = 4;
// Thin-side small-code quads (ThinSideSmallQrCodeQuads): boxes and grid reads per frame, after
// and beside the ones above.
constexpr int kMaxThinSideBoxes = 2;
constexpr int kMaxThinSideReads = 1;
// Merged-fragment quads (MergedFragmentQrCodeQuads): quads and grid reads per frame, after all
// the others, each read only with its known-module contrast (gray levels) times its code
// likeness (UnorientedCodeEvidence) at least kMinMergedCodeEvidence: on eight traced frames
// of issue seeds 4, 6, 7, 8 the clutter's merged quads scored at most 3.7, the codes 1.3-32
// (a read of clutter costs milliseconds: the grid fits, the perspective search).
constexpr int kMaxMergedBoxes = 4;
constexpr int kMaxMergedReads = 2;
constexpr double kMinMergedCodeEvidence = 4.0;
// Candidates completed from a pair of finders of a finder search and the third finder found
// where the pair puts it (QrCandidatesFromFinderPairs) read per frame.
constexpr int kMaxPairReads = 2;

// First refinement window, fraction of the shortest side: 0.74 module in version 1 (21
// modules), less in larger versions.
constexpr double kRefineWindowFraction = 0.035;
// Codes with modules under this many pixels get their corners from the photometric fit of
// the whole module pattern (detect/module_fit.h).
constexpr double kModuleFitMaxModulePx = 4.0;

// The corners from the symbol's edges: the fourth corner from the finders
// (QrCornerFromFinderEdges), then every side refined (detect/refine.h) with a first
// window of at most a module: the outermost row and column of a QR code hold data modules,
// and where one is light the next dark module inwards makes an edge one module inside,
// which a wider window would take for the side (a line of them can outvote the true side).
// Last, with the module grid read off those corners: a code whose modules are under
// kModuleFitMaxModulePx gets its corners from the photometric fit of its whole module pattern
// (detect/module_fit.h; the one-sided side fits leave such codes 0.1-0.3 px too large along
// their diagonals), and any other code, or one whose fit fails, has every side re-fitted on
// its dark outer modules only (detect/qr_grid.h).
void RefineQrCorners(const cv::Mat& gray, MarkerObservation* obs) {
  RefineOptions options;
  options.search_px = 1.25;
  options.search_fraction = kRefineWindowFraction;
  MarkerObservation corrected = *obs;
  QrCornerFromFinderEdges(gray, &corrected.corners_px);
  // A light-on-dark code has no light-outside edges: nothing refines, zxing's corners stay.
  std::optional<RefinedQuad> refined = RefineQuadCorners(gray, corrected.corners_px, options);
  if (!refined) refined = RefineQuadCorners(gray, obs->corners_px, options);
  obs->quality = 0.0;
  if (refined) {
    obs->corners_px = refined->corners_px;
    obs->quality = refined->inlier_fraction;
    if (const std::optional<QrGridEstimate> grid = EstimateQrGrid(gray, obs->corners_px)) {
      bool photometric = false;
      if (QuadMeanSide(obs->corners_px) < kModuleFitMaxModulePx * grid->modules) {
        const std::vector<uint8_t> dark = SampleQrModules(gray, obs->corners_px, *grid);
        if (!dark.empty()) {
          if (const std::optional<ModuleFit> fit =
                  FitModuleGrid(gray, obs->corners_px, grid->modules, dark)) {
            obs->corners_px = fit->corners_px;
            photometric = true;
          }
        }
      }
      if (!photometric) {
        if (const std::optional<Quad2d> fitted = FitQrSidesOnDarkModules(gray, obs->corners_px, *grid)) {
          obs->corners_px = *fitted;
        }
      }
    }
  }
}

// True if the candidate's centre is at a code already read, of this family or another
// (FrameWork::IsRead).
bool CandidateIsRead(const QrCandidate& candidate, const std::vector<MarkerObservation>& found,
                     const FrameWork& work) {
  return work.IsRead(found, QuadCenter(candidate.corners_px));
}

// Pass 2a (and 2a', 2a''): the candidates that a pair of `finders` used by none of `triples`
// completes with its third finder found where the pair puts it (QrCandidatesFromFinderPairs),
// within `near` of a point when given, not read yet, read rectified while `pair_reads` lasts.
void ReadFinderPairs(const cv::Mat& gray, const std::vector<QrFinderPattern>& finders,
                     const std::vector<QrCandidate>& triples,
                     const std::function<bool(const QrCandidate&)>& near, int* pair_reads, FrameWork* work,
                     std::vector<MarkerObservation>* found) {
  if (*pair_reads <= 0 || finders.size() < 2) return;
  for (const QrCandidate& candidate :
       QrCandidatesFromFinderPairs(gray, finders, triples, kMaxPairFinderWidthPx)) {
    if (*pair_reads <= 0) return;
    if ((near && !near(candidate)) || CandidateIsRead(candidate, *found, *work) || !work->Allow()) continue;
    --*pair_reads;
    AppendUnique(ReadRectifiedQr(gray, candidate), found);
  }
}

// Pass 2a: QR candidates from finder patterns (detect/qr_finder.h) in each region
// (smallest first) that is not one code already read, each candidate not read yet resampled
// upright and read: at most `max_reads` candidates per frame (and none once a live frame's
// time is up). Returns, for each region (in the order given), the number of finder patterns
// found in it, or -1 where it was not searched.
std::vector<int> ReadFinderCandidates(const cv::Mat& gray, const std::vector<cv::Rect>& regions,
                                      int max_reads, int* pair_reads, FrameWork* work,
                                      std::vector<MarkerObservation>* found) {
  // Smallest regions first: a whole close-up costs milliseconds (its binarization holds
  // many blobs) and small codes are the ones zxing misses on the whole frame.
  std::vector<int> order(regions.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int>(i);
  std::stable_sort(order.begin(), order.end(),
                   [&regions](int a, int b) { return regions[a].area() < regions[b].area(); });
  std::vector<int> finders_found(regions.size(), -1);
  int reads = 0;
  for (const int index : order) {
    const cv::Rect& region = regions[index];
    if (reads >= max_reads) break;
    if (work->RegionIsRead(region, *found)) continue;
    if (!work->Allow()) continue;
    const std::vector<QrFinderPattern> finders = FindQrFinderPatterns(gray, region);
    finders_found[index] = static_cast<int>(finders.size());
    const std::vector<QrCandidate> candidates = GroupQrFinders(finders, gray.size());
    for (const QrCandidate& candidate : candidates) {
      if (reads >= max_reads) break;
      if (CandidateIsRead(candidate, *found, *work)) continue;
      if (!work->Allow()) continue;
      ++reads;
      AppendUnique(ReadRectifiedQr(gray, candidate), found);
    }
    ReadFinderPairs(gray, finders, candidates, {}, pair_reads, work, found);
  }
  return finders_found;
}

// The bounding box of `corners` grown on every side by pad(its longer side) pixels, inside
// the image.
template <typename Pad>
cv::Rect PaddedBox(const Quad2d& corners_px, Pad pad_of, const cv::Size& image) {
  std::vector<cv::Point2f> corners;
  for (const Eigen::Vector2d& c : corners_px) corners.emplace_back(c.x(), c.y());
  const cv::Rect box = cv::boundingRect(corners);
  const int pad = pad_of(std::max(box.width, box.height));
  return cv::Rect(box.x - pad, box.y - pad, box.width + 2 * pad, box.height + 2 * pad) &
         cv::Rect(0, 0, image.width, image.height);
}

// The first finder triple found in `box` whose centre is within `max_offset_px` of `centre`,
// read rectified, or else what the pairs of its finders complete there (ReadFinderPairs, while
// `pair_reads` lasts); empty when there is none or it does not read.
std::vector<MarkerObservation> ReadFinderTripleNear(const cv::Mat& gray, const cv::Rect& box,
                                                    const Eigen::Vector2d& centre, double max_offset_px,
                                                    int* pair_reads, FrameWork* work,
                                                    const std::vector<MarkerObservation>& found) {
  const std::vector<QrFinderPattern> finders = FindQrFinderPatterns(gray, box);
  const std::vector<QrCandidate> triples = GroupQrFinders(finders, gray.size());
  const auto near = [&](const QrCandidate& candidate) {
    return (QuadCenter(candidate.corners_px) - centre).norm() <= max_offset_px;
  };
  for (const QrCandidate& candidate : triples) {
    if (near(candidate)) return ReadRectifiedQr(gray, candidate);
  }
  // No triple there: a pair of its finders and the third found where they put it.
  std::vector<MarkerObservation> read = found;
  ReadFinderPairs(gray, finders, triples, near, pair_reads, work, &read);
  return std::vector<MarkerObservation>(read.begin() + static_cast<std::ptrdiff_t>(found.size()), read.end());
}

// Pass 2a': QR candidates from the shared dark-quad stage (QrCandidatesFromQuads), for
// codes that no candidate region holds (a region is a blob's box, and a small code near
// other things is inside none of the few kept): best-shaped first, each not read yet is
// searched again for finders in its own box (padded by a quarter side: the quads' finders
// are a coarse binarization's) and read from there, or else from the quads' own corners;
// at most `max_reads` per frame (one larger than kFinderWorkSidePx is read from the quads'
// corners only).
constexpr double kMaxSearchedSidePx = kFinderWorkSidePx;
void ReadQuadCandidates(const cv::Mat& gray, double min_side_px, int max_reads, int* pair_reads,
                        FrameWork* work, std::vector<MarkerObservation>* found) {
  int reads = 0;
  for (const QrCandidate& candidate : QrCandidatesFromQuads(gray, FindDarkQuads(gray, min_side_px))) {
    if (reads >= max_reads) return;
    if (CandidateIsRead(candidate, *found, *work)) continue;
    if (!work->Allow()) continue;
    ++reads;
    const cv::Rect box = PaddedBox(
        candidate.corners_px, [](int side) { return static_cast<int>(std::ceil(0.25 * side)); }, gray.size());
    std::vector<MarkerObservation> read;
    // A candidate larger than the finder search's working size is read from the quads' own
    // corners only: a triple of distant finder-like quads would cost a search of most of the
    // frame (40 ms on a recall bench frame).
    if (QuadMeanSide(candidate.corners_px) <= kMaxSearchedSidePx) {
      read = ReadFinderTripleNear(gray, box, QuadCenter(candidate.corners_px),
                                  0.25 * QuadMeanSide(candidate.corners_px), pair_reads, work, *found);
    }
    if (read.empty()) read = ReadRectifiedQr(gray, candidate);
    AppendUnique(read, found);
  }
}

// Pass 2a'': small codes (about 18-80 px) whose finders neither the candidate regions nor
// the finder quads give: a dark quad that may be a whole code (SmallQrCodeQuads), not read
// yet, is searched for finders in its own box (padded by a third of its side, upscaled up
// to 4x) and the triple at its centre is read; then the quads of at most
// kMaxUnorientedSidePx with no such triple, ranked by the contrast of their known modules
// (UnorientedKnownModuleContrast: clutter quads come before a code in the stage's order, and
// took the reads from it), are read as module grids from their own corners
// (detect/qr_modules.h), at most kMaxUnorientedReads per frame; at most `max_boxes` boxes
// per frame. Then the same for the quads with one mostly light side (ThinSideSmallQrCodeQuads),
// within their own bounds (kMaxThinSideBoxes, kMaxThinSideReads).
void ReadSmallCodeQuads(const cv::Mat& gray, double min_side_px, int max_boxes, int* pair_reads,
                        FrameWork* work, std::vector<MarkerObservation>* found) {
  struct Unoriented {
    Quad2d corners_px;
    double contrast;
  };
  // Each quad's box searched for a finder triple; the quads with none kept for grid reads.
  const auto search_boxes = [&](const std::vector<DarkQuad>& quads, std::vector<Unoriented>* unoriented) {
    for (const DarkQuad& quad : quads) {
      QrCandidate as_code;
      as_code.corners_px = quad.corners_px;
      if (CandidateIsRead(as_code, *found, *work) || !work->Allow()) continue;
      const cv::Rect box = PaddedBox(
          quad.corners_px, [](int side) { return static_cast<int>(std::ceil(side / 3.0)); }, gray.size());
      const double side = QuadMeanSide(quad.corners_px);
      const std::vector<MarkerObservation> r = ReadFinderTripleNear(
          gray, box, QuadCenter(quad.corners_px), kSmallCodeCentreFraction * side, pair_reads, work, *found);
      AppendUnique(r, found);
      // No finders (an oblique code's finders are foreshortened to a module or so of light
      // ring): the module grid read from the quad's own corners, in any orientation, below.
      if (r.empty() && side <= kMaxUnorientedSidePx) {
        unoriented->push_back({quad.corners_px, UnorientedKnownModuleContrast(gray, quad.corners_px)});
      }
    }
  };
  // The best `max_reads` by known-module contrast read as module grids. With `raw_contrast`
  // (the contrast field is UnorientedKnownModuleContrast) a quad under kMinUnorientedRawContrast
  // takes its read but is not handed to the reader, which would read nothing: it would rank
  // the same hypotheses again only to find that out.
  const auto read_grids = [&](std::vector<Unoriented>* unoriented, int max_reads, bool raw_contrast) {
    std::stable_sort(unoriented->begin(), unoriented->end(),
                     [](const Unoriented& a, const Unoriented& b) { return a.contrast > b.contrast; });
    int reads = 0;
    for (const Unoriented& u : *unoriented) {
      if (reads >= max_reads) break;
      QrCandidate as_code;
      as_code.corners_px = u.corners_px;
      if (CandidateIsRead(as_code, *found, *work) || !work->Allow()) continue;
      ++reads;
      if (raw_contrast && !(u.contrast >= kMinUnorientedRawContrast)) continue;
      AppendUnique(ReadUnorientedQrModuleGrid(gray, u.corners_px), found);
    }
  };
  const std::vector<DarkQuad>& quads = FindDarkQuads(gray, min_side_px);
  const std::vector<DarkQuad> small = SmallQrCodeQuads(quads, max_boxes);
  std::vector<Unoriented> unoriented;
  search_boxes(small, &unoriented);
  read_grids(&unoriented, kMaxUnorientedReads, true);
  // Codes with a mostly light side, after the others and within their own bounds.
  std::vector<Unoriented> thin_unoriented;
  const std::vector<DarkQuad> thin = ThinSideSmallQrCodeQuads(quads, small, kMaxThinSideBoxes);
  search_boxes(thin, &thin_unoriented);
  read_grids(&thin_unoriented, kMaxThinSideReads, true);
  // Codes whose modules fall apart at every level, last and within their own bounds.
  std::vector<DarkQuad> taken = small;
  taken.insert(taken.end(), thin.begin(), thin.end());
  // No finder search in their boxes: their finders are what fell apart. Ranked by the
  // evidence (in the contrast field).
  std::vector<Unoriented> merged_unoriented;
  for (const DarkQuad& quad : MergedFragmentQrCodeQuads(quads, taken, kMaxMergedBoxes)) {
    const double evidence = UnorientedCodeEvidence(gray, quad.corners_px);
    if (evidence >= kMinMergedCodeEvidence) merged_unoriented.push_back({quad.corners_px, evidence});
  }
  read_grids(&merged_unoriented, kMaxMergedReads, false);
}

class QrDetector : public MarkerDetector {
 public:
  explicit QrDetector(const DetectorOptions& options) : options_(options) {}

  std::vector<std::string> Families() const override { return {kFamilyQr}; }
  int SkippedAttempts() const override { return skipped_; }
  // The first pass is zxing on the whole frame; the second passes search it again (finders,
  // quads, small codes, crops): far more time, most of it in clutter and, beside other
  // families, at their codes.
  bool SecondPassesLast() const override { return true; }

  std::vector<MarkerObservation> Detect(const cv::Mat& image) override {
    const cv::Mat gray = ToGray8(image);
    FrameWork work(options_.live_budget_ms, ReadByOthers());
    std::vector<MarkerObservation> found = FirstPass(gray);
    if (options_.second_pass) SecondPasses(gray, &work, &found);
    skipped_ = work.skipped();
    return KeepValidObservations(gray, Refine(gray, found), options_.min_side_px);
  }

  std::vector<MarkerObservation> DetectFirstPass(const cv::Mat& image) override {
    staged_.gray = ToGray8(image);
    staged_.raw = FirstPass(staged_.gray);
    staged_.refined = Refine(staged_.gray, staged_.raw);
    staged_.started = true;
    skipped_ = 0;
    return KeepValidObservations(staged_.gray, staged_.refined, options_.min_side_px);
  }

  std::vector<MarkerObservation> DetectSecondPasses() override {
    staged_.CheckStarted();
    FrameWork work(options_.live_budget_ms, ReadByOthers());
    std::vector<MarkerObservation> found = staged_.raw;
    if (options_.second_pass) SecondPasses(staged_.gray, &work, &found);
    skipped_ = work.skipped();
    const cv::Mat& gray = staged_.gray;
    const bool refine = options_.refine_corners;
    return staged_.KeptRefinedWith(
        found,
        [&gray, refine](MarkerObservation* obs) {
          if (refine) RefineQrCorners(gray, obs);
        },
        options_.min_side_px);
  }

 private:
  static std::vector<MarkerObservation> FirstPass(const cv::Mat& gray) {
    ZxingPass pass;
    pass.min_dynamic_range =
        NoiseAwareThreshold(kZxingMinDynamicRange, NoiseSigma(gray), kMinDynamicRangePerSigma);
    return ReadWithZxing(gray, ZxingSymbology::kQrCode, pass);
  }

  void SecondPasses(const cv::Mat& gray, FrameWork* work, std::vector<MarkerObservation>* found) {
    const std::vector<CropAttempt> attempts = {
        [](const cv::Mat& crop) { return ReadInverted(crop); },
        [](const cv::Mat& crop) { return ReadUpscaled(crop); },
        // WeChat costs milliseconds per crop: only for close-ups, where the crop is the
        // whole image (pass 1 and the cheap attempts read codes in larger frames). Not on a
        // larger frame whose candidate region, padded and clipped, is the whole frame (a blob
        // of clutter across it): 750 ms of CPU on an empty 1280x960 issue frame (seed 30,
        // frame 129) before.
        [this, full = gray.size()](const cv::Mat& crop) {
          return options_.close_up && crop.size() == full && MayBeCloseUp(full)
                     ? ReadWeChat(crop)
                     : std::vector<MarkerObservation>{};
        },
    };
    const std::vector<cv::Rect> regions = SecondPassRegions(gray, options_.max_candidates, options_.close_up);
    int pair_reads = kMaxPairReads;
    const std::vector<int> finders_found =
        ReadFinderCandidates(gray, regions, options_.max_qr_finder_candidates, &pair_reads, work, found);
    ReadQuadCandidates(gray, options_.min_side_px, options_.max_qr_finder_candidates, &pair_reads, work,
                       found);
    ReadSmallCodeQuads(gray, options_.min_side_px, kMaxSmallCodeBoxes, &pair_reads, work, found);
    // A region searched for finders with none found holds no dark-on-light code that zxing
    // would find either (it needs three finders): only the inverted crop (a light-on-dark
    // code has light finders; the search finds them in most such codes, but not in all:
    // DetectQr.InvertedCodeWithoutFindersIsRead) and WeChat are tried there.
    const std::vector<CropAttempt> without_finders = {attempts[0], attempts[2]};
    for (size_t i = 0; i < regions.size(); ++i) {
      RunSecondPass(gray, {regions[i]}, finders_found[i] == 0 ? without_finders : attempts, work, found);
    }
  }

  // The corners refined (the quality is the refinement's inlier fraction, 0 if it failed).
  std::vector<MarkerObservation> Refine(const cv::Mat& gray, std::vector<MarkerObservation> found) const {
    if (options_.refine_corners) {
      for (MarkerObservation& obs : found) RefineQrCorners(gray, &obs);
    }
    return found;
  }

 private:
  static std::vector<MarkerObservation> ReadInverted(const cv::Mat& crop) {
    cv::Mat inverted;
    cv::bitwise_not(crop, inverted);
    return ReadWithZxing(inverted, ZxingSymbology::kQrCode, ZxingPass{});
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
  int skipped_ = 0;
  StagedDetection staged_;
  cv::wechat_qrcode::WeChatQRCode wechat_;
  cv::QRCodeDetector corner_finder_;
};

}  // namespace

std::unique_ptr<MarkerDetector> CreateQrDetector(const DetectorOptions& options) {
  return std::make_unique<QrDetector>(options);
}

}  // namespace waymark
