#include "detect/quads.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <iterator>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <optional>

#include "detect/components.h"

namespace waymark {
namespace {

// Local-mean binarization: box side (work pixels) and how much darker than the box mean a
// pixel must be to count as dark (gray levels).
constexpr int kBoxPx = 15;
constexpr int kDarkerBy = 7;
// Pyramid levels (scale of the work image) and the largest hull side each one keeps (work
// pixels; larger codes are found at the next level, where the box spans more modules).
constexpr double kLevelScales[] = {1.0, 0.5, 0.25};
// FindCoarseDarkQuads' one level.
constexpr double kCoarseLevelScale = 0.125;
constexpr double kLevelMaxSidePx = 130.0;
// The L test: samples just inside each side (the first module row or column), from 8 % to
// 92 % of the side.
constexpr double kInsetFraction = 0.03;
constexpr double kSolidMin = 0.85;
// The DataMatrix L's legs: a little less than solid (a blurred leg sampled at the coarse levels,
// where a module is a pixel or two, reads 80-85 % dark).
constexpr double kLSolidMin = 0.8;
constexpr double kDashedMin = 0.15;
// An L without a timing pattern on the hull's other sides (DataMatrixCandidates): its legs,
// and its score's factor (below every L with its timing pattern).
constexpr double kLAloneSolidMin = 0.75;
constexpr double kLAloneScale = 0.5;
// An L's completion quad (DarkQuad::l_completion) ranks after every hull's quad: where both
// are candidates of one symbol, the hull's patch is the one zxing confirms on, whose corners
// start the refinement (`e2e_render_detect_test`: a symbol at the image border read from the
// completion first kept libdmtx's corners, 0.92 px off; ranked at 0.9 of a hull's it was).
constexpr double kLCompletionScale = 0.5;
constexpr int kDashedMinRuns = 2;
constexpr int kRunsForFullScore = 5;
// DataMatrix: the hull's top-right corner is kept when within this fraction of the mean
// side of the L's parallelogram completion.
constexpr double kCompletionTolerance = 0.08;
constexpr double kMaxAspect = 3.5;  // longest / shortest side (tilted up to ~70 degrees)
// A tag's interior: gray-level spread of its middle half over the border's contrast.
constexpr double kInteriorMinSpread = 0.2;
// A DataMatrix symbol's data region mixes dark and light modules about evenly (its
// codewords are scrambled): every symbol read on the 150 frames of the recall bench (seed 1,
// 70 read) had a spread >= 0.46, while a third of the 1598 L-shaped candidates not read
// were under 0.3 (a bare corner of a frame, text): each cost 0.7 ms of libdmtx seeds.
constexpr double kDataMatrixMinSpread = 0.3;
// DataMatrix candidates at one place are one symbol's only when of about one size (the same
// symbol at two levels): on issue-scenario seed 1 the dark background around a symbol's card
// (an L-shaped quad 1.7x the symbol, ranked first) hid the symbol's own candidate.
constexpr double kDuplicateMaxSizeRatio = 1.4;

double Cross(const Eigen::Vector2d& a, const Eigen::Vector2d& b) { return a.x() * b.y() - a.y() * b.x(); }

std::optional<Eigen::Vector2d> Intersect(const Eigen::Vector2d& p0, const Eigen::Vector2d& p1,
                                         const Eigen::Vector2d& q0, const Eigen::Vector2d& q1) {
  const Eigen::Vector2d d = p1 - p0, e = q1 - q0;
  const double den = Cross(d, e);
  if (std::abs(den) < 1e-9 * d.norm() * e.norm()) return std::nullopt;
  return p0 + d * (Cross(q0 - p0, e) / den);
}

// Four corners of a convex hull, clockwise on screen, or nothing.
std::optional<Quad2d> QuadFromHull(const std::vector<cv::Point>& hull) {
  const double perimeter = cv::arcLength(hull, true);
  for (const double eps : {0.03, 0.05, 0.08}) {
    std::vector<cv::Point> poly;
    cv::approxPolyDP(hull, poly, eps * perimeter, true);
    std::vector<Eigen::Vector2d> p;
    for (const cv::Point& q : poly) p.emplace_back(q.x, q.y);
    if (p.size() == 5) {
      // A cut corner (DataMatrix: the light top-right module): the shortest side goes, its
      // neighbours meet.
      size_t shortest = 0;
      for (size_t i = 1; i < 5; ++i) {
        if ((p[(i + 1) % 5] - p[i]).norm() < (p[(shortest + 1) % 5] - p[shortest]).norm()) shortest = i;
      }
      const size_t a = shortest, b = (shortest + 1) % 5;
      const auto corner = Intersect(p[(a + 4) % 5], p[a], p[(b + 1) % 5], p[b]);
      if (!corner) continue;
      std::vector<Eigen::Vector2d> four;
      for (size_t i = 0; i < 5; ++i) {
        if (i == a) {
          four.push_back(*corner);
        } else if (i != b) {
          four.push_back(p[i]);
        }
      }
      p = four;
    }
    if (p.size() != 4) continue;
    Quad2d quad = {p[0], p[1], p[2], p[3]};
    // Clockwise on screen (y down): positive cross products.
    if (Cross(quad[1] - quad[0], quad[2] - quad[1]) < 0) std::swap(quad[1], quad[3]);
    return quad;
  }
  return std::nullopt;
}

// The quad of an L: the polygon of the hull (3 % of its perimeter) with five or six corners,
// its longest side and the longer of that side's neighbours as the legs, the far corner their
// parallelogram completion; clockwise on screen. A DataMatrix symbol whose light modules near
// the far corner leave the hull well short of it (two or three hull sides across the corner).
std::optional<Quad2d> LQuadFromHull(const std::vector<cv::Point>& hull) {
  std::vector<cv::Point> poly;
  cv::approxPolyDP(hull, poly, 0.03 * cv::arcLength(hull, true), true);
  const size_t n = poly.size();
  if (n != 5 && n != 6) return std::nullopt;
  std::vector<Eigen::Vector2d> p;
  for (const cv::Point& q : poly) p.emplace_back(q.x, q.y);
  const auto length = [&](size_t i) { return (p[(i + 1) % n] - p[i]).norm(); };
  size_t longest = 0;
  for (size_t i = 1; i < n; ++i) {
    if (length(i) > length(longest)) longest = i;
  }
  // Side i runs p[i] -> p[i+1]; its neighbours are sides i-1 and i+1.
  const size_t before = (longest + n - 1) % n, after = (longest + 1) % n;
  Eigen::Vector2d corner, end1, end2;
  if (length(before) >= length(after)) {
    corner = p[longest];
    end1 = p[before];
    end2 = p[(longest + 1) % n];
  } else {
    corner = p[(longest + 1) % n];
    end1 = p[longest];
    end2 = p[(after + 1) % n];
  }
  Quad2d quad = {corner, end1, end1 + end2 - corner, end2};
  if (Cross(quad[1] - quad[0], quad[2] - quad[1]) < 0) std::swap(quad[1], quad[3]);
  return quad;
}

struct SideSamples {
  double dark_fraction = 0.0;
  int runs = 0;  // dark runs along the side
};

// Samples just inside side (a -> b) of a clockwise quad in the binary image (255 = dark).
SideSamples SampleSide(const cv::Mat& dark, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const Eigen::Vector2d d = b - a;
  const double length = d.norm();
  const Eigen::Vector2d inward = Eigen::Vector2d(-d.y(), d.x()) / length;
  const Eigen::Vector2d offset = inward * std::max(1.0, kInsetFraction * length);
  const int n = std::max(12, static_cast<int>(length));
  SideSamples out;
  int dark_count = 0, counted = 0;
  bool previous = false;
  for (int i = 0; i < n; ++i) {
    const double t = 0.08 + 0.84 * i / (n - 1);
    const Eigen::Vector2d p = a + t * d + offset;
    const int x = static_cast<int>(std::lround(p.x())), y = static_cast<int>(std::lround(p.y()));
    if (x < 0 || y < 0 || x >= dark.cols || y >= dark.rows) continue;
    const bool is_dark = dark.at<uint8_t>(y, x) != 0;
    dark_count += is_dark;
    ++counted;
    out.runs += is_dark && !previous;
    previous = is_dark;
  }
  out.dark_fraction = counted > 0 ? static_cast<double>(dark_count) / counted : 0.0;
  return out;
}

// How much the quad's inside varies, relative to the contrast of its border: the standard
// deviation of the gray levels in its middle half over (mean just outside the sides - mean
// just inside them). About 0.5 inside a tag (dark and light bits), near 0 inside a filled
// box or an empty frame.
double InteriorSpread(const cv::Mat& gray, const Quad2d& q) {
  const auto at = [&gray](const Eigen::Vector2d& p) -> std::optional<double> {
    const int x = static_cast<int>(std::lround(p.x())), y = static_cast<int>(std::lround(p.y()));
    if (x < 0 || y < 0 || x >= gray.cols || y >= gray.rows) return std::nullopt;
    return gray.at<uint8_t>(y, x);
  };
  double sum = 0.0, sum2 = 0.0;
  int n = 0;
  for (int i = 0; i < 7; ++i) {
    for (int j = 0; j < 7; ++j) {
      const double u = 0.25 + 0.5 * i / 6.0, v = 0.25 + 0.5 * j / 6.0;
      if (const auto g = at((1 - v) * ((1 - u) * q[0] + u * q[1]) + v * ((1 - u) * q[3] + u * q[2]))) {
        sum += *g;
        sum2 += *g * *g;
        ++n;
      }
    }
  }
  double inside = 0.0, outside = 0.0;
  int m = 0;
  const Eigen::Vector2d centre = QuadCenter(q);
  for (int k = 0; k < 4; ++k) {
    for (const double t : {0.3, 0.5, 0.7}) {
      const Eigen::Vector2d p = q[k] + t * (q[(k + 1) % 4] - q[k]);
      const Eigen::Vector2d in = (centre - p).normalized() * std::max(1.0, 0.03 * QuadMeanSide(q));
      const auto gi = at(p + in), go = at(p - 2.0 * in);
      if (!gi || !go) continue;
      inside += *gi;
      outside += *go;
      ++m;
    }
  }
  if (n < 10 || m < 6) return 0.0;
  const double mean = sum / n;
  const double stddev = std::sqrt(std::max(0.0, sum2 / n - mean * mean));
  return stddev / std::max(10.0, (outside - inside) / m);
}

bool Dashed(double dark_fraction, int runs) {
  return dark_fraction >= kDashedMin && dark_fraction < kSolidMin && runs >= kDashedMinRuns;
}

// Drops quads whose centre lies within half a side of a better one (input best first) and,
// when max_size_ratio is finite, whose mean side is within that ratio of it: a symbol inside a
// larger dark outline (the background around its card, a frame) is not that outline's duplicate.
template <typename T, typename QuadOf>
std::vector<T> Deduplicate(const std::vector<T>& sorted, int max_count, QuadOf quad_of,
                           double max_size_ratio = std::numeric_limits<double>::infinity()) {
  std::vector<T> kept;
  for (const T& c : sorted) {
    if (static_cast<int>(kept.size()) >= max_count) break;
    const Quad2d& q = quad_of(c);
    const bool duplicate = std::any_of(kept.begin(), kept.end(), [&](const T& k) {
      const double a = QuadMeanSide(quad_of(k)), b = QuadMeanSide(q);
      return (QuadCenter(quad_of(k)) - QuadCenter(q)).norm() < 0.5 * std::min(a, b) &&
             std::max(a, b) < max_size_ratio * std::min(a, b);
    });
    if (!duplicate) kept.push_back(c);
  }
  return kept;
}

std::vector<DarkQuad> ComputeDarkQuads(const cv::Mat& gray, double min_side_px,
                                       const std::vector<double>& scales);

}  // namespace

std::vector<DarkQuad> FindDarkQuads(const cv::Mat& gray, double min_side_px) {
  CV_Assert(gray.type() == CV_8UC1);
  // The families of one frame (DataMatrix, AprilTag) share one run, also on different
  // threads (PerImageCache: keyed by the pixels, so it is the result a new run would give).
  static PerImageCache<std::vector<DarkQuad>> cache;
  return cache.Get(gray, min_side_px, [&gray, min_side_px] {
    return ComputeDarkQuads(gray, min_side_px,
                            std::vector<double>(std::begin(kLevelScales), std::end(kLevelScales)));
  });
}

std::vector<DarkQuad> FindCoarseDarkQuads(const cv::Mat& gray, double min_side_px) {
  CV_Assert(gray.type() == CV_8UC1);
  static PerImageCache<std::vector<DarkQuad>> cache;
  return cache.Get(gray, min_side_px,
                   [&gray, min_side_px] { return ComputeDarkQuads(gray, min_side_px, {kCoarseLevelScale}); });
}

namespace {

std::vector<DarkQuad> ComputeDarkQuads(const cv::Mat& gray, double min_side_px,
                                       const std::vector<double>& scales) {
  std::vector<DarkQuad> all;
  for (const double scale : scales) {
    const int width = static_cast<int>(std::lround(gray.cols * scale));
    const int height = static_cast<int>(std::lround(gray.rows * scale));
    if (std::min(width, height) < 2 * kBoxPx) break;
    cv::Mat small;
    if (scale < 1.0) {
      cv::resize(gray, small, cv::Size(width, height), 0, 0, cv::INTER_AREA);
    } else {
      small = gray;
    }
    const cv::Mat dark = DarkerThanLocalMean(small, kBoxPx, kDarkerBy);
    const double min_side = std::max(8.0, min_side_px * scale);
    const bool last_level = scale == scales.back();
    // Dark components from runs (detect/components.h), sized by their boxes before any hull:
    // sensor noise and text make thousands of small components, each one run or a few.
    std::vector<RunComponent> components = RunComponents(dark, [&](const cv::Rect& box) {
      return std::max(box.width, box.height) >= min_side &&
             (last_level || std::min(box.width, box.height) <= kLevelMaxSidePx);
    });
    // Last found first (bottom-up), as cv::findContours listed them before.
    std::reverse(components.begin(), components.end());
    for (const RunComponent& component : components) {
      std::vector<cv::Point> hull;
      cv::convexHull(component.row_ends, hull);
      if (hull.size() < 4) continue;
      // A canonical start (approxPolyDP below depends on it): the hull's vertex after the
      // component's first pixel (top row, leftmost), which is always a vertex. This is where
      // cv::convexHull of the traced outline started too.
      const cv::Point first = component.row_ends.front();
      const auto at_first = std::find(hull.begin(), hull.end(), first);
      if (at_first != hull.end()) std::rotate(hull.begin(), at_first + 1, hull.end());
      const auto add = [&](const Quad2d& quad, bool l_completion) {
        double shortest = 1e300, longest = 0.0;
        for (int j = 0; j < 4; ++j) {
          const double side = (quad[(j + 1) % 4] - quad[j]).norm();
          shortest = std::min(shortest, side);
          longest = std::max(longest, side);
        }
        if (shortest < min_side || longest > kMaxAspect * shortest) return;
        DarkQuad q;
        for (int j = 0; j < 4; ++j) {
          const SideSamples side = SampleSide(dark, quad[j], quad[(j + 1) % 4]);
          q.side_dark[j] = side.dark_fraction;
          q.side_runs[j] = side.runs;
        }
        q.interior_spread = InteriorSpread(small, quad);
        // Work pixels -> frame pixels (pixel centres: scaling is about pixel edges), and the
        // outline through the dark pixels' centres -> their outer edges (half a pixel out).
        const Eigen::Vector2d centre = QuadCenter(quad);
        for (int j = 0; j < 4; ++j) {
          const Eigen::Vector2d out = (quad[j] - centre).normalized() * 0.5;
          q.corners_px[j] = ((quad[j] + out).array() + 0.5) / scale - 0.5;
        }
        q.scale = scale;
        q.l_completion = l_completion;
        all.push_back(q);
      };
      const std::optional<Quad2d> quad = QuadFromHull(hull);
      if (quad) add(*quad, false);
      // The L's own quad when the hull has five or six corners and its two longest adjacent
      // sides complete to another quad (DataMatrixCandidates only).
      if (const std::optional<Quad2d> l_quad = LQuadFromHull(hull)) {
        const bool same = quad && [&] {
          for (int j = 0; j < 4; ++j) {
            const double d =
                std::min({((*l_quad)[j] - (*quad)[0]).norm(), ((*l_quad)[j] - (*quad)[1]).norm(),
                          ((*l_quad)[j] - (*quad)[2]).norm(), ((*l_quad)[j] - (*quad)[3]).norm()});
            if (d > kCompletionTolerance * QuadMeanSide(*quad)) return false;
          }
          return true;
        }();
        if (!same) add(*l_quad, true);
      }
    }
  }
  return all;
}

}  // namespace

std::vector<DataMatrixCandidate> DataMatrixCandidates(const std::vector<DarkQuad>& quads,
                                                      int max_candidates) {
  std::vector<DataMatrixCandidate> all;
  for (const DarkQuad& q : quads) {
    if (q.interior_spread < kDataMatrixMinSpread) continue;
    std::optional<DataMatrixCandidate> best;
    for (int k = 0; k < 4; ++k) {
      // Corner k is the L's corner: sides k-1 (ends at k) and k (starts at k) solid, the
      // two others dashed (the timing pattern).
      const int s1 = (k + 3) % 4, s2 = k, t1 = (k + 1) % 4, t2 = (k + 2) % 4;
      if (q.side_dark[s1] < kLSolidMin || q.side_dark[s2] < kLSolidMin) continue;
      if (!Dashed(q.side_dark[t1], q.side_runs[t1]) || !Dashed(q.side_dark[t2], q.side_runs[t2])) continue;
      // The L's solidity, and among orientations of one quad the one whose other two sides
      // alternate most (the timing pattern).
      const int runs = std::min(std::min(q.side_runs[t1], q.side_runs[t2]), kRunsForFullScore);
      const double score = std::min(q.side_dark[s1], q.side_dark[s2]) *
                           (0.8 + 0.2 * runs / kRunsForFullScore) *
                           (q.l_completion ? kLCompletionScale : 1.0);
      if (best && best->score >= score) continue;
      DataMatrixCandidate c;
      // The L's corner is the upright symbol's bottom-left: TL, TR, BR, BL = k+1, k+2, k+3, k.
      for (int i = 0; i < 4; ++i) c.corners_px[i] = q.corners_px[(k + 1 + i) % 4];
      // The hull may cut deep into the top-right corner (light timing and data modules
      // there leave the dark component short of it): unless the hull's corner is near it,
      // the L's parallelogram completion is the better guess.
      const Eigen::Vector2d completion = c.corners_px[0] + c.corners_px[2] - c.corners_px[3];
      if ((c.corners_px[1] - completion).norm() > kCompletionTolerance * QuadMeanSide(c.corners_px)) {
        c.corners_px[1] = completion;
      }
      c.score = score;
      best = c;
    }
    if (!best) {
      // An L alone: two adjacent solid sides and the others not (light modules near the
      // far corner can leave the component's hull well inside the timing pattern, so the
      // hull's other sides run through the quiet zone). The far corner is the L's
      // parallelogram completion; ranked after every L with its timing pattern.
      for (int k = 0; k < 4; ++k) {
        const int s1 = (k + 3) % 4, s2 = k, t1 = (k + 1) % 4, t2 = (k + 2) % 4;
        if (q.side_dark[s1] < kLAloneSolidMin || q.side_dark[s2] < kLAloneSolidMin) continue;
        if (q.side_dark[t1] >= kSolidMin || q.side_dark[t2] >= kSolidMin) continue;
        const double score = kLAloneScale * std::min(q.side_dark[s1], q.side_dark[s2]) *
                             (q.l_completion ? kLCompletionScale : 1.0);
        if (best && best->score >= score) continue;
        DataMatrixCandidate c;
        for (int i = 0; i < 4; ++i) c.corners_px[i] = q.corners_px[(k + 1 + i) % 4];
        c.corners_px[1] = c.corners_px[0] + c.corners_px[2] - c.corners_px[3];
        c.score = score;
        best = c;
      }
    }
    if (best) all.push_back(*best);
  }
  std::stable_sort(all.begin(), all.end(), [](const DataMatrixCandidate& a, const DataMatrixCandidate& b) {
    return a.score > b.score;
  });
  return Deduplicate(
      all, max_candidates, [](const DataMatrixCandidate& c) -> const Quad2d& { return c.corners_px; },
      kDuplicateMaxSizeRatio);
}

std::vector<Quad2d> SolidBorderQuads(const std::vector<DarkQuad>& quads, double max_side_px,
                                     int max_candidates) {
  std::vector<std::pair<double, Quad2d>> all;
  for (const DarkQuad& q : quads) {
    if (q.l_completion || QuadMeanSide(q.corners_px) > max_side_px) continue;
    const double solid = std::min({q.side_dark[0], q.side_dark[1], q.side_dark[2], q.side_dark[3]});
    if (solid < kSolidMin) continue;
    // A tag's inside mixes dark and light bits (a filled box or an empty frame is even).
    if (q.interior_spread < kInteriorMinSpread) continue;
    all.push_back({solid, q.corners_px});
  }
  std::stable_sort(all.begin(), all.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  std::vector<Quad2d> sorted;
  for (const auto& a : all) sorted.push_back(a.second);
  return Deduplicate(sorted, max_candidates, [](const Quad2d& q) -> const Quad2d& { return q; });
}

}  // namespace waymark
