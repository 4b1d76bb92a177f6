// Dark quadrilaterals: the candidate stage Waymark runs itself for DataMatrix (the solid L
// finder and the dashed timing pattern) and for AprilTag (a solid dark border around mixed
// bits: libapriltag searches a crop of each, detect/apriltag.cc).
//
// The frame is binarized against its local mean (dark = at least 7 gray levels below the
// mean of a 15x15 box) at 1, 1/2 and 1/4 resolution, so that at some level the box spans a
// few modules of codes from about 10 to 400 px (levels above the last keep components up
// to 130 work pixels; larger ones are the next level's). FindCoarseDarkQuads does the same at
// 1/8, for DataMatrix only: there a symbol of 80-170 px with large modules is one component,
// where at 1/4 it broke at clusters of dark modules. Every dark component (8-connected,
// from the binary image's runs: detect/components.h) gives a convex hull reduced to four corners
// (approxPolyDP; a fifth corner, where the hull cuts off a light corner module as at a DataMatrix symbol's
// top-right, is replaced by the intersection of its neighbouring sides). Each side is sampled just inside
// itself (3 % of its length in, from 8 % to 92 % along): its dark fraction and its number of dark runs; and
// the middle half of the quad: the standard deviation of its gray levels over the border's contrast (just
// outside minus just inside the sides). A hull whose polygon (3 % of its perimeter) has five or six
// corners also gives the quad of an L (its longest side and the longer neighbour as the legs, the
// far corner their parallelogram completion; DarkQuad::l_completion), when that differs from the
// hull's quad: for DataMatrix candidates only. A hull that gives no quad (its polygon a triangle,
// or a triangle with a short cut that the side-ratio bound turns away: an L finder whose other
// modules join it only near it) gives the quad of the L found by its two dark legs (the corner
// of the polygon whose two sides are dark and span the most, the line between their ends not
// solid), marked the same way. The work is a fixed function of the image (no clock).
#pragma once

#include <array>
#include <opencv2/core.hpp>
#include <optional>
#include <vector>

#include "detect/common.h"

namespace waymark {

struct DarkQuad {
  Quad2d corners_px;                  // frame pixels, clockwise on screen
  std::array<double, 4> side_dark{};  // side j runs from corner j to corner j+1
  std::array<int, 4> side_runs{};     // dark runs along side j (DataMatrix timing)
  double interior_spread = 0.0;       // gray-level spread inside / the border's contrast
  double scale = 1.0;                 // the level it was found at
  // An L's parallelogram completion rather than the hull's quad (a hull of five or six corners
  // whose two longest adjacent sides are the legs, or a hull that gave no quad, by its two dark
  // legs): for DataMatrix candidates only.
  bool l_completion = false;
};

// Every dark component's quad with each side at least `min_side_px` (and at most 3.5 times
// another), in the order found (level by level, contour order): deterministic. The families
// of one frame share one run: each thread keeps its last result with the image's size,
// min_side_px and a 64-bit hash of its pixels (about 0.2 ms for 1280x960), and returns it for
// the same pixels again.
std::vector<DarkQuad> FindDarkQuads(const cv::Mat& gray, double min_side_px = 10.0);

// The same at 1/8 resolution alone (every component size kept), shared the same way; the
// DataMatrix detector's candidates come from both (large symbols with 13-17 px modules are
// whole only here). The other families do not use it.
std::vector<DarkQuad> FindCoarseDarkQuads(const cv::Mat& gray, double min_side_px = 10.0);

struct DataMatrixCandidate {
  // Outer corners in frame pixels in docs/design.md order of the symbol as the L finder puts it
  // upright: top-left, top-right, bottom-right, bottom-left (the L's corner is bottom-left;
  // its legs are the left and bottom sides).
  Quad2d corners_px;
  // The L's solidity (the smaller dark fraction of its two sides) times 0.8 + 0.2 r / 5,
  // r = the dark runs of the less alternating timing side, at most 5.
  double score = 0.0;
};

// The quads with a varied interior (spread >= 0.3: the data modules), two adjacent solid sides
// (>= 80 % dark) and two dashed ones (15-85 % dark, at least 2 dark runs), best first, at most
// `max_candidates`, duplicates (a centre within half a side of a better one and a size within 1.4x
// of it, e.g. the same symbol at two levels) dropped. The top-right corner is the L's parallelogram
// completion unless the hull's corner is within 8 % of a side of it (light modules near that corner
// can leave the dark component well short). After them, an L alone: a quad with a varied interior,
// two adjacent sides >= 75 % dark and neither other side solid (the hull cut deep into the timing
// pattern), its top-right corner the completion, its score half its legs' solidity. Quads
// with l_completion score half (after every hull's quad).
std::vector<DataMatrixCandidate> DataMatrixCandidates(const std::vector<DarkQuad>& quads, int max_candidates);

// A cheap test of a candidate's rectified patch (`side` px symbol at (`margin`, `margin`), the
// L's corner bottom-left) before any decoder: the L darker than the lightest modules inside by
// at least 8 gray levels, 20-80 % of a 9 x 9 grid over the inside darker than halfway
// between the two (the data modules mix dark and light), and a timing pattern: two adjacent
// sides each with at least 2 dark runs along a line near it (from 3 % of the side outside
// to 8 % inside; the orientation may be a quarter turn off). *timing_runs (when not null):
// the larger over adjacent side pairs of the pair's smaller run count (0 when the contrast
// or inside test fails).
// Implemented in detect/datamatrix.cc.
bool DataMatrixPatchPlausible(const cv::Mat& patch, int margin, int side, int* timing_runs = nullptr);

// The quiet zone outside the L's two legs on a candidate's rectified patch (as for
// DataMatrixPatchPlausible): at 16 places along each leg (15-85 % of it), the leg's outer edge
// is the strongest light-to-dark step of a profile across it (from 15 % of the side outside to
// 10 % inside: the candidate's legs may be a few pixels off), and the place counts as dark
// when the step is under a quarter of the patch's contrast or the gray level a module's width
// (4 % of the side, at least 1.5 px) outside the edge is under halfway between the L and the
// light modules. Returns the larger of the two legs' dark fractions (1 when the patch has no
// contrast).
double DataMatrixQuietZoneDark(const cv::Mat& patch, int margin, int side);

// A candidate rectified onto a small upright patch (side 48-140 px and a 30 % quiet zone, through
// the homography of its corners).
struct DataMatrixPatch {
  cv::Mat patch;
  cv::Matx33d patch_to_frame;
  int side = 0;
  int margin = 0;
  int timing_runs = 0;  // DataMatrixPatchPlausible's
  // DataMatrixQuietZoneDark's: the larger over the two legs of the fraction of places along
  // the leg with no light quiet zone just outside its outer edge.
  double quiet_zone_dark = 0.0;
  DataMatrixCandidate candidate;
};

// The candidate's patch, or nothing unless DataMatrixPatchPlausible. Implemented in
// detect/datamatrix.cc.
std::optional<DataMatrixPatch> RectifyDataMatrixCandidate(const cv::Mat& gray,
                                                          const DataMatrixCandidate& candidate);

// Decodes a rectified candidate: libdmtx started only at seed pixels on the L's two outer
// edges (dmtxRegionScanPixel: never a scan of the frame or of the patch; at the middle of the
// legs, and at 0.3 and 0.7 of them too when timing_runs >= 4; its edge-length bounds half and
// twice the patch's symbol side, beyond the size bound below), and zxing-cpp's
// DataMatrix reader on the same patch as the fallback (the symbol at its centre, where
// zxing 1.4 starts its search). When zxing reads the same text as libdmtx on the patch, its
// corners are returned (a better start for the refinement), and its text replaces a libdmtx
// text with control bytes (ECI designators, which libdmtx passes through). A symbol whose
// centre is more than a fifth of a side from the candidate's, or whose size is off by more
// than 40 %, is dropped. Corners in frame pixels, docs/design.md order, not refined.
// Implemented in detect/datamatrix.cc with the rest of the libdmtx glue.
std::vector<MarkerObservation> DecodeDataMatrixPatch(const DataMatrixPatch& patch);

// RectifyDataMatrixCandidate then DecodeDataMatrixPatch.
std::vector<MarkerObservation> ReadDataMatrixCandidate(const cv::Mat& gray,
                                                       const DataMatrixCandidate& candidate);

// The quads with four solid sides and a varied interior (spread >= 0.2) whose mean side is at
// most `max_side_px`: where an AprilTag (black border) may be. Best first, at most
// `max_candidates`, duplicates dropped. After every such quad, the quads with three solid sides
// (a dark bar across a tag's border joins its component, and the hull's quad then runs partly
// outside the border on one side), by their fourth side's dark fraction.
std::vector<Quad2d> SolidBorderQuads(const std::vector<DarkQuad>& quads, double max_side_px,
                                     int max_candidates);

}  // namespace waymark
