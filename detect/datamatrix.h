// DataMatrix detector (family "datamatrix").
//
// zxing 1.4's DataMatrix detector searches outwards from the image centre and misses
// symbols far from it, so every pass works on candidate regions ([George]: Canny,
// dilation, scored bounding boxes; FindCodeCandidates, at most max_candidates, plus the
// whole image when it is at most 640x480), each cropped so the candidate is centred:
// Pass 1: zxing-cpp on every candidate crop.
// Pass 2, while the frame's CPU time is within DetectorOptions::time_budget_ms, on the
// crops still holding no decoded code, best score first:
//   a. libdmtx on the crop only (the crop is a view into the frame: libdmtx scans no other
//      pixel; at half resolution above 320 px) with a timeout of an equal share of the
//      budget left among the crops not yet tried (at least 4 ms), stopping at the first
//      symbol, which is what makes libdmtx usable per frame ([George] needed ~1 s per
//      1280x960 image scanning all of it). It reads the rotations (around 45 degrees) that
//      zxing 1.4's DataMatrix detector misses.
//   b. zxing on small crops (<= 240 px) upscaled 2x (small modules).
//   Then, while budget is left, libdmtx again on the crops still unread, each with all the
//   time left (a slow crop early in the list can no longer starve a code behind it).
// libdmtx's image origin is the bottom-left corner with y up; its fitted grid maps the
// symbol's (0,0) (the corner of the L finder) .. (1,1) to raw pixels, converted here to
// y-down image pixels and docs/design.md order (top-left = grid (0,1)).
#pragma once

#include <memory>

#include "detect/detector.h"

namespace waymark {

std::unique_ptr<MarkerDetector> CreateDataMatrixDetector(const DetectorOptions& options);

// libdmtx alone on `gray` (8-bit) within `timeout_ms`, stopping after `max_symbols`
// decoded symbols (libdmtx otherwise scans on until the timeout): corners in image pixels,
// not refined. Exposed for tests and the benchmark.
std::vector<MarkerObservation> ReadWithLibdmtx(const cv::Mat& gray, double timeout_ms, int max_symbols = 1);

}  // namespace waymark
