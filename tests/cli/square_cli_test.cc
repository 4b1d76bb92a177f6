// [Seki] end to end through the binary: `waymark sim square-ceiling --render` (LED pairs),
// `waymark detect D --families square`, `waymark localize D --map D/markers.json`; and the
// errors of bad LED pairs (a lone on image, a lone off image, a pair of different sizes, no pairs, family
// square on a lone image): exit 1, one line, no output file.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <string>

#include "io/detections_io.h"
#include "io/tum_io.h"

namespace waymark {
namespace {

namespace fs = std::filesystem;

class SquareCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    base_ = fs::temp_directory_path() / ("waymark_square_cli_" + std::to_string(::getpid()));
    fs::remove_all(base_);
    // Two turns on the spot under the square (8 s), every 10th camera frame rendered: 9 pairs.
    ASSERT_EQ(Waymark("sim square-ceiling --out " + (base_ / "d").string() +
                      " --seed 3 --render --render-every 10 --set path.half_side_m=0"),
              0);
  }
  static void TearDownTestSuite() { fs::remove_all(base_); }
  void SetUp() override {
    dir_ = base_ / ::testing::UnitTest::GetInstance()->current_test_info()->name();
    fs::create_directories(dir_);
    fs::copy(base_ / "d", dir_ / "d", fs::copy_options::recursive);
  }

  static int Waymark(const std::string& arguments, const fs::path& err = "/dev/null") {
    const std::string command =
        std::string(WAYMARK_BINARY) + " " + arguments + " > /dev/null 2> " + err.string();
    const int status = std::system(command.c_str());
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }
  int Detect(const std::string& extra = "") {
    return Waymark("detect " + (dir_ / "d").string() + " --out " + (dir_ / "out.jsonl").string() +
                       " --families square" + extra,
                   dir_ / "stderr.txt");
  }
  std::string Stderr() const {
    std::ifstream in(dir_ / "stderr.txt");
    return std::string(std::istreambuf_iterator<char>(in), {});
  }
  std::string ImagesCsv() const {
    std::ifstream in(dir_ / "d" / "images.csv");
    return std::string(std::istreambuf_iterator<char>(in), {});
  }
  void WriteImagesCsv(const std::string& text) { std::ofstream(dir_ / "d" / "images.csv") << text; }

  static fs::path base_;
  fs::path dir_;
};

fs::path SquareCli::base_;

TEST_F(SquareCli, DetectsTheSquareInEveryPairAndLocalizes) {
  ASSERT_EQ(Detect(), 0) << Stderr();
  ReadWarnings warnings;
  const std::vector<DetectionFrame> frames = ReadDetections(dir_ / "out.jsonl", &warnings);
  ASSERT_EQ(frames.size(), 9u);
  for (const DetectionFrame& frame : frames) {
    ASSERT_EQ(frame.markers.size(), 1u) << frame.stamp_s;
    EXPECT_EQ(frame.markers[0].key.ToString(), "square:S0");
    EXPECT_NE(frame.image->find("-on.png"), std::string::npos);
  }
  // Against the exact corners of the rendered pairs.
  const std::vector<DetectionFrame> truth =
      ReadDetections(dir_ / "d" / "groundtruth" / "corners.jsonl", &warnings);
  ASSERT_EQ(truth.size(), frames.size());
  double worst_px = 0.0;
  for (size_t i = 0; i < frames.size(); ++i) {
    ASSERT_EQ(truth[i].markers.size(), 1u);
    EXPECT_EQ(truth[i].stamp_s, frames[i].stamp_s);
    for (int k = 0; k < 4; ++k) {
      worst_px =
          std::max(worst_px, (frames[i].markers[0].corners_px[k] - truth[i].markers[0].corners_px[k]).norm());
    }
  }
  EXPECT_LT(worst_px, 0.5);
  EXPECT_NE(Stderr().find("detect: 9 frames, 9 markers"), std::string::npos) << Stderr();
  // The localizer starts from the square and follows the turns.
  fs::copy_file(dir_ / "out.jsonl", dir_ / "d" / "detections.jsonl", fs::copy_options::overwrite_existing);
  ASSERT_EQ(Waymark("localize " + (dir_ / "d").string() + " --map " + (dir_ / "d" / "markers.json").string() +
                        " --out " + (dir_ / "run.tum").string(),
                    dir_ / "stderr.txt"),
            0)
      << Stderr();
  EXPECT_FALSE(ReadTum(dir_ / "run.tum").empty());
}

TEST_F(SquareCli, LoneOnImageIsAnError) {
  std::string csv = ImagesCsv();
  const size_t off = csv.find("-off.png");
  ASSERT_NE(off, std::string::npos);
  const size_t begin = csv.rfind('\n', off) + 1, end = csv.find('\n', off) + 1;
  const std::string removed = csv.substr(begin, end - begin);
  WriteImagesCsv(csv.erase(begin, end - begin));
  EXPECT_EQ(Detect(), 1);
  const std::string err = Stderr();
  EXPECT_NE(err.find("has no LED-off partner"), std::string::npos) << err;
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
  EXPECT_FALSE(fs::exists(dir_ / "out.jsonl"));
  (void)removed;
}

TEST_F(SquareCli, LoneOffImageIsAnError) {
  std::string csv = ImagesCsv();
  const size_t on = csv.find("-on.png");
  ASSERT_NE(on, std::string::npos);
  const size_t begin = csv.rfind('\n', on) + 1, end = csv.find('\n', on) + 1;
  const size_t path_begin = csv.rfind(',', on) + 1;
  const std::string off_path = csv.substr(path_begin, on - path_begin) + "-off.png";
  WriteImagesCsv(csv.erase(begin, end - begin));
  EXPECT_EQ(Detect(), 1);
  const std::string err = Stderr();
  EXPECT_NE(err.find("LED-off image '" + off_path + "' (camera up) has no LED-on partner"), std::string::npos)
      << err;
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
  EXPECT_FALSE(fs::exists(dir_ / "out.jsonl"));
}

TEST_F(SquareCli, PairOfDifferentSizesIsAnError) {
  std::string csv = ImagesCsv();
  const size_t off = csv.find("-off.png");
  const size_t begin = csv.rfind(',', off) + 1;
  const std::string path = csv.substr(begin, off + 8 - begin);
  cv::imwrite((dir_ / "d" / path).string(), cv::Mat(512, 640, CV_8U, cv::Scalar(0)));
  EXPECT_EQ(Detect(), 1);
  EXPECT_NE(Stderr().find("LED pair: the on image is 1280x1024 but its off image " + path + " is 640x512"),
            std::string::npos)
      << Stderr();
  EXPECT_FALSE(fs::exists(dir_ / "out.jsonl"));
}

TEST_F(SquareCli, NoPairsOrNoDatasetIsAnError) {
  std::string csv = ImagesCsv();
  std::string only_on;
  std::istringstream lines(csv);
  for (std::string line; std::getline(lines, line);) {
    if (line.find("-off.png") == std::string::npos) only_on += line + "\n";
  }
  // Without their partners the on rows are lone on images; rename them to plain images.
  std::string plain;
  std::istringstream on_lines(only_on);
  for (std::string line; std::getline(on_lines, line);) {
    const size_t at = line.find("-on.png");
    if (at != std::string::npos) line.replace(at, 7, ".png");
    plain += line + "\n";
  }
  WriteImagesCsv(plain);
  EXPECT_EQ(Detect(), 1);
  EXPECT_NE(Stderr().find("no LED pairs"), std::string::npos) << Stderr();
  EXPECT_EQ(Waymark("detect " + (dir_ / "d" / "images" / "up" / "000000-on.png").string() + " --out " +
                        (dir_ / "out.jsonl").string() + " --families square",
                    dir_ / "stderr.txt"),
            1);
  EXPECT_NE(Stderr().find("family square is detected in the LED pairs of a dataset"), std::string::npos)
      << Stderr();
  EXPECT_FALSE(fs::exists(dir_ / "out.jsonl"));
}

}  // namespace
}  // namespace waymark
