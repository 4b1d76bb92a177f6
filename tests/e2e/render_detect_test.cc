// End to end: `waymark sim rooms --render`, then the project's detectors on every rendered
// image, matched to groundtruth/corners.jsonl. Acceptance: for codes whose shortest side is
// over 40 px, >= 98 % are detected with their exact id and every corner within 0.5 px.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <set>
#include <string>

#include "detect/detector.h"
#include "io/dataset_io.h"
#include "io/detections_io.h"
#include "io/util.h"
#include "sim/render.h"

namespace waymark {
namespace {

namespace fs = std::filesystem;

TEST(RenderDetectTest, DetectionsMatchRenderedGroundTruth) {
  const fs::path dir = fs::temp_directory_path() / ("waymark-render-e2e-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  const std::string command = std::string(WAYMARK_BINARY) +
                              " sim rooms --seed 5 --render --render-every 80 --out " + dir.string() +
                              " 2> " + (dir.string() + ".log");
  ASSERT_EQ(std::system(command.c_str()), 0) << ReadTextFile(dir.string() + ".log");
  const Dataset dataset = LoadDataset(dir);
  ASSERT_FALSE(dataset.images.empty());
  ReadWarnings warnings;
  const std::vector<DetectionFrame> truth =
      ReadDetections(dir / "groundtruth" / "corners.jsonl", &warnings, &dataset.cameras);
  ASSERT_EQ(truth.size(), dataset.images.size());
  EXPECT_EQ(warnings.Total(), 0);

  // Codes in the world: a detection whose id is not one of them is a misread. (A code can be
  // read without being in a frame's truth: the truth lists only codes with all four corners
  // visible and unoccluded, within 89 degrees.)
  ASSERT_TRUE(dataset.groundtruth_markers.has_value());
  std::set<MarkerKey> world_keys;
  for (const MapMarker& m : dataset.groundtruth_markers->markers) world_keys.insert(m.key);
  const auto detector = CreateMultiDetector({"datamatrix", "qr"});
  long wide = 0, matched = 0, wrong_id = 0, not_in_truth = 0;
  double worst_px = 0.0;
  for (size_t i = 0; i < truth.size(); ++i) {
    const cv::Mat image = cv::imread((dir / dataset.images[i].path).string(), cv::IMREAD_GRAYSCALE);
    ASSERT_FALSE(image.empty()) << dataset.images[i].path;
    const std::vector<MarkerObservation> found = detector->Detect(image);
    for (const MarkerObservation& obs : found) {
      bool in_truth = false;
      for (const MarkerObservation& t : truth[i].markers) in_truth = in_truth || t.key == obs.key;
      not_in_truth += !in_truth;
      wrong_id += world_keys.count(obs.key) == 0;
    }
    for (const MarkerObservation& t : truth[i].markers) {
      if (sim::ShortestSidePx(t.corners_px) <= 40.0) continue;
      ++wide;
      for (const MarkerObservation& obs : found) {
        if (obs.key != t.key) continue;
        double max_px = 0.0;
        for (int k = 0; k < 4; ++k) max_px = std::max(max_px, (obs.corners_px[k] - t.corners_px[k]).norm());
        worst_px = std::max(worst_px, max_px);
        if (max_px <= 0.5) ++matched;
        break;
      }
    }
  }
  const double rate = wide > 0 ? static_cast<double>(matched) / wide : 0.0;
  std::printf(
      "%zu images, %ld codes wider than 40 px, %ld matched (ids exact, corners <= 0.5 px): %.1f %%; "
      "worst corner error of a detected code %.3f px; %ld detections of codes not fully visible; "
      "%ld with an id not in the world\n",
      truth.size(), wide, matched, 100.0 * rate, worst_px, not_in_truth, wrong_id);
  EXPECT_GE(wide, 10);
  EXPECT_GE(rate, 0.98);
  EXPECT_EQ(wrong_id, 0);
  fs::remove_all(dir);
  fs::remove(dir.string() + ".log");
}

}  // namespace
}  // namespace waymark
