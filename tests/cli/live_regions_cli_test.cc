// Issue 14, item 6: `waymark localize --live` with image lines detects where the map predicts
// its codes (runner/predicted_regions.h). On the shipped demo run (data/demo/run: 76 rendered
// images of two cameras, odometry, exact ground truth) against the true map, the poses are as
// accurate as with the whole frame every time, and the summary says how many images were
// detected each way and what they cost.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include "io/dataset_io.h"
#include "io/tum_io.h"
#include "tests/cli/cli_test_util.h"

namespace waymark {
namespace {

namespace fs = std::filesystem;

class LiveRegionsCliTest : public CliTest {
 protected:
  LiveRegionsCliTest() : CliTest("live_regions") {}

  // The demo run as live input: odometry and image lines in stamp order (odometry first).
  std::string WriteLiveInput() const {
    const fs::path run = fs::path(WAYMARK_SOURCE_DIR) / "data" / "demo" / "run";
    std::vector<std::tuple<double, int, std::string>> lines;
    for (const StampedSE3& pose : ReadTum(run / "odometry.tum")) {
      const Eigen::Quaterniond q(pose.T.rotation());
      const Eigen::Vector3d t = pose.T.translation();
      std::ostringstream line;
      line.precision(17);
      line << "{\"t\": " << pose.stamp_s << ", \"T_odom_robot\": {\"t\": [" << t.x() << ", " << t.y() << ", "
           << t.z() << "], \"q_xyzw\": [" << q.x() << ", " << q.y() << ", " << q.z() << ", " << q.w()
           << "]}}";
      lines.emplace_back(pose.stamp_s, 0, line.str());
    }
    const Dataset dataset = LoadDataset(run);
    for (const ImageEntry& image : dataset.images) {
      std::ostringstream line;
      line.precision(17);
      line << "{\"t\": " << image.stamp_s << ", \"camera\": \"" << image.camera << "\", \"image\": \""
           << (run / image.path).string() << "\"}";
      lines.emplace_back(image.stamp_s, 1, line.str());
    }
    std::stable_sort(lines.begin(), lines.end(), [](const auto& a, const auto& b) {
      return std::tie(std::get<0>(a), std::get<1>(a)) < std::tie(std::get<0>(b), std::get<1>(b));
    });
    const fs::path path = dir_ / "live.jsonl";
    std::ofstream out(path);
    for (const auto& line : lines) out << std::get<2>(line) << "\n";
    return path.string();
  }

  struct Accuracy {
    int poses = 0, corrected = 0;
    double rms_m = 0.0;
  };
  // Position error of every pose line against the ground truth (interpolated at its stamp).
  static Accuracy Evaluate(const std::string& pose_lines) {
    const Trajectory truth =
        ReadTum(fs::path(WAYMARK_SOURCE_DIR) / "data" / "demo" / "run" / "groundtruth" / "trajectory.tum");
    Accuracy a;
    double sum = 0.0;
    std::istringstream in(pose_lines);
    for (std::string line; std::getline(in, line);) {
      const nlohmann::json o = nlohmann::json::parse(line);
      a.corrected += o.at("accepted").get<int>() > 0;
      if (!o.contains("T_world_robot")) continue;
      const double t = o.at("t").get<double>();
      const auto next = std::lower_bound(truth.begin(), truth.end(), t,
                                         [](const StampedSE3& s, double v) { return s.stamp_s < v; });
      if (next == truth.end()) continue;
      Eigen::Vector3d p = next->T.translation();
      if (next != truth.begin() && next->stamp_s > t) {
        const auto prev = next - 1;
        const double w = (t - prev->stamp_s) / (next->stamp_s - prev->stamp_s);
        p = (1 - w) * prev->T.translation() + w * next->T.translation();
      }
      const auto& xyz = o.at("T_world_robot").at("t");
      sum += (Eigen::Vector3d(xyz[0], xyz[1], xyz[2]) - p).squaredNorm();
      ++a.poses;
    }
    a.rms_m = a.poses > 0 ? std::sqrt(sum / a.poses) : 0.0;
    return a;
  }
};

TEST_F(LiveRegionsCliTest, PredictedRegionsKeepTheAccuracyOfWholeFrames) {
  const std::string input = WriteLiveInput();
  const fs::path run = fs::path(WAYMARK_SOURCE_DIR) / "data" / "demo" / "run";
  const std::string base = "localize " + run.string() + " --map " +
                           (run / "groundtruth" / "markers.json").string() + " --live --detect-budget-ms 0";
  const RunResult whole = RunWaymark(base + " --full-frame-every 1", dir_, input);
  ASSERT_EQ(whole.exit_code, 0) << whole.err;
  EXPECT_NE(whole.err.find("detection: 0 images in the map's predicted regions only"), std::string::npos)
      << whole.err;
  const RunResult regions = RunWaymark(base, dir_, input);  // default: whole frame every 10th
  ASSERT_EQ(regions.exit_code, 0) << regions.err;
  // Most images were detected in the predicted regions only.
  const size_t at = regions.err.find("images in the map's predicted regions only");
  ASSERT_NE(at, std::string::npos) << regions.err;
  const size_t start = regions.err.rfind("detection: ", at) + std::string("detection: ").size();
  EXPECT_GE(std::stoi(regions.err.substr(start, at - start)), 50) << regions.err;
  // The CPU without decoding the image files is given beside it.
  EXPECT_NE(regions.err.find("detection: of which reading the image files: regions "), std::string::npos)
      << regions.err;
  // ... and the mean over every image (regions and whole frames) without it: below the regions'
  // and whole frames' means with it.
  const size_t all = regions.err.find(" ms mean; all images ");
  ASSERT_NE(all, std::string::npos) << regions.err;
  const double all_ms = std::stod(regions.err.substr(all + std::string(" ms mean; all images ").size()));
  EXPECT_GT(all_ms, 0.0) << regions.err;
  const size_t with_read = regions.err.find("all images: CPU ");
  ASSERT_NE(with_read, std::string::npos) << regions.err;
  EXPECT_LE(all_ms, std::stod(regions.err.substr(with_read + std::string("all images: CPU ").size())))
      << regions.err;
  const Accuracy a = Evaluate(whole.out), b = Evaluate(regions.out);
  ASSERT_GE(a.poses, 70);
  EXPECT_EQ(b.poses, a.poses);
  EXPECT_GE(b.corrected, a.corrected);
  EXPECT_LE(b.rms_m, a.rms_m * 1.05 + 1e-4)
      << "whole frames " << a.rms_m << " m, regions " << b.rms_m << " m";
}

TEST_F(LiveRegionsCliTest, BadFullFrameEveryIsAOneLineError) {
  const fs::path run = fs::path(WAYMARK_SOURCE_DIR) / "data" / "demo" / "run";
  const std::string map = (run / "groundtruth" / "markers.json").string();
  const fs::path empty = dir_ / "empty.jsonl";
  std::ofstream(empty).close();
  const RunResult zero = RunWaymark(
      "localize " + run.string() + " --map " + map + " --live --full-frame-every 0", dir_, empty.string());
  EXPECT_EQ(zero.exit_code, 1);
  EXPECT_NE(zero.err.find("--full-frame-every: expected 1..1000000, got 0"), std::string::npos) << zero.err;
  const RunResult offline = Run("localize " + run.string() + " --map " + map + " --out " +
                                (dir_ / "x.tum").string() + " --full-frame-every 5");
  EXPECT_EQ(offline.exit_code, 1);
  EXPECT_NE(offline.err.find("--full-frame-every applies to --live only"), std::string::npos) << offline.err;
}

}  // namespace
}  // namespace waymark
