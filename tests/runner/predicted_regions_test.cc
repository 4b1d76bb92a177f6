#include "runner/predicted_regions.h"

#include <gtest/gtest.h>

#include <limits>
#include <memory>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "detect/common.h"
#include "detect/detector.h"
#include "detect/synthetic.h"

namespace waymark {
namespace {

Vector8d Square(double x0, double y0, double side) {
  Vector8d px;
  px << x0, y0, x0 + side, y0, x0 + side, y0 + side, x0, y0 + side;
  return px;
}

TEST(PredictedRegions, GrowClipAndMerge) {
  PredictedRegionOptions options;  // half the side, at least 24 px
  const cv::Size image(640, 480);
  // A 100 px code: 50 px around it; a 20 px code: 24 px.
  std::vector<PredictedRegion> regions =
      PredictedRegions({Square(200, 200, 100), Square(500, 50, 20)}, image, options);
  ASSERT_EQ(regions.size(), 2u);
  EXPECT_EQ(regions[0].rect, cv::Rect(cv::Point(150, 150), cv::Point(351, 351)));
  EXPECT_EQ(regions[1].rect, cv::Rect(cv::Point(476, 26), cv::Point(545, 95)));
  EXPECT_EQ(regions[1].codes, 1);
  // At the border: clipped; entirely outside or not finite: dropped.
  Vector8d nan = Square(10, 10, 30);
  nan[3] = std::numeric_limits<double>::quiet_NaN();
  regions = PredictedRegions({Square(-20, 400, 60), Square(900, 100, 40), nan}, image, options);
  ASSERT_EQ(regions.size(), 1u);
  EXPECT_EQ(regions[0].rect, cv::Rect(cv::Point(0, 370), cv::Point(71, 480)));
  // Overlapping boxes become their union, also through a third one.
  regions =
      PredictedRegions({Square(100, 100, 60), Square(300, 100, 60), Square(190, 100, 60)}, image, options);
  ASSERT_EQ(regions.size(), 1u);
  EXPECT_EQ(regions[0].rect, cv::Rect(cv::Point(70, 70), cv::Point(391, 191)));
  EXPECT_EQ(regions[0].codes, 3);
  std::string why;
  options.full_frame_every = 0;
  EXPECT_FALSE(options.Check(&why));
  EXPECT_NE(why.find("full_frame_every"), std::string::npos);
}

TEST(PredictedRegions, PolicyLooksAtTheWholeFrameEveryNFramesAndWhenNotTracking) {
  PredictedRegionOptions options;
  options.full_frame_every = 3;
  PredictedRegionPolicy policy(options);
  std::vector<bool> left;
  for (int i = 0; i < 7; ++i) left.push_back(policy.WholeFrame("left", true));
  EXPECT_EQ(left, (std::vector<bool>{true, false, false, true, false, false, true}));
  EXPECT_TRUE(policy.WholeFrame("right", true));  // each camera its own count
  EXPECT_FALSE(policy.WholeFrame("right", true));
  EXPECT_TRUE(policy.WholeFrame("right", false));  // not tracking: at once
  EXPECT_FALSE(policy.WholeFrame("right", true));
  options.full_frame_every = 1;
  PredictedRegionPolicy always(options);
  for (int i = 0; i < 3; ++i) EXPECT_TRUE(always.WholeFrame("left", true));
}

// The code in the predicted region is found, with the corners of a whole-frame detection in
// full-image pixels; a code outside every region is not looked at.
TEST(PredictedRegions, DetectInRegionsFindsTheCodeWhereTheMapSays) {
  cv::Mat image(960, 1280, CV_8U, cv::Scalar(200));
  const Quad2d a = MakeQuad({400.0, 300.0}, 120.0, 0.3, 0.9);
  const Quad2d b = MakeQuad({950.0, 650.0}, 110.0, -0.2);
  DrawSymbol(QrSymbol("here"), a, &image);
  DrawSymbol(DataMatrixSymbol("elsewhere"), b, &image);
  const auto detector = CreateMultiDetector({"qr", "datamatrix"});
  DetectorOptions options;
  options.close_up = false;
  const auto in_regions = CreateMultiDetector({"qr", "datamatrix"}, options);
  options.second_pass = false;
  const auto first_pass = CreateMultiDetector({"qr", "datamatrix"}, options);
  const std::vector<MarkerObservation> whole = detector->Detect(image);
  ASSERT_EQ(whole.size(), 2u);
  // The prediction 6 px off the truth.
  Vector8d predicted;
  for (int k = 0; k < 4; ++k) predicted.segment<2>(2 * k) = a[k] + Eigen::Vector2d(6.0, -4.0);
  const std::vector<PredictedRegion> regions =
      PredictedRegions({predicted}, image.size(), PredictedRegionOptions{});
  ASSERT_EQ(regions.size(), 1u);
  int skipped = 0;
  const std::vector<MarkerObservation> found = DetectInRegions(*in_regions, image, regions, &skipped);
  ASSERT_EQ(found.size(), 1u);
  EXPECT_EQ(found[0].key.id, "here");
  EXPECT_EQ(skipped, 0);
  const MarkerObservation& reference = whole[0].key.id == "here" ? whole[0] : whole[1];
  for (int k = 0; k < 4; ++k) {
    EXPECT_LT((found[0].corners_px[k] - a[k]).norm(), 0.3) << k;
    EXPECT_LT((found[0].corners_px[k] - reference.corners_px[k]).norm(), 0.05) << k;
  }
  EXPECT_TRUE(DetectInRegions(*in_regions, image, {}).empty());
  // A light-on-dark code only the second passes read (inverted crops): the first passes find
  // fewer codes than predicted, so the region gets the second passes.
  cv::Mat dark(480, 640, CV_8U, cv::Scalar(40));
  const Quad2d c = MakeQuad({320.0, 240.0}, 140.0, 0.1);
  DrawSymbol(QrSymbol("inverted"), c, &dark, 235, 20);
  Vector8d at;
  for (int k = 0; k < 4; ++k) at.segment<2>(2 * k) = c[k];
  const std::vector<PredictedRegion> one = PredictedRegions({at}, dark.size(), PredictedRegionOptions{});
  ASSERT_TRUE(first_pass->Detect(dark(one[0].rect)).empty());
  const std::vector<MarkerObservation> inverted = DetectInRegions(*in_regions, dark, one);
  ASSERT_EQ(inverted.size(), 1u);
  EXPECT_EQ(inverted[0].key.id, "inverted");
}

// Counts the stages DetectInRegions asks of a detector (and forwards them).
class CountingDetector : public MarkerDetector {
 public:
  explicit CountingDetector(std::unique_ptr<MarkerDetector> inner) : inner_(std::move(inner)) {}
  std::vector<std::string> Families() const override { return inner_->Families(); }
  std::vector<MarkerObservation> Detect(const cv::Mat& image) override {
    ++detects;
    return inner_->Detect(image);
  }
  std::vector<MarkerObservation> DetectFirstPass(const cv::Mat& image) override {
    ++first_passes;
    return inner_->DetectFirstPass(image);
  }
  std::vector<MarkerObservation> DetectSecondPasses() override {
    ++second_passes;
    return inner_->DetectSecondPasses();
  }
  int detects = 0, first_passes = 0, second_passes = 0;

 private:
  std::unique_ptr<MarkerDetector> inner_;
};

// A region whose code the first pass misses (light on dark) is still read, by the second passes
// alone: the first pass runs once per region, never again, and a region whose code the first
// pass read gets no second passes. The result is what the full detector gives on the crop.
TEST(PredictedRegions, SecondPassesContinueFromTheFirstPass) {
  cv::Mat image(480, 1280, CV_8U, cv::Scalar(200));
  const Quad2d plain = MakeQuad({250.0, 240.0}, 120.0, 0.2);
  DrawSymbol(QrSymbol("plain"), plain, &image);
  cv::rectangle(image, cv::Rect(700, 40, 400, 400), cv::Scalar(40), cv::FILLED);
  const Quad2d dark = MakeQuad({900.0, 240.0}, 130.0, -0.1);
  DrawSymbol(QrSymbol("inverted"), dark, &image, 235, 20);
  std::vector<Vector8d> quads(2);
  for (int k = 0; k < 4; ++k) {
    quads[0].segment<2>(2 * k) = plain[k];
    quads[1].segment<2>(2 * k) = dark[k];
  }
  const std::vector<PredictedRegion> regions =
      PredictedRegions(quads, image.size(), PredictedRegionOptions{});
  ASSERT_EQ(regions.size(), 2u);
  DetectorOptions options;
  options.close_up = false;
  CountingDetector counting(CreateMultiDetector({"qr", "datamatrix"}, options));
  const std::vector<MarkerObservation> found = DetectInRegions(counting, image, regions);
  ASSERT_EQ(found.size(), 2u);
  EXPECT_EQ(found[0].key.id, "plain");
  EXPECT_EQ(found[1].key.id, "inverted");
  EXPECT_EQ(counting.first_passes, 2);
  EXPECT_EQ(counting.second_passes, 1);  // the dark region only
  EXPECT_EQ(counting.detects, 0);
  // The same as the full detector run from scratch on the dark region's crop.
  std::vector<MarkerObservation> full =
      CreateMultiDetector({"qr", "datamatrix"}, options)->Detect(image(regions[1].rect));
  MapFromCrop(regions[1].rect.tl(), 1.0, &full);
  ASSERT_EQ(full.size(), 1u);
  EXPECT_EQ(full[0].quality, found[1].quality);
  for (int k = 0; k < 4; ++k) EXPECT_EQ(full[0].corners_px[k], found[1].corners_px[k]) << k;
}

}  // namespace
}  // namespace waymark
