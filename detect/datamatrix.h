// DataMatrix detector (family "datamatrix"). Found by Waymark, decoded by libdmtx.
//
// Pass 1: Waymark's own candidates (detect/quads.h: dark components whose quad shows the
// solid L finder and the dashed timing pattern, or an L alone), best first, at most 4 x
// DetectorOptions::max_datamatrix_candidates per frame rectified onto a small upright patch
// and tested there (first at least 4 dark runs along one side, DataMatrixTimingSideRuns, then
// RectifyDataMatrixCandidate: contrast, a mixed inside, a timing pattern);
// of those that pass, the ones with a clear timing pattern first, at most
// max_datamatrix_candidates not already holding a decoded symbol are read
// (DecodeDataMatrixPatch): libdmtx started only at seed pixels on the L's two outer edges,
// zxing-cpp on the same patch as the rescue. No libdmtx scan of the frame or of a region.
// Pass 2 (second_pass), for symbols whose L the candidate stage did not see (glare, a bar
// across it, a symbol touching other dark things): zxing-cpp on the candidate regions
// ([George]: Canny, dilation, scored bounding boxes; FindCodeCandidates, at most
// max_candidates, plus the whole image when it is at most 640x480) holding no symbol yet
// (zxing 1.4 searches outwards from the image centre, so each crop is centred on its
// candidate), then on small crops (<= 240 px) upscaled 2x where the crop holds the centre of
// a candidate that passed the timing-side test and RectifyDataMatrixCandidate's tests.
// All work is bounded by those counts (no clock offline); in a live loop
// (DetectorOptions::live_budget_ms) attempts past the budget are skipped and counted.
// libdmtx's image origin is the bottom-left corner with y up; its fitted grid maps the
// symbol's (0,0) (the corner of the L finder) .. (1,1) to raw pixels, converted here to
// y-down image pixels and docs/design.md order (top-left = grid (0,1)).
#pragma once

#include <limits>
#include <memory>

#include "detect/detector.h"
#include "detect/quads.h"

namespace waymark {

std::unique_ptr<MarkerDetector> CreateDataMatrixDetector(const DetectorOptions& options);

// libdmtx alone on `gray` (8-bit), scanned at 1/shrink resolution (longer side at most
// 320 px), stopping after `max_symbols` decoded symbols: corners in image pixels, not
// refined. `timeout_ms` infinite (offline): the whole image is scanned; finite (live
// loops): libdmtx's wall-clock timeout, nothing under 1 ms. Exposed for tests and the
// benchmark.
std::vector<MarkerObservation> ReadWithLibdmtx(const cv::Mat& gray, double timeout_ms, int max_symbols = 1);

// The most dark runs along the timing lines of any one side of the patch a candidate with
// these corners would be rectified onto (RectifyDataMatrixCandidate; lines parallel to each side
// from 3 % of the side outside to 8 % inside, thresholded halfway between the L and the lightest
// modules inside, as DataMatrixPatchPlausible), sampled in `gray` (8-bit) where the patch's
// pixels would be, without warping; 0 when the patch has under 8 gray levels of contrast. A
// DataMatrix symbol's timing sides alternate dark and light modules, at least 4 dark ones on
// its shortest side (8 x 18): the detector warps and decodes no candidate with fewer.
// `enough`: the sampling stops at the first line with at least that many runs, and that line's
// count is returned (the answer to "at least `enough`?" is the same, at less cost: the detector
// asks only that, issue 14's tenth round).
int DataMatrixTimingSideRuns(const cv::Mat& gray, const Quad2d& corners_px,
                             int enough = std::numeric_limits<int>::max());

// The candidate with its four sides moved onto the symbol's outermost module rows and columns,
// found in its rectified patch: from a quarter of the side inside, outwards while a line
// parallel to the side (over its middle 70 %) is at least 20 % dark (halfway between the
// patch's darkest and lightest tenth); the first line with less is the quiet zone. Each side
// moves on its own (a hull's quad that took in part of the quiet zone or of the card, or
// stopped a module short: its patch fails the timing test or the decoders). Nothing when a
// side finds no symbol or no quiet zone within a quarter of the side, the refitted symbol is
// under 0.6 of the candidate, or no corner moved a pixel. Used by the detector for candidates
// whose patch failed, within the same decode bound.
std::optional<DataMatrixCandidate> RefitDataMatrixCandidate(const cv::Mat& gray,
                                                            const DataMatrixCandidate& candidate);

}  // namespace waymark
