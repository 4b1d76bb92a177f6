#include "io/detections_io.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <random>
#include <string>

#include "io/util.h"

namespace waymark {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

const char* const kMarker =
    R"({"family": "qr", "id": "0/2/10", "corners_px": [[10, 20], [30, 20], [30, 40], [10, 40]]})";

std::string Line(double t, const std::string& markers, const std::string& camera = "cam0") {
  return "{\"t\": " + FormatDouble(t) + ", \"camera\": \"" + camera + "\", \"markers\": [" + markers + "]}\n";
}

std::map<std::string, CameraInfo> OneCamera() {
  CameraInfo camera;
  camera.name = "cam0";
  camera.width = 640;
  camera.height = 480;
  return {{"cam0", camera}};
}

std::string ParseError(const std::string& text) {
  const std::map<std::string, CameraInfo> cameras = OneCamera();
  ReadWarnings warnings;
  try {
    ParseDetections(text, "detections.jsonl", &warnings, &cameras);
  } catch (const FormatError& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected a FormatError for:\n" << text;
  return "";
}

TEST(DetectionsIoTest, ParsesFramesWithAndWithoutMarkers) {
  const std::string text =
      Line(1.0, kMarker) + "\n" + Line(2.0, "") +
      R"({"t": 3, "camera": "cam0", "image": "img/3.png", "frame": 3, "markers": [)" +
      R"({"family": "apriltag-36h11", "id": "7", "quality": 0.5, "corners_px": [[1,2],[3,4],[5,6],[7,8]]}]})" +
      "\n";
  ReadWarnings warnings;
  const std::map<std::string, CameraInfo> cameras = OneCamera();
  const std::vector<DetectionFrame> frames = ParseDetections(text, "detections.jsonl", &warnings, &cameras);
  ASSERT_EQ(frames.size(), 3u);
  ASSERT_EQ(frames[0].markers.size(), 1u);
  EXPECT_EQ(frames[0].markers[0].key, (MarkerKey{"qr", "0/2/10"}));
  EXPECT_EQ(frames[0].markers[0].corners_px[2], Eigen::Vector2d(30, 40));
  EXPECT_FALSE(frames[0].markers[0].quality.has_value());
  EXPECT_TRUE(frames[1].markers.empty());
  EXPECT_EQ(frames[2].image, "img/3.png");
  EXPECT_EQ(frames[2].frame, 3);
  EXPECT_EQ(frames[2].markers[0].quality, 0.5);
  EXPECT_EQ(warnings.Total(), 0);
}

TEST(DetectionsIoTest, MalformedLinesAreErrorsWithTheirLine) {
  EXPECT_THAT(ParseError(Line(1, kMarker) + "{\"t\": 2, \"camera\": \"cam0\", \"markers\": [}\n"),
              HasSubstr("detections.jsonl:2: invalid JSON"));
  EXPECT_THAT(ParseError(Line(1, kMarker) + Line(2, kMarker, "cam7")),
              HasSubstr("detections.jsonl:2: camera: camera \"cam7\" is not in the dataset (cameras: cam0)"));
  EXPECT_THAT(
      ParseError(Line(1, R"({"family": "qr", "id": "a", "corners_px": [[1, 2], [3, 4], [5, 6]]})")),
      HasSubstr("detections.jsonl:1: markers[0].corners_px: expected 4 corners [[x, y], ...], got 3"));
  EXPECT_THAT(
      ParseError(Line(1, R"({"family": "qr", "id": 5, "corners_px": [[1, 2], [3, 4], [5, 6], [7, 8]]})")),
      HasSubstr("detections.jsonl:1: markers[0].id: expected a string, got a number"));
  EXPECT_THAT(
      ParseError(Line(1, R"({"family": "qr", "id": "a", "corners_px": [[1, 2], [3, 4], [5, 6], [7, "8"]]})")),
      HasSubstr("detections.jsonl:1: markers[0].corners_px[3][1]: expected a number"));
  EXPECT_THAT(
      ParseError(Line(2, kMarker) + "\n" + Line(2, kMarker) + Line(1.5, kMarker)),
      HasSubstr(
          "detections.jsonl:4: t: expected stamps non-decreasing per camera, got 1.5 after 2 for cam0"));
  EXPECT_THAT(ParseError(R"({"t": NaN, "camera": "cam0", "markers": []})"),
              HasSubstr("detections.jsonl:1: t: expected a number"));
  EXPECT_THAT(ParseError(R"({"t": 1, "camera": "cam0"})"),
              HasSubstr("detections.jsonl:1: missing key \"markers\""));
  EXPECT_THAT(ParseError(R"({"t": 1, "camera": "cam0", "markers": [], "frame": 2.5})"),
              HasSubstr("detections.jsonl:1: frame: expected an integer, got 2.5"));
  EXPECT_THAT(ParseError("[1, 2]"), HasSubstr("detections.jsonl:1: expected a JSON object"));
}

TEST(DetectionsIoTest, RejectedMarkersAreCountedWarnings) {
  const std::string text =
      Line(1, std::string(R"({"family": "aztec", "id": "x", "corners_px": [[1,2],[3,4],[5,6],[7,8]]}, )") +
                  kMarker) +
      Line(2, R"({"family": "qr", "id": "n", "corners_px": [[1,2],[3,NaN],[5,6],[7,8]]})") +
      Line(3, R"({"family": "qr", "id": "n", "corners_px": [[1,2],[3,4],[5,-Infinity],[7,8]]})") +
      Line(4, R"({"family": "qr", "id": "o", "corners_px": [[1,2],[3,4],[5,6],[700,8]]})") +
      Line(5, R"({"family": "qr", "id": "u", "colour": 1, "corners_px": [[1,2],[3,4],[5,6],[7,8]]})");
  ReadWarnings warnings;
  const std::map<std::string, CameraInfo> cameras = OneCamera();
  const std::vector<DetectionFrame> frames = ParseDetections(text, "detections.jsonl", &warnings, &cameras);
  ASSERT_EQ(frames.size(), 5u);
  EXPECT_EQ(frames[0].markers.size(), 1u);  // the qr marker is kept
  EXPECT_TRUE(frames[1].markers.empty());
  EXPECT_TRUE(frames[2].markers.empty());
  EXPECT_TRUE(frames[3].markers.empty());
  EXPECT_EQ(frames[4].markers.size(), 1u);  // an unknown key is only a warning
  EXPECT_EQ(warnings.counts["unknown family"], 1);
  EXPECT_EQ(warnings.counts["non-finite corner"], 2);
  EXPECT_EQ(warnings.counts["corner outside image"], 1);
  EXPECT_EQ(warnings.counts["unknown key"], 1);
  ASSERT_EQ(warnings.first_messages.size(), 5u);
  EXPECT_THAT(warnings.first_messages[0],
              HasSubstr("detections.jsonl:1: markers[0].family: unknown family \"aztec\""));
  EXPECT_THAT(warnings.first_messages[1],
              HasSubstr("detections.jsonl:2: markers[0].corners_px: non-finite corner"));
  EXPECT_THAT(warnings.first_messages[3],
              HasSubstr("detections.jsonl:4: markers[0].corners_px: corner (700, 8) outside the 640x480"));

  // Without camera sizes, out-of-image corners cannot be checked and are kept.
  ReadWarnings no_camera_warnings;
  EXPECT_EQ(ParseDetections(text, "detections.jsonl", &no_camera_warnings)[3].markers.size(), 1u);
}

// A code cut by the image border: AprilTag puts the corner where the edge lines meet, outside
// the image. Kept while it is within half the quad's shorter diagonal of the image (TagSLAM's
// real test10 has 51 such corners up to 25 px out, which TagSLAM uses); farther out, dropped.
TEST(DetectionsIoTest, ACornerJustOutsideTheImageIsKept) {
  const std::string text =
      Line(1, R"({"family": "qr", "id": "a", "corners_px": [[600,100],[660,100],[660,160],[600,160]]})") +
      Line(2, R"({"family": "qr", "id": "b", "corners_px": [[600,100],[720,100],[720,160],[600,160]]})");
  ReadWarnings warnings;
  const std::map<std::string, CameraInfo> cameras = OneCamera();
  ASSERT_EQ(cameras.at("cam0").width, 640);
  const std::vector<DetectionFrame> frames = ParseDetections(text, "detections.jsonl", &warnings, &cameras);
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_EQ(frames[0].markers.size(), 1u);  // 20 px out, diagonal 85 px
  EXPECT_TRUE(frames[1].markers.empty());   // 80 px out, diagonal 134 px
  EXPECT_EQ(warnings.counts["corner outside image"], 1);
}

// Issue 18, finding 2: a line of 10^6 markers was accepted (minutes of work per frame), and
// the same code twice in one frame silently.
TEST(DetectionsIoTest, MarkersPerFrameAreLimitedAndDuplicatesDropped) {
  std::string many;
  for (size_t i = 0; i <= kMaxMarkersPerFrame; ++i) {
    many += std::string(i ? "," : "") + R"({"family": "qr", "id": ")" + std::to_string(i) +
            R"(", "corners_px": [[10, 20], [30, 20], [30, 40], [10, 40]]})";
  }
  EXPECT_THAT(ParseError(Line(1, kMarker) + Line(2, many)),
              HasSubstr("detections.jsonl:2: markers: expected at most 1000 markers in one frame, got 1001"));
  const std::string other =
      R"({"family": "qr", "id": "other", "corners_px": [[100, 20], [130, 20], [130, 40], [100, 40]]})";
  ReadWarnings warnings;
  const std::vector<DetectionFrame> frames = ParseDetections(
      Line(1, std::string(kMarker) + "," + other + "," + kMarker), "detections.jsonl", &warnings);
  ASSERT_EQ(frames.size(), 1u);
  ASSERT_EQ(frames[0].markers.size(), 1u);
  EXPECT_EQ(frames[0].markers[0].key.id, "other");
  EXPECT_EQ(warnings.counts["duplicate marker in frame"], 1);
  ASSERT_EQ(warnings.first_messages.size(), 1u);
  EXPECT_EQ(warnings.first_messages[0],
            "detections.jsonl:1: markers: qr:0/2/10 seen 2 times in one frame, all ignored");
  // Unidentified squares (id "*") are not codes: two in view are both kept.
  const std::string square =
      R"({"family": "square", "id": "*", "corners_px": [[100, 20], [130, 20], [130, 40], [100, 40]]})";
  ReadWarnings square_warnings;
  const std::vector<DetectionFrame> squares =
      ParseDetections(Line(1, square + "," + square), "detections.jsonl", &square_warnings);
  ASSERT_EQ(squares.size(), 1u);
  EXPECT_EQ(squares[0].markers.size(), 2u);
  EXPECT_EQ(square_warnings.Total(), 0);
  DetectionFrame big;
  big.camera = "cam0";
  big.markers.resize(kMaxMarkersPerFrame + 1, frames[0].markers[0]);
  EXPECT_THROW(FormatDetectionLine(big), std::invalid_argument);
}

TEST(DetectionsIoTest, MissingFileIsNamed) {
  ReadWarnings warnings;
  try {
    ReadDetections("/nonexistent/detections.jsonl", &warnings);
    FAIL() << "expected FormatError";
  } catch (const FormatError& e) {
    EXPECT_THAT(e.what(), HasSubstr("/nonexistent/detections.jsonl: cannot open"));
  }
}

TEST(DetectionsIoTest, RoundTripIsExact) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> px(0.0, 640.0);
  std::vector<DetectionFrame> frames;
  for (int i = 0; i < 100; ++i) {
    DetectionFrame frame;
    frame.stamp_s = 1609357294.418401 + i * 0.1 / 3.0;
    frame.camera = i % 2 ? "cam0" : "cam1";
    if (i % 3 == 0) frame.image = "images/ünï \"" + std::to_string(i) + "\".png";
    if (i % 4 == 0) frame.frame = i;
    for (int k = 0; k < i % 4; ++k) {
      MarkerObservation marker;
      marker.key = {k % 2 ? "datamatrix" : "apriltag-16h5", "payload/" + std::to_string(k) + "\\\n"};
      for (Eigen::Vector2d& corner_px : marker.corners_px) corner_px = {px(rng), px(rng)};
      if (k == 1) marker.quality = px(rng) / 640.0;
      frame.markers.push_back(marker);
    }
    frames.push_back(frame);
  }
  const fs::path path = fs::temp_directory_path() /
                        ("waymark_detections_io_test_" + std::to_string(::getpid())) / "detections.jsonl";
  WriteDetections(path, frames);
  ReadWarnings warnings;
  const std::vector<DetectionFrame> read = ReadDetections(path, &warnings);
  EXPECT_EQ(warnings.Total(), 0);
  ASSERT_EQ(read.size(), frames.size());
  for (size_t i = 0; i < read.size(); ++i) {
    EXPECT_EQ(read[i].stamp_s, frames[i].stamp_s);
    EXPECT_EQ(read[i].camera, frames[i].camera);
    EXPECT_EQ(read[i].image, frames[i].image);
    EXPECT_EQ(read[i].frame, frames[i].frame);
    ASSERT_EQ(read[i].markers.size(), frames[i].markers.size());
    for (size_t k = 0; k < read[i].markers.size(); ++k) {
      EXPECT_EQ(read[i].markers[k].key, frames[i].markers[k].key);
      EXPECT_EQ(read[i].markers[k].quality, frames[i].markers[k].quality);
      EXPECT_EQ(read[i].markers[k].corners_px, frames[i].markers[k].corners_px);
    }
  }
  EXPECT_EQ(FormatDetections(read), FormatDetections(frames));
  fs::remove_all(path.parent_path());

  frames.push_back(frames.back());  // same camera, same stamp: allowed (photos without a time)
  EXPECT_NO_THROW(FormatDetections(frames));
  frames.back().stamp_s -= 1.0;  // decreasing: rejected
  EXPECT_THROW(FormatDetections(frames), std::invalid_argument);
  frames.pop_back();
  frames.back().markers.push_back(MarkerObservation{{"aztec", "1"}, {}, std::nullopt});
  EXPECT_THROW(FormatDetections(frames), std::invalid_argument);
}

TEST(DetectionsIoTest, ReadsTagslamDetections) {
  const fs::path root = fs::path(WAYMARK_SHARED_DATA) / "tagslam";
  if (!fs::exists(root))
    GTEST_SKIP() << "shared data absent: " << root << " (tagslam detections not checked)";
  ReadWarnings warnings;
  const std::vector<DetectionFrame> frames =
      ReadDetections(root / "tagslam-test16" / "detections.jsonl", &warnings);
  EXPECT_EQ(frames.size(), 297u);
  EXPECT_EQ(warnings.Total(), 0);
}

}  // namespace
}  // namespace waymark
