// runner/image.h: decoding image bytes for the detectors with bounded work and one-line
// reasons (issue 18, finding 3), and the detectors on odd image shapes.
#include "runner/image.h"

#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "detect/detector.h"

namespace waymark {
namespace {

std::string Encode(const cv::Mat& image, const std::string& ext = ".png") {
  std::vector<uchar> bytes;
  EXPECT_TRUE(cv::imencode(ext, image, bytes));
  return std::string(bytes.begin(), bytes.end());
}

TEST(DecodeImageTest, TypesTheDetectorsTake) {
  std::string why;
  EXPECT_EQ(DecodeImage(Encode(cv::Mat(4, 6, CV_8UC1, cv::Scalar(9))), &why).type(), CV_8UC1);
  EXPECT_EQ(DecodeImage(Encode(cv::Mat(4, 6, CV_8UC3, cv::Scalar(1, 2, 3))), &why).type(), CV_8UC3);
  EXPECT_EQ(DecodeImage(Encode(cv::Mat(4, 6, CV_16UC1, cv::Scalar(999))), &why).type(), CV_16UC1);
  // 16-bit colour is not a detector type: read as 8-bit gray.
  const cv::Mat wide = DecodeImage(Encode(cv::Mat(4, 6, CV_16UC3, cv::Scalar(1, 2, 3))), &why);
  EXPECT_EQ(wide.type(), CV_8UC1);
  EXPECT_EQ(wide.size(), cv::Size(6, 4));
}

TEST(DecodeImageTest, BadBytesSayWhyInOneLine) {
  std::string why;
  EXPECT_TRUE(DecodeImage("", &why).empty());
  EXPECT_EQ(why, "empty file");
  EXPECT_TRUE(DecodeImage("not an image at all", &why).empty());
  EXPECT_EQ(why, "corrupt or not an image");
  std::string png = Encode(cv::Mat(40, 60, CV_8UC1, cv::Scalar(9)));
  EXPECT_TRUE(DecodeImage(png.substr(0, png.size() / 2), &why).empty());
  EXPECT_EQ(why.find('\n'), std::string::npos);
  // The header says 40000 x 40000: refused before the decoder allocates 1.6 GB.
  png[16] = 0;
  png[17] = 0;
  png[18] = static_cast<char>(0x9c);
  png[19] = 0x40;
  png[20] = 0;
  png[21] = 0;
  png[22] = static_cast<char>(0x9c);
  png[23] = 0x40;
  EXPECT_TRUE(DecodeImage(png, &why).empty());
  EXPECT_EQ(why,
            "image of 40000x40000 is larger than the limit (sides up to 32768 px, 67108864 pixels in all)");
}

TEST(ReadImageFileTest, MissingFileIsNamed) {
  std::string why;
  EXPECT_TRUE(ReadImageFile("/nonexistent/x.png", &why).empty());
  EXPECT_EQ(why, "/nonexistent/x.png: cannot read image: no such file");
}

// 2000x1 once made cv::resize assert inside the candidate search; every shape is fine now.
TEST(DetectOddShapesTest, ThinAndTinyImagesGiveNothing) {
  const auto detector = CreateMultiDetector({"qr", "datamatrix", "apriltag-36h11"}, DetectorOptions{});
  for (const cv::Size size : {cv::Size(2000, 1), cv::Size(4000, 1), cv::Size(20000, 4), cv::Size(1, 2000),
                              cv::Size(1, 1), cv::Size(3, 5000), cv::Size(8000, 2)}) {
    cv::Mat image(size, CV_8UC1);
    cv::randu(image, 0, 256);
    EXPECT_TRUE(detector->Detect(image).empty()) << size;
  }
}

}  // namespace
}  // namespace waymark
