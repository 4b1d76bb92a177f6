#include "detect/datamatrix.h"

#include <dmtx.h>

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <utility>
#include <vector>

#include "detect/common.h"
#include "detect/datamatrix_ecc.h"
#include "detect/quads.h"
#include "detect/zxing.h"

namespace waymark {
namespace {

constexpr int kMaxUpscaleSidePx = 240;  // only small crops are upscaled
// Candidates given the patch test per candidate given the decoders (pass 1), and the timing
// evidence (DataMatrixPatchPlausible) that puts a patch among the first decoded.
constexpr int kPatchTestsPerDecode = 4;
constexpr int kTimingFirstRuns = 3;
// A patch goes to the decoders only when one of its sides shows a timing pattern: at least
// the dark modules of the shortest DataMatrix side (the 8 x 18 symbol's: 8 modules, 4 dark) along
// one of its timing lines (DataMatrixTimingSideRuns). On the recall bench's 900 frames (issue
// and hard renders, seeds 1-3) every one of the 571 patches read had a side with at least 4;
// 72 % of the 7826 decoded patches that read nothing had none, and cost 54 % of the decoders'
// time on them (about 2.9 ms per frame, libdmtx's seeds failing on clutter).
constexpr int kMinTimingSideRuns = 4;
// A patch with more than this fraction of the places along one of its legs without a light
// quiet zone outside (DataMatrixQuietZoneDark) goes to no decoder. On the recall bench's 900
// frames (issue and hard renders, seeds 1-3; 514 patches read, 10815 not) 512 of the patches
// read had at most 4 of 16 places dark, one 8 and one 10 (a misread, `F115` of hard seed 2); 55 %
// of the patches not read had more than 8. The patches turned away make room for others
// within max_datamatrix_candidates.
constexpr double kQuietMaxDark = 0.5;
// libdmtx scans an image at 1/shrink resolution, shrink the smallest integer that brings
// its longer side to at most this: the work of a full scan is bounded by the image alone.
constexpr int kDmtxMaxScanPx = 320;

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

  int SkippedAttempts() const override { return skipped_; }

  std::vector<MarkerObservation> Detect(const cv::Mat& image) override {
    const cv::Mat gray = ToGray8(image);
    FrameWork work(options_.live_budget_ms, ReadByOthers());
    std::vector<Eigen::Vector2d> seen;
    std::vector<MarkerObservation> found = FirstPass(gray, &work, &seen);
    if (options_.second_pass) SecondPasses(gray, seen, &work, &found);
    skipped_ = work.skipped();
    return FinishObservations(gray, found, options_.refine_corners, options_.min_side_px);
  }

  std::vector<MarkerObservation> DetectFirstPass(const cv::Mat& image) override {
    staged_.gray = ToGray8(image);
    FrameWork work(options_.live_budget_ms, ReadByOthers());
    staged_seen_.clear();
    staged_.raw = FirstPass(staged_.gray, &work, &staged_seen_);
    staged_.refined = RefineObservations(staged_.gray, staged_.raw, options_.refine_corners);
    staged_.started = true;
    skipped_ = work.skipped();
    return KeepValidObservations(staged_.gray, staged_.refined, options_.min_side_px);
  }

  std::vector<MarkerObservation> DetectSecondPasses() override {
    staged_.CheckStarted();
    FrameWork work(options_.live_budget_ms, ReadByOthers());
    std::vector<MarkerObservation> found = staged_.raw;
    if (options_.second_pass) SecondPasses(staged_.gray, staged_seen_, &work, &found);
    skipped_ = work.skipped();
    const cv::Mat& gray = staged_.gray;
    const bool refine = options_.refine_corners;
    return staged_.KeptRefinedWith(
        found,
        [&gray, refine](MarkerObservation* obs) { *obs = RefineObservations(gray, {*obs}, refine).front(); },
        options_.min_side_px);
  }

 private:
  // *seen: the centres of the candidates that passed the timing-side test and whose patch passed
  // RectifyDataMatrixCandidate's tests (something DataMatrix-like), for the second pass.
  std::vector<MarkerObservation> FirstPass(const cv::Mat& gray, FrameWork* work,
                                           std::vector<Eigen::Vector2d>* seen) const {
    std::vector<MarkerObservation> found;
    // Pass 1: Waymark's own candidates (the L finder and the timing pattern), each rectified
    // onto its own small patch (detect/quads.h) and tested there; of those that pass, the
    // ones whose timing pattern alternates clearly go to the decoders first, at most
    // max_datamatrix_candidates decoded per frame. The cheap patch test runs on at most
    // kPatchTestsPerDecode times as many candidates (clutter that fails it costs a warp).
    std::vector<DataMatrixPatch> patches;
    std::vector<int> patch_index;
    std::vector<DarkQuad> quads = FindDarkQuads(gray, options_.min_side_px);
    const std::vector<DarkQuad> coarse = FindCoarseDarkQuads(gray, options_.min_side_px);
    quads.insert(quads.end(), coarse.begin(), coarse.end());
    const std::vector<DataMatrixCandidate> candidates =
        DataMatrixCandidates(quads, kPatchTestsPerDecode * options_.max_datamatrix_candidates);
    // 1: its patch failed the patch test or the decoders; 2: it failed the timing-side test.
    std::vector<char> failed(candidates.size(), 0);
    for (size_t ci = 0; ci < candidates.size(); ++ci) {
      const DataMatrixCandidate& candidate = candidates[ci];
      // Another family's code there (an AprilTag's border or a QR code's finder corner makes
      // an L): not a symbol, and neither tested nor refitted.
      if (AnyObservationAt(work->read_by_others(), QuadCenter(candidate.corners_px))) continue;
      bool timing_side = true;
      std::optional<DataMatrixPatch> patch = TestedPatch(gray, candidate, seen, &timing_side);
      if (patch) {
        // No quiet zone along most of a leg: an L-shaped part of something larger.
        if (patch->quiet_zone_dark > kQuietMaxDark) continue;
        patches.push_back(std::move(*patch));
        patch_index.push_back(static_cast<int>(ci));
      } else {
        failed[ci] = timing_side ? 1 : 2;
      }
    }
    std::vector<size_t> order(patches.size());
    for (size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::stable_sort(order.begin(), order.end(), [&patches](size_t a, size_t b) {
      return (patches[a].timing_runs >= kTimingFirstRuns) > (patches[b].timing_runs >= kTimingFirstRuns);
    });
    int decoded = 0;
    for (const size_t pi : order) {
      const DataMatrixPatch& patch = patches[pi];
      if (decoded >= options_.max_datamatrix_candidates) break;
      if (AnyObservationAt(found, QuadCenter(patch.candidate.corners_px)) || !work->Allow()) continue;
      ++decoded;
      const std::vector<MarkerObservation> read = DecodeDataMatrixPatch(patch);
      if (read.empty()) failed[patch_index[pi]] = 1;
      AppendUnique(read, &found);
    }
    // Candidates whose patch failed the test or the decoders, best first: their sides refitted
    // to the symbol's outer module rows in the patch (RefitDataMatrixCandidate: a hull's quad
    // that took in the quiet zone or stopped a module short), tested and read again, within
    // the same decode bound. Not those without a timing pattern along any side (failed 2):
    // traced on the recall bench's 900 frames (issue and hard renders, seeds 1-3), 89 % of the
    // refits (about 14 of the 16 per frame, each a warp) were of such candidates and none read,
    // while the 11 symbols read from a refit all came from candidates with one.
    int refits = 0;
    for (size_t ci = 0; ci < candidates.size() && refits < options_.max_datamatrix_candidates &&
                        decoded < options_.max_datamatrix_candidates;
         ++ci) {
      if (failed[ci] != 1) continue;
      if (AnyObservationAt(found, QuadCenter(candidates[ci].corners_px))) continue;
      ++refits;
      const std::optional<DataMatrixCandidate> refit = RefitDataMatrixCandidate(gray, candidates[ci]);
      if (!refit) continue;
      std::optional<DataMatrixPatch> patch = TestedPatch(gray, *refit, seen, nullptr);
      if (!patch || patch->quiet_zone_dark > kQuietMaxDark || !work->Allow()) continue;
      ++decoded;
      AppendUnique(DecodeDataMatrixPatch(*patch), &found);
    }
    return found;
  }

  // The candidate's patch when it shows a timing pattern along one side (kMinTimingSideRuns;
  // *timing_side, when not null, says whether it did) and passes RectifyDataMatrixCandidate's
  // tests (then its centre is appended to *seen).
  static std::optional<DataMatrixPatch> TestedPatch(const cv::Mat& gray, const DataMatrixCandidate& candidate,
                                                    std::vector<Eigen::Vector2d>* seen, bool* timing_side) {
    // The timing side first: it samples the frame where the patch's pixels would be, without
    // the warp (most candidates fail it).
    const bool shows =
        DataMatrixTimingSideRuns(gray, candidate.corners_px, kMinTimingSideRuns) >= kMinTimingSideRuns;
    if (timing_side != nullptr) *timing_side = shows;
    if (!shows) return std::nullopt;
    std::optional<DataMatrixPatch> patch = RectifyDataMatrixCandidate(gray, candidate);
    if (patch) seen->push_back(QuadCenter(candidate.corners_px));
    return patch;
  }

  void SecondPasses(const cv::Mat& gray, const std::vector<Eigen::Vector2d>& seen, FrameWork* work,
                    std::vector<MarkerObservation>* found) const {
    // Pass 2, for symbols whose L the candidate stage did not see or whose patch did not read
    // (glare, a bar across the L, a symbol touching other dark things): zxing on the candidate
    // regions holding no symbol yet, then, where the region holds the centre of a candidate
    // that passed the timing-side and patch tests (FirstPass's *seen: something
    // DataMatrix-like), on small ones upscaled. Traced on the recall bench's 900 frames (issue and hard
    // renders, seeds 1-3) before issue 14's sixth round, when every small region was also read upscaled: 6502
    // upscaled reads (1.0 ms per frame) read nothing; the plain reads (0.7 ms per frame) read 3 symbols.
    // Limiting the plain reads the same way lost 11 of the 26 symbols read on the datamatrix-1 photos.
    const CropAttempt plain = [](const cv::Mat& crop) {
      return ReadWithZxing(crop, ZxingSymbology::kDataMatrix, ZxingPass{});
    };
    const std::vector<CropAttempt> plain_only = {plain};
    const std::vector<CropAttempt> plain_then_upscaled = {
        plain, [](const cv::Mat& crop) { return ReadUpscaled(crop); }};
    for (const cv::Rect& region : SecondPassRegions(gray, options_.max_candidates, options_.close_up)) {
      const bool something = std::any_of(seen.begin(), seen.end(), [&region](const Eigen::Vector2d& c) {
        return c.x() >= region.x && c.y() >= region.y && c.x() < region.x + region.width &&
               c.y() < region.y + region.height;
      });
      RunSecondPass(gray, {region}, something ? plain_then_upscaled : plain_only, work, found);
    }
  }

  static std::vector<MarkerObservation> ReadUpscaled(const cv::Mat& crop) {
    if (std::max(crop.cols, crop.rows) > kMaxUpscaleSidePx) return {};
    cv::Mat big;
    cv::resize(crop, big, cv::Size(), 2.0, 2.0, cv::INTER_CUBIC);
    std::vector<MarkerObservation> found = ReadWithZxing(big, ZxingSymbology::kDataMatrix, ZxingPass{});
    MapFromCrop(cv::Point(0, 0), 2.0, &found);
    return found;
  }

  DetectorOptions options_;
  int skipped_ = 0;
  StagedDetection staged_;
  std::vector<Eigen::Vector2d> staged_seen_;  // FirstPass's *seen for the staged second pass
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

// libdmtx's decode of `region`, or nullptr; also nullptr (the message destroyed) when its
// codewords after error correction are not a Reed-Solomon codeword of the symbol (libdmtx 0.7.7
// lets some through: detect/datamatrix_ecc.h).
DmtxMessage* DecodeVerifiedRegion(DmtxDecode* decode, DmtxRegion* region) {
  DmtxMessage* message = dmtxDecodeMatrixRegion(decode, region, DmtxUndefined);
  if (message == nullptr) return nullptr;
  const std::vector<std::uint8_t> codewords(message->code, message->code + message->codeSize);
  const int size_idx = region->sizeIdx;
  if (!DataMatrixCodewordsValid(codewords, dmtxGetSymbolAttribute(DmtxSymAttribSymbolDataWords, size_idx),
                                dmtxGetSymbolAttribute(DmtxSymAttribInterleavedBlocks, size_idx),
                                dmtxGetSymbolAttribute(DmtxSymAttribBlockErrorWords, size_idx))) {
    dmtxMessageDestroy(&message);
    return nullptr;
  }
  return message;
}

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
  const int shrink = std::max(1, (std::max(gray.cols, gray.rows) + kDmtxMaxScanPx - 1) / kDmtxMaxScanPx);
  scan.decode = dmtxDecodeCreate(scan.image, shrink);
  if (scan.decode == nullptr) return out;
  // No deadline unless one is given: a timeout would make the result depend on the machine.
  const bool timed = std::isfinite(timeout_ms);
  if (timed && timeout_ms < 1.0) return out;  // libdmtx's timeout granularity is 1 ms
  DmtxTime deadline =
      timed ? dmtxTimeAdd(dmtxTimeNow(), static_cast<long>(std::ceil(timeout_ms))) : DmtxTime{};
  while (DmtxRegion* region = dmtxRegionFindNext(scan.decode, timed ? &deadline : nullptr)) {
    if (DmtxMessage* message = DecodeVerifiedRegion(scan.decode, region)) {
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

namespace {

// The rectified patch of a candidate: the symbol's side and the quiet zone around it.
constexpr int kPatchMinSidePx = 48;
constexpr int kPatchMaxSidePx = 140;
constexpr double kPatchMarginFraction = 0.3;
// Seeds on each of the L's two outer edges (fractions of the side), and across the edge
// (pixels): the candidate's corners are about a pixel off. The symbols read on 900 recall-bench
// frames (issue and hard renders, seeds 1-3) needed 9 different seeds, 462 of 468 one at the
// middle of the legs; a candidate that is no symbol (about 10 per frame) fails all 18, about
// 0.8 ms. So the seeds at 0.3 and 0.7 of the side are tried only on patches whose timing pattern
// alternates clearly: two adjacent sides with at least 4 dark runs each (timing_runs; the dark
// modules of the shortest DataMatrix side; 3 before issue 14's sixth round). Traced on those
// 900 frames: each of the 7 symbols (of 571) these seeds read had 4 or more, while the 907
// patches with 3 that passed the timing-side test (DataMatrixTimingSideRuns) read nothing and
// paid all 18 seeds (1.3 ms per frame in all, at load 4-6).
constexpr double kSeedFractions[] = {0.5, 0.3, 0.7};
constexpr int kSeedFractionsForAll = 1;
constexpr int kAllSeedsTimingRuns = 4;
constexpr int kSeedOffsetsPx[] = {0, -1, 1};
// A decoded symbol must lie where its candidate is (fraction of the candidate's side) and be
// of about its size.
constexpr double kMaxCentreOffset = 0.2;
constexpr double kMaxSizeRatio = 1.4;
// libdmtx's edge-length bounds on a patch (DmtxPropEdgeMin / DmtxPropEdgeMax, in patch pixels,
// as fractions of the symbol's side there): its edge trail is dropped when the trail's bounding
// box is under 2 edgeMin^2 (any shape; an upright square L spans about side^2, the 8 x 18
// symbol's about 0.86 side^2 at its mean side, both above 0.5 side^2) or its diagonal over 1.56
// edgeMax (3.1 sides: the whole patch, quiet zone included, is 2.3). Both lie beyond the 1.4x
// size bound a read must meet anyway (kMaxSizeRatio), so no symbol the candidate can give is
// turned away; what goes is clutter's short edges and trails that wander off the patch. Issue 14's
// tenth round: the same detections on the recall bench (issue seeds 1-3, DataMatrix-only issue
// seeds 4-5 and hard seeds 1-3), libdmtx's seeds 4 % fewer instructions.
constexpr double kDmtxEdgeMinFraction = 0.5;
constexpr double kDmtxEdgeMaxFactor = 2.0;
// DataMatrixPatchPlausible (detect/quads.h). On two recall-bench sets (issue scenario seed
// 2, hard renders seed 3: 131 candidates read, 3198 not) every candidate read had a contrast
// >= 29 gray levels (25 for a low-light symbol of hard seed 1) and 31-62 % of its inside
// dark; these bounds, with a margin, turned away 11 % of the candidates not read (17-19 % of
// their libdmtx time: even boxes, frames, no contrast) and none read. A third test, at most
// 35 % dark just outside each leg (the quiet zone), turned away two thirds but also six small
// symbols of hard seeds 1 and 2 (26-84 px, their candidates' legs a few pixels off): not kept.
constexpr int kPlausibleSamples = 40;
constexpr double kPlausibleMinContrast = 8.0;
constexpr double kPlausibleInsideDark[2] = {0.2, 0.8};
// The timing test: lines 3 % of the side outside to 8 % inside each side (within the
// first module row of symbols up to 12 x 12 modules, in the first two up to 26 x 26), 80
// samples each; a patch with fewer than 2 dark runs along both sides of every adjacent pair
// is no symbol (issue-scenario seed 1: 2 of 270 patches read, 945 of 2040 not read).
// Patches with at least kTimingFirstRuns go to the decoders first.
constexpr double kTimingDepths[] = {-0.03, -0.015, 0.0, 0.015, 0.03, 0.05, 0.08};
constexpr int kTimingSamples = 80;
constexpr int kTimingMinRuns = 2;
// DataMatrixQuietZoneDark (detect/quads.h).
constexpr int kQuietPlaces = 16;
constexpr double kQuietProfileOutside = 0.15, kQuietProfileInside = 0.10;  // fractions of the side
constexpr double kQuietModuleFraction = 0.04;
constexpr double kQuietMinStep = 0.25;

// RefitDataMatrixCandidate: lines parallel to each side over its middle (kRefitSpan of the
// side off each end), searched from kRefitInside of the side inside to kRefitOutside outside;
// a line crosses the symbol when at least kRefitMinDark of it is dark.
constexpr double kRefitSpan = 0.15;
constexpr double kRefitInside = 0.25, kRefitOutside = 0.25;
constexpr double kRefitMinDark = 0.05;
constexpr double kRefitMinSize = 0.6;
constexpr double kRefitMinMovePx = 1.0;

// True if `text` holds a control character other than tab, line feed or carriage return.
bool HasControlBytes(const std::string& text) {
  return std::any_of(text.begin(), text.end(), [](char c) {
    const unsigned char u = static_cast<unsigned char>(c);
    return u < 0x20 && u != '\t' && u != '\n' && u != '\r';
  });
}

Eigen::Vector2d Apply(const cv::Matx33d& h, const Eigen::Vector2d& p) {
  const cv::Vec3d q = h * cv::Vec3d(p.x(), p.y(), 1.0);
  return Eigen::Vector2d(q[0] / q[2], q[1] / q[2]);
}

// A patch's gray level at (x, y), nearest pixel, clamped to the patch.
double PatchAt(const cv::Mat& patch, double x, double y) {
  const int c = std::clamp(static_cast<int>(RoundHalfAwayFromZero(x)), 0, patch.cols - 1);
  const int r = std::clamp(static_cast<int>(RoundHalfAwayFromZero(y)), 0, patch.rows - 1);
  return static_cast<double>(patch.at<uint8_t>(r, c));
}

// The L's gray level: the median just inside its two legs (3 % of the side in); the light
// modules': the upper decile of a 9 x 9 grid over the middle 70 % of the symbol.
struct PatchLevels {
  double dark = 0.0;
  double light = 0.0;
  std::vector<double> inside;  // the 9 x 9 grid's samples (partially sorted)
};
// `at(x, y)`: the patch's gray level at patch pixel (x, y) (PatchAt, or the frame sampled where
// the patch's pixel would be, as DataMatrixTimingSideRuns does).
template <typename At>
PatchLevels LegAndLightLevelsWith(const At& at, double m, double s) {
  std::vector<double> leg, inside;
  for (int k = 0; k < kPlausibleSamples; ++k) {
    const double t = 0.08 + 0.84 * k / (kPlausibleSamples - 1);
    leg.push_back(at(m + 0.03 * s, m + t * s));
    leg.push_back(at(m + t * s, m + s - 1 - 0.03 * s));
  }
  for (int i = 0; i < 9; ++i) {
    for (int j = 0; j < 9; ++j)
      inside.push_back(at(m + s * (0.15 + 0.7 * i / 8.0), m + s * (0.15 + 0.7 * j / 8.0)));
  }
  std::nth_element(leg.begin(), leg.begin() + leg.size() / 2, leg.end());
  std::nth_element(inside.begin(), inside.begin() + inside.size() * 9 / 10, inside.end());
  const double dark = leg[leg.size() / 2], light = inside[inside.size() * 9 / 10];
  return {dark, light, std::move(inside)};
}
PatchLevels LegAndLightLevels(const cv::Mat& patch, double m, double s) {
  return LegAndLightLevelsWith([&patch](double x, double y) { return PatchAt(patch, x, y); }, m, s);
}

// The most dark runs (gray level under `threshold`) along any of the timing lines of side
// `which` (0 top, 1 right, 2 bottom, 3 left) of a patch with the symbol's `s` px at (m, m):
// lines parallel to the side at kTimingDepths of the side inside it (the candidate's far
// corner can be a few pixels off), kTimingSamples samples each over 4-96 % of it.
// `enough`: the first line with at least that many runs ends the search (its count is returned).
template <typename At>
int SideDarkRunsWith(const At& at, double m, double s, double threshold, int which,
                     int enough = std::numeric_limits<int>::max()) {
  int most = 0;
  long done[std::size(kTimingDepths)];  // the pixel row (column) of each line sampled so far
  size_t lines = 0;
  for (const double depth : kTimingDepths) {
    // A line on the same pixel row (column) as one already sampled gives the same runs: the
    // samples are the nearest pixels.
    const double in = depth * s;
    const long fixed = RoundHalfAwayFromZero(which == 0   ? m + in
                                             : which == 1 ? m + s - 1 - in
                                             : which == 2 ? m + s - 1 - in
                                                          : m + in);
    if (std::find(done, done + lines, fixed) != done + lines) continue;
    done[lines++] = fixed;
    int runs = 0;
    bool previous = false;
    for (int k = 0; k < kTimingSamples; ++k) {
      const double t = 0.04 + 0.92 * k / (kTimingSamples - 1);
      const double along = t * s;
      const double g = which == 0   ? at(m + along, m + in)
                       : which == 1 ? at(m + s - 1 - in, m + along)
                       : which == 2 ? at(m + along, m + s - 1 - in)
                                    : at(m + in, m + along);
      const bool is_dark = g < threshold;
      runs += is_dark && !previous;
      previous = is_dark;
    }
    most = std::max(most, runs);
    if (most >= enough) break;
  }
  return most;
}
int SideDarkRuns(const cv::Mat& patch, double m, double s, double threshold, int which) {
  return SideDarkRunsWith([&patch](double x, double y) { return PatchAt(patch, x, y); }, m, s, threshold,
                          which);
}

// The rectified patch's geometry for a candidate (RectifyDataMatrixCandidate): the symbol's side
// (kPatchMinSidePx-kPatchMaxSidePx), the margin, and the homography from patch to frame pixels.
struct PatchGeometry {
  int side = 0;
  int margin = 0;
  cv::Matx33d patch_to_frame;
};
PatchGeometry PatchGeometryOf(const Quad2d& corners_px) {
  PatchGeometry out;
  out.side =
      std::clamp(static_cast<int>(std::lround(QuadMeanSide(corners_px))), kPatchMinSidePx, kPatchMaxSidePx);
  out.margin = static_cast<int>(std::lround(kPatchMarginFraction * out.side));
  const double lo = out.margin - 0.5,
               hi = out.margin + out.side - 0.5;  // outer edges, pixel-centre coordinates
  std::vector<cv::Point2f> patch_pts = {
      {float(lo), float(lo)}, {float(hi), float(lo)}, {float(hi), float(hi)}, {float(lo), float(hi)}};
  std::vector<cv::Point2f> frame_pts;
  for (const Eigen::Vector2d& c : corners_px) frame_pts.emplace_back(float(c.x()), float(c.y()));
  out.patch_to_frame = cv::getPerspectiveTransform(patch_pts, frame_pts);
  return out;
}

}  // namespace

bool DataMatrixPatchPlausible(const cv::Mat& patch, int margin, int side, int* timing_runs) {
  if (timing_runs != nullptr) *timing_runs = 0;
  CV_Assert(patch.type() == CV_8UC1);
  const double m = margin, s = side;
  const PatchLevels levels = LegAndLightLevels(patch, m, s);
  const double contrast = levels.light - levels.dark;
  if (contrast < kPlausibleMinContrast) return false;
  const double threshold = levels.dark + 0.5 * contrast;
  // The data modules mix dark and light.
  const std::vector<double>& inside = levels.inside;
  const double inside_dark =
      std::count_if(inside.begin(), inside.end(), [threshold](double g) { return g < threshold; }) /
      static_cast<double>(inside.size());
  if (inside_dark < kPlausibleInsideDark[0] || inside_dark > kPlausibleInsideDark[1]) return false;
  // The timing pattern: two adjacent sides alternate (the candidate's orientation may be a
  // quarter turn off: libdmtx, seeded on any leg, still finds the L). A side's evidence is the
  // most dark runs along any of its lines (SideDarkRuns), the patch's the larger of the
  // smaller of two adjacent sides'.
  const int runs[4] = {SideDarkRuns(patch, m, s, threshold, 0), SideDarkRuns(patch, m, s, threshold, 1),
                       SideDarkRuns(patch, m, s, threshold, 2), SideDarkRuns(patch, m, s, threshold, 3)};
  int evidence = 0;
  for (int k = 0; k < 4; ++k) evidence = std::max(evidence, std::min(runs[k], runs[(k + 1) % 4]));
  if (timing_runs != nullptr) *timing_runs = evidence;
  return evidence >= kTimingMinRuns;
}

int DataMatrixTimingSideRuns(const cv::Mat& gray, const Quad2d& corners_px, int enough) {
  CV_Assert(gray.type() == CV_8UC1 && !gray.empty());
  // The patch RectifyDataMatrixCandidate would warp, sampled where its pixels are: each
  // sample's patch pixel (nearest, clamped to the patch, as PatchAt) mapped into the frame and
  // interpolated there (bilinear, the frame's border replicated, as the warp).
  const PatchGeometry geometry = PatchGeometryOf(corners_px);
  const int size = geometry.side + 2 * geometry.margin;
  const cv::Matx33d& h = geometry.patch_to_frame;
  int last_c = -1, last_r = -1;  // the last sample's patch pixel and value (lines revisit a pixel)
  double last = 0.0;
  const auto at = [&](double x, double y) {
    const int c = std::clamp(static_cast<int>(RoundHalfAwayFromZero(x)), 0, size - 1);
    const int r = std::clamp(static_cast<int>(RoundHalfAwayFromZero(y)), 0, size - 1);
    if (c == last_c && r == last_r) return last;
    last_c = c;
    last_r = r;
    const cv::Vec3d q = h * cv::Vec3d(c, r, 1.0);
    const double fx = std::clamp(q[0] / q[2], 0.0, gray.cols - 1.0),
                 fy = std::clamp(q[1] / q[2], 0.0, gray.rows - 1.0);
    const int x0 = std::max(0, std::min(static_cast<int>(fx), gray.cols - 2));
    const int y0 = std::max(0, std::min(static_cast<int>(fy), gray.rows - 2));
    const int x1 = std::min(x0 + 1, gray.cols - 1), y1 = std::min(y0 + 1, gray.rows - 1);
    const double ax = fx - x0, ay = fy - y0;
    const double top = (1 - ax) * gray.at<uint8_t>(y0, x0) + ax * gray.at<uint8_t>(y0, x1);
    const double bottom = (1 - ax) * gray.at<uint8_t>(y1, x0) + ax * gray.at<uint8_t>(y1, x1);
    last = std::round((1 - ay) * top + ay * bottom);
    return last;
  };
  const double m = geometry.margin, s = geometry.side;
  const PatchLevels levels = LegAndLightLevelsWith(at, m, s);
  if (levels.light - levels.dark < kPlausibleMinContrast) return 0;
  const double threshold = levels.dark + 0.5 * (levels.light - levels.dark);
  int most = 0;
  for (int which = 0; which < 4 && most < enough; ++which)
    most = std::max(most, SideDarkRunsWith(at, m, s, threshold, which, enough));
  return most;
}

double DataMatrixQuietZoneDark(const cv::Mat& patch, int margin, int side) {
  CV_Assert(patch.type() == CV_8UC1);
  const auto at = [&patch](double x, double y) { return PatchAt(patch, x, y); };
  const double m = margin, s = side;
  const PatchLevels levels = LegAndLightLevels(patch, m, s);
  const double contrast = levels.light - levels.dark;
  if (contrast <= 0.0) return 1.0;
  const double threshold = levels.dark + 0.5 * contrast;
  const double module = std::max(1.5, kQuietModuleFraction * s);
  const int from = static_cast<int>(std::floor(-kQuietProfileOutside * s));
  const int to = static_cast<int>(std::ceil(kQuietProfileInside * s));
  double worst = 0.0;
  for (int which = 0; which < 2; ++which) {
    // which 0: the left leg (outside is -x); 1: the bottom leg (outside is +y). u = distance
    // outward from the leg's nominal outer edge, v = position along the leg.
    const auto sample = [&](double u, double v) {
      return which == 0 ? at(m - 0.5 - u, m + v) : at(m + v, m + s - 0.5 + u);
    };
    int dark_places = 0;
    for (int k = 0; k < kQuietPlaces; ++k) {
      const double v = s * (0.15 + 0.7 * k / (kQuietPlaces - 1));
      // Strongest step from dark (inside, smaller u) to light (outside, larger u).
      double best_step = 0.0, edge = 0.0;
      for (int i = -to; i <= -from; ++i) {
        const double u = i;
        const double step = sample(u + 1.0, v) - sample(u - 1.0, v);
        if (step > best_step) best_step = step, edge = u;
      }
      const bool quiet = best_step >= kQuietMinStep * contrast && sample(edge + module, v) >= threshold;
      dark_places += !quiet;
    }
    worst = std::max(worst, dark_places / static_cast<double>(kQuietPlaces));
  }
  return worst;
}

namespace {

// The candidate's patch, untested.
DataMatrixPatch WarpDataMatrixCandidate(const cv::Mat& gray, const DataMatrixCandidate& candidate) {
  CV_Assert(gray.type() == CV_8UC1);
  DataMatrixPatch out;
  out.candidate = candidate;
  const PatchGeometry geometry = PatchGeometryOf(candidate.corners_px);
  out.side = geometry.side;
  out.margin = geometry.margin;
  out.patch_to_frame = geometry.patch_to_frame;
  const int size = out.side + 2 * out.margin;
  cv::warpPerspective(gray, out.patch, cv::Mat(out.patch_to_frame), cv::Size(size, size),
                      cv::INTER_LINEAR | cv::WARP_INVERSE_MAP, cv::BORDER_REPLICATE);
  return out;
}

}  // namespace

std::optional<DataMatrixPatch> RectifyDataMatrixCandidate(const cv::Mat& gray,
                                                          const DataMatrixCandidate& candidate) {
  DataMatrixPatch out = WarpDataMatrixCandidate(gray, candidate);
  // Text, frames and other L-shaped clutter: no decoder is started on them.
  if (!DataMatrixPatchPlausible(out.patch, out.margin, out.side, &out.timing_runs)) return std::nullopt;
  out.quiet_zone_dark = DataMatrixQuietZoneDark(out.patch, out.margin, out.side);
  return out;
}

std::optional<DataMatrixCandidate> RefitDataMatrixCandidate(const cv::Mat& gray,
                                                            const DataMatrixCandidate& candidate) {
  const DataMatrixPatch warped = WarpDataMatrixCandidate(gray, candidate);
  const cv::Mat& patch = warped.patch;
  const int m = warped.margin, s = warped.side;
  // The threshold: halfway between the darkest and lightest tenth of the middle of the patch.
  std::vector<uint8_t> middle;
  for (int y = m + s / 5; y < m + s - s / 5; ++y) {
    for (int x = m + s / 5; x < m + s - s / 5; ++x) middle.push_back(patch.at<uint8_t>(y, x));
  }
  if (middle.empty()) return std::nullopt;
  std::nth_element(middle.begin(), middle.begin() + middle.size() / 10, middle.end());
  const double low = middle[middle.size() / 10];
  std::nth_element(middle.begin(), middle.begin() + middle.size() * 9 / 10, middle.end());
  const double high = middle[middle.size() * 9 / 10];
  if (high - low < kPlausibleMinContrast) return std::nullopt;
  const double threshold = 0.5 * (low + high);
  // Dark fraction of the line `depth` px inside side `which` (0 top, 1 right, 2 bottom,
  // 3 left), over the middle of the side.
  const auto dark_fraction = [&](int which, int depth) {
    int dark = 0, total = 0;
    for (int a = m + static_cast<int>(kRefitSpan * s); a < m + s - static_cast<int>(kRefitSpan * s); ++a) {
      const int x = which == 0 || which == 2 ? a : which == 1 ? m + s - 1 - depth : m + depth;
      const int y = which == 1 || which == 3 ? a : which == 0 ? m + depth : m + s - 1 - depth;
      if (x < 0 || y < 0 || x >= patch.cols || y >= patch.rows) continue;
      dark += patch.at<uint8_t>(y, x) < threshold;
      ++total;
    }
    return total > 0 ? dark / static_cast<double>(total) : 0.0;
  };
  // Each side's edge: from inside (kRefitInside of the side) outwards while the lines cross
  // the symbol's modules; the outermost such line is its first module row or column.
  double edge[4];
  const int inside = static_cast<int>(std::lround(kRefitInside * s));
  const int outside = std::min(m, static_cast<int>(std::lround(kRefitOutside * s)));
  for (int which = 0; which < 4; ++which) {
    int depth = inside;
    while (depth > -outside && dark_fraction(which, depth) < kRefitMinDark) --depth;  // the symbol's inside
    if (depth <= -outside) return std::nullopt;
    while (depth - 1 > -outside && dark_fraction(which, depth - 1) >= kRefitMinDark) --depth;
    if (depth - 1 <= -outside) return std::nullopt;  // no light quiet zone
    edge[which] = depth - 0.5;                       // the outer edge of that line
  }
  // The refitted sides, in patch coordinates (outer edges, pixel-centre coordinates).
  const double top = m + edge[0], right = m + s - 1 - edge[1];
  const double bottom = m + s - 1 - edge[2], left = m + edge[3];
  if (right - left < kRefitMinSize * s || bottom - top < kRefitMinSize * s) return std::nullopt;
  const Eigen::Vector2d corners[4] = {{left, top}, {right, top}, {right, bottom}, {left, bottom}};
  DataMatrixCandidate out = candidate;
  double moved = 0.0;
  for (int i = 0; i < 4; ++i) {
    out.corners_px[i] = Apply(warped.patch_to_frame, corners[i]);
    moved = std::max(moved, (out.corners_px[i] - candidate.corners_px[i]).norm());
  }
  // Nothing new to read where no corner moved.
  if (moved < kRefitMinMovePx) return std::nullopt;
  return out;
}

std::vector<MarkerObservation> ReadDataMatrixCandidate(const cv::Mat& gray,
                                                       const DataMatrixCandidate& candidate) {
  const std::optional<DataMatrixPatch> patch = RectifyDataMatrixCandidate(gray, candidate);
  if (!patch) return {};
  return DecodeDataMatrixPatch(*patch);
}

std::vector<MarkerObservation> DecodeDataMatrixPatch(const DataMatrixPatch& rectified) {
  const cv::Mat& patch = rectified.patch;
  const DataMatrixCandidate& candidate = rectified.candidate;
  const cv::Matx33d& patch_to_frame = rectified.patch_to_frame;
  const int side = rectified.side, margin = rectified.margin, size = patch.rows;
  // Back to frame pixels; a symbol that is not where the candidate is (its centre more than
  // a fifth of a side away, or its size off by more than 40 %) is dropped: a decode of some
  // other grid in the patch is not this candidate's symbol.
  const Eigen::Vector2d centre = QuadCenter(candidate.corners_px);
  const double side_px = QuadMeanSide(candidate.corners_px);
  const auto to_frame = [&](std::vector<MarkerObservation> found) {
    std::vector<MarkerObservation> out;
    for (MarkerObservation& obs : found) {
      for (Eigen::Vector2d& c : obs.corners_px) c = Apply(patch_to_frame, c);
      const double ratio = QuadMeanSide(obs.corners_px) / side_px;
      if ((QuadCenter(obs.corners_px) - centre).norm() > kMaxCentreOffset * side_px) continue;
      if (ratio < 1.0 / kMaxSizeRatio || ratio > kMaxSizeRatio) continue;
      out.push_back(std::move(obs));
    }
    return out;
  };

  // libdmtx, started only on the L's outer edges: the left side (x = margin) and the bottom
  // side (y = margin + side) of the upright patch. Its y axis points up from the last row.
  DmtxScan scan;
  // libdmtx reads through a non-const pointer but does not write the pixels.
  scan.image = dmtxImageCreate(const_cast<unsigned char*>(patch.ptr<unsigned char>(0)), patch.cols,
                               patch.rows, DmtxPack8bppK);
  if (scan.image != nullptr) {
    dmtxImageSetProp(scan.image, DmtxPropRowPadBytes, static_cast<int>(patch.step[0]) - patch.cols);
    scan.decode = dmtxDecodeCreate(scan.image, 1);
    if (scan.decode != nullptr) {
      // The symbol is `side` px in the patch, and a region more than 1.4x off that is dropped
      // below (kMaxSizeRatio): libdmtx gives up on edge trails whose bounding box is under
      // kDmtxEdgeMinFraction of it squared, or whose diagonal is beyond kDmtxEdgeMaxFactor of
      // it (times sqrt 2 + 10 %), before it fits lines and sizes to them.
      dmtxDecodeSetProp(scan.decode, DmtxPropEdgeMin, static_cast<int>(kDmtxEdgeMinFraction * side));
      dmtxDecodeSetProp(scan.decode, DmtxPropEdgeMax, static_cast<int>(std::ceil(kDmtxEdgeMaxFactor * side)));
    }
  }
  if (scan.decode != nullptr) {
    // Every patch gets the seeds at the middle of the legs; only a patch with a clear timing
    // pattern (kAllSeedsTimingRuns) the others (which read 7 of 571 symbols, while every
    // candidate that is no symbol fails all of them).
    const int fractions = rectified.timing_runs >= kAllSeedsTimingRuns
                              ? static_cast<int>(std::size(kSeedFractions))
                              : kSeedFractionsForAll;
    for (int f = 0; f < fractions; ++f) {
      const double t = kSeedFractions[f];
      for (const int offset : kSeedOffsetsPx) {
        const int along = margin + static_cast<int>(std::lround(t * side));
        const cv::Point seeds[2] = {{margin + offset, along}, {along, margin + side - 1 + offset}};
        for (const cv::Point& seed : seeds) {
          DmtxRegion* region = dmtxRegionScanPixel(scan.decode, seed.x, (size - 1) - seed.y);
          if (region == nullptr) continue;
          std::vector<MarkerObservation> out;
          if (DmtxMessage* message = DecodeVerifiedRegion(scan.decode, region)) {
            MarkerObservation obs;
            obs.key.family = kFamilyDataMatrix;
            obs.key.id =
                TextToId(std::string(reinterpret_cast<const char*>(message->output), message->outputIdx));
            obs.corners_px = DmtxCorners(*region, size, 1);
            out.push_back(std::move(obs));
            dmtxMessageDestroy(&message);
          }
          dmtxRegionDestroy(&region);
          if (!out.empty()) {
            out = to_frame(std::move(out));
            // libdmtx passes ECI designators and other control codewords through as bytes
            // (an ECI symbol reads "\xb6\x07\xb6"); zxing-cpp applies them.
            // zxing-cpp confirms: when it reads the same patch, its corners are the start of
            // the refinement (libdmtx's grid fit can be a pixel or two off, beyond the
            // refinement's first window on small symbols), and its text replaces a libdmtx
            // text with control bytes.
            if (!out.empty()) {
              std::vector<MarkerObservation> confirmed =
                  to_frame(ReadWithZxing(patch, ZxingSymbology::kDataMatrix, ZxingPass{}));
              if (confirmed.size() == 1 &&
                  (confirmed[0].key == out[0].key || HasControlBytes(out[0].key.id))) {
                return confirmed;
              }
              return out;
            }
          }
        }
      }
    }
  }
  // zxing-cpp's DataMatrix reader on the same patch: the symbol is at its centre, where
  // zxing 1.4 starts its search.
  return to_frame(ReadWithZxing(patch, ZxingSymbology::kDataMatrix, ZxingPass{}));
}

std::unique_ptr<MarkerDetector> CreateDataMatrixDetector(const DetectorOptions& options) {
  return std::make_unique<DataMatrixDetector>(options);
}

}  // namespace waymark
