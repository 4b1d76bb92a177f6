// SkipsOtherFamilies (detect/common.h): a family's second passes skip the places other
// families' first passes read, and the multi-family detector hands those over between its
// stages, with the same result for any thread count.
#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "detect/common.h"
#include "detect/detector.h"
#include "detect/synthetic.h"

namespace waymark {
namespace {

// A light-on-dark QR code (only QR's second passes read it: the inverted crop of its
// candidate region) beside a DataMatrix symbol and an AprilTag that their first passes read.
cv::Mat Frame() {
  cv::Mat image(480, 640, CV_8U, cv::Scalar(200));
  DrawSymbol(DataMatrixSymbol("matrix"), MakeQuad({480.0, 110.0}, 100.0, -0.3), &image);
  DrawSymbol(AprilTagSymbol("apriltag-36h11", 7), MakeQuad({130.0, 360.0}, 100.0, 0.1), &image);
  cv::rectangle(image, cv::Rect(380, 250, 220, 220), cv::Scalar(40), cv::FILLED);
  DrawSymbol(QrSymbol("inverted"), MakeQuad({490.0, 360.0}, 120.0, 0.1), &image, 235, 20);
  return image;
}

bool Has(const std::vector<MarkerObservation>& found, const std::string& family, const std::string& id) {
  for (const MarkerObservation& obs : found) {
    if (obs.key.family == family && obs.key.id == id) return true;
  }
  return false;
}

TEST(OtherFamilies, RegionIsOneCodeWhenTheCodeFillsEnoughOfIt) {
  MarkerObservation code;
  code.corners_px = MakeQuad({100.0, 100.0}, 40.0, 0.0);
  // The code's box is 40x40 = 1600 px: one code of a 60x60 region (0.44), not of a 100x100 one.
  EXPECT_TRUE(RegionIsOneCode(cv::Rect(70, 70, 60, 60), {code}));
  EXPECT_FALSE(RegionIsOneCode(cv::Rect(50, 50, 100, 100), {code}));
  // Its centre must be inside.
  EXPECT_FALSE(RegionIsOneCode(cv::Rect(101, 70, 60, 60), {code}));
  EXPECT_FALSE(RegionIsOneCode(cv::Rect(70, 70, 60, 60), {}));
  EXPECT_TRUE(QuadIsOneOf(MakeQuad({105.0, 95.0}, 30.0, 0.3), {code}));
  EXPECT_FALSE(QuadIsOneOf(MakeQuad({125.0, 100.0}, 30.0, 0.0), {code}));
}

TEST(OtherFamilies, QrSecondPassesSkipAPlaceAnotherFamilyRead) {
  const cv::Mat image = Frame();
  DetectorOptions options;
  options.close_up = false;  // else the whole 640x480 image is a region too
  const auto qr = CreateDetector("qr", options);
  auto* skips = dynamic_cast<SkipsOtherFamilies*>(qr.get());
  ASSERT_NE(skips, nullptr);
  // Alone, the second passes read the light-on-dark code.
  EXPECT_FALSE(Has(qr->DetectFirstPass(image), "qr", "inverted"));
  EXPECT_TRUE(Has(qr->DetectSecondPasses(), "qr", "inverted"));
  // Told that another family read a code there (the dark square around it), they do not look
  // at it.
  MarkerObservation other;
  other.key = {"datamatrix", "there"};
  other.corners_px = {Eigen::Vector2d(380, 250), Eigen::Vector2d(599, 250), Eigen::Vector2d(599, 469),
                      Eigen::Vector2d(380, 469)};
  qr->DetectFirstPass(image);
  skips->SetOtherFamiliesCodes({other});
  EXPECT_FALSE(Has(qr->DetectSecondPasses(), "qr", "inverted"));
  // A new first pass forgets what was handed over.
  qr->DetectFirstPass(image);
  EXPECT_TRUE(Has(qr->DetectSecondPasses(), "qr", "inverted"));
  EXPECT_TRUE(Has(qr->Detect(image), "qr", "inverted"));
}

TEST(OtherFamilies, MultiDetectorReadsWhatEachFamilyReadsAloneForAnyThreadCount) {
  const cv::Mat image = Frame();
  const std::vector<std::string> families = {"qr", "datamatrix", "apriltag-36h11"};
  std::vector<MarkerObservation> alone;
  for (const std::string& family : families) {
    for (const MarkerObservation& obs : CreateDetector(family)->Detect(image)) alone.push_back(obs);
  }
  ASSERT_EQ(alone.size(), 3u);
  std::vector<MarkerObservation> one_thread;
  for (const int threads : {1, 2, 3}) {
    DetectorOptions options;
    options.threads = threads;
    const std::vector<MarkerObservation> all = CreateMultiDetector(families, options)->Detect(image);
    ASSERT_EQ(all.size(), alone.size()) << threads;
    for (size_t i = 0; i < all.size(); ++i) {
      EXPECT_EQ(all[i].key.family, alone[i].key.family);
      EXPECT_EQ(all[i].key.id, alone[i].key.id);
      for (int k = 0; k < 4; ++k) EXPECT_EQ(all[i].corners_px[k], alone[i].corners_px[k]);
    }
  }
}

}  // namespace
}  // namespace waymark
