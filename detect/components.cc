#include "detect/components.h"

#include <algorithm>
#include <cstdint>
#include <cstring>

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

// Appends the runs of non-zero pixels of one row; light stretches are skipped eight pixels
// at a time.
void RowRuns(const uint8_t* row, int cols, int y, std::vector<Run>* runs) {
  int x = 0;
  while (x < cols) {
    while (x + 8 <= cols) {
      uint64_t word;
      std::memcpy(&word, row + x, 8);
      if (word != 0) break;
      x += 8;
    }
    while (x < cols && row[x] == 0) ++x;
    if (x >= cols) break;
    const int start = x;
    while (x < cols && row[x] != 0) ++x;
    runs->push_back({y, start, x - 1});
  }
}

}  // namespace

std::vector<RunComponent> RunComponents(const cv::Mat& binary,
                                        const std::function<bool(const cv::Rect&)>& keep) {
  CV_Assert(binary.type() == CV_8UC1);
  std::vector<Run> runs;
  runs.reserve(static_cast<size_t>(binary.rows) * 8);
  std::vector<int> parent;
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
  // Bounding boxes per root (a root is its component's first run).
  const int n = static_cast<int>(runs.size());
  std::vector<int> root(n);
  std::vector<int> x0(n), x1(n), y1(n), count(n, 0);
  for (int i = 0; i < n; ++i) {
    const int r = root[i] = Find(parent, i);
    const Run& run = runs[i];
    if (r == i) {
      x0[r] = run.x0;
      x1[r] = run.x1;
      y1[r] = run.y;
    } else {
      x0[r] = std::min(x0[r], run.x0);
      x1[r] = std::max(x1[r], run.x1);
      y1[r] = std::max(y1[r], run.y);
    }
    ++count[r];
  }
  // The kept components, in the order of their roots; their run ends in a second pass.
  std::vector<int> slot(n, -1);
  std::vector<RunComponent> out;
  for (int i = 0; i < n; ++i) {
    if (root[i] != i) continue;
    const cv::Rect box(x0[i], runs[i].y, x1[i] - x0[i] + 1, y1[i] - runs[i].y + 1);
    if (keep && !keep(box)) continue;
    slot[i] = static_cast<int>(out.size());
    out.push_back({box, {}});
    out.back().row_ends.reserve(2 * static_cast<size_t>(std::min(count[i], out.back().box.height)));
  }
  // Runs come row by row, left to right: a row's first run gives its left end, its last run
  // its right end.
  for (int i = 0; i < n; ++i) {
    const int s = slot[root[i]];
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

}  // namespace waymark
