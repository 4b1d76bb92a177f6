// Test patches of the DataMatrix candidate tests (tests/detect/datamatrix_test.cc, quads_test.cc):
// a square patch with the symbol's square `side` px wide, `margin` px from each edge.
#pragma once

#include <opencv2/imgproc.hpp>

#include "geometry/types.h"

namespace waymark {

// The symbol square's corners (docs/design.md order, pixel edges: the square covers pixels
// margin .. margin + side - 1).
inline Quad2d PatchSquare(int margin, int side) {
  return {Eigen::Vector2d(margin - 0.5, margin - 0.5), Eigen::Vector2d(margin + side - 0.5, margin - 0.5),
          Eigen::Vector2d(margin + side - 0.5, margin + side - 0.5),
          Eigen::Vector2d(margin - 0.5, margin + side - 0.5)};
}

// A light (220) patch with a dark (25) L of 6 px legs along the square's left and bottom sides:
// L-shaped clutter with no timing pattern.
inline cv::Mat LFramePatch(int margin, int side) {
  const int size = side + 2 * margin;
  cv::Mat patch(size, size, CV_8U, cv::Scalar(220));
  cv::rectangle(patch, cv::Rect(margin, margin, 6, side), cv::Scalar(25), cv::FILLED);
  cv::rectangle(patch, cv::Rect(margin, margin + side - 6, side, 6), cv::Scalar(25), cv::FILLED);
  return patch;
}

// Three dark dashes along the square's top and right sides (a timing pattern's three runs).
inline void AddThreeDashes(int margin, int side, cv::Mat* patch) {
  for (int k = 0; k < 3; ++k) {
    cv::rectangle(*patch, cv::Rect(margin + 4 + 20 * k, margin, 10, 4), cv::Scalar(25), cv::FILLED);
    cv::rectangle(*patch, cv::Rect(margin + side - 4, margin + 4 + 20 * k, 4, 10), cv::Scalar(25),
                  cv::FILLED);
  }
}

}  // namespace waymark
