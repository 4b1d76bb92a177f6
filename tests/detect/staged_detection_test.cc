// MarkerDetector::DetectFirstPass / DetectSecondPasses (detect/detector.h): the two stages give
// what Detect() gives, for every family and the multi-family detector.
#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "detect/detector.h"
#include "detect/synthetic.h"

namespace waymark {
namespace {

void ExpectSame(const std::vector<MarkerObservation>& a, const std::vector<MarkerObservation>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].key.family, b[i].key.family) << i;
    EXPECT_EQ(a[i].key.id, b[i].key.id) << i;
    EXPECT_EQ(a[i].quality, b[i].quality) << i;
    for (int k = 0; k < 4; ++k) EXPECT_EQ(a[i].corners_px[k], b[i].corners_px[k]) << i << " " << k;
  }
}

// A frame with a code of each family the first passes read (AprilTag's first pass reads the
// small tag too: crops of the candidate quads), and a light-on-dark QR code only the second
// passes read.
cv::Mat Frame() {
  cv::Mat image(480, 640, CV_8U, cv::Scalar(200));
  DrawSymbol(QrSymbol("plain"), MakeQuad({130.0, 120.0}, 110.0, 0.2), &image);
  DrawSymbol(DataMatrixSymbol("matrix"), MakeQuad({480.0, 110.0}, 100.0, -0.3), &image);
  DrawSymbol(AprilTagSymbol("apriltag-36h11", 7), MakeQuad({130.0, 360.0}, 100.0, 0.1), &image);
  DrawSymbol(AprilTagSymbol("apriltag-36h11", 9), MakeQuad({300.0, 400.0}, 30.0, 0.4), &image);
  cv::rectangle(image, cv::Rect(380, 250, 220, 220), cv::Scalar(40), cv::FILLED);
  DrawSymbol(QrSymbol("inverted"), MakeQuad({490.0, 360.0}, 120.0, 0.1), &image, 235, 20);
  return image;
}

TEST(StagedDetection, TwoStagesGiveWhatDetectGives) {
  const cv::Mat image = Frame();
  const std::vector<std::vector<std::string>> lists = {
      {"qr"}, {"datamatrix"}, {"apriltag-36h11"}, {"qr", "datamatrix", "apriltag-36h11"}};
  for (const auto& families : lists) {
    SCOPED_TRACE(families.size() == 1 ? families[0] : "all");
    for (const bool close_up : {true, false}) {
      DetectorOptions options;
      options.close_up = close_up;
      const auto staged = CreateMultiDetector(families, options);
      const auto reference = CreateMultiDetector(families, options);
      options.second_pass = false;
      const auto first_only = CreateMultiDetector(families, options);
      const std::vector<MarkerObservation> first = staged->DetectFirstPass(image);
      ExpectSame(first, first_only->Detect(image));
      const std::vector<MarkerObservation> all = staged->DetectSecondPasses();
      ExpectSame(all, reference->Detect(image));
      // The second passes read more than the first here (else this test pins little): the
      // light-on-dark QR code (the DataMatrix symbol is read by pass 1). AprilTag's every pass
      // is in the first stage: both tags, the 30 px one too.
      if (families == std::vector<std::string>{"apriltag-36h11"}) {
        EXPECT_EQ(first.size(), 2u);
        EXPECT_EQ(all.size(), first.size());
      } else if (families != std::vector<std::string>{"datamatrix"}) {
        EXPECT_GT(all.size(), first.size());
      }
      // Stages on a second image start afresh.
      const cv::Mat blank(480, 640, CV_8U, cv::Scalar(200));
      EXPECT_TRUE(staged->DetectFirstPass(blank).empty());
      EXPECT_TRUE(staged->DetectSecondPasses().empty());
    }
  }
}

TEST(StagedDetection, SecondPassesWithoutAFirstPassThrow) {
  for (const std::string family : {"qr", "datamatrix", "apriltag-36h11"}) {
    const auto detector = CreateDetector(family);
    EXPECT_THROW(detector->DetectSecondPasses(), std::logic_error) << family;
  }
  const auto multi = CreateMultiDetector({"qr", "datamatrix"});
  EXPECT_THROW(multi->DetectSecondPasses(), std::logic_error);
}

// A detector written without stages of its own (as a user's subclass of the installed library
// may be): the defaults make its whole Detect() the first stage, and the second returns it again.
class DetectOnly : public MarkerDetector {
 public:
  std::vector<std::string> Families() const override { return {"qr"}; }
  std::vector<MarkerObservation> Detect(const cv::Mat& image) override {
    ++calls;
    MarkerObservation obs;
    obs.key = {"qr", std::to_string(image.cols)};
    obs.corners_px = {Eigen::Vector2d(0, 0), Eigen::Vector2d(1, 0), Eigen::Vector2d(1, 1),
                      Eigen::Vector2d(0, 1)};
    return {obs};
  }
  int calls = 0;
};

TEST(StagedDetection, DefaultStagesAreTheWholeDetect) {
  DetectOnly detector;
  EXPECT_THROW(detector.DetectSecondPasses(), std::logic_error);
  const cv::Mat image(20, 30, CV_8U, cv::Scalar(255));
  const std::vector<MarkerObservation> first = detector.DetectFirstPass(image);
  const std::vector<MarkerObservation> second = detector.DetectSecondPasses();
  ASSERT_EQ(first.size(), 1u);
  ASSERT_EQ(second.size(), 1u);
  EXPECT_EQ(first[0].key.id, "30");
  EXPECT_EQ(second[0].key, first[0].key);
  EXPECT_EQ(detector.calls, 1);  // Detect() once, not again for the second stage
}

}  // namespace
}  // namespace waymark
