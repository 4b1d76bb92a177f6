// `waymark detect` end to end through the binary: an image, a directory of images, a
// dataset directory and a video of synthetic codes; the output read back with the
// detections.jsonl reader; and the error cases (corrupt image, empty directory,
// unreadable video, unknown family): exit 1, one line, no output file.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <string>
#include <thread>
#include <vector>

#include "detect/synthetic.h"
#include "io/detections_io.h"
#include "tests/cli/cli_test_util.h"

namespace waymark {
namespace {

namespace fs = std::filesystem;

class DetectCli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("waymark_detect_cli_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // Runs the binary; returns its exit status; stderr goes to dir_/stderr.txt.
  int Run(const std::string& arguments) {
    const std::string command =
        std::string(WAYMARK_BINARY) + " detect " + arguments + " 2> " + (dir_ / "stderr.txt").string();
    const int status = std::system(command.c_str());
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }
  std::string Stderr() const {
    std::ifstream in(dir_ / "stderr.txt");
    return std::string(std::istreambuf_iterator<char>(in), {});
  }

  // A 640x480 image with a QR code and an AprilTag.
  static cv::Mat Scene(const std::string& qr_text, int tag_id) {
    cv::Mat image(480, 640, CV_8U, cv::Scalar(185));
    DrawSymbol(QrSymbol(qr_text), MakeQuad({170.0, 240.0}, 170.0, 0.2), &image);
    DrawSymbol(AprilTagSymbol("apriltag-36h11", tag_id), MakeQuad({470.0, 240.0}, 160.0, -0.3), &image);
    return image;
  }

  std::vector<DetectionFrame> ReadBack(const fs::path& path) {
    ReadWarnings warnings;
    auto frames = ReadDetections(path, &warnings);
    EXPECT_EQ(warnings.Total(), 0);
    return frames;
  }

  fs::path dir_;
};

std::set<std::string> Keys(const DetectionFrame& frame) {
  std::set<std::string> keys;
  for (const auto& m : frame.markers) keys.insert(m.key.ToString());
  return keys;
}

TEST_F(DetectCli, SingleImageAndDirectory) {
  fs::create_directories(dir_ / "images");
  cv::imwrite((dir_ / "images" / "a.png").string(), Scene("A/1", 1));
  cv::imwrite((dir_ / "images" / "b.png").string(), Scene("B/2", 2));
  cv::imwrite((dir_ / "images" / "c.png").string(), cv::Mat(480, 640, CV_8U, cv::Scalar(128)));
  const fs::path one = dir_ / "one.jsonl";
  ASSERT_EQ(Run((dir_ / "images" / "a.png").string() + " --out " + one.string()), 0) << Stderr();
  auto frames = ReadBack(one);
  ASSERT_EQ(frames.size(), 1u);
  EXPECT_EQ(frames[0].image, (dir_ / "images" / "a.png").string());
  EXPECT_EQ(frames[0].camera, "cam0");
  EXPECT_EQ(Keys(frames[0]), (std::set<std::string>{"qr:A/1", "apriltag-36h11:1"}));
  EXPECT_NE(Stderr().find("median"), std::string::npos);

  const fs::path all = dir_ / "all.jsonl";
  ASSERT_EQ(Run((dir_ / "images").string() + " --families qr --out " + all.string() + " --annotate " +
                (dir_ / "ann").string()),
            0)
      << Stderr();
  frames = ReadBack(all);
  ASSERT_EQ(frames.size(), 3u);  // the blank image still gets its line
  EXPECT_EQ(Keys(frames[0]), std::set<std::string>{"qr:A/1"});
  EXPECT_EQ(Keys(frames[1]), std::set<std::string>{"qr:B/2"});
  EXPECT_TRUE(frames[2].markers.empty());
  EXPECT_EQ(frames[2].image, (dir_ / "images" / "c.png").string());
  int annotated = 0;
  for (const auto& e : fs::directory_iterator(dir_ / "ann")) annotated += e.path().extension() == ".png";
  EXPECT_EQ(annotated, 3);
}

TEST_F(DetectCli, DatasetDirectoryUsesRowsStampsAndCameras) {
  const fs::path data = dir_ / "ds";
  fs::create_directories(data / "cameras");
  fs::create_directories(data / "img");
  std::ofstream(data / "dataset.yaml")
      << "format: waymark-dataset\nversion: 1\nmotion: planar\ncameras: [front]\n";
  std::ofstream(data / "cameras" / "front.yaml")
      << "model: pinhole-radtan\nwidth: 640\nheight: 480\nintrinsics: [500, 500, 320, 240]\n"
         "distortion: [0, 0, 0, 0, 0]\nT_robot_camera: {t: [0, 0, 0], q_xyzw: [0, 0, 0, 1]}\n";
  cv::imwrite((data / "img" / "0.png").string(), Scene("P/0", 7));
  cv::imwrite((data / "img" / "1.png").string(), Scene("P/1", 8));
  std::ofstream(data / "images.csv") << "t,camera,path\n1.5,front,img/0.png\n2.5,front,img/1.png\n";
  const fs::path out = dir_ / "ds.jsonl";
  ASSERT_EQ(Run(data.string() + " --out " + out.string()), 0) << Stderr();
  const auto frames = ReadBack(out);
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_EQ(frames[1].stamp_s, 2.5);
  EXPECT_EQ(frames[1].camera, "front");
  EXPECT_EQ(frames[1].image, "img/1.png");
  EXPECT_EQ(Keys(frames[1]), (std::set<std::string>{"qr:P/1", "apriltag-36h11:8"}));
}

TEST_F(DetectCli, VideoFramesAreNumbered) {
  const fs::path video = dir_ / "clip.avi";
  cv::VideoWriter writer(video.string(), cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 10.0,
                         cv::Size(640, 480));
  if (!writer.isOpened()) GTEST_SKIP() << "this OpenCV cannot write MJPG/AVI";
  for (int i = 0; i < 3; ++i) {
    cv::Mat bgr;
    cv::cvtColor(Scene("V/" + std::to_string(i), i), bgr, cv::COLOR_GRAY2BGR);
    writer.write(bgr);
  }
  writer.release();
  const fs::path out = dir_ / "video.jsonl";
  ASSERT_EQ(Run(video.string() + " --families apriltag-36h11 --out " + out.string()), 0) << Stderr();
  const auto frames = ReadBack(out);
  ASSERT_EQ(frames.size(), 3u);
  for (int i = 0; i < 3; ++i) {
    ASSERT_TRUE(frames[i].frame.has_value());
    EXPECT_EQ(*frames[i].frame, i);
    EXPECT_FALSE(frames[i].image.has_value());
    EXPECT_EQ(Keys(frames[i]), std::set<std::string>{"apriltag-36h11:" + std::to_string(i)});
  }
}

// Issue 18, finding 3: an 8-bit PNG of 2000x1 (or 4000x1, 20000x4) ended `detect` with a raw
// OpenCV assertion (resize.cpp, !dsize.empty()); now a normal empty result.
TEST_F(DetectCli, OddImageShapesGiveAnEmptyResult) {
  for (const cv::Size size :
       {cv::Size(2000, 1), cv::Size(4000, 1), cv::Size(20000, 4), cv::Size(1, 3000), cv::Size(1, 1)}) {
    cv::Mat image(size, CV_8U);
    cv::randu(image, 0, 256);
    const fs::path file =
        dir_ / ("odd_" + std::to_string(size.width) + "x" + std::to_string(size.height) + ".png");
    ASSERT_TRUE(cv::imwrite(file.string(), image));
    const fs::path out = dir_ / "odd.jsonl";
    ASSERT_EQ(Run(file.string() + " --out " + out.string()), 0) << file << ": " << Stderr();
    const auto frames = ReadBack(out);
    ASSERT_EQ(frames.size(), 1u);
    EXPECT_TRUE(frames[0].markers.empty());
  }
}

// Issue 18, finding 3: a corrupt PNG printed libpng's warnings beside the one-line error.
TEST_F(DetectCli, CorruptPngIsOneLineWithoutDecoderNoise) {
  std::vector<uchar> png;
  ASSERT_TRUE(cv::imencode(".png", Scene("P/1", 1), png));
  // A wrong CRC in the header chunk, and a file cut in the middle of its pixels.
  std::vector<uchar> bad_crc = png;
  bad_crc[29] ^= 0xff;
  std::ofstream(dir_ / "crc.png", std::ios::binary)
      .write(reinterpret_cast<const char*>(bad_crc.data()), bad_crc.size());
  std::ofstream(dir_ / "cut.png", std::ios::binary)
      .write(reinterpret_cast<const char*>(png.data()), png.size() / 2);
  // A PNG header declaring 100000 x 100000 pixels: refused before decoding.
  std::vector<uchar> huge(png.begin(), png.begin() + 33);
  for (int i = 0; i < 2; ++i) {
    const uint32_t side = 100000;
    for (int b = 0; b < 4; ++b) huge[16 + 4 * i + b] = static_cast<uchar>(side >> (24 - 8 * b));
  }
  std::ofstream(dir_ / "huge.png", std::ios::binary)
      .write(reinterpret_cast<const char*>(huge.data()), huge.size());
  for (const std::string name : {"crc.png", "cut.png", "huge.png"}) {
    EXPECT_EQ(Run((dir_ / name).string() + " --out " + (dir_ / "never.jsonl").string()), 1) << name;
    const std::string err = Stderr();
    EXPECT_NE(err.find(name + ": cannot read image"), std::string::npos) << err;
    EXPECT_EQ(err.find("libpng"), std::string::npos) << err;
    EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
    EXPECT_FALSE(fs::exists(dir_ / "never.jsonl"));
  }
  EXPECT_NE(Stderr().find("larger than the limit"), std::string::npos) << Stderr();
}

TEST_F(DetectCli, BadInputsFailWithOneLineAndNoOutput) {
  const fs::path out = dir_ / "never.jsonl";
  std::ofstream(dir_ / "corrupt.png") << "not a png at all";
  fs::create_directories(dir_ / "empty");
  std::ofstream(dir_ / "broken.mp4") << "no video here";
  fs::create_directories(dir_ / "mixed");
  cv::imwrite((dir_ / "mixed" / "a.png").string(), Scene("M/1", 1));
  std::ofstream(dir_ / "mixed" / "b.png") << "truncated";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {(dir_ / "corrupt.png").string(), "cannot read image"},
      {(dir_ / "empty").string(), "no images"},
      {(dir_ / "broken.mp4").string(), "cannot open video"},
      {(dir_ / "mixed").string(), "b.png: cannot read image"},
      {(dir_ / "missing.png").string(), "no such file"},
      {(dir_ / "mixed").string() + " --families qr,ean13", "unknown marker family"},
      {(dir_ / "mixed").string() + " --max-candidates -1", "--max-candidates: expected 0..64, got -1"},
      {(dir_ / "mixed").string() + " --max-candidates 65", "--max-candidates: expected 0..64, got 65"},
      {(dir_ / "mixed").string() + " --threads 0", "--threads: expected 1..256, got 0"},
      {(dir_ / "mixed").string() + " --threads 257", "--threads: expected 1..256, got 257"},
  };
  const fs::path annotate = dir_ / "new" / "annotated";  // neither exists yet
  for (const auto& [input, message] : cases) {
    EXPECT_EQ(Run(input + " --out " + out.string()), 1) << input;
    EXPECT_NE(Stderr().find(message), std::string::npos) << input << ": " << Stderr();
    // One line: no decoder or backend noise beside it (a broken video printed FFmpeg's and
    // GStreamer's messages before the error).
    const std::string error = Stderr();
    EXPECT_EQ(std::count(error.begin(), error.end(), '\n'), 1) << input << ": " << error;
    EXPECT_FALSE(fs::exists(out)) << input;
    // With --annotate: the same error, and no directory left behind (not even empty).
    EXPECT_EQ(Run(input + " --out " + out.string() + " --annotate " + annotate.string()), 1) << input;
    EXPECT_NE(Stderr().find(message), std::string::npos) << input << ": " << Stderr();
    EXPECT_FALSE(fs::exists(dir_ / "new")) << input;
  }
  // An annotate directory that existed is kept, and holds nothing after a failed run.
  fs::create_directories(dir_ / "kept");
  EXPECT_EQ(
      Run((dir_ / "mixed").string() + " --out " + out.string() + " --annotate " + (dir_ / "kept").string()),
      1);
  EXPECT_TRUE(fs::exists(dir_ / "kept"));
  EXPECT_TRUE(fs::is_empty(dir_ / "kept"));
  EXPECT_EQ(Run((dir_ / "mixed" / "a.png").string()), 1);  // --out missing
  EXPECT_NE(Stderr().find("--out"), std::string::npos);
}

// Frames that make every second pass work: a cluttered 1280x960 background, a small oblique
// QR code (finder pass), DataMatrix symbols at 45 degrees (zxing 1.4 misses them), a small
// AprilTag, light-on-dark QR, blur and noise.
cv::Mat HardFrame(int seed) {
  cv::Mat frame(960, 1280, CV_8U);
  cv::RNG rng(seed);
  for (int y = 0; y < frame.rows; ++y) {
    for (int x = 0; x < frame.cols; ++x) frame.at<uint8_t>(y, x) = static_cast<uint8_t>(100 + 70 * x / 1280);
  }
  for (int i = 0; i < 25; ++i) {
    const cv::Rect box(rng.uniform(0, 1200), rng.uniform(0, 900), rng.uniform(20, 200), rng.uniform(20, 200));
    cv::rectangle(frame, box, cv::Scalar(rng.uniform(30, 230)), rng.uniform(0, 2) ? cv::FILLED : 3);
  }
  DrawSymbol(QrSymbol("hard/" + std::to_string(seed)), MakeQuad({250.0, 250.0}, 60.0, 0.4, 0.6), &frame);
  DrawSymbol(DataMatrixSymbol("DM" + std::to_string(seed)), MakeQuad({700.0, 300.0}, 110.0, 0.785, 0.9),
             &frame);
  DrawSymbol(DataMatrixSymbol("dm" + std::to_string(seed)), MakeQuad({1050.0, 650.0}, 70.0, 2.2, 0.8),
             &frame);
  DrawSymbol(AprilTagSymbol("apriltag-36h11", seed), MakeQuad({300.0, 720.0}, 50.0, 0.3, 0.8), &frame);
  DrawSymbol(QrSymbol("inv/" + std::to_string(seed)), MakeQuad({700.0, 720.0}, 150.0, -0.2), &frame, 230, 25);
  cv::GaussianBlur(frame, frame, cv::Size(0, 0), 0.8);
  cv::Mat noise(frame.size(), CV_16S), wide;
  rng.fill(noise, cv::RNG::NORMAL, 0, 3.0);
  frame.convertTo(wide, CV_16S);
  wide += noise;
  wide.convertTo(frame, CV_8U);
  return frame;
}

// Issue 14: offline detection depends on the images alone. Two runs, the second beside
// busy threads on every core, write byte-identical files.
TEST_F(DetectCli, SameImagesGiveIdenticalFilesUnderLoad) {
  fs::create_directories(dir_ / "frames");
  for (int i = 0; i < 3; ++i) {
    cv::imwrite((dir_ / "frames" / ("f" + std::to_string(i) + ".png")).string(), HardFrame(i + 1));
  }
  const std::string input = (dir_ / "frames").string();
  ASSERT_EQ(Run(input + " --out " + (dir_ / "quiet.jsonl").string()), 0) << Stderr();
  {
    const CpuHog hog;
    ASSERT_EQ(Run(input + " --out " + (dir_ / "loaded.jsonl").string()), 0) << Stderr();
  }
  const auto slurp = [](const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  const std::string quiet = slurp(dir_ / "quiet.jsonl");
  EXPECT_EQ(quiet, slurp(dir_ / "loaded.jsonl"));
  // The frames hold codes the second passes read (not an empty file compared with itself).
  const auto frames = ReadBack(dir_ / "quiet.jsonl");
  ASSERT_EQ(frames.size(), 3u);
  size_t markers = 0;
  for (const DetectionFrame& frame : frames) markers += frame.markers.size();
  EXPECT_GE(markers, 9u) << quiet;
}

// Issue 14: `--threads N` runs the families of a frame at the same time; the file is the
// same byte for byte at 1 and 2 threads (and at 3: more threads than the three families'
// workers need), and says how much CPU time a frame took.
TEST_F(DetectCli, ThreadsGiveIdenticalFiles) {
  fs::create_directories(dir_ / "frames");
  for (int i = 0; i < 2; ++i) {
    cv::imwrite((dir_ / "frames" / ("f" + std::to_string(i) + ".png")).string(), HardFrame(i + 7));
  }
  const std::string input = (dir_ / "frames").string();
  const auto slurp = [](const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  ASSERT_EQ(Run(input + " --threads 1 --out " + (dir_ / "one.jsonl").string()), 0) << Stderr();
  EXPECT_NE(Stderr().find("CPU time per frame (all threads)"), std::string::npos) << Stderr();
  for (const char* n : {"2", "3"}) {
    const fs::path out = dir_ / (std::string("threads") + n + ".jsonl");
    ASSERT_EQ(Run(input + " --threads " + n + " --out " + out.string()), 0) << Stderr();
    EXPECT_EQ(slurp(dir_ / "one.jsonl"), slurp(out)) << n << " threads";
  }
  size_t markers = 0;
  for (const DetectionFrame& frame : ReadBack(dir_ / "one.jsonl")) markers += frame.markers.size();
  EXPECT_GE(markers, 6u) << slurp(dir_ / "one.jsonl");
  // Every family at once (none skipping another's codes): the same codes here, also at 2 threads.
  for (const char* n : {"1", "2"}) {
    const fs::path out = dir_ / (std::string("at-once") + n + ".jsonl");
    ASSERT_EQ(Run(input + " --families-at-once --threads " + n + " --out " + out.string()), 0) << Stderr();
    EXPECT_EQ(slurp(dir_ / "one.jsonl"), slurp(out)) << n << " threads, families at once";
  }
}

}  // namespace
}  // namespace waymark
