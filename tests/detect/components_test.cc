// Connected components from runs and the local-mean binarization (detect/components.h): the
// binarization bit for bit OpenCV's adaptiveThreshold; the same components and boxes as
// OpenCV's 8-connected labelling on random images, each component's row ends spanning the same
// convex hull as all its pixels, raster order, the box filter, and the corner cases (empty,
// all dark, one-pixel rows and columns, diagonal joins, wide images whose runs cross the
// eight-pixel skip), and the eight-pixel run scans (SkipEqual, SkipNonZero) against a
// pixel-by-pixel scan.
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

// DarkerThanLocalMean against cv::adaptiveThreshold on `trials` random images of up to
// max_cols x max_rows (every other one blurred), for each box and offset.
void ExpectAdaptiveThreshold(cv::RNG& rng, int trials, int max_cols, int max_rows, int blur_box,
                             double blur_sigma, const std::vector<int>& boxes,
                             const std::vector<int>& darker_bys) {
  for (int trial = 0; trial < trials; ++trial) {
    const int cols = 1 + rng.uniform(0, max_cols), rows = 1 + rng.uniform(0, max_rows);
    cv::Mat gray(rows, cols, CV_8U);
    // Smooth shapes and noise: many pixels near the threshold.
    rng.fill(gray, cv::RNG::UNIFORM, 0, 256);
    if (trial % 2 == 0) cv::GaussianBlur(gray, gray, cv::Size(blur_box, blur_box), blur_sigma);
    for (const int box : boxes) {
      for (const int darker_by : darker_bys) {
        cv::Mat expected;
        cv::adaptiveThreshold(gray, expected, 255, cv::ADAPTIVE_THRESH_MEAN_C, cv::THRESH_BINARY_INV, box,
                              darker_by);
        const cv::Mat dark = DarkerThanLocalMean(gray, box, darker_by);
        ASSERT_EQ(cv::countNonZero(dark != expected), 0)
            << "trial " << trial << " " << cols << "x" << rows << " box " << box << " by " << darker_by;
      }
    }
  }
}

TEST(DetectComponents, DarkerThanLocalMeanIsOpenCvsAdaptiveThreshold) {
  cv::RNG rng(11);
  ExpectAdaptiveThreshold(rng, 24, 120, 90, 5, 2.0, {3, 5, 7, 9, 15}, {0, 7, 20});
  // Boxes over 15 px (the QR finder search's, block = side / 8 up to 101), 32-bit sums: images
  // smaller and larger than the box.
  ExpectAdaptiveThreshold(rng, 12, 330, 260, 9, 4.0, {17, 29, 31, 63, 101}, {0, 4, 9});
  // The largest boxes: the comparison in single precision while area 255 + t stays under 2^24
  // (255 with offset 0), in 32-bit integers beyond (255 with offset 9, 257).
  ExpectAdaptiveThreshold(rng, 3, 300, 280, 9, 4.0, {255, 257}, {0, 9});
  // A view into a larger image: its own border is replicated (as BORDER_ISOLATED).
  cv::Mat big(100, 140, CV_8U);
  rng.fill(big, cv::RNG::UNIFORM, 0, 256);
  const cv::Mat view = big(cv::Rect(13, 9, 77, 61));
  cv::Mat expected;
  cv::adaptiveThreshold(view, expected, 255, cv::ADAPTIVE_THRESH_MEAN_C, cv::THRESH_BINARY_INV, 15, 7);
  EXPECT_EQ(cv::countNonZero(DarkerThanLocalMean(view, 15, 7) != expected), 0);
  cv::adaptiveThreshold(view, expected, 255, cv::ADAPTIVE_THRESH_MEAN_C, cv::THRESH_BINARY_INV, 41, 4);
  EXPECT_EQ(cv::countNonZero(DarkerThanLocalMean(view, 41, 4) != expected), 0);
}

TEST(DetectComponents, HalfAndQuarterAreaIsOpenCvsResize) {
  cv::RNG rng(23);
  for (int trial = 0; trial < 8; ++trial) {
    const int cols = 4 * (1 + rng.uniform(0, 90)), rows = 4 * (1 + rng.uniform(0, 70));
    cv::Mat gray(rows, cols, CV_8U);
    rng.fill(gray, cv::RNG::UNIFORM, 0, 256);
    if (trial % 2 == 0) cv::GaussianBlur(gray, gray, cv::Size(5, 5), 1.5);
    cv::Mat half, quarter, expected_half, expected_quarter;
    ASSERT_TRUE(HalfAndQuarterArea(gray, &half, &quarter));
    cv::resize(gray, expected_half, cv::Size(cols / 2, rows / 2), 0, 0, cv::INTER_AREA);
    cv::resize(gray, expected_quarter, cv::Size(cols / 4, rows / 4), 0, 0, cv::INTER_AREA);
    ASSERT_EQ(half.size(), expected_half.size());
    ASSERT_EQ(quarter.size(), expected_quarter.size());
    EXPECT_EQ(cv::countNonZero(half != expected_half), 0) << cols << "x" << rows;
    EXPECT_EQ(cv::countNonZero(quarter != expected_quarter), 0) << cols << "x" << rows;
  }
  // A recall-bench-sized frame, and a view into a larger image.
  cv::Mat frame(960, 1280, CV_8U);
  rng.fill(frame, cv::RNG::UNIFORM, 0, 256);
  const cv::Mat view = frame(cv::Rect(3, 5, 640, 480));
  for (const cv::Mat& gray : {frame, view}) {
    cv::Mat half, quarter, expected;
    ASSERT_TRUE(HalfAndQuarterArea(gray, &half, &quarter));
    cv::resize(gray, expected, cv::Size(gray.cols / 2, gray.rows / 2), 0, 0, cv::INTER_AREA);
    EXPECT_EQ(cv::countNonZero(half != expected), 0);
    cv::resize(gray, expected, cv::Size(gray.cols / 4, gray.rows / 4), 0, 0, cv::INTER_AREA);
    EXPECT_EQ(cv::countNonZero(quarter != expected), 0);
  }
  // Sides not multiples of 4: nothing written.
  cv::Mat half, quarter;
  EXPECT_FALSE(HalfAndQuarterArea(cv::Mat(30, 42, CV_8U, cv::Scalar(9)), &half, &quarter));
  EXPECT_FALSE(HalfAndQuarterArea(cv::Mat(33, 40, CV_8U, cv::Scalar(9)), &half, &quarter));
  EXPECT_TRUE(half.empty() && quarter.empty());
}

TEST(DetectComponents, EighthAreaIsOpenCvsResize) {
  cv::RNG rng(29);
  for (int trial = 0; trial < 8; ++trial) {
    const int cols = 8 * (1 + rng.uniform(0, 60)), rows = 8 * (1 + rng.uniform(0, 50));
    cv::Mat gray(rows, cols, CV_8U);
    rng.fill(gray, cv::RNG::UNIFORM, 0, 256);
    if (trial % 2 == 0) cv::GaussianBlur(gray, gray, cv::Size(5, 5), 1.5);
    cv::Mat eighth, expected;
    ASSERT_TRUE(EighthArea(gray, &eighth));
    cv::resize(gray, expected, cv::Size(cols / 8, rows / 8), 0, 0, cv::INTER_AREA);
    ASSERT_EQ(eighth.size(), expected.size());
    EXPECT_EQ(cv::countNonZero(eighth != expected), 0) << cols << "x" << rows;
  }
  // A recall-bench-sized frame seen through a view (row padding).
  cv::Mat big(970, 1290, CV_8U);
  rng.fill(big, cv::RNG::UNIFORM, 0, 256);
  const cv::Mat frame = big(cv::Rect(5, 7, 1280, 960));
  cv::Mat eighth, expected;
  ASSERT_TRUE(EighthArea(frame, &eighth));
  cv::resize(frame, expected, cv::Size(160, 120), 0, 0, cv::INTER_AREA);
  EXPECT_EQ(cv::countNonZero(eighth != expected), 0);
  cv::Mat untouched;
  EXPECT_FALSE(EighthArea(cv::Mat(36, 40, CV_8U, cv::Scalar(3)), &untouched));
  EXPECT_TRUE(untouched.empty());
}

// cv::findContours after ClearIsolatedPixels: the same contours (points, order, nesting) but
// the one-point ones, each of which was an isolated pixel with no children.
TEST(DetectComponents, ClearIsolatedPixelsDropsOnlyOnePointContours) {
  cv::RNG rng(31);
  int dropped = 0, kept_total = 0;
  for (int trial = 0; trial < 20; ++trial) {
    cv::Mat noise(60 + trial * 7, 90 + trial * 5, CV_8U);
    rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
    if (trial % 2 == 0) cv::GaussianBlur(noise, noise, cv::Size(3, 3), 0.6);
    cv::Mat binary = noise > (trial % 4 == 0 ? 200 : 150);
    // Rings with specks inside (a finder's hole holding noise), bars, and pixels on the border.
    cv::rectangle(binary, cv::Rect(10, 10, 30, 30), cv::Scalar(255), 3);
    cv::rectangle(binary, cv::Rect(16, 16, 18, 18), cv::Scalar(0), cv::FILLED);
    binary.at<uint8_t>(25, 25) = 255;
    binary.at<uint8_t>(0, 3) = 255;
    const cv::Mat view = binary(cv::Rect(1, 2, binary.cols - 3, binary.rows - 4));
    cv::Mat cleared = view.clone();
    ClearIsolatedPixels(&cleared);
    std::vector<std::vector<cv::Point>> before, after;
    std::vector<cv::Vec4i> before_tree, after_tree;
    cv::findContours(view.clone(), before, before_tree, cv::RETR_TREE, cv::CHAIN_APPROX_SIMPLE);
    cv::findContours(cleared, after, after_tree, cv::RETR_TREE, cv::CHAIN_APPROX_SIMPLE);
    // Index of each kept contour after clearing (-1: dropped).
    std::vector<int> index(before.size(), -1);
    int next = 0;
    for (size_t i = 0; i < before.size(); ++i) {
      if (before[i].size() == 1) {
        EXPECT_LT(before_tree[i][2], 0) << "trial " << trial;  // no children
        ++dropped;
        continue;
      }
      index[i] = next++;
    }
    ASSERT_EQ(static_cast<int>(after.size()), next) << "trial " << trial;
    kept_total += next;
    const auto mapped = [&](int i) { return i < 0 ? -1 : index[i]; };
    for (size_t i = 0; i < before.size(); ++i) {
      if (index[i] < 0) continue;
      EXPECT_EQ(after[index[i]], before[i]) << "trial " << trial;
      // Parent and first child the same contours (the first child may have been a dropped one:
      // then it is the next kept sibling).
      EXPECT_EQ(after_tree[index[i]][3], mapped(before_tree[i][3])) << "trial " << trial;
      int child = before_tree[i][2];
      while (child >= 0 && index[child] < 0) child = before_tree[child][0];
      EXPECT_EQ(after_tree[index[i]][2], mapped(child)) << "trial " << trial;
    }
  }
  EXPECT_GT(dropped, 100);
  EXPECT_GT(kept_total, 500);
}

TEST(DetectComponents, RowEndsHullIsOpenCvsConvexHull) {
  cv::RNG rng(17);
  int compared = 0;
  for (int trial = 0; trial < 30; ++trial) {
    // Blobs of every shape: thresholded smoothed noise (blobs, thin strokes, single pixels),
    // and straight bars (collinear row ends).
    cv::Mat noise(90 + trial, 120, CV_8U);
    rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
    if (trial % 3 != 0) cv::GaussianBlur(noise, noise, cv::Size(7, 7), 1.0 + trial % 4);
    cv::Mat binary = noise > (trial % 3 == 0 ? 230 : 140);
    cv::line(binary, cv::Point(5, 5), cv::Point(60, 5 + trial), cv::Scalar(255), 1 + trial % 3);
    cv::rectangle(binary, cv::Rect(70, 10, 11, 9 + trial % 5), cv::Scalar(255), cv::FILLED);
    for (const RunComponent& component : RunComponents(binary)) {
      std::vector<cv::Point> expected;
      cv::convexHull(component.row_ends, expected);
      std::vector<cv::Point> hull = RowEndsHull(component.row_ends);
      ASSERT_EQ(hull.size(), expected.size()) << "trial " << trial << " at " << component.box;
      const auto first = std::find(hull.begin(), hull.end(), expected.front());
      ASSERT_NE(first, hull.end());
      std::rotate(hull.begin(), first, hull.end());
      EXPECT_EQ(hull, expected) << "trial " << trial << " at " << component.box;
      ++compared;
    }
  }
  EXPECT_GT(compared, 1000);
}

// SkipEqual and SkipNonZero (eight pixels per step) against a pixel-by-pixel scan: rows of
// 0 to 40 pixels of runs of 0, 255 and other values, from every start.
TEST(DetectComponents, SkipScansMatchAPixelByPixelScan) {
  cv::RNG rng(11);
  int checked = 0;
  for (int trial = 0; trial < 300; ++trial) {
    const int cols = rng.uniform(0, 41);
    std::vector<uint8_t> row(static_cast<size_t>(cols) + 1, 0);  // + 1: data() of an empty row
    for (int x = 0; x < cols;) {
      const int length = 1 + rng.uniform(0, trial % 3 == 0 ? 3 : 12);
      const int kind = rng.uniform(0, 4);
      for (int k = 0; k < length && x < cols; ++k, ++x) {
        row[x] = kind == 0 ? 0 : kind == 1 ? 255 : kind == 2 ? 1 : static_cast<uint8_t>(rng.uniform(0, 256));
      }
    }
    for (int x = 0; x <= cols; ++x) {
      for (const uint8_t value : {uint8_t{0}, uint8_t{255}, uint8_t{1}, row[std::min(x, cols)]}) {
        int expected = x;
        while (expected < cols && row[expected] == value) ++expected;
        ASSERT_EQ(SkipEqual(row.data(), x, cols, value), expected) << "trial " << trial << " x " << x;
      }
      int expected = x;
      while (expected < cols && row[expected] != 0) ++expected;
      ASSERT_EQ(SkipNonZero(row.data(), x, cols), expected) << "trial " << trial << " x " << x;
      ++checked;
    }
  }
  EXPECT_GT(checked, 3000);
}

// ClearIsolatedPixels against its definition, pixel by pixel: random images of any non-zero
// values (sparse and dense, one row or one column among them), also through a view.
TEST(DetectComponents, ClearIsolatedPixelsMatchesItsDefinition) {
  cv::RNG rng(5);
  int cleared_total = 0;
  for (int trial = 0; trial < 40; ++trial) {
    const int rows = trial % 10 == 0 ? 1 : rng.uniform(1, 50),
              cols = trial % 10 == 5 ? 1 : rng.uniform(1, 70);
    cv::Mat big(rows + 2, cols + 3, CV_8U);
    rng.fill(big, cv::RNG::UNIFORM, 0, 256);
    cv::Mat sparse = big.clone();
    sparse.setTo(0, big < (trial % 2 == 0 ? 220 : 120));
    const cv::Mat binary = sparse(cv::Rect(1, 1, cols, rows));
    cv::Mat expected = binary.clone();
    for (int y = 0; y < rows; ++y) {
      for (int x = 0; x < cols; ++x) {
        bool neighbour = false;
        for (int dy = -1; dy <= 1; ++dy) {
          for (int dx = -1; dx <= 1; ++dx) {
            const int ny = y + dy, nx = x + dx;
            if ((dy != 0 || dx != 0) && ny >= 0 && ny < rows && nx >= 0 && nx < cols &&
                binary.at<uint8_t>(ny, nx) != 0) {
              neighbour = true;
            }
          }
        }
        if (!neighbour) expected.at<uint8_t>(y, x) = 0;
      }
    }
    cleared_total += cv::countNonZero(binary) - cv::countNonZero(expected);
    cv::Mat view = binary;  // clears in place, through the view
    ClearIsolatedPixels(&view);
    ASSERT_EQ(cv::countNonZero(binary != expected), 0) << "trial " << trial;
  }
  EXPECT_GT(cleared_total, 100);
}

}  // namespace
}  // namespace waymark
