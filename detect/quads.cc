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
// ... or, on a noisy frame, this many noise sigmas of the level (NoiseAwareThreshold; the
// sensor noise of the frame, NoiseSigma, times the level's scale: its pixels are means of
// 1 / scale^2 frame pixels). Dark then stays as rare in a flat area as at 3.5 gray levels of
// noise, the most the recall bench renders: at 7 gray levels of noise a fixed 7 made a fifth
// of a flat frame dark, in clusters, and the full-resolution level cost 7 ms instead of 1.
constexpr double kDarkerByPerSigma = 2.0;
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
// The L found by its dark legs (LQuadFromDarkLegs): each leg at least this long in work pixels
// (an L whose modules join nothing has modules of at least a third of the 15 px box, so a
// 10 x 10 symbol's legs are 40+ px at that level; text, the commonest such hull, is 10-30 px),
// at most this ratio of the other (a square seen at up to 65 degrees of tilt: 2.4), and the
// line between their ends with at least this many dark runs. On issue-scenario seeds 1-3
// (DataMatrix only) these bounds took the quads made per frame from about 20 to 4 and the
// candidates from 11 more than before to 1 more, with the same symbols read.
constexpr double kLegsMinPx = 20.0;
constexpr double kLegsMaxRatio = 2.5;
constexpr int kAcrossMinRuns = 2;
constexpr int kRunsForFullScore = 5;
// DataMatrix: the hull's top-right corner is kept when within this fraction of the mean
// side of the L's parallelogram completion.
constexpr double kCompletionTolerance = 0.08;
constexpr double kMaxAspect = 3.5;  // longest / shortest side (tilted up to ~70 degrees)
// SolidBorderQuads: at most this many quads with three solid sides (after every four-sided
// one). Each is a libapriltag crop; frame corners and U shapes make many on cluttered frames
// (all of them: +51 % AprilTag instructions on the recall bench's issue frames).
constexpr int kMaxThreeSidedBorders = 4;
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
    const int x = static_cast<int>(RoundHalfAwayFromZero(p.x())),
              y = static_cast<int>(RoundHalfAwayFromZero(p.y()));
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

// The quad of an L found by its dark legs, for a hull that gave no quad: a DataMatrix symbol
// whose data and timing modules join its L finder only near it (large sharp symbols, where the
// box of the local mean spans a few modules and the lone timing modules are components of
// their own). Its hull's polygon (3 % of the perimeter) is then the L's triangle, or that
// triangle with a short cut where modules join a leg's end, which the side-ratio bound
// turns away. Every corner of a polygon of three to six corners is tried as the L's corner,
// its two sides as the legs: each at least kLegsMinPx long and at most kLegsMaxRatio times the
// other, both at least kLSolidMin dark just inside, and the line between their ends with at
// least kAcrossMinRuns dark runs and not solid (it crosses the data modules; a filled shape's
// is solid, a letter's or a frame corner's light). Of those, the corner whose legs span the
// largest parallelogram (the L's legs are its hull's longest dark sides; an outline has two
// dark sides at every corner) gives the quad, its far corner the parallelogram completion;
// clockwise on screen.
std::optional<Quad2d> LQuadFromDarkLegs(const std::vector<cv::Point>& hull, const cv::Mat& dark) {
  const double perimeter = cv::arcLength(hull, true);
  if (perimeter < 2.0 * kLegsMinPx) return std::nullopt;  // most hulls: text, noise
  std::vector<cv::Point> poly;
  cv::approxPolyDP(hull, poly, 0.03 * perimeter, true);
  const size_t n = poly.size();
  if (n < 3 || n > 6) return std::nullopt;
  std::vector<Eigen::Vector2d> p;
  for (const cv::Point& q : poly) p.emplace_back(q.x, q.y);
  // Clockwise on screen (y down), so that every side's inside is on the same hand.
  double area2 = 0.0;
  for (size_t i = 0; i < n; ++i) area2 += Cross(p[i], p[(i + 1) % n]);
  if (area2 < 0.0) std::reverse(p.begin(), p.end());
  // Side i runs p[i] -> p[i+1]; its dark fraction is sampled when first needed (-1: not yet).
  std::vector<double> side_dark(n, -1.0);
  const auto dark_of = [&](size_t i) {
    if (side_dark[i] < 0.0) side_dark[i] = SampleSide(dark, p[i], p[(i + 1) % n]).dark_fraction;
    return side_dark[i];
  };
  std::optional<Quad2d> best;
  double best_area = 0.0;
  for (size_t k = 0; k < n; ++k) {
    // Corner k's legs: side k-1 (into it) and side k (out of it).
    const Eigen::Vector2d& corner = p[k];
    const Eigen::Vector2d& a = p[(k + 1) % n];
    const Eigen::Vector2d& b = p[(k + n - 1) % n];
    const double la = (a - corner).norm(), lb = (b - corner).norm();
    if (std::min(la, lb) < kLegsMinPx || std::max(la, lb) > kLegsMaxRatio * std::min(la, lb)) continue;
    if (dark_of((k + n - 1) % n) < kLSolidMin || dark_of(k) < kLSolidMin) continue;
    const double area = std::abs(Cross(a - corner, b - corner));
    if (area <= best_area) continue;
    // An L's triangle holds the data modules: the line between the legs' ends crosses dark and
    // light ones (a filled shape's is solid, a letter's or a frame corner's light).
    const SideSamples across = SampleSide(dark, a, b);
    if (across.dark_fraction >= kSolidMin || across.runs < kAcrossMinRuns) continue;
    best_area = area;
    best = Quad2d{corner, a, a + b - corner, b};
  }
  return best;
}

// How much the quad's inside varies, relative to the contrast of its border: the standard
// deviation of the gray levels in its middle half over (mean just outside the sides - mean
// just inside them). About 0.5 inside a tag (dark and light bits), near 0 inside a filled
// box or an empty frame.
double InteriorSpread(const cv::Mat& gray, const Quad2d& q) {
  const auto at = [&gray](const Eigen::Vector2d& p) -> std::optional<double> {
    const int x = static_cast<int>(RoundHalfAwayFromZero(p.x())),
              y = static_cast<int>(RoundHalfAwayFromZero(p.y()));
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
  const double noise_sigma = NoiseSigma(gray);
  // The 1/2 and 1/4 levels in one pass (the same pixels as cv::resize's), when the sides allow.
  cv::Mat half, quarter;
  const bool half_and_quarter = std::count(scales.begin(), scales.end(), 0.5) > 0 &&
                                std::count(scales.begin(), scales.end(), 0.25) > 0 &&
                                HalfAndQuarterArea(gray, &half, &quarter);
  for (const double scale : scales) {
    const int width = static_cast<int>(std::lround(gray.cols * scale));
    const int height = static_cast<int>(std::lround(gray.rows * scale));
    if (std::min(width, height) < 2 * kBoxPx) break;
    cv::Mat small;
    if (half_and_quarter && (scale == 0.5 || scale == 0.25)) {
      small = scale == 0.5 ? half : quarter;
    } else if (scale == 0.125 && EighthArea(gray, &small)) {
      // FindCoarseDarkQuads' level, the pixels of cv::resize's in one pass.
    } else if (scale < 1.0) {
      cv::resize(gray, small, cv::Size(width, height), 0, 0, cv::INTER_AREA);
    } else {
      small = gray;
    }
    const cv::Mat dark = DarkerThanLocalMean(
        small, kBoxPx, NoiseAwareThreshold(kDarkerBy, scale * noise_sigma, kDarkerByPerSigma));
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
      std::vector<cv::Point> hull = RowEndsHull(component.row_ends);
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
        if (shortest < min_side || longest > kMaxAspect * shortest) return false;
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
        return true;
      };
      const std::optional<Quad2d> quad = QuadFromHull(hull);
      const bool hull_quad_kept = quad && add(*quad, false);
      // Corners of `a` each within kCompletionTolerance of the mean side of `b` of a corner of `b`.
      const auto same_quad = [](const Quad2d& a, const Quad2d& b) {
        for (int j = 0; j < 4; ++j) {
          const double d = std::min(
              {(a[j] - b[0]).norm(), (a[j] - b[1]).norm(), (a[j] - b[2]).norm(), (a[j] - b[3]).norm()});
          if (d > kCompletionTolerance * QuadMeanSide(b)) return false;
        }
        return true;
      };
      // The L's own quad when the hull has five or six corners and its two longest adjacent
      // sides complete to another quad (DataMatrixCandidates only).
      const std::optional<Quad2d> l_quad = LQuadFromHull(hull);
      if (l_quad && !(quad && same_quad(*l_quad, *quad))) add(*l_quad, true);
      // No quad kept from the hull: an L whose other modules join it only near it.
      if (!hull_quad_kept) {
        const std::optional<Quad2d> leg_quad = LQuadFromDarkLegs(hull, dark);
        if (leg_quad && !(l_quad && same_quad(*leg_quad, *l_quad))) add(*leg_quad, true);
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
    // Its sides' dark fractions, least dark first: four solid sides, or three (a dark bar
    // across the border joins the component, whose hull then bulges where the bar leaves and
    // puts one side of the quad partly outside the border), ranked after every four-sided one.
    std::array<double, 4> dark = q.side_dark;
    std::sort(dark.begin(), dark.end());
    if (dark[1] < kSolidMin) continue;
    // A tag's inside mixes dark and light bits (a filled box or an empty frame is even).
    if (q.interior_spread < kInteriorMinSpread) continue;
    all.push_back({dark[0] >= kSolidMin ? dark[0] : dark[0] - 1.0, q.corners_px});
  }
  std::stable_sort(all.begin(), all.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  std::vector<Quad2d> sorted;
  int three_sided = 0;
  for (const auto& a : all) {
    if (a.first < 0.0 && ++three_sided > kMaxThreeSidedBorders) break;
    sorted.push_back(a.second);
  }
  return Deduplicate(sorted, max_candidates, [](const Quad2d& q) -> const Quad2d& { return q; });
}

}  // namespace waymark
