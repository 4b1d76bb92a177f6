// AprilTag detector on tags drawn from libapriltag's own code tables through known
// homographies: ids exact, libapriltag's corner order and pixel offset converted to
// docs/design.md order and OpenCV pixel centres in all four rotations, several families.
#include "detect/apriltag.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <opencv2/imgproc.hpp>

#include "detect/detector.h"
#include "detect/synthetic.h"

namespace waymark {
namespace {

cv::Mat Canvas(int width = 640, int height = 480) { return cv::Mat(height, width, CV_8U, cv::Scalar(200)); }

double MaxCornerError(const Quad2d& corners, const Quad2d& truth) {
  double worst = 0.0;
  for (int i = 0; i < 4; ++i) worst = std::max(worst, (corners[i] - truth[i]).norm());
  return worst;
}

TEST(DetectAprilTag, ModuleImageMatchesTheFamilyLayout) {
  cv::Rect symbol;
  const cv::Mat modules = AprilTagModuleImage("apriltag-36h11", 0, &symbol);
  ASSERT_EQ(modules.rows, 10);
  EXPECT_EQ(symbol, cv::Rect(1, 1, 8, 8));
  // White quiet ring outside, black border ring inside it.
  EXPECT_EQ(modules.at<uint8_t>(0, 0), 255);
  EXPECT_EQ(modules.at<uint8_t>(1, 1), 0);
  EXPECT_EQ(modules.at<uint8_t>(8, 5), 0);
  EXPECT_THROW(AprilTagModuleImage("apriltag-36h11", 587, &symbol), std::invalid_argument);
  EXPECT_THROW(AprilTagModuleImage("apriltag-99h1", 0, &symbol), std::invalid_argument);
}

TEST(DetectAprilTag, FourRotationsGiveDesignOrderCorners) {
  auto detector = CreateDetector("apriltag-36h11");
  const SymbolImage tag = AprilTagSymbol("apriltag-36h11", 17);
  for (int r = 0; r < 4; ++r) {
    cv::Mat image = Canvas();
    const Quad2d truth = MakeQuad({318.4, 244.9}, 160.0, r * M_PI / 2 + 0.12, 0.9);
    DrawSymbol(tag, truth, &image);
    const auto found = detector->Detect(image);
    ASSERT_EQ(found.size(), 1u) << "rotation " << r;
    EXPECT_EQ(found[0].key.family, "apriltag-36h11");
    EXPECT_EQ(found[0].key.id, "17");
    EXPECT_LT(MaxCornerError(found[0].corners_px, truth), 0.1) << "rotation " << r;
  }
}

TEST(DetectAprilTag, UnrefinedCornersAreWithinHalfAPixel) {
  // libapriltag's own corners after the order and 0.5 px conversion, without our
  // refinement: checks the convention, not just the refinement.
  DetectorOptions options;
  options.refine_corners = false;
  auto detector = CreateDetector("apriltag-36h11", options);
  cv::Mat image = Canvas();
  const Quad2d truth = MakeQuad({300.0, 250.0}, 200.0, 0.3);
  DrawSymbol(AprilTagSymbol("apriltag-36h11", 5), truth, &image);
  const auto found = detector->Detect(image);
  ASSERT_EQ(found.size(), 1u);
  EXPECT_LT(MaxCornerError(found[0].corners_px, truth), 0.5);
}

TEST(DetectAprilTag, SeveralTagsAndOtherFamilies) {
  cv::Mat image = Canvas(1280, 960);
  const std::vector<std::string> families = {"apriltag-36h11", "apriltag-25h9", "apriltag-standard41h12"};
  std::vector<Quad2d> truths;
  for (size_t i = 0; i < families.size(); ++i) {
    truths.push_back(MakeQuad({250.0 + 400 * i, 300.0 + 200 * (i % 2)}, 180.0, 0.3 * i + 0.1));
    DrawSymbol(AprilTagSymbol(families[i], 3 + static_cast<int>(i)), truths.back(), &image);
  }
  auto detector = CreateMultiDetector(families);
  const auto found = detector->Detect(image);
  ASSERT_EQ(found.size(), 3u);
  for (const MarkerObservation& obs : found) {
    const size_t i = std::find(families.begin(), families.end(), obs.key.family) - families.begin();
    ASSERT_LT(i, families.size()) << obs.key.family;
    EXPECT_EQ(obs.key.id, std::to_string(3 + i));
    // Reversed-border families keep libapriltag's corners (no outer edge to refine on).
    EXPECT_LT(MaxCornerError(obs.corners_px, truths[i]), i == 2 ? 0.5 : 0.1) << obs.key.family;
  }
}

// A dark bar across a tag's border (a cable, a shelf edge: the recall bench's occlusion)
// joins the border, and libapriltag's quad can follow the bar: a tag is then either not
// reported or reported with its border's corners, never with the bar's.
TEST(DetectAprilTag, DarkBarAcrossTheBorderGivesNoBadCorners) {
  const auto detector = CreateDetector("apriltag-36h11");
  int reported = 0;
  for (int k = 0; k < 16; ++k) {
    cv::Mat image = Canvas(640, 480);
    const Quad2d truth = MakeQuad({320.0, 240.0}, 60.0 + (k % 7) * 10.0, 0.37 * k, 0.75 + 0.05 * (k % 5));
    DrawSymbol(AprilTagSymbol("apriltag-36h11", 385), truth, &image, 30, 230);
    // 6-11 % of a side wide, from well outside to a quarter of a side inside, across the
    // outer third of the right side.
    const double width = (0.06 + 0.01 * (k % 6)) * QuadMeanSide(truth);
    const Eigen::Vector2d a = truth[1] + (0.2 + 0.05 * (k % 4)) * (truth[2] - truth[1]);
    const Eigen::Vector2d dir = (QuadCenter(truth) - a).normalized();
    const Eigen::Vector2d p0 = a - dir * 3 * width, p1 = a + dir * 0.25 * QuadMeanSide(truth);
    cv::line(image, cv::Point(int(p0.x()), int(p0.y())), cv::Point(int(p1.x()), int(p1.y())), cv::Scalar(40),
             int(width), cv::LINE_AA);
    cv::GaussianBlur(image, image, cv::Size(0, 0), 0.8);
    for (const MarkerObservation& obs : detector->Detect(image)) {
      ++reported;
      EXPECT_LT(MaxCornerError(obs.corners_px, truth), 0.5) << "pose " << k;
    }
  }
  std::printf("%d of 16 tags with a bar across the border reported\n", reported);
  // Crops of the quads with three solid sides too (the bar's side broken), and the whole frame
  // at decimation 8 blurred by 0.8 px: 7 of 16 (6 unblurred; 3 when only four solid sides made
  // a crop; 8 with the whole frame at decimation 4).
  EXPECT_GE(reported, 7);
}

// Tags from 24 to 420 px in one cluttered frame at the default options: the small ones are read
// from crops of the candidate stage's quads (the whole frame at decimation 4 lost tags of
// 44-94 px), the large ones too (or from the whole frame at decimation 8).
TEST(DetectAprilTag, SmallAndLargeTagsAtTheDefaultDecimation) {
  cv::Mat image = Canvas(1280, 960);
  cv::RNG rng(11);
  for (int k = 0; k < 60; ++k) {  // clutter: boxes and frames
    const cv::Point p(rng.uniform(0, 1280), rng.uniform(0, 960));
    cv::rectangle(image, cv::Rect(p, cv::Size(rng.uniform(5, 60), rng.uniform(5, 60))),
                  cv::Scalar(rng.uniform(20, 120)), k % 2 == 0 ? cv::FILLED : 2);
  }
  const double sides[] = {24.0, 32.0, 44.0, 60.0, 94.0, 150.0, 420.0};
  const Eigen::Vector2d centres[] = {{80, 80},   {200, 80},  {330, 90}, {480, 100},
                                     {660, 120}, {900, 140}, {640, 600}};
  std::vector<Quad2d> truth;
  for (int i = 0; i < 7; ++i) {
    truth.push_back(MakeQuad(centres[i], sides[i], 0.3 * i, 0.85));
    DrawSymbol(AprilTagSymbol("apriltag-36h11", 10 + i), truth.back(), &image);
  }
  cv::GaussianBlur(image, image, cv::Size(0, 0), 0.7);
  const auto found = CreateDetector("apriltag-36h11")->Detect(image);
  ASSERT_EQ(found.size(), 7u);
  for (const MarkerObservation& obs : found) {
    const int i = std::stoi(obs.key.id) - 10;
    ASSERT_GE(i, 0);
    ASSERT_LT(i, 7);
    EXPECT_LT(MaxCornerError(obs.corners_px, truth[i]), 0.3) << sides[i] << " px";
  }
}

// Low light (issue 14, sixth round: libapriltag ignores tiles whose gray levels span under 15,
// in the crops of the candidate quads too): tags 24-150 px drawn at a fifth of full exposure
// (dark 12, light 55), blurred and with sensor noise, among faint clutter, are all read.
TEST(DetectAprilTag, LowLightTagsAreRead) {
  cv::Mat image(960, 1280, CV_8U, cv::Scalar(45));
  cv::RNG rng(14);
  for (int k = 0; k < 40; ++k) {  // faint clutter
    const cv::Point p(rng.uniform(0, 1280), rng.uniform(0, 960));
    cv::rectangle(image, cv::Rect(p, cv::Size(rng.uniform(5, 60), rng.uniform(5, 60))),
                  cv::Scalar(rng.uniform(30, 50)), k % 2 == 0 ? cv::FILLED : 2);
  }
  const double sides[] = {24.0, 32.0, 44.0, 60.0, 94.0, 150.0};
  std::vector<Quad2d> truth;
  for (int i = 0; i < 6; ++i) {
    truth.push_back(MakeQuad({150.0 + 200 * i, 300.0 + 60 * i}, sides[i], 0.4 * i, 0.8));
    DrawSymbol(AprilTagSymbol("apriltag-36h11", 20 + i), truth.back(), &image, 12, 55);
  }
  cv::GaussianBlur(image, image, cv::Size(0, 0), 0.8);
  cv::Mat noise(image.size(), CV_16S);
  rng.fill(noise, cv::RNG::NORMAL, 0, 2);
  cv::Mat noisy;
  image.convertTo(noisy, CV_16S);
  noisy += noise;
  noisy.convertTo(image, CV_8U);
  const auto found = CreateDetector("apriltag-36h11")->Detect(image);
  ASSERT_EQ(found.size(), 6u);
  for (const MarkerObservation& obs : found) {
    const int i = std::stoi(obs.key.id) - 20;
    ASSERT_GE(i, 0);
    ASSERT_LT(i, 6);
    EXPECT_LT(MaxCornerError(obs.corners_px, truth[i]), 0.3) << sides[i] << " px";
  }
}

TEST(DetectAprilTag, BlankNoiseAndBadInput) {
  auto detector = CreateDetector("apriltag-36h11");
  EXPECT_TRUE(detector->Detect(Canvas()).empty());
  cv::Mat noise(480, 640, CV_8U);
  cv::RNG rng(5);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
  EXPECT_TRUE(detector->Detect(noise).empty());
  EXPECT_THROW(detector->Detect(cv::Mat()), std::invalid_argument);
  // Sizes that crash libapriltag 3.3 itself when passed through.
  for (const cv::Size size : {cv::Size(1, 1), cv::Size(8, 8), cv::Size(2000, 3), cv::Size(40, 33)}) {
    EXPECT_TRUE(detector->Detect(cv::Mat(size, CV_8U, cv::Scalar(0))).empty()) << size;
  }
  DetectorOptions coarse;
  coarse.apriltag_decimate = 4.0;
  EXPECT_TRUE(
      CreateDetector("apriltag-36h11", coarse)->Detect(cv::Mat(20, 20, CV_8U, cv::Scalar(0))).empty());
  EXPECT_THROW(CreateDetector("apriltag-36h12"), std::invalid_argument);
}

}  // namespace
}  // namespace waymark
