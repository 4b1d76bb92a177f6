#include "detect/components.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace waymark {
namespace {

struct Run {
  int y, x0, x1;  // inclusive ends
};

int Find(std::vector<int>& parent, int i) {
  int root = i;
  while (parent[root] != root) root = parent[root];
  while (parent[i] != root) {
    const int next = parent[i];
    parent[i] = root;
    i = next;
  }
  return root;
}

// The smaller index becomes the root: a component's root is its first run in raster order.
void Union(std::vector<int>& parent, int a, int b) {
  a = Find(parent, a);
  b = Find(parent, b);
  if (a < b) {
    parent[b] = a;
  } else if (b < a) {
    parent[a] = b;
  }
}

// Appends the runs of non-zero pixels of one row (SkipEqual, SkipNonZero: eight pixels at a time).
void RowRuns(const uint8_t* row, int cols, int y, std::vector<Run>* runs) {
  int x = SkipEqual(row, 0, cols, 0);
  while (x < cols) {
    const int end = SkipNonZero(row, x, cols);
    runs->push_back({y, x, end - 1});
    x = SkipEqual(row, end, cols, 0);
  }
}

// The column sums of a (2r + 1)-row box slid down the image: sums over rows y - r .. y + r
// (clamped: the border replicated), padded by r columns on each side with the border
// columns' sums (PadBorders). Unsigned 16-bit arithmetic wraps, but every sum the callers
// keep fits, so the wrapped differences are exact.
class SlidingColumnSums {
 public:
  SlidingColumnSums(const cv::Mat& gray, int r)
      : gray_(gray), r_(r), column_(gray.cols + 2 * r, 0), c_(column_.data() + r) {
    for (int dy = -r; dy <= r; ++dy) {
      const uint8_t* in = gray.ptr<uint8_t>(std::clamp(dy, 0, gray.rows - 1));
      for (int x = 0; x < gray.cols; ++x) c_[x] = static_cast<uint16_t>(c_[x] + in[x]);
    }
  }

  // The padded sums, padded_cols = cols + 2 r entries.
  const uint16_t* data() const { return column_.data(); }

  // Copies the border columns' sums into the padding.
  void PadBorders() {
    const int cols = gray_.cols;
    for (int x = 0; x < r_; ++x) {
      column_[x] = c_[0];
      c_[cols + x] = c_[cols - 1];
    }
  }

  // From row y's box to row y + 1's: adds row y + 1 + r, drops row y - r (both clamped).
  void SlideDown(int y) {
    const uint8_t* add = gray_.ptr<uint8_t>(std::min(y + 1 + r_, gray_.rows - 1));
    const uint8_t* drop = gray_.ptr<uint8_t>(std::max(y - r_, 0));
    for (int x = 0; x < gray_.cols; ++x) c_[x] = static_cast<uint16_t>(c_[x] + add[x] - drop[x]);
  }

 private:
  const cv::Mat& gray_;
  int r_;
  std::vector<uint16_t> column_;
  uint16_t* c_;
};

// out[x] = sums[0] + ... + sums[x] for x < n (32-bit). With SSE2 eight at a time (each half's
// running sum by two shifted adds, plus the sum before it), the same integers as the plain loop.
void PrefixSums(const uint16_t* sums, int n, int32_t* out) {
  int x = 0;
  int32_t running = 0;
#if defined(__SSE2__)
  const __m128i zero = _mm_setzero_si128();
  __m128i carry = _mm_setzero_si128();  // the sum so far in every lane
  for (; x + 8 <= n; x += 8) {
    const __m128i v = _mm_loadu_si128(reinterpret_cast<const __m128i*>(sums + x));
    const __m128i halves[2] = {_mm_unpacklo_epi16(v, zero), _mm_unpackhi_epi16(v, zero)};
    for (int k = 0; k < 2; ++k) {
      __m128i p = _mm_add_epi32(halves[k], _mm_slli_si128(halves[k], 4));
      p = _mm_add_epi32(p, _mm_slli_si128(p, 8));
      p = _mm_add_epi32(p, carry);
      _mm_storeu_si128(reinterpret_cast<__m128i*>(out + x + 4 * k), p);
      carry = _mm_shuffle_epi32(p, 0xff);
    }
  }
  if (x > 0) running = out[x - 1];
#endif
  for (; x < n; ++x) {
    running += sums[x];
    out[x] = running;
  }
}

// DarkerThanLocalMean for boxes over 15 px (the QR finder search's, up to 101): 16-bit column
// sums (at most 255 x 101) slid down the rows, each row's box sums as differences of a 32-bit
// running sum along it.
cv::Mat DarkerThanLocalMeanWide(const cv::Mat& gray, int box, int darker_by) {
  CV_Assert(box <= 257);  // a column sum fits 16 bits
  const int rows = gray.rows, cols = gray.cols, r = box / 2;
  cv::Mat dark(rows, cols, CV_8U);
  if (rows == 0 || cols == 0) return dark;
  const int padded_cols = cols + 2 * r;
  SlidingColumnSums column(gray, r);
  // As below: dark when sum >= area pixel + t, t = ceil(area (2 darker_by - 1) / 2).
  const int area = box * box;
  const int t_exact = static_cast<int>(std::ceil(area * (2.0 * darker_by - 1.0) / 2.0));
  // The comparison in single precision when every value in it is an integer under 2^24 (then
  // exact; the compiler vectorizes it without 32-bit multiplies): box sums (at most 255 area),
  // area pixel + t.
  const bool exact_in_float =
      static_cast<int64_t>(area) * 255 + std::abs(static_cast<int64_t>(t_exact)) < (1 << 24);
  const float area_f = static_cast<float>(area), t_f = static_cast<float>(t_exact);
  std::vector<int32_t> prefix(padded_cols + 1, 0);  // prefix[x]: sum of columns before x
  const uint16_t* const sums = column.data();
  for (int y = 0; y < rows; ++y) {
    column.PadBorders();
    PrefixSums(sums, padded_cols, prefix.data() + 1);
    const int32_t* high = prefix.data() + box;
    const int32_t* low = prefix.data();
    const uint8_t* in = gray.ptr<uint8_t>(y);
    uint8_t* out = dark.ptr<uint8_t>(y);
    if (exact_in_float) {
      for (int x = 0; x < cols; ++x) {
        out[x] = static_cast<float>(high[x] - low[x]) >= area_f * static_cast<float>(in[x]) + t_f ? 255 : 0;
      }
    } else {
      for (int x = 0; x < cols; ++x) out[x] = high[x] - low[x] >= area * in[x] + t_exact ? 255 : 0;
    }
    if (y + 1 == rows) break;
    column.SlideDown(y);
  }
  return dark;
}

}  // namespace

cv::Mat DarkerThanLocalMean(const cv::Mat& gray, int box, int darker_by) {
  CV_Assert(gray.type() == CV_8UC1 && box >= 3 && box % 2 == 1);
  if (box > 15) return DarkerThanLocalMeanWide(gray, box, darker_by);
  // Box sums in 16 bits: at most 255 * 15 * 15.
  const int rows = gray.rows, cols = gray.cols, r = box / 2;
  cv::Mat dark(rows, cols, CV_8U);
  if (rows == 0 || cols == 0) return dark;
  const int padded_cols = cols + 2 * r;
  SlidingColumnSums column(gray, r);
  // Sums of 2, 4 and 8 neighbouring columns: a box sum is the sum of a few of them (its
  // width in binary), each pass a plain loop the compiler vectorizes.
  std::vector<uint16_t> pow2[3];
  for (auto& p : pow2) p.resize(padded_cols);
  const std::vector<uint16_t> zeros(padded_cols, 0);
  const uint16_t* parts[4];
  for (int k = 3, start = 0, n = 0; k >= 0; --k, ++n) {
    const uint16_t* base = k == 0 ? column.data() : pow2[k - 1].data();
    parts[n] = ((box >> k) & 1) != 0 ? base + start : zeros.data();
    if (((box >> k) & 1) != 0) start += 1 << k;
  }
  // Dark when round(sum / area) - pixel >= darker_by, i.e. sum / area >= pixel + darker_by -
  // 0.5 (sum / area is never a half-integer: area is odd), i.e. sum >= area pixel + t with
  // t = ceil(area (2 darker_by - 1) / 2); in 16 bits when that fits.
  const int area = box * box;
  const int t_exact = static_cast<int>(std::ceil(area * (2.0 * darker_by - 1.0) / 2.0));
  const bool narrow = t_exact >= 0 && area * 255 + t_exact <= 65535;
  for (int y = 0; y < rows; ++y) {
    column.PadBorders();
    for (int k = 1, step = 1; k < 4 && (1 << k) <= box; ++k, step *= 2) {
      const uint16_t* lower = k == 1 ? column.data() : pow2[k - 2].data();
      uint16_t* out = pow2[k - 1].data();
      for (int x = 0; x + step < padded_cols; ++x) out[x] = static_cast<uint16_t>(lower[x] + lower[x + step]);
    }
    const uint8_t* in = gray.ptr<uint8_t>(y);
    uint8_t* out = dark.ptr<uint8_t>(y);
    const uint16_t *p0 = parts[0], *p1 = parts[1], *p2 = parts[2], *p3 = parts[3];
    if (narrow) {
      const uint16_t a16 = static_cast<uint16_t>(area), t16 = static_cast<uint16_t>(t_exact);
      for (int x = 0; x < cols; ++x) {
        const uint16_t sum = static_cast<uint16_t>(p0[x] + p1[x] + p2[x] + p3[x]);
        out[x] = sum >= static_cast<uint16_t>(a16 * in[x] + t16) ? 255 : 0;
      }
    } else {
      for (int x = 0; x < cols; ++x) {
        const int sum = p0[x] + p1[x] + p2[x] + p3[x];
        out[x] = sum >= area * in[x] + t_exact ? 255 : 0;
      }
    }
    if (y + 1 == rows) break;
    column.SlideDown(y);
  }
  return dark;
}

std::vector<RunComponent> RunComponents(const cv::Mat& binary,
                                        const std::function<bool(const cv::Rect&)>& keep) {
  CV_Assert(binary.type() == CV_8UC1);
  std::vector<Run> runs;
  runs.reserve(static_cast<size_t>(binary.rows) * 8);
  std::vector<int> parent;
  parent.reserve(runs.capacity());
  size_t previous_begin = 0, previous_end = 0;
  for (int y = 0; y < binary.rows; ++y) {
    const size_t begin = runs.size();
    RowRuns(binary.ptr<uint8_t>(y), binary.cols, y, &runs);
    for (size_t i = begin; i < runs.size(); ++i) parent.push_back(static_cast<int>(i));
    // Runs of the row above touching this run, diagonals included.
    size_t j = previous_begin;
    for (size_t i = begin; i < runs.size(); ++i) {
      while (j < previous_end && runs[j].x1 < runs[i].x0 - 1) ++j;
      for (size_t k = j; k < previous_end && runs[k].x0 <= runs[i].x1 + 1; ++k) {
        Union(parent, static_cast<int>(i), static_cast<int>(k));
      }
    }
    previous_begin = begin;
    previous_end = runs.size();
  }
  // Each run's root in place: a root is its component's first run and every run's parent
  // an earlier run (or itself), so the parent's entry already holds its root.
  const int n = static_cast<int>(runs.size());
  for (int i = 0; i < n; ++i) parent[i] = parent[parent[i]];
  // Bounding boxes and run counts per root.
  struct Extent {
    int x0, x1, y1, count;
  };
  std::vector<Extent> extent(n);
  for (int i = 0; i < n; ++i) {
    const int r = parent[i];
    const Run& run = runs[i];
    Extent& e = extent[r];
    if (r == i) {
      e = {run.x0, run.x1, run.y, 1};
    } else {
      e.x0 = std::min(e.x0, run.x0);
      e.x1 = std::max(e.x1, run.x1);
      e.y1 = std::max(e.y1, run.y);
      ++e.count;
    }
  }
  // The kept components, in the order of their roots; their run ends in a second pass. A
  // root's count becomes its slot in `out` (-1: not kept).
  std::vector<RunComponent> out;
  for (int i = 0; i < n; ++i) {
    if (parent[i] != i) continue;
    Extent& e = extent[i];
    const cv::Rect box(e.x0, runs[i].y, e.x1 - e.x0 + 1, e.y1 - runs[i].y + 1);
    if (keep && !keep(box)) {
      e.count = -1;
      continue;
    }
    out.push_back({box, {}});
    out.back().row_ends.reserve(2 * static_cast<size_t>(std::min(e.count, box.height)));
    e.count = static_cast<int>(out.size()) - 1;
  }
  // Runs come row by row, left to right: a row's first run gives its left end, its last run
  // its right end.
  for (int i = 0; i < n; ++i) {
    const int s = extent[parent[i]].count;
    if (s < 0) continue;
    std::vector<cv::Point>& ends = out[s].row_ends;
    if (!ends.empty() && ends.back().y == runs[i].y) {
      ends.back().x = runs[i].x1;
    } else {
      ends.emplace_back(runs[i].x0, runs[i].y);
      ends.emplace_back(runs[i].x1, runs[i].y);
    }
  }
  return out;
}

bool HalfAndQuarterArea(const cv::Mat& gray, cv::Mat* half, cv::Mat* quarter) {
  if (gray.type() != CV_8UC1 || gray.empty() || gray.cols % 4 != 0 || gray.rows % 4 != 0) return false;
  const int hw = gray.cols / 2, hh = gray.rows / 2, qw = hw / 2;
  cv::Mat h(hh, hw, CV_8U), q(hh / 2, qw, CV_8U);
  // 2x2 block sums of two consecutive half-size rows (at most 4 * 255).
  std::vector<uint16_t> even_row(hw), odd_row(hw);
  for (int y = 0; y < hh; ++y) {
    const uint8_t* a = gray.ptr<uint8_t>(2 * y);
    const uint8_t* b = gray.ptr<uint8_t>(2 * y + 1);
    uint16_t* s = (y % 2 == 0 ? even_row : odd_row).data();
    uint8_t* out = h.ptr<uint8_t>(y);
    for (int x = 0; x < hw; ++x) {
      s[x] = static_cast<uint16_t>(a[2 * x] + a[2 * x + 1] + b[2 * x] + b[2 * x + 1]);
      out[x] = static_cast<uint8_t>((s[x] + 2) >> 2);
    }
    if (y % 2 == 0) continue;
    uint8_t* qout = q.ptr<uint8_t>(y / 2);
    for (int x = 0; x < qw; ++x) {
      const int t = even_row[2 * x] + even_row[2 * x + 1] + odd_row[2 * x] + odd_row[2 * x + 1];
      // t / 16 rounded half to even.
      const int base = t >> 4, rest = t & 15;
      qout[x] = static_cast<uint8_t>(base + (rest > 8 || (rest == 8 && (base & 1) != 0) ? 1 : 0));
    }
  }
  *half = h;
  *quarter = q;
  return true;
}

bool EighthArea(const cv::Mat& gray, cv::Mat* eighth) {
  if (gray.type() != CV_8UC1 || gray.empty() || gray.cols % 8 != 0 || gray.rows % 8 != 0) return false;
  const int ew = gray.cols / 8, eh = gray.rows / 8;
  cv::Mat e(eh, ew, CV_8U);
  std::vector<uint16_t> column(gray.cols);  // sums of 8 rows (at most 8 * 255)
  for (int y = 0; y < eh; ++y) {
    std::fill(column.begin(), column.end(), uint16_t{0});
    for (int dy = 0; dy < 8; ++dy) {
      const uint8_t* in = gray.ptr<uint8_t>(8 * y + dy);
      for (int x = 0; x < gray.cols; ++x) column[x] = static_cast<uint16_t>(column[x] + in[x]);
    }
    uint8_t* out = e.ptr<uint8_t>(y);
    for (int x = 0; x < ew; ++x) {
      const uint16_t* b = column.data() + 8 * x;
      const int t = b[0] + b[1] + b[2] + b[3] + b[4] + b[5] + b[6] + b[7];
      // t / 64 rounded half to even.
      const int base = t >> 6, rest = t & 63;
      out[x] = static_cast<uint8_t>(base + (rest > 32 || (rest == 32 && (base & 1) != 0) ? 1 : 0));
    }
  }
  *eighth = e;
  return true;
}

namespace {

// out[x] = own[x + 1] where own[x] | own[x + 2] | across[x .. x + 2] is non-zero, else 0.
void KeepWithNeighbours(const uint8_t* __restrict own, const uint8_t* __restrict across, int cols,
                        uint8_t* __restrict out) {
  for (int x = 0; x < cols; ++x) {
    const uint8_t neighbours = own[x] | own[x + 2] | across[x] | across[x + 1] | across[x + 2];
    out[x] = own[x + 1] & static_cast<uint8_t>(neighbours != 0 ? 0xff : 0);
  }
}

}  // namespace

void ClearIsolatedPixels(cv::Mat* binary) {
  CV_Assert(binary->type() == CV_8UC1);
  const int rows = binary->rows, cols = binary->cols;
  if (rows == 0 || cols == 0) return;
  // Per row, branch-free (loops the compiler vectorizes): the row and the OR of the rows above
  // and below it, each padded by a 0 on either side; a pixel stays when the OR of its eight
  // neighbours is non-zero. Clearing in place changes no other pixel's test: a cleared pixel's
  // neighbours are all 0 already.
  std::vector<uint8_t> own(cols + 2, 0), across(cols + 2, 0);
  const std::vector<uint8_t> zeros(cols, 0);
  uint8_t* const o = own.data();
  uint8_t* const a = across.data();
  for (int y = 0; y < rows; ++y) {
    uint8_t* row = binary->ptr<uint8_t>(y);
    const uint8_t* above = y > 0 ? binary->ptr<uint8_t>(y - 1) : zeros.data();
    const uint8_t* below = y + 1 < rows ? binary->ptr<uint8_t>(y + 1) : zeros.data();
    uint8_t any = 0;
    for (int x = 0; x < cols; ++x) {
      o[x + 1] = row[x];
      any |= row[x];
    }
    if (any == 0) continue;
    for (int x = 0; x < cols; ++x) a[x + 1] = above[x] | below[x];
    KeepWithNeighbours(o, a, cols, row);
  }
}

std::vector<cv::Point> RowEndsHull(const std::vector<cv::Point>& row_ends) {
  // Sorted by (y, x) with repeats (a one-pixel row's two ends) dropped.
  std::vector<cv::Point> p;
  p.reserve(row_ends.size());
  for (const cv::Point& q : row_ends) {
    if (p.empty() || p.back() != q) p.push_back(q);
  }
  if (p.size() < 3) return p;
  // Positive when o -> a -> b turns clockwise on screen (y down).
  const auto turn = [](const cv::Point& o, const cv::Point& a, const cv::Point& b) {
    return static_cast<int64_t>(a.x - o.x) * (b.y - o.y) - static_cast<int64_t>(a.y - o.y) * (b.x - o.x);
  };
  std::vector<cv::Point> hull(2 * p.size());
  int k = 0;
  for (size_t i = 0; i < p.size(); ++i) {
    while (k >= 2 && turn(hull[k - 2], hull[k - 1], p[i]) <= 0) --k;
    hull[k++] = p[i];
  }
  for (int i = static_cast<int>(p.size()) - 2, lower = k + 1; i >= 0; --i) {
    while (k >= lower && turn(hull[k - 2], hull[k - 1], p[i]) <= 0) --k;
    hull[k++] = p[i];
  }
  hull.resize(static_cast<size_t>(std::max(1, k - 1)));
  return hull;
}

}  // namespace waymark
