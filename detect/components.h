// Connected components of a binary image from its runs (issue 14's candidate stage): one
// pass over the rows collects the runs of non-zero pixels, runs that touch in adjacent rows
// (8-connectivity, as cv::findContours joins non-zero pixels) are merged with a union-find,
// and each component is its bounding box and the leftmost and rightmost pixel of each of its
// rows. These hold every extreme point of the component, so their convex hull is the
// component's (and its outer contour's). Noise pixels and other small components cost a run each, not a
// contour trace. The work is a fixed function of the image.
#pragma once

#include <functional>
#include <opencv2/core.hpp>
#include <vector>

namespace waymark {

struct RunComponent {
  cv::Rect box;                     // bounding box of the component's pixels
  std::vector<cv::Point> row_ends;  // leftmost and rightmost pixel of each row, top row first
};

// 255 where a pixel of `gray` (CV_8UC1) is at least `darker_by` gray levels below the mean of
// the `box` x `box` square around it (`box` odd, 3 to 15; the mean rounded to an integer, the image's
// border replicated), else 0: exactly cv::adaptiveThreshold(gray, dark, 255,
// ADAPTIVE_THRESH_MEAN_C, THRESH_BINARY_INV, box, darker_by), in 16-bit integers (column sums
// slid down the rows, box sums from sums of 2, 4 and 8 columns; no division).
cv::Mat DarkerThanLocalMean(const cv::Mat& gray, int box, int darker_by);

// The 8-connected components of the non-zero pixels of `binary` (CV_8UC1) whose bounding box
// passes `keep` (all when empty), in the raster order of their first pixel (top row first,
// then left to right).
std::vector<RunComponent> RunComponents(const cv::Mat& binary,
                                        const std::function<bool(const cv::Rect&)>& keep = {});

}  // namespace waymark
