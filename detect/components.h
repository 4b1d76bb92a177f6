// Connected components of a binary image from its runs (issue 14's candidate stage): one
// pass over the rows collects the runs of non-zero pixels, runs that touch in adjacent rows
// (8-connectivity, as cv::findContours joins non-zero pixels) are merged with a union-find,
// and each component is its bounding box and the leftmost and rightmost pixel of each of its
// rows. These hold every extreme point of the component, so their convex hull is the
// component's (and its outer contour's). Noise pixels and other small components cost a run each, not a
// contour trace. The work is a fixed function of the image.
#pragma once

#include <cstdint>
#include <cstring>
#include <functional>
#include <opencv2/core.hpp>
#include <vector>

namespace waymark {

struct RunComponent {
  cv::Rect box;                     // bounding box of the component's pixels
  std::vector<cv::Point> row_ends;  // leftmost and rightmost pixel of each row, top row first
};

// 255 where a pixel of `gray` (CV_8UC1) is at least `darker_by` gray levels below the mean of
// the `box` x `box` square around it (`box` odd, 3 to 257; the mean rounded to an integer, the
// image's border replicated), else 0: exactly cv::adaptiveThreshold(gray, dark, 255,
// ADAPTIVE_THRESH_MEAN_C, THRESH_BINARY_INV, box, darker_by), in integers (no division): up to
// 15 in 16 bits (column sums slid down the rows, box sums from sums of 2, 4 and 8 columns),
// larger boxes (the QR finder search's) in 32 bits (column sums, a running sum along the row,
// eight columns at a time with SSE2; the comparison in single precision where that is exact).
cv::Mat DarkerThanLocalMean(const cv::Mat& gray, int box, int darker_by);

// The 8-connected components of the non-zero pixels of `binary` (CV_8UC1) whose bounding box
// passes `keep` (all when empty), in the raster order of their first pixel (top row first,
// then left to right).
std::vector<RunComponent> RunComponents(const cv::Mat& binary,
                                        const std::function<bool(const cv::Rect&)>& keep = {});

// The first x' in [x, cols) with row[x'] != value (SkipEqual) or row[x'] == 0 (SkipNonZero), or
// cols when there is none; eight pixels at a time (the run scans of RunComponents and of the QR
// finder search, detect/qr_finder.cc).
// Both load eight pixels as one little-endian word (the pixel at the lower address is the lower
// byte); on a big-endian machine they scan pixel by pixel.
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
#define WAYMARK_WORD_SCANS 1
#else
#define WAYMARK_WORD_SCANS 0
#endif

inline int SkipEqual(const uint8_t* row, int x, int cols, uint8_t value) {
#if WAYMARK_WORD_SCANS
  const uint64_t pattern = 0x0101010101010101ULL * value;
  for (; x + 8 <= cols; x += 8) {
    uint64_t word;
    std::memcpy(&word, row + x, 8);
    const uint64_t differ = word ^ pattern;  // non-zero bytes where a pixel is not `value`
    if (differ != 0) return x + (__builtin_ctzll(differ) >> 3);
  }
#endif
  while (x < cols && row[x] == value) ++x;
  return x;
}

inline int SkipNonZero(const uint8_t* row, int x, int cols) {
#if WAYMARK_WORD_SCANS
  for (; x + 8 <= cols; x += 8) {
    uint64_t word;
    std::memcpy(&word, row + x, 8);
    // The lowest set bit of (word - 0x01s) & ~word & 0x80s is the lowest zero byte's high bit
    // (a borrow only carries into the bytes above a zero byte).
    const uint64_t zero = (word - 0x0101010101010101ULL) & ~word & 0x8080808080808080ULL;
    if (zero != 0) return x + (__builtin_ctzll(zero) >> 3);
  }
#endif
  while (x < cols && row[x] != 0) ++x;
  return x;
}

// `gray` (CV_8UC1) at half and a quarter of its size, exactly as cv::resize(gray, ...,
// INTER_AREA) gives them (the mean of each 2x2 block rounded half up, of each 4x4 block rounded
// half to even, as OpenCV 4.6's integer-scale area paths round), in one pass over the image
// (the quarter from the half's block sums). False, and nothing written, unless both sides are
// multiples of 4.
bool HalfAndQuarterArea(const cv::Mat& gray, cv::Mat* half, cv::Mat* quarter);

// `gray` (CV_8UC1) at an eighth of its size, exactly as cv::resize(gray, ..., INTER_AREA) gives
// it (the mean of each 8x8 block rounded half to even), in one pass. False, and nothing written,
// unless both sides are multiples of 8.
bool EighthArea(const cv::Mat& gray, cv::Mat* eighth);

// Sets to 0 every non-zero pixel of `binary` (CV_8UC1) whose eight neighbours are all 0 (outside
// the image counts as 0). cv::findContours traces each such pixel as a one-point contour of its
// own, with no children, touching no other contour; the others (their points, their nesting, their
// order) are the same without it.
void ClearIsolatedPixels(cv::Mat* binary);

// The convex hull of a component's row ends (its own hull), as cv::convexHull(row_ends, hull)
// gives it (the same vertices in the same cyclic order, collinear points and repeats dropped;
// the first vertex may differ), in linear time: the row ends are already sorted by row, then
// column (Andrew's monotone chain without its sort).
std::vector<cv::Point> RowEndsHull(const std::vector<cv::Point>& row_ends);

}  // namespace waymark
