// MarkerDetector::SetReadByOthers (detect/detector.h): each family skips the places another
// family has read, and the multi-family detector, which hands them on, reads what every
// family reads alone.
#include <gtest/gtest.h>

#include <algorithm>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "detect/detector.h"
#include "detect/synthetic.h"

namespace waymark {
namespace {

const Quad2d kPlainQr = MakeQuad({130.0, 120.0}, 110.0, 0.2);
const Quad2d kDataMatrix = MakeQuad({480.0, 110.0}, 100.0, -0.3);
const Quad2d kLargeTag = MakeQuad({130.0, 360.0}, 100.0, 0.1);
const Quad2d kSmallTag = MakeQuad({300.0, 400.0}, 30.0, 0.4);
const Quad2d kInvertedQr = MakeQuad({490.0, 360.0}, 120.0, 0.1);

// A code of each family; the light-on-dark QR code is read by QR's second passes only, the
// 30 px tag by AprilTag's crops of the candidate quads only (the whole frame at decimation 8
// does not see it).
cv::Mat Frame() {
  cv::Mat image(480, 640, CV_8U, cv::Scalar(200));
  DrawSymbol(QrSymbol("plain"), kPlainQr, &image);
  DrawSymbol(DataMatrixSymbol("matrix"), kDataMatrix, &image);
  DrawSymbol(AprilTagSymbol("apriltag-36h11", 7), kLargeTag, &image);
  DrawSymbol(AprilTagSymbol("apriltag-36h11", 9), kSmallTag, &image);
  cv::rectangle(image, cv::Rect(380, 250, 220, 220), cv::Scalar(40), cv::FILLED);
  DrawSymbol(QrSymbol("inverted"), kInvertedQr, &image, 235, 20);
  return image;
}

MarkerObservation Other(const std::string& family, const Quad2d& corners) {
  MarkerObservation obs;
  obs.key = {family, "elsewhere"};
  obs.corners_px = corners;
  return obs;
}

std::vector<std::string> Ids(const std::vector<MarkerObservation>& found) {
  std::vector<std::string> ids;
  for (const MarkerObservation& obs : found) ids.push_back(obs.key.family + "/" + obs.key.id);
  std::sort(ids.begin(), ids.end());
  return ids;
}

bool Has(const std::vector<MarkerObservation>& found, const std::string& id) {
  return std::any_of(found.begin(), found.end(),
                     [&id](const MarkerObservation& o) { return o.key.id == id; });
}

TEST(ReadByOthers, QrSecondPassesSkipAnotherFamilysCode) {
  const cv::Mat image = Frame();
  const auto detector = CreateDetector("qr");
  ASSERT_TRUE(Has(detector->Detect(image), "inverted"));
  // Something else read where the light-on-dark code is: its second passes do not look there.
  const std::vector<MarkerObservation> others = {Other("datamatrix", kInvertedQr)};
  detector->SetReadByOthers(&others);
  const std::vector<MarkerObservation> found = detector->Detect(image);
  EXPECT_FALSE(Has(found, "inverted"));
  EXPECT_TRUE(Has(found, "plain"));  // the first pass (the whole frame) is not limited
  // Cleared, it reads there again.
  detector->SetReadByOthers(nullptr);
  EXPECT_TRUE(Has(detector->Detect(image), "inverted"));
}

TEST(ReadByOthers, DataMatrixSkipsAnotherFamilysCode) {
  const cv::Mat image = Frame();
  const auto detector = CreateDetector("datamatrix");
  ASSERT_TRUE(Has(detector->Detect(image), "matrix"));
  const std::vector<MarkerObservation> others = {Other("qr", kDataMatrix)};
  detector->SetReadByOthers(&others);
  EXPECT_FALSE(Has(detector->Detect(image), "matrix"));  // neither its candidates nor its regions
  detector->SetReadByOthers(nullptr);
  EXPECT_TRUE(Has(detector->Detect(image), "matrix"));
}

TEST(ReadByOthers, AprilTagCropsSkipAnotherFamilysCode) {
  const cv::Mat image = Frame();
  const auto detector = CreateDetector("apriltag-36h11");
  ASSERT_TRUE(Has(detector->Detect(image), "9"));
  const std::vector<MarkerObservation> others = {Other("qr", kSmallTag)};
  detector->SetReadByOthers(&others);
  const std::vector<MarkerObservation> found = detector->Detect(image);
  EXPECT_FALSE(Has(found, "9"));
  EXPECT_TRUE(Has(found, "7"));
}

TEST(ReadByOthers, MultiDetectorReadsWhatEachFamilyReadsAlone) {
  const cv::Mat image = Frame();
  const std::vector<std::string> families = {"qr", "datamatrix", "apriltag-36h11"};
  std::vector<MarkerObservation> alone;
  for (const std::string& family : families) {
    for (const MarkerObservation& obs : CreateDetector(family)->Detect(image)) alone.push_back(obs);
  }
  for (const int threads : {1, 2, 3}) {
    for (const bool steps : {true, false}) {
      DetectorOptions options;
      options.threads = threads;
      options.family_steps = steps;
      const auto multi = CreateMultiDetector(families, options);
      const std::vector<MarkerObservation> together = multi->Detect(image);
      EXPECT_EQ(Ids(together), Ids(alone)) << threads << " threads, steps " << steps;
      EXPECT_EQ(together.size(), 5u);  // two QR codes, a DataMatrix symbol, two tags
      // The same corners as each family alone (a family's reads do not depend on the others').
      for (const MarkerObservation& a : alone) {
        const auto same = std::find_if(together.begin(), together.end(),
                                       [&a](const MarkerObservation& t) { return t.key == a.key; });
        ASSERT_NE(same, together.end());
        for (int k = 0; k < 4; ++k) EXPECT_EQ(same->corners_px[k], a.corners_px[k]) << a.key.id << " " << k;
      }
      // A second image gets no stale codes of the first: the blank frame reads nothing, and the
      // frame again reads everything.
      EXPECT_TRUE(multi->Detect(cv::Mat(480, 640, CV_8U, cv::Scalar(200))).empty());
      EXPECT_EQ(Ids(multi->Detect(image)), Ids(alone));
    }
  }
}

}  // namespace
}  // namespace waymark
