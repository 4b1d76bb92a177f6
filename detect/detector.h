// Code detectors: one interface for QR (zxing-cpp + OpenCV's WeChat decoder), DataMatrix
// (zxing-cpp + libdmtx) and AprilTag (libapriltag), and a multi-family detector.
//
//   image (cv::Mat, 8-bit gray or BGR/BGRA) -> std::vector<MarkerObservation>
//
// Every observation carries its key (family, id: decoded text for QR/DataMatrix, tag
// number for AprilTag), and its four corners in docs/design.md order: top-left, top-right,
// bottom-right, bottom-left of the upright symbol, i.e. the images of the object points
// (-s/2, s/2), (s/2, s/2), (s/2, -s/2), (-s/2, -s/2) of MarkerCorners(size_m).
// Corners are the outer corners of the symbol (QR: outer edge of the finder patterns;
// DataMatrix: outer edge of the L finder and of the timing pattern; AprilTag: outer edge
// of the black border), in pixels with OpenCV's convention: the centre of pixel (c, r) is
// at (c, r), so the image spans [-0.5, width - 0.5] x [-0.5, height - 0.5].
// `quality` is in [0, 1]: the fraction of edge samples that agreed with the refined
// corner lines (see detect/refine.h); 0 when refinement failed and the decoder's
// corners were kept; absent when refinement is off for that family.
//
// Nothing is returned whose corners are non-finite, outside the image, or form a
// non-convex or degenerate quadrilateral. A detector is not thread-safe (AprilTag keeps
// state); use one per thread. Detect() throws std::invalid_argument for an empty image or
// an unsupported pixel type, never crashes on image content.
#pragma once

#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "geometry/types.h"

namespace waymark {

struct DetectorOptions {
  // Sub-pixel corner refinement from the symbol's outer edges (detect/refine.h).
  bool refine_corners = true;
  // Quads with a side shorter than this are rejected as degenerate.
  double min_side_px = 6.0;

  // QR and DataMatrix: after the first pass, a second pass (inverted and rescaled crops,
  // a second decoder) runs on candidate regions that were not decoded. Its work is bounded
  // by counts, never by the clock, so that the same image gives the same detections on any
  // machine and at any load: at most `max_candidates` regions per frame (best score first)
  // and, for QR, at most `max_qr_finder_candidates` finder-pattern triples read per frame.
  bool second_pass = true;
  int max_candidates = 8;  // candidate regions tried per frame, best score first
  int max_qr_finder_candidates = 8;
  // DataMatrix: Waymark's own candidates (L finder + timing pattern, detect/quads.h)
  // rectified and decoded per frame, best first.
  int max_datamatrix_candidates = 16;
  // Close-ups: an image of at most 640x480 is itself the first second-pass region (the code may
  // fill it, leaving no blob boundary) and QR's WeChat decoder reads it. Off for crops of a
  // larger frame (the live loop's predicted regions, runner/predicted_regions.h), which are not
  // close-ups: there these attempts cost milliseconds per region holding no readable code.
  bool close_up = true;
  // Live loops only (`waymark localize --live`): when > 0, second-pass attempts stop once
  // the frame has taken this much wall-clock time, and each attempt not run is counted
  // (MarkerDetector::SkippedAttempts). 0 (the default, and every offline command): no
  // clock is read, results depend on the image alone.
  double live_budget_ms = 0.0;

  // AprilTag (libapriltag's apriltag_detector_t fields).
  // quad_decimate, the coarsest: libapriltag searches a crop of each solid-bordered quad of the
  // candidate stage (detect/quads.h) at the decimation that leaves the quad's shortest side
  // about 32 px (at most this one), then the whole frame at this one for tags at no such quad
  // (corners are refined at full resolution).
  double apriltag_decimate = 8.0;
  double apriltag_blur_sigma = 0.0;  // quad_sigma of the crops (the whole frame's: 0.8)
  int apriltag_max_bits_corrected = 1;
  // Worker threads of one Detect() call of a multi-family detector (CreateMultiDetector): its
  // families run at the same time, sharing the frame's whole-frame work (the candidate stage
  // and regions are computed once, whichever family asks first). The result is the same for
  // any count: each family's work depends on the image alone (and on the codes of the steps
  // before its own, below) and the families' results are merged in the order of the list.
  // libapriltag itself always runs on one thread.
  int threads = 1;
  // A multi-family detector's Detect() in steps, each family skipping the codes the others
  // have read (CreateMultiDetector): the least work, best on one core or a busy machine. false:
  // every family at once on its own, the way before 2026-11-27: more work, but on two or more
  // idle cores the shortest wall time per frame when QR is the longest family (the cluttered
  // frames of docs/detection.md). The codes read are the same on every recall run measured;
  // they may differ where a count bound (candidates per frame) is reached, a skipped place
  // leaving room for another candidate.
  bool family_steps = true;

  // True if usable; otherwise false with the reason in *why (when why != nullptr).
  bool Check(std::string* why) const;
};

class MarkerDetector {
 public:
  virtual ~MarkerDetector() = default;
  // The families this detector reports, as written in files ("qr", "apriltag-36h11", ...).
  virtual std::vector<std::string> Families() const = 0;
  // All codes found in `image`, in no particular order.
  virtual std::vector<MarkerObservation> Detect(const cv::Mat& image) = 0;
  // Second-pass attempts the last Detect() skipped because DetectorOptions::live_budget_ms
  // ran out (always 0 when it is 0).
  virtual int SkippedAttempts() const { return 0; }

  // Detect() in two stages on one image, for the live loop's predicted regions
  // (runner/predicted_regions.h), which want the second passes only where the first found too
  // few codes. DetectFirstPass(image) returns what Detect(image) returns with
  // DetectorOptions::second_pass off; DetectSecondPasses() then returns what Detect(image)
  // returns with this detector's options, continuing from the first pass's reads (neither the
  // first pass nor the corner refinement of its reads runs again). `image` must stay alive and
  // unchanged until DetectSecondPasses() or the next DetectFirstPass(). Each stage has its own
  // live budget (DetectorOptions::live_budget_ms), and SkippedAttempts() is the last stage's.
  // DetectSecondPasses() throws std::logic_error before any DetectFirstPass().
  // The defaults serve a detector without stages of its own (a user's subclass written
  // before the stages existed keeps compiling): the whole Detect() is the first stage, and
  // DetectSecondPasses() returns its result again.
  virtual std::vector<MarkerObservation> DetectFirstPass(const cv::Mat& image) {
    first_pass_ = Detect(image);
    return *first_pass_;
  }
  virtual std::vector<MarkerObservation> DetectSecondPasses() {
    if (!first_pass_) throw std::logic_error("DetectSecondPasses() before DetectFirstPass()");
    return *first_pass_;
  }

  // Codes of other families already read in the image of the next Detect() or
  // DetectSecondPasses() (the multi-family detector sets them; none by default). One place
  // holds one code, so a detector may skip its candidates at them: what it would read there is
  // not its own. `codes` must outlive those calls; nullptr clears them.
  void SetReadByOthers(const std::vector<MarkerObservation>* codes) { read_by_others_ = codes; }
  const std::vector<MarkerObservation>& ReadByOthers() const {
    static const std::vector<MarkerObservation> kNone;
    return read_by_others_ != nullptr ? *read_by_others_ : kNone;
  }
  // True if DetectFirstPass() is a cheap read of the whole image and DetectSecondPasses() the
  // costly search for what it missed (QR): the multi-family detector then runs the first pass
  // before the other families and the second passes after them (see CreateMultiDetector).
  virtual bool SecondPassesLast() const { return false; }

 private:
  std::optional<std::vector<MarkerObservation>> first_pass_;  // of the default stages
  const std::vector<MarkerObservation>* read_by_others_ = nullptr;
};

// Family names CreateDetector accepts: qr, datamatrix, and apriltag-<name> for every
// family libapriltag 3.3 ships (16h5, 25h9, 36h10, 36h11, Circle21h7, Circle49h12,
// Custom48h12, Standard41h12, Standard52h13).
std::vector<std::string> SupportedFamilies();

// A detector for one family. Throws std::invalid_argument for an unknown family or
// options that fail Check().
std::unique_ptr<MarkerDetector> CreateDetector(const std::string& family,
                                               const DetectorOptions& options = {});

// One detector running several families on each image (on up to options.threads threads at
// once, the same result for any count); duplicates (same key, same place) are dropped. Its
// Detect() runs in three steps, each family of a step on whichever thread takes it: (1) the
// first passes of the families whose second passes come last (SecondPassesLast: QR's whole-frame
// zxing read); (2) every other family whole, each given step 1's codes (SetReadByOthers); (3)
// the second passes of step 1's families, each given the codes every other family read. A
// family thus skips the places another has read (on issue 14's frames a third of a frame's
// time went to one family's candidates at another family's codes) and the steps' order, not
// the threads, decides what each sees. DetectFirstPass() and DetectSecondPasses() run every
// family's stage at once, without SetReadByOthers. Throws like
// CreateDetector, and for an empty or repeated family list.
std::unique_ptr<MarkerDetector> CreateMultiDetector(const std::vector<std::string>& families,
                                                    const DetectorOptions& options = {});

// "qr,datamatrix,apriltag-36h11" -> {"qr", "datamatrix", "apriltag-36h11"}; throws
// std::invalid_argument naming the first unsupported or empty entry.
std::vector<std::string> ParseFamilyList(const std::string& comma_separated);

}  // namespace waymark
