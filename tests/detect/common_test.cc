// Shared detector pieces: quad validation, the family factory and its errors, options
// checks, candidate regions, the edge-based corner refinement, and the multi-family detector.
#include "detect/common.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <thread>

#include "detect/detector.h"
#include "detect/refine.h"
#include "detect/synthetic.h"
#include "detect/zxing.h"

namespace waymark {
namespace {

Quad2d Square(double x0, double y0, double side) {
  return {Eigen::Vector2d(x0, y0), Eigen::Vector2d(x0 + side, y0), Eigen::Vector2d(x0 + side, y0 + side),
          Eigen::Vector2d(x0, y0 + side)};
}

TEST(DetectCommon, QuadIsValidRejectsEachBadCase) {
  const cv::Size size(100, 80);
  std::string why;
  EXPECT_TRUE(QuadIsValid(Square(10, 10, 50), size, 6.0, &why)) << why;
  Quad2d nan_quad = Square(10, 10, 50);
  nan_quad[2].x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(QuadIsValid(nan_quad, size, 6.0, &why));
  EXPECT_EQ(why, "non-finite corner");
  EXPECT_FALSE(QuadIsValid(Square(60, 10, 50), size, 6.0, &why));
  EXPECT_EQ(why, "corner outside the image");
  EXPECT_FALSE(QuadIsValid(Square(10, 10, 3), size, 6.0, &why));
  EXPECT_EQ(why, "side shorter than the minimum");
  const Quad2d square = Square(10, 10, 50);
  const Quad2d mirrored = {square[1], square[0], square[3], square[2]};  // counter-clockwise
  EXPECT_FALSE(QuadIsValid(mirrored, size, 6.0, &why));
  EXPECT_EQ(why, "quad not convex and clockwise");
  Quad2d dart = Square(10, 10, 50);
  dart[2] = Eigen::Vector2d(20, 20);  // reflex corner
  EXPECT_FALSE(QuadIsValid(dart, size, 6.0, &why));
  Quad2d flat = Square(10, 10, 50);
  flat[2] = Eigen::Vector2d(35, 10.5);  // three corners nearly on one line
  EXPECT_FALSE(QuadIsValid(flat, size, 6.0, &why));
}

TEST(DetectCommon, RefinementRecoversCornersOfADarkSquare) {
  cv::Mat image(200, 200, CV_8U, cv::Scalar(220));
  const Quad2d truth = MakeQuad({101.3, 98.6}, 90.0, 0.3, 0.9);
  SymbolImage black;
  black.modules = cv::Mat(3, 3, CV_8U, cv::Scalar(255));
  black.modules.at<uint8_t>(1, 1) = 0;
  black.symbol = cv::Rect(1, 1, 1, 1);
  DrawSymbol(black, truth, &image);
  cv::GaussianBlur(image, image, cv::Size(0, 0), 1.0);
  Quad2d start = truth;
  const double offsets[4][2] = {{1.5, -1.0}, {-1.2, 1.4}, {0.8, 1.5}, {-1.5, -0.7}};
  for (int i = 0; i < 4; ++i) start[i] += Eigen::Vector2d(offsets[i][0], offsets[i][1]);
  const auto refined = RefineQuadCorners(image, start);
  ASSERT_TRUE(refined.has_value());
  for (int i = 0; i < 4; ++i) EXPECT_LT((refined->corners_px[i] - truth[i]).norm(), 0.05) << i;
  EXPECT_GT(refined->inlier_fraction, 0.9);
  // Nothing to refine on a blank image, and a wrong-handed quad finds no light-outside edge.
  EXPECT_FALSE(RefineQuadCorners(cv::Mat(200, 200, CV_8U, cv::Scalar(128)), start).has_value());
  const Quad2d reversed = {start[0], start[3], start[2], start[1]};
  EXPECT_FALSE(RefineQuadCorners(image, reversed).has_value());
}

TEST(DetectCommon, CandidatesCoverACodeAndIgnoreABlankFrame) {
  cv::Mat image(960, 1280, CV_8U, cv::Scalar(170));
  EXPECT_TRUE(FindCodeCandidates(image, CandidateOptions{}).empty());
  const Quad2d quad = MakeQuad({900.0, 300.0}, 150.0, 0.2);
  DrawSymbol(DataMatrixSymbol("candidate"), quad, &image);
  const auto regions = FindCodeCandidates(image, CandidateOptions{});
  ASSERT_FALSE(regions.empty());
  const cv::Rect& best = regions.front().rect;
  for (const auto& c : quad) EXPECT_TRUE(best.contains(cv::Point(int(c.x()), int(c.y())))) << best;
}

TEST(DetectCommon, FactoryFamiliesAndOptions) {
  const auto families = SupportedFamilies();
  EXPECT_NE(std::find(families.begin(), families.end(), "apriltag-36h11"), families.end());
  EXPECT_NE(std::find(families.begin(), families.end(), "qr"), families.end());
  for (const std::string& f : families) EXPECT_EQ(CreateDetector(f)->Families(), std::vector<std::string>{f});
  EXPECT_THROW(CreateDetector("aztec"), std::invalid_argument);
  EXPECT_THROW(CreateMultiDetector({}), std::invalid_argument);
  EXPECT_THROW(CreateMultiDetector({"qr", "qr"}), std::invalid_argument);
  EXPECT_EQ(ParseFamilyList("qr,datamatrix,apriltag-36h11"),
            (std::vector<std::string>{"qr", "datamatrix", "apriltag-36h11"}));
  EXPECT_THROW(ParseFamilyList(""), std::invalid_argument);
  EXPECT_THROW(ParseFamilyList("qr,"), std::invalid_argument);
  EXPECT_THROW(ParseFamilyList("qr,,datamatrix"), std::invalid_argument);
  EXPECT_THROW(ParseFamilyList("qr,ean13"), std::invalid_argument);
  DetectorOptions options;
  std::string why;
  EXPECT_TRUE(options.Check(&why));
  options.apriltag_decimate = 0.5;
  EXPECT_FALSE(options.Check(&why));
  EXPECT_EQ(why, "apriltag_decimate must be >= 1");
  EXPECT_THROW(CreateDetector("qr", options), std::invalid_argument);
  options = DetectorOptions{};
  options.threads = 0;
  EXPECT_FALSE(options.Check(&why));
  options = DetectorOptions{};
  options.live_budget_ms = -1.0;
  EXPECT_FALSE(options.Check(&why));
  EXPECT_EQ(why, "live_budget_ms must be >= 0");
  options.live_budget_ms = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(options.Check(&why));
  options = DetectorOptions{};
  options.max_qr_finder_candidates = -1;
  EXPECT_FALSE(options.Check(&why));
  EXPECT_EQ(why, "max_qr_finder_candidates must be >= 0");
}

TEST(DetectCommon, MultiDetectorReadsEveryFamilyInOneImage) {
  cv::Mat image(480, 1280, CV_8U, cv::Scalar(190));
  DrawSymbol(QrSymbol("q-1"), MakeQuad({220.0, 240.0}, 170.0, 0.1), &image);
  DrawSymbol(DataMatrixSymbol("d-2"), MakeQuad({640.0, 240.0}, 150.0, -0.1), &image);
  DrawSymbol(AprilTagSymbol("apriltag-36h11", 3), MakeQuad({1060.0, 240.0}, 170.0, 0.2), &image);
  auto detector = CreateMultiDetector({"qr", "datamatrix", "apriltag-36h11"});
  const auto found = detector->Detect(image);
  std::set<std::string> keys;
  for (const auto& obs : found) keys.insert(obs.key.ToString());
  EXPECT_EQ(keys, (std::set<std::string>{"qr:q-1", "datamatrix:d-2", "apriltag-36h11:3"}));
}

// Issue 14: the families on two threads give the same observations, in the same order, as
// on one.
TEST(DetectCommon, MultiDetectorOnTwoThreadsGivesTheSameResult) {
  cv::Mat image(480, 1280, CV_8U, cv::Scalar(190));
  DrawSymbol(QrSymbol("q-7"), MakeQuad({220.0, 240.0}, 120.0, 0.5, 0.8), &image);
  DrawSymbol(DataMatrixSymbol("d-8"), MakeQuad({640.0, 240.0}, 100.0, 0.8, 0.9), &image);
  DrawSymbol(AprilTagSymbol("apriltag-36h11", 9), MakeQuad({1060.0, 240.0}, 40.0, 0.2), &image);
  DetectorOptions options;
  const auto one = CreateMultiDetector({"qr", "datamatrix", "apriltag-36h11"}, options);
  options.threads = 2;
  const auto two = CreateMultiDetector({"qr", "datamatrix", "apriltag-36h11"}, options);
  const auto a = one->Detect(image);
  ASSERT_EQ(a.size(), 3u);
  for (int run = 0; run < 3; ++run) {
    const auto b = two->Detect(image);
    ASSERT_EQ(b.size(), a.size());
    for (size_t i = 0; i < a.size(); ++i) {
      EXPECT_EQ(b[i].key, a[i].key);
      for (int k = 0; k < 4; ++k) EXPECT_EQ(b[i].corners_px[k], a[i].corners_px[k]);
    }
  }
}

// Issue 14: the families of one frame read one shared image, on several threads at once, so no
// detector may write its pixels. libapriltag blurs the image it is given in place when it does not
// decimate it (quad_sigma > 0, quad_decimate 1: the crops of small tags, or the whole frame at
// apriltag_decimate 1): the blurred tag region changed what the refinement and, on other threads,
// the other families saw.
TEST(DetectCommon, DetectorsLeaveTheImageUnchanged) {
  cv::Mat image(480, 1280, CV_8U, cv::Scalar(190));
  DrawSymbol(QrSymbol("q-3"), MakeQuad({220.0, 240.0}, 120.0, 0.3, 0.8), &image);
  DrawSymbol(DataMatrixSymbol("d-4"), MakeQuad({640.0, 240.0}, 100.0, 0.4, 0.9), &image);
  DrawSymbol(AprilTagSymbol("apriltag-36h11", 5), MakeQuad({1000.0, 240.0}, 40.0, 0.2), &image);
  DrawSymbol(AprilTagSymbol("apriltag-36h11", 6), MakeQuad({1150.0, 240.0}, 90.0, -0.2), &image);
  const cv::Mat before = image.clone();
  for (const double decimate : {8.0, 1.0}) {
    for (const double sigma : {0.0, 0.8}) {
      for (const int threads : {1, 2}) {
        DetectorOptions options;
        options.apriltag_decimate = decimate;
        options.apriltag_blur_sigma = sigma;
        options.threads = threads;
        const auto found =
            CreateMultiDetector({"qr", "datamatrix", "apriltag-36h11"}, options)->Detect(image);
        EXPECT_GE(found.size(), 3u) << "decimate " << decimate << " sigma " << sigma;
        EXPECT_EQ(cv::countNonZero(image != before), 0)
            << "decimate " << decimate << " sigma " << sigma << " threads " << threads;
      }
    }
  }
}

// The shared whole-frame work: computed once per image content, also when asked from several
// threads at once; other pixels or another key compute anew.
TEST(DetectCommon, PerImageCacheComputesOncePerImage) {
  PerImageCache<int> cache;
  std::atomic<int> computed{0};
  cv::Mat image(64, 80, CV_8U, cv::Scalar(7));
  const auto compute = [&computed] {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    return ++computed;
  };
  std::vector<std::thread> threads;
  std::vector<int> got(4, 0);
  for (int i = 0; i < 4; ++i) threads.emplace_back([&, i] { got[i] = cache.Get(image, 1.0, compute); });
  for (std::thread& t : threads) t.join();
  EXPECT_EQ(computed.load(), 1);
  for (int g : got) EXPECT_EQ(g, 1);
  EXPECT_EQ(cache.Get(image, 2.0, compute), 2);  // another key
  image.at<uint8_t>(63, 79) = 8;                 // the same buffer drawn on
  EXPECT_EQ(cache.Get(image, 1.0, compute), 3);
  EXPECT_EQ(cache.Get(image, 1.0, compute), 3);
  EXPECT_NE(PixelHash(image), PixelHash(cv::Mat(64, 80, CV_8U, cv::Scalar(7))));
  // A computation that throws passes its exception to the caller.
  cv::Mat other(10, 10, CV_8U, cv::Scalar(1));
  EXPECT_THROW(cache.Get(other, 1.0, []() -> int { throw std::runtime_error("boom"); }), std::runtime_error);
}

// PixelHashScope: within it PixelHash of its image is the hash computed once (the same value),
// of another view of other pixels its own; after it the pixels are hashed anew.
TEST(DetectCommon, PixelHashScopeKeepsTheImagesHash) {
  cv::Mat image(48, 64, CV_8U);
  cv::randu(image, 0, 256);
  const uint64_t before = PixelHash(image);
  const cv::Mat roi = image(cv::Rect(8, 8, 32, 32));
  const uint64_t roi_hash = PixelHash(roi);
  {
    const PixelHashScope scope(image);
    EXPECT_EQ(PixelHash(image), before);
    EXPECT_EQ(PixelHash(roi), roi_hash);  // another view: not the scope's image
    {
      const PixelHashScope nested(roi);
      EXPECT_EQ(PixelHash(roi), roi_hash);
      EXPECT_EQ(PixelHash(image), before);
    }
    std::thread other([&] { EXPECT_EQ(PixelHash(image), before); });
    other.join();
  }
  image.at<uint8_t>(0, 0) ^= 1;  // after the scope, a change is seen
  EXPECT_NE(PixelHash(image), before);
}

// A close-up (at most 640x480) is itself the first second-pass region unless close_up is off
// (a crop of a larger frame: the live loop's predicted regions).
TEST(DetectCommon, CloseUpRegionOnlyForCloseUps) {
  cv::Mat image(240, 320, CV_8U, cv::Scalar(200));
  DrawSymbol(QrSymbol("close"), MakeQuad({160.0, 120.0}, 150.0, 0.2), &image);
  const std::vector<cv::Rect> with = SecondPassRegions(image, 8, true);
  ASSERT_FALSE(with.empty());
  EXPECT_EQ(with[0], cv::Rect(0, 0, 320, 240));
  for (const cv::Rect& r : SecondPassRegions(image, 8, false)) EXPECT_NE(r, cv::Rect(0, 0, 320, 240));
}

TEST(DetectCommon, OnlyImagesUpTo640x480MayBeCloseUps) {
  EXPECT_TRUE(MayBeCloseUp(cv::Size(640, 480)));
  EXPECT_TRUE(MayBeCloseUp(cv::Size(480, 640)));
  EXPECT_TRUE(MayBeCloseUp(cv::Size(320, 240)));
  EXPECT_FALSE(MayBeCloseUp(cv::Size(641, 480)));
  EXPECT_FALSE(MayBeCloseUp(cv::Size(1280, 960)));
  // A larger frame can still have a candidate region that is all of it (clutter across the
  // frame, padded and clipped): the region's size alone does not make it a close-up, so QR's
  // WeChat attempt asks MayBeCloseUp of the frame too (750 ms on one such issue frame).
  cv::Mat clutter(960, 1280, CV_8U);
  cv::RNG rng(3);
  for (int y = 0; y < clutter.rows; y += 8) {
    for (int x = 0; x < clutter.cols; x += 8) {
      clutter(cv::Rect(x, y, 8, 8)).setTo(cv::Scalar(rng.uniform(0, 2) ? 40 : 210));
    }
  }
  const std::vector<cv::Rect> regions = SecondPassRegions(clutter, 8, true);
  EXPECT_NE(std::find(regions.begin(), regions.end(), cv::Rect(0, 0, 1280, 960)), regions.end());
}

TEST(DetectCommon, IdsAreAlwaysValidUtf8) {
  EXPECT_EQ(TextToId("plain"), "plain");
  EXPECT_EQ(TextToId("caf\xc3\xa9"), "caf\xc3\xa9");
  EXPECT_EQ(TextToId(std::string("\xe9t\xe9")), "\xc3\xa9t\xc3\xa9");  // ISO-8859-1 bytes
  EXPECT_FALSE(IsValidUtf8("\xc3"));
  EXPECT_TRUE(IsValidUtf8(TextToId(std::string("\xff\x00\x80", 3))));
}

// RoundHalfAwayFromZero is std::lround bit for bit: halves (both signs), the doubles next to them
// (0.49999999999999994, where adding 0.5 and truncating goes wrong), integers, and random values.
TEST(DetectCommon, RoundHalfAwayFromZeroIsLround) {
  std::vector<double> values = {
      0.0, -0.0, 0.5, -0.5, 1.5, -1.5, 2.5, -2.5, 1e15 + 0.5, -1e15 - 0.5, 4503599627370495.5};
  for (const double h : {0.5, 1.5, 2.5, 99.5, 223.5}) {
    for (const double sign : {1.0, -1.0}) {
      values.push_back(sign * std::nextafter(h, 0.0));
      values.push_back(sign * std::nextafter(h, 1e9));
    }
  }
  cv::RNG rng(52);
  for (int i = 0; i < 100000; ++i) values.push_back(rng.uniform(-300.0, 300.0));
  for (int i = 0; i < 1000; ++i) values.push_back(std::round(rng.uniform(-300.0, 300.0) * 2.0) / 2.0);
  for (const double x : values) EXPECT_EQ(RoundHalfAwayFromZero(x), std::lround(x)) << std::hexfloat << x;
  EXPECT_EQ(RoundHalfAwayFromZero(std::nextafter(0.5, 0.0)), 0);
  EXPECT_EQ(RoundHalfAwayFromZero(-2.5), -3);
}

// A place is read when it is near a code's centre or anywhere inside its quad (a finder-like
// corner of a large code is neither a code nor the centre's neighbourhood).
TEST(DetectCommon, AnyObservationAtCoversTheWholeQuad) {
  MarkerObservation code;
  code.key = {"datamatrix", "x"};
  code.corners_px = MakeQuad({200.0, 150.0}, 100.0, 0.2, 1.0);
  const std::vector<MarkerObservation> found = {code};
  EXPECT_TRUE(AnyObservationAt(found, {200.0, 150.0}));
  // Near a corner, outside the half-side circle around the centre but inside the quad.
  const Eigen::Vector2d near_corner =
      code.corners_px[2] + 0.08 * (QuadCenter(code.corners_px) - code.corners_px[2]);
  EXPECT_GT((near_corner - QuadCenter(code.corners_px)).norm(), 0.5 * QuadMeanSide(code.corners_px));
  EXPECT_TRUE(AnyObservationAt(found, near_corner));
  // Just outside the corner, and well away from the code.
  const Eigen::Vector2d outside =
      code.corners_px[2] - 0.08 * (QuadCenter(code.corners_px) - code.corners_px[2]);
  EXPECT_FALSE(AnyObservationAt(found, outside));
  EXPECT_FALSE(AnyObservationAt(found, {400.0, 150.0}));
  // Either winding.
  MarkerObservation reversed = code;
  std::reverse(reversed.corners_px.begin(), reversed.corners_px.end());
  EXPECT_TRUE(AnyObservationAt({reversed}, near_corner));
  EXPECT_FALSE(AnyObservationAt({reversed}, outside));
}

// A region is one code when the code fills enough of it, or when the region is a blob of the
// code's own modules; not when the code is only part of a larger region or the region reaches
// well outside it.
TEST(DetectCommon, RegionIsMostlyOneCodeInsideAndAround) {
  MarkerObservation code;
  code.key = {"qr", "x"};
  code.corners_px = Square(100, 100, 120);
  const std::vector<MarkerObservation> codes = {code};
  EXPECT_TRUE(RegionIsMostlyOneCode(cv::Rect(70, 70, 180, 180), codes));   // padded code: 0.44
  EXPECT_FALSE(RegionIsMostlyOneCode(cv::Rect(20, 20, 300, 300), codes));  // 0.16 of it
  EXPECT_TRUE(RegionIsMostlyOneCode(cv::Rect(110, 180, 30, 30), codes));   // a blob inside
  EXPECT_TRUE(RegionIsMostlyOneCode(cv::Rect(195, 130, 28, 30), codes));   // a blob at its edge
  EXPECT_FALSE(RegionIsMostlyOneCode(cv::Rect(200, 130, 60, 30), codes));  // half outside
  EXPECT_FALSE(RegionIsMostlyOneCode(cv::Rect(400, 100, 30, 30), codes));  // elsewhere
  EXPECT_FALSE(RegionIsMostlyOneCode(cv::Rect(110, 180, 30, 30), {}));
}

// The noise estimate on flat, graded and code-holding frames under white noise of known sigma,
// and the thresholds that grow with it.
TEST(DetectCommon, NoiseSigmaOfWhiteNoiseOnFramesWithContent) {
  for (const double sigma : {1.5, 3.0, 5.0, 8.0, 12.0}) {
    cv::Mat frame(960, 1280, CV_8UC1);
    for (int y = 0; y < frame.rows; ++y) {
      for (int x = 0; x < frame.cols; ++x)
        frame.at<uint8_t>(y, x) = static_cast<uint8_t>(90 + x / 16 + y / 24);
    }
    DrawSymbol(QrSymbol("noise"), MakeQuad({400.0, 300.0}, 220.0, 0.3, 0.9), &frame);
    DrawSymbol(DataMatrixSymbol("noise"), MakeQuad({900.0, 600.0}, 160.0, -0.2, 0.85), &frame);
    cv::GaussianBlur(frame, frame, cv::Size(0, 0), 0.8);
    cv::RNG rng(static_cast<uint64_t>(sigma * 10));
    AddSensorNoise(rng, sigma, &frame);
    const double estimate = NoiseSigma(frame);
    EXPECT_NEAR(estimate, sigma, 0.15 * sigma + 0.3) << sigma;
    EXPECT_EQ(NoiseSigma(frame), estimate);  // cached, the same number
  }
  EXPECT_LT(NoiseSigma(cv::Mat(480, 640, CV_8UC1, cv::Scalar(77))), 0.3);  // every difference 0
  EXPECT_EQ(NoiseSigma(cv::Mat(5, 1, CV_8UC1, cv::Scalar(77))), 0.0);
  EXPECT_EQ(NoiseAwareThreshold(24, 2.0, 7.0), 24);
  EXPECT_EQ(NoiseAwareThreshold(24, 5.0, 7.0), 35);
  EXPECT_EQ(NoiseAwareThreshold(7, 3.5, 2.0), 7);
  EXPECT_EQ(NoiseAwareThreshold(7, 4.0, 2.0), 8);
  EXPECT_EQ(NoiseAwareThreshold(7, 1000.0, 2.0), 255);
  EXPECT_EQ(NoiseAwareThreshold(7, std::numeric_limits<double>::quiet_NaN(), 2.0), 7);
}

}  // namespace
}  // namespace waymark
