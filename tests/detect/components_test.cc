// Connected components from runs and the local-mean binarization (detect/components.h): the
// binarization bit for bit OpenCV's adaptiveThreshold; the same components and boxes as
// OpenCV's 8-connected labelling on random images, each component's row ends spanning the same
// convex hull as all its pixels, raster order, the box filter, and the corner cases (empty,
// all dark, one-pixel rows and columns, diagonal joins, wide images whose runs cross the
// eight-pixel skip).
#include "detect/components.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <opencv2/imgproc.hpp>
#include <set>

namespace waymark {
namespace {

// The component boxes OpenCV finds (8-connectivity), sorted.
std::vector<std::tuple<int, int, int, int>> OpenCvBoxes(const cv::Mat& binary) {
  cv::Mat labels, stats, centroids;
  const int n = cv::connectedComponentsWithStats(binary, labels, stats, centroids, 8, CV_32S);
  std::vector<std::tuple<int, int, int, int>> boxes;
  for (int i = 1; i < n; ++i) {
    boxes.emplace_back(stats.at<int>(i, cv::CC_STAT_LEFT), stats.at<int>(i, cv::CC_STAT_TOP),
                       stats.at<int>(i, cv::CC_STAT_WIDTH), stats.at<int>(i, cv::CC_STAT_HEIGHT));
  }
  std::sort(boxes.begin(), boxes.end());
  return boxes;
}

double HullArea(const std::vector<cv::Point>& points) {
  std::vector<cv::Point> hull;
  cv::convexHull(points, hull);
  return hull.size() < 3 ? 0.0 : cv::contourArea(hull);
}

TEST(DetectComponents, SameComponentsAsOpenCvOnRandomImages) {
  cv::RNG rng(7);
  for (int trial = 0; trial < 20; ++trial) {
    const int cols = 1 + rng.uniform(0, 90), rows = 1 + rng.uniform(0, 60);
    cv::Mat noise(rows, cols, CV_8U);
    rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
    const int level = rng.uniform(60, 200);
    cv::Mat binary = noise < level;  // 255 where dark
    const std::vector<RunComponent> components = RunComponents(binary);
    std::vector<std::tuple<int, int, int, int>> boxes;
    for (const RunComponent& c : components) boxes.emplace_back(c.box.x, c.box.y, c.box.width, c.box.height);
    std::sort(boxes.begin(), boxes.end());
    ASSERT_EQ(boxes, OpenCvBoxes(binary)) << "trial " << trial;
    // Each component's row ends: the same hull as all its pixels (labels from OpenCV, matched
    // by a pixel of each end).
    cv::Mat labels;
    cv::connectedComponents(binary, labels, 8, CV_32S);
    for (const RunComponent& c : components) {
      const int label = labels.at<int>(c.row_ends.front());
      std::vector<cv::Point> pixels;
      for (int y = c.box.y; y < c.box.y + c.box.height; ++y) {
        for (int x = c.box.x; x < c.box.x + c.box.width; ++x) {
          if (labels.at<int>(y, x) == label) pixels.emplace_back(x, y);
        }
      }
      for (const cv::Point& p : c.row_ends) ASSERT_EQ(labels.at<int>(p), label);
      EXPECT_DOUBLE_EQ(HullArea(c.row_ends), HullArea(pixels));
      // Two ends per row, rows top to bottom.
      EXPECT_EQ(c.row_ends.size(), 2u * static_cast<size_t>(c.box.height));
      for (size_t k = 0; k < c.row_ends.size(); k += 2) {
        EXPECT_EQ(c.row_ends[k].y, c.box.y + static_cast<int>(k / 2));
        EXPECT_LE(c.row_ends[k].x, c.row_ends[k + 1].x);
      }
    }
    // Raster order of the first pixel.
    for (size_t i = 1; i < components.size(); ++i) {
      const cv::Point a = components[i - 1].row_ends.front(), b = components[i].row_ends.front();
      EXPECT_TRUE(a.y < b.y || (a.y == b.y && a.x < b.x));
    }
  }
}

TEST(DetectComponents, DiagonalNeighboursJoinAndGapsSplit) {
  cv::Mat binary(6, 40, CV_8U, cv::Scalar(0));
  binary.at<uint8_t>(0, 0) = binary.at<uint8_t>(1, 1) = binary.at<uint8_t>(2, 2) = 255;  // one diagonal
  binary.at<uint8_t>(0, 5) = binary.at<uint8_t>(2, 5) = 255;                             // a row between
  binary.row(4).colRange(9, 37).setTo(255);  // one run across several 8-pixel words
  binary.at<uint8_t>(5, 8) = 255;            // diagonal below its first pixel
  const std::vector<RunComponent> components = RunComponents(binary);
  ASSERT_EQ(components.size(), 4u);
  EXPECT_EQ(components[0].box, cv::Rect(0, 0, 3, 3));
  EXPECT_EQ(components[1].box, cv::Rect(5, 0, 1, 1));
  EXPECT_EQ(components[2].box, cv::Rect(5, 2, 1, 1));
  EXPECT_EQ(components[3].box, cv::Rect(8, 4, 29, 2));
  EXPECT_EQ(components[3].row_ends, (std::vector<cv::Point>{{9, 4}, {36, 4}, {8, 5}, {8, 5}}));
}

TEST(DetectComponents, KeepFiltersByBoxAndCornerCases) {
  cv::Mat binary(30, 50, CV_8U, cv::Scalar(0));
  cv::rectangle(binary, cv::Rect(2, 2, 20, 10), cv::Scalar(255), cv::FILLED);
  cv::rectangle(binary, cv::Rect(30, 20, 3, 3), cv::Scalar(255), cv::FILLED);
  const std::vector<RunComponent> large =
      RunComponents(binary, [](const cv::Rect& box) { return box.width >= 10; });
  ASSERT_EQ(large.size(), 1u);
  EXPECT_EQ(large[0].box, cv::Rect(2, 2, 20, 10));
  EXPECT_TRUE(RunComponents(cv::Mat(5, 5, CV_8U, cv::Scalar(0))).empty());
  const std::vector<RunComponent> all = RunComponents(cv::Mat(7, 13, CV_8U, cv::Scalar(1)));
  ASSERT_EQ(all.size(), 1u);
  EXPECT_EQ(all[0].box, cv::Rect(0, 0, 13, 7));
  // A view into a larger image (row padding).
  const cv::Mat view = binary(cv::Rect(1, 1, 25, 15));
  const std::vector<RunComponent> in_view = RunComponents(view);
  ASSERT_EQ(in_view.size(), 1u);
  EXPECT_EQ(in_view[0].box, cv::Rect(1, 1, 20, 10));
}

TEST(DetectComponents, DarkerThanLocalMeanIsOpenCvsAdaptiveThreshold) {
  cv::RNG rng(11);
  for (int trial = 0; trial < 24; ++trial) {
    const int cols = 1 + rng.uniform(0, 120), rows = 1 + rng.uniform(0, 90);
    cv::Mat gray(rows, cols, CV_8U);
    // Smooth shapes and noise: many pixels near the threshold.
    rng.fill(gray, cv::RNG::UNIFORM, 0, 256);
    if (trial % 2 == 0) cv::GaussianBlur(gray, gray, cv::Size(5, 5), 2.0);
    for (const int box : {3, 5, 7, 9, 15}) {
      for (const int darker_by : {0, 7, 20}) {
        cv::Mat expected;
        cv::adaptiveThreshold(gray, expected, 255, cv::ADAPTIVE_THRESH_MEAN_C, cv::THRESH_BINARY_INV, box,
                              darker_by);
        const cv::Mat dark = DarkerThanLocalMean(gray, box, darker_by);
        ASSERT_EQ(cv::countNonZero(dark != expected), 0)
            << "trial " << trial << " " << cols << "x" << rows << " box " << box << " by " << darker_by;
      }
    }
  }
  // A view into a larger image: its own border is replicated (as BORDER_ISOLATED).
  cv::Mat big(100, 140, CV_8U);
  rng.fill(big, cv::RNG::UNIFORM, 0, 256);
  const cv::Mat view = big(cv::Rect(13, 9, 77, 61));
  cv::Mat expected;
  cv::adaptiveThreshold(view, expected, 255, cv::ADAPTIVE_THRESH_MEAN_C, cv::THRESH_BINARY_INV, 15, 7);
  EXPECT_EQ(cv::countNonZero(DarkerThanLocalMean(view, 15, 7) != expected), 0);
}

}  // namespace
}  // namespace waymark
