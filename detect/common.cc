#include "detect/common.h"

#include <time.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <mutex>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "detect/refine.h"

namespace waymark {

double FrameClock::ThreadCpuMs() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

namespace {

uint64_t ComputePixelHash(const cv::Mat& gray);

// The images of the live PixelHashScopes and their hashes.
struct ScopedHash {
  size_t id;
  const uchar* data;
  cv::Size size;
  int type;
  size_t step;
  uint64_t hash;
};
std::mutex scoped_mutex;
std::vector<ScopedHash> scoped_hashes;
std::atomic<int> scoped_count{0};
size_t next_scope_id = 0;

bool ScopedHashOf(const cv::Mat& gray, uint64_t* hash) {
  if (scoped_count.load(std::memory_order_acquire) == 0) return false;
  std::lock_guard<std::mutex> lock(scoped_mutex);
  for (const ScopedHash& s : scoped_hashes) {
    if (s.data == gray.data && s.size == gray.size() && s.type == gray.type() && s.step == gray.step[0]) {
      *hash = s.hash;
      return true;
    }
  }
  return false;
}

}  // namespace

PixelHashScope::PixelHashScope(const cv::Mat& gray) {
  const uint64_t hash = PixelHash(gray);
  std::lock_guard<std::mutex> lock(scoped_mutex);
  id_ = next_scope_id++;
  scoped_hashes.push_back({id_, gray.data, gray.size(), gray.type(), gray.step[0], hash});
  scoped_count.fetch_add(1, std::memory_order_release);
}

PixelHashScope::~PixelHashScope() {
  std::lock_guard<std::mutex> lock(scoped_mutex);
  for (size_t i = 0; i < scoped_hashes.size(); ++i) {
    if (scoped_hashes[i].id == id_) {
      scoped_hashes.erase(scoped_hashes.begin() + static_cast<std::ptrdiff_t>(i));
      break;
    }
  }
  scoped_count.fetch_sub(1, std::memory_order_release);
}

uint64_t PixelHash(const cv::Mat& gray) {
  CV_Assert(gray.depth() == CV_8U);
  uint64_t hash = 0;
  if (ScopedHashOf(gray, &hash)) return hash;
  return ComputePixelHash(gray);
}

namespace {

uint64_t ComputePixelHash(const cv::Mat& gray) {
  const uint64_t kMul = 0x9E3779B97F4A7C15ull;
  uint64_t lane[4] = {1469598103934665603ull ^ (static_cast<uint64_t>(gray.cols) << 32) ^ uint64_t(gray.rows),
                      0x243F6A8885A308D3ull, 0x13198A2E03707344ull, 0xA4093822299F31D0ull};
  const int bytes = gray.cols * static_cast<int>(gray.elemSize());
  for (int y = 0; y < gray.rows; ++y) {
    const uint8_t* row = gray.ptr<uint8_t>(y);
    int x = 0;
    for (; x + 32 <= bytes; x += 32) {
      for (int k = 0; k < 4; ++k) {
        uint64_t word;
        std::memcpy(&word, row + x + 8 * k, 8);
        lane[k] = (lane[k] ^ word) * kMul;
        lane[k] ^= lane[k] >> 29;
      }
    }
    for (; x < bytes; ++x) lane[0] = (lane[0] ^ row[x]) * 1099511628211ull;
  }
  uint64_t h = lane[0];
  for (int k = 1; k < 4; ++k) {
    h = (h ^ lane[k]) * kMul;
    h ^= h >> 31;
  }
  return h;
}

}  // namespace

double FrameClock::ProcessCpuMs() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

cv::Mat ToGray8(const cv::Mat& image) {
  if (image.empty()) throw std::invalid_argument("detector: empty image");
  cv::Mat gray;
  switch (image.type()) {
    case CV_8UC1:
      return image;
    case CV_8UC3:
      cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
      return gray;
    case CV_8UC4:
      cv::cvtColor(image, gray, cv::COLOR_BGRA2GRAY);
      return gray;
    case CV_16UC1:
      image.convertTo(gray, CV_8U, 1.0 / 256.0);
      return gray;
    default:
      throw std::invalid_argument("detector: unsupported pixel type " + std::to_string(image.type()) +
                                  " (expected 8-bit gray, BGR or BGRA, or 16-bit gray)");
  }
}

namespace {

double ComputeNoiseSigma(const cv::Mat& gray) {
  if (gray.cols < 2) return 0.0;
  std::array<int64_t, 256> histogram{};
  int64_t n = 0;
  for (int y = 0; y < gray.rows; y += 4) {
    const uint8_t* row = gray.ptr<uint8_t>(y);
    for (int x = 0; x + 1 < gray.cols; ++x) ++histogram[std::abs(row[x + 1] - row[x])];
    n += gray.cols - 1;
  }
  if (n == 0) return 0.0;
  // The median of the absolute differences, linear within its level: level 0 stands for
  // [0, 0.5), level k > 0 for [k - 0.5, k + 0.5).
  const double half = 0.5 * static_cast<double>(n);
  int64_t below = 0;
  double median = 0.0;
  for (int level = 0; level < 256; ++level) {
    if (static_cast<double>(below + histogram[level]) >= half) {
      const double lo = level == 0 ? 0.0 : level - 0.5, width = level == 0 ? 0.5 : 1.0;
      median = lo + width * (half - static_cast<double>(below)) / static_cast<double>(histogram[level]);
      break;
    }
    below += histogram[level];
  }
  return median / (0.6745 * std::sqrt(2.0));
}

}  // namespace

double NoiseSigma(const cv::Mat& gray) {
  CV_Assert(gray.type() == CV_8UC1);
  static PerImageCache<double> cache;
  return cache.Get(gray, 0.0, [&gray] { return ComputeNoiseSigma(gray); });
}

int NoiseAwareThreshold(int base, double noise_sigma, double levels_per_sigma) {
  if (!(noise_sigma > 0.0) || !(levels_per_sigma > 0.0)) return base;
  const double grown = std::round(std::min(levels_per_sigma * noise_sigma, 255.0));
  return std::max(base, static_cast<int>(grown));
}

namespace {

double Cross(const Eigen::Vector2d& a, const Eigen::Vector2d& b) { return a.x() * b.y() - a.y() * b.x(); }

bool Fail(std::string* why, const std::string& reason) {
  if (why != nullptr) *why = reason;
  return false;
}

}  // namespace

bool QuadIsValid(const Quad2d& corners_px, const cv::Size& image_size, double min_side_px, std::string* why) {
  for (const Eigen::Vector2d& c : corners_px) {
    if (!c.allFinite()) return Fail(why, "non-finite corner");
    if (c.x() < -0.5 || c.y() < -0.5 || c.x() > image_size.width - 0.5 || c.y() > image_size.height - 0.5) {
      return Fail(why, "corner outside the image");
    }
  }
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector2d side = corners_px[(i + 1) % 4] - corners_px[i];
    if (side.norm() < min_side_px) return Fail(why, "side shorter than the minimum");
    const Eigen::Vector2d next = corners_px[(i + 2) % 4] - corners_px[(i + 1) % 4];
    // Clockwise on screen (y down) means a positive cross product at every corner;
    // a small positive bound rejects near-collinear (degenerate) corners.
    if (Cross(side, next) <= 0.05 * side.norm() * next.norm()) {
      return Fail(why, "quad not convex and clockwise");
    }
  }
  return true;
}

Eigen::Vector2d QuadCenter(const Quad2d& corners_px) {
  return 0.25 * (corners_px[0] + corners_px[1] + corners_px[2] + corners_px[3]);
}

double QuadMeanSide(const Quad2d& corners_px) {
  double sum = 0.0;
  for (int i = 0; i < 4; ++i) sum += (corners_px[(i + 1) % 4] - corners_px[i]).norm();
  return 0.25 * sum;
}

Quad2d RotateCorners(const Quad2d& corners_px, int steps) {
  Quad2d out;
  const int s = ((steps % 4) + 4) % 4;
  for (int i = 0; i < 4; ++i) out[i] = corners_px[(i + s) % 4];
  return out;
}

bool SameDetection(const MarkerObservation& a, const MarkerObservation& b) {
  if (a.key != b.key) return false;
  const double side = std::min(QuadMeanSide(a.corners_px), QuadMeanSide(b.corners_px));
  return (QuadCenter(a.corners_px) - QuadCenter(b.corners_px)).norm() < 0.5 * side;
}

void AppendUnique(const std::vector<MarkerObservation>& found, std::vector<MarkerObservation>* all) {
  for (const MarkerObservation& f : found) {
    const bool seen = std::any_of(all->begin(), all->end(),
                                  [&](const MarkerObservation& a) { return SameDetection(a, f); });
    if (!seen) all->push_back(f);
  }
}

namespace {

// True if `p` is inside the convex quad, either winding.
bool InsideConvexQuad(const Quad2d& quad, const Eigen::Vector2d& p) {
  int positive = 0, negative = 0;
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector2d side = quad[(i + 1) % 4] - quad[i], to_p = p - quad[i];
    const double cross = side.x() * to_p.y() - side.y() * to_p.x();
    positive += cross > 0.0;
    negative += cross < 0.0;
  }
  return positive == 0 || negative == 0;
}

}  // namespace

bool AnyObservationAt(const std::vector<MarkerObservation>& found, const Eigen::Vector2d& centre_px) {
  return std::any_of(found.begin(), found.end(), [&centre_px](const MarkerObservation& o) {
    return (QuadCenter(o.corners_px) - centre_px).norm() < 0.5 * QuadMeanSide(o.corners_px) ||
           InsideConvexQuad(o.corners_px, centre_px);
  });
}

bool ObservationInside(const MarkerObservation& obs, const cv::Rect& rect) {
  const Eigen::Vector2d c = QuadCenter(obs.corners_px);
  return c.x() >= rect.x && c.y() >= rect.y && c.x() < rect.x + rect.width && c.y() < rect.y + rect.height;
}

void MapFromCrop(const cv::Point& offset, double scale, std::vector<MarkerObservation>* observations) {
  for (MarkerObservation& obs : *observations) {
    for (Eigen::Vector2d& c : obs.corners_px) {
      c = (c.array() + 0.5) / scale - 0.5;
      c += Eigen::Vector2d(offset.x, offset.y);
    }
  }
}

namespace {

// Score in (0, 1] of one blob's bounding box at work resolution; 0 rejects it.
double ScoreBox(const cv::Mat& small, const cv::Mat& edges, const std::vector<cv::Point>& contour,
                const cv::Rect& box, double scale_to_full, const CandidateOptions& options) {
  const double short_side = std::min(box.width, box.height);
  const double long_side = std::max(box.width, box.height);
  if (short_side / scale_to_full < options.min_side_px) return 0.0;
  const double aspect = long_side / short_side;
  if (aspect > options.max_aspect) return 0.0;
  const double area = static_cast<double>(box.area());
  const double edge_density = cv::countNonZero(edges(box)) / area;
  if (edge_density < options.min_edge_density) return 0.0;
  const double fill = std::min(1.0, cv::contourArea(contour) / area);
  cv::Scalar mean, stddev;
  cv::meanStdDev(small(box), mean, stddev);
  const double contrast = std::min(1.0, stddev[0] / 60.0);
  const double squareness = 1.0 - 0.5 * (aspect - 1.0) / std::max(options.max_aspect - 1.0, 1e-9);
  // Larger blobs first (text glyphs and small clutter are small); a box cut by the image
  // border holds at most part of a code.
  const double size = std::min(1.0, short_side / scale_to_full / options.preferred_side_px);
  const bool at_border =
      box.x <= 1 || box.y <= 1 || box.x + box.width >= small.cols - 1 || box.y + box.height >= small.rows - 1;
  return fill * std::min(1.0, edge_density / 0.3) * contrast * squareness * size * (at_border ? 0.5 : 1.0);
}

}  // namespace

std::vector<CandidateRegion> FindCodeCandidates(const cv::Mat& gray, const CandidateOptions& options) {
  const double scale = std::min(1.0, static_cast<double>(options.work_width_px) / gray.cols);
  cv::Mat small;
  if (scale < 1.0) {
    // At least one pixel each way: a 2000x1 image scaled by 0.32 has rows 0.32 (cv::resize
    // with fx, fy would round it to 0 and assert).
    const cv::Size size(std::max(1, static_cast<int>(std::lround(gray.cols * scale))),
                        std::max(1, static_cast<int>(std::lround(gray.rows * scale))));
    cv::resize(gray, small, size, 0, 0, cv::INTER_AREA);
  } else {
    small = gray;
  }
  cv::Mat edges, blobs;
  cv::Canny(small, edges, 50, 150);
  cv::dilate(edges, blobs, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(3, 3)), cv::Point(-1, -1), 2);
  std::vector<std::vector<cv::Point>> contours;
  // Every contour, not only the outermost: a code on a card, or touching clutter, is a blob
  // nested inside the card's outline.
  cv::findContours(blobs, contours, cv::RETR_LIST, cv::CHAIN_APPROX_SIMPLE);
  std::vector<CandidateRegion> regions;
  const cv::Rect full(0, 0, gray.cols, gray.rows);
  for (const auto& contour : contours) {
    const cv::Rect box = cv::boundingRect(contour);
    const double score = ScoreBox(small, edges, contour, box, scale, options);
    if (score <= 0.0) continue;
    const double margin = options.margin_fraction * std::max(box.width, box.height);
    const int x0 = static_cast<int>(std::floor((box.x - margin) / scale));
    const int y0 = static_cast<int>(std::floor((box.y - margin) / scale));
    const int x1 = static_cast<int>(std::ceil((box.x + box.width + margin) / scale));
    const int y1 = static_cast<int>(std::ceil((box.y + box.height + margin) / scale));
    regions.push_back({cv::Rect(cv::Point(x0, y0), cv::Point(x1, y1)) & full, score});
  }
  std::sort(regions.begin(), regions.end(),
            [](const CandidateRegion& a, const CandidateRegion& b) { return a.score > b.score; });
  // Greedy: drop a region overlapping a better one by more than 40 % (intersection over
  // union): a code's blob and its card's blob are the same candidate.
  std::vector<CandidateRegion> kept;
  for (const CandidateRegion& r : regions) {
    const bool overlaps = std::any_of(kept.begin(), kept.end(), [&](const CandidateRegion& k) {
      const double inter = (r.rect & k.rect).area();
      return inter > 0.4 * (r.rect.area() + k.rect.area() - inter);
    });
    if (!overlaps) kept.push_back(r);
    if (static_cast<int>(kept.size()) >= options.max_regions) break;
  }
  return kept;
}

std::vector<cv::Rect> SecondPassRegions(const cv::Mat& gray, int max_candidates, bool close_up) {
  // QR and DataMatrix ask for the same frame's regions: one computation (PerImageCache).
  static PerImageCache<std::vector<cv::Rect>> cache;
  return cache.Get(gray, max_candidates + (close_up ? 0.5 : 0.0), [&gray, max_candidates, close_up] {
    CandidateOptions options;
    options.max_regions = max_candidates;
    std::vector<cv::Rect> regions;
    // A close-up first: its code may fill the image and its candidates be parts of it.
    if (close_up && MayBeCloseUp(gray.size())) regions.push_back(cv::Rect(0, 0, gray.cols, gray.rows));
    for (const CandidateRegion& c : FindCodeCandidates(gray, options)) regions.push_back(c.rect);
    return regions;
  });
}

namespace {

double WallMs() {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

}  // namespace

FrameWork::FrameWork(double live_budget_ms, const std::vector<MarkerObservation>& read_by_others)
    : budget_ms_(live_budget_ms), read_by_others_(&read_by_others) {
  if (budget_ms_ > 0.0) start_ms_ = WallMs();
}

bool FrameWork::IsRead(const std::vector<MarkerObservation>& found, const Eigen::Vector2d& centre_px) const {
  return AnyObservationAt(found, centre_px) || AnyObservationAt(*read_by_others_, centre_px);
}

bool FrameWork::RegionIsRead(const cv::Rect& region, const std::vector<MarkerObservation>& found) const {
  return RegionIsMostlyOneCode(region, found) || RegionIsMostlyOneCode(region, *read_by_others_);
}

bool RegionIsMostlyOneCode(const cv::Rect& region, const std::vector<MarkerObservation>& codes) {
  constexpr double kCoveredFraction = 0.3;
  constexpr double kInsideFraction = 0.75;
  const Eigen::Vector2d region_centre(region.x + 0.5 * region.width, region.y + 0.5 * region.height);
  return std::any_of(codes.begin(), codes.end(), [&](const MarkerObservation& obs) {
    std::vector<cv::Point2f> corners;
    for (const Eigen::Vector2d& c : obs.corners_px) corners.emplace_back(c.x(), c.y());
    const cv::Rect box = cv::boundingRect(corners);
    if (ObservationInside(obs, region)) return box.area() >= kCoveredFraction * region.area();
    // A region inside the code: a blob of its modules.
    return InsideConvexQuad(obs.corners_px, region_centre) &&
           (box & region).area() >= kInsideFraction * region.area();
  });
}

bool FrameWork::Allow() {
  if (budget_ms_ <= 0.0 || WallMs() - start_ms_ < budget_ms_) return true;
  ++skipped_;
  return false;
}

double FrameWork::LeftMs() const {
  if (budget_ms_ <= 0.0) return std::numeric_limits<double>::infinity();
  return budget_ms_ - (WallMs() - start_ms_);
}

void RunSecondPass(const cv::Mat& gray, const std::vector<cv::Rect>& regions,
                   const std::vector<CropAttempt>& attempts, FrameWork* work,
                   std::vector<MarkerObservation>* found) {
  for (const cv::Rect& region : regions) {
    if (region.width < 8 || region.height < 8) continue;
    const bool covered = std::any_of(found->begin(), found->end(), [&](const MarkerObservation& o) {
      return ObservationInside(o, region);
    });
    if (covered || work->RegionIsRead(region, *found)) continue;
    const cv::Mat crop = gray(region);
    for (const CropAttempt& attempt : attempts) {
      if (!work->Allow()) continue;
      std::vector<MarkerObservation> decoded = attempt(crop);
      if (decoded.empty()) continue;
      MapFromCrop(region.tl(), 1.0, &decoded);
      AppendUnique(decoded, found);
      break;
    }
  }
}

std::vector<MarkerObservation> RefineObservations(const cv::Mat& gray,
                                                  const std::vector<MarkerObservation>& raw,
                                                  bool refine_corners) {
  std::vector<MarkerObservation> out;
  out.reserve(raw.size());
  for (MarkerObservation obs : raw) {
    if (refine_corners) {
      obs.quality = 0.0;
      if (const auto refined = RefineQuadCorners(gray, obs.corners_px)) {
        obs.corners_px = refined->corners_px;
        obs.quality = refined->inlier_fraction;
      }
    }
    out.push_back(obs);
  }
  return out;
}

std::vector<MarkerObservation> KeepValidObservations(const cv::Mat& gray,
                                                     const std::vector<MarkerObservation>& refined,
                                                     double min_side_px) {
  std::vector<MarkerObservation> out;
  for (const MarkerObservation& obs : refined) {
    if (!QuadIsValid(obs.corners_px, gray.size(), min_side_px)) continue;
    AppendUnique({obs}, &out);
  }
  return out;
}

std::vector<MarkerObservation> FinishObservations(const cv::Mat& gray,
                                                  const std::vector<MarkerObservation>& raw,
                                                  bool refine_corners, double min_side_px) {
  return KeepValidObservations(gray, RefineObservations(gray, raw, refine_corners), min_side_px);
}

void StagedDetection::CheckStarted() const {
  if (!started) throw std::logic_error("detector: DetectSecondPasses() without DetectFirstPass()");
}

}  // namespace waymark
