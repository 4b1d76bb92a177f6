#include "io/dataset_io.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <functional>
#include <limits>
#include <random>
#include <string>

#include "io/camera_io.h"
#include "io/detections_io.h"
#include "io/map_io.h"
#include "io/tum_io.h"
#include "io/util.h"

namespace waymark {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

const char* const kGoodYaml = R"(format: waymark-dataset
version: 1
name: corridor-1m
motion: planar
cameras: [cam0, cam1]
default_marker_size_m: 0.10
odometry_sigma: {trans_per_m: 0.02, rot_per_rad: 0.03}
payload: {pattern: "^(\\d+)/(-?[0-9.]+)/(-?[0-9.]+)$", fields: [kind, x, y]}
)";

std::string GoodYamlWith(const std::string& from, const std::string& to) {
  std::string text = kGoodYaml;
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return text.replace(at, from.size(), to);
}

std::string ParseError(const std::string& text) {
  try {
    ParseDatasetYaml(text, "dataset.yaml");
  } catch (const FormatError& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected a FormatError for:\n" << text;
  return "";
}

// A fresh temporary directory, removed by the destructor.
struct TempDir {
  explicit TempDir(const std::string& tag)
      : path(fs::temp_directory_path() /
             ("waymark_dataset_io_test_" + tag + "_" + std::to_string(::getpid()))) {
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TempDir() { fs::remove_all(path); }
  fs::path path;
};

CameraInfo MakeCamera(const std::string& name, CameraModel model) {
  CameraInfo camera;
  camera.name = name;
  camera.model = model;
  camera.width = 640;
  camera.height = 480;
  camera.intrinsics = {500.0 + 1.0 / 3.0, 501.0, 320.5, 240.25};
  camera.distortion.assign(CameraInfo::DistortionSize(model), 1e-3 / 7.0);
  camera.T_robot_camera =
      SE3d(Eigen::Quaterniond(0.5, -0.5, 0.5, -0.5), Eigen::Vector3d(0.1, 0.2 / 3.0, 0.3));
  camera.pixel_sigma = 0.5;
  return camera;
}

// A small dataset with every optional part present.
Dataset MakeDataset() {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  Dataset dataset;
  dataset.config.name = "round trip";
  dataset.config.motion = MotionModel::kFree;
  dataset.config.cameras = {"cam0", "cam1"};
  dataset.config.default_marker_size_m = 0.1;
  dataset.config.odometry_sigma = OdometrySigma{0.02, 0.01};
  dataset.config.payload = PayloadSpec{"^(\\d+)/(-?[0-9.]+)/(-?[0-9.]+)$", {"kind", "x", "y"}, 0.0};
  dataset.config.odometry_file = "odom/wheel.tum";
  dataset.cameras["cam0"] = MakeCamera("cam0", CameraModel::kPinholeRadtan);
  dataset.cameras["cam1"] = MakeCamera("cam1", CameraModel::kPinholeEquidistant);
  Trajectory trajectory;
  for (int i = 0; i < 20; ++i) {
    trajectory.push_back({100.0 + i * 0.1, SE3d::FromXYZYaw(0.1 * i, uniform(rng), 0.0, uniform(rng))});
    for (const char* camera : {"cam0", "cam1"}) {
      DetectionFrame frame;
      frame.stamp_s = 100.0 + i * 0.1;
      frame.camera = camera;
      frame.image = "images/" + std::string(camera) + "_" + std::to_string(i) + ".png";
      if (i % 2 == 0) {
        MarkerObservation marker{{"qr", "0/" + std::to_string(i) + "/1"}, {}, 0.9};
        for (Eigen::Vector2d& corner_px : marker.corners_px)
          corner_px = {uniform(rng) * 640, uniform(rng) * 480};
        frame.markers.push_back(marker);
      }
      dataset.detections.push_back(frame);
      dataset.images.push_back({frame.stamp_s, camera, *frame.image});
    }
  }
  dataset.odometry = trajectory;
  dataset.groundtruth_trajectory = trajectory;
  dataset.reference_trajectory = trajectory;
  MarkerMap map;
  map.markers.push_back({{"qr", "0/0/1"}, 0.12, SE3d::FromXYZYaw(1, 2, 0.5, 0.3), std::nullopt, true, 0});
  dataset.known_markers = map;
  dataset.groundtruth_markers = map;
  dataset.reference_markers = map;
  return dataset;
}

TEST(DatasetIoTest, ParsesDatasetYaml) {
  ReadWarnings warnings;
  std::set<std::string> named;
  const DatasetConfig config = ParseDatasetYaml(std::string(kGoodYaml) + "odometry: wheel.tum\ncolour: red\n",
                                                "dataset.yaml", &warnings, &named);
  EXPECT_EQ(config.name, "corridor-1m");
  EXPECT_EQ(config.motion, MotionModel::kPlanar);
  EXPECT_EQ(config.cameras, (std::vector<std::string>{"cam0", "cam1"}));
  EXPECT_EQ(config.default_marker_size_m, 0.10);
  ASSERT_TRUE(config.odometry_sigma.has_value());
  EXPECT_EQ(config.odometry_sigma->rot_per_rad, 0.03);
  ASSERT_TRUE(config.payload.has_value());
  EXPECT_EQ(config.payload->pattern, "^(\\d+)/(-?[0-9.]+)/(-?[0-9.]+)$");
  EXPECT_EQ(config.payload->fields.size(), 3u);
  EXPECT_EQ(config.odometry_file, "wheel.tum");
  EXPECT_EQ(config.detections_file, "detections.jsonl");
  EXPECT_EQ(named, (std::set<std::string>{"odometry"}));
  EXPECT_EQ(warnings.counts["unknown key"], 1);
  EXPECT_THAT(warnings.first_messages.at(0), HasSubstr("dataset.yaml:10: unknown key 'colour' ignored"));
}

// odometry_sigma's random-walk terms are optional (0 when absent) and written back only when set.
TEST(DatasetIoTest, OdometrySigmaRandomWalkTermsParseAndRoundTrip) {
  const DatasetConfig plain = ParseDatasetYaml(kGoodYaml, "dataset.yaml");
  ASSERT_TRUE(plain.odometry_sigma.has_value());
  EXPECT_FALSE(plain.odometry_sigma->HasRandomWalk());
  const DatasetConfig vio =
      ParseDatasetYaml(GoodYamlWith("rot_per_rad: 0.03}",
                                    "rot_per_rad: 0.03, trans_per_sqrt_s: 0.05, rot_per_sqrt_s: 0.004,\n"
                                    "  trans_per_sqrt_m: 0.01, rot_per_sqrt_m: 0.02}"),
                       "dataset.yaml");
  ASSERT_TRUE(vio.odometry_sigma.has_value());
  EXPECT_EQ(vio.odometry_sigma->trans_per_m, 0.02);
  EXPECT_EQ(vio.odometry_sigma->trans_per_sqrt_s, 0.05);
  EXPECT_EQ(vio.odometry_sigma->rot_per_sqrt_s, 0.004);
  EXPECT_EQ(vio.odometry_sigma->trans_per_sqrt_m, 0.01);
  EXPECT_EQ(vio.odometry_sigma->rot_per_sqrt_m, 0.02);
  const std::string written = FormatDatasetYaml(vio);
  EXPECT_NE(written.find("trans_per_sqrt_s: 0.05"), std::string::npos) << written;
  const DatasetConfig again = ParseDatasetYaml(written, "dataset.yaml");
  EXPECT_EQ(again.odometry_sigma->rot_per_sqrt_m, 0.02);
  EXPECT_EQ(again.odometry_sigma->rot_per_sqrt_s, 0.004);
  EXPECT_EQ(FormatDatasetYaml(plain).find("sqrt"), std::string::npos);
  DatasetConfig bad = vio;
  bad.odometry_sigma->rot_per_sqrt_s = -1.0;
  EXPECT_THROW(FormatDatasetYaml(bad), std::invalid_argument);
  bad.odometry_sigma->rot_per_sqrt_s = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(FormatDatasetYaml(bad), std::invalid_argument);
}

TEST(DatasetIoTest, DatasetYamlErrorsNameFileAndLine) {
  EXPECT_THAT(ParseError(GoodYamlWith("motion: planar", "motion: flying")),
              HasSubstr("dataset.yaml:4: motion: expected planar or free, got 'flying'"));
  EXPECT_THAT(ParseError(GoodYamlWith("version: 1", "version: 2")),
              HasSubstr("dataset.yaml:2: version: expected 1, got 2"));
  EXPECT_THAT(ParseError(GoodYamlWith("waymark-dataset", "waymark-map")),
              HasSubstr("dataset.yaml:1: format: expected waymark-dataset"));
  EXPECT_THAT(ParseError(GoodYamlWith("[cam0, cam1]", "cam0")),
              HasSubstr("dataset.yaml:5: cameras: expected a list of strings"));
  EXPECT_THAT(ParseError(GoodYamlWith("[cam0, cam1]", "[cam0, cam0]")),
              HasSubstr("dataset.yaml:5: cameras: 'cam0' is listed twice"));
  EXPECT_THAT(ParseError(GoodYamlWith("[cam0, cam1]", "[../cam0]")),
              HasSubstr("dataset.yaml:5: cameras: '../cam0' is not a valid"));
  EXPECT_THAT(ParseError(GoodYamlWith("0.10", ".inf")),
              HasSubstr("dataset.yaml:6: default_marker_size_m: expected a finite number"));
  EXPECT_THAT(ParseError(GoodYamlWith("rot_per_rad: 0.03", "rot_per_rad: x")),
              HasSubstr("dataset.yaml:7: odometry_sigma.rot_per_rad: expected a finite number, got 'x'"));
  EXPECT_THAT(ParseError(GoodYamlWith(", rot_per_rad: 0.03", "")),
              HasSubstr("dataset.yaml:7: missing key 'rot_per_rad'"));
  EXPECT_THAT(
      ParseError(GoodYamlWith("rot_per_rad: 0.03", "rot_per_rad: 0.03, rot_per_sqrt_s: fast")),
      HasSubstr("dataset.yaml:7: odometry_sigma.rot_per_sqrt_s: expected a finite number, got 'fast'"));
  EXPECT_THAT(
      ParseError(GoodYamlWith("rot_per_rad: 0.03", "rot_per_rad: 0.03, trans_per_sqrt_m: -0.1")),
      HasSubstr("dataset.yaml:7: odometry_sigma.trans_per_sqrt_m: expected a non-negative noise figure"));
  EXPECT_THAT(ParseError(GoodYamlWith("rot_per_rad: 0.03", "rot_per_rad: -0.03")),
              HasSubstr("dataset.yaml:7: odometry_sigma.rot_per_rad: expected a non-negative noise figure"));
  EXPECT_THAT(
      ParseError(GoodYamlWith("rot_per_rad: 0.03", "rot_per_rad: 0.03, drift: 1")),
      HasSubstr("dataset.yaml:7: odometry_sigma: unknown key 'drift' (expected trans_per_m, rot_per_rad, "
                "trans_per_sqrt_s"));
  EXPECT_THAT(ParseError(GoodYamlWith("{trans_per_m: 0.02, rot_per_rad: 0.03}", "[0.02, 0.03]")),
              HasSubstr("dataset.yaml:7: odometry_sigma: expected a map"));
  EXPECT_THAT(ParseError(GoodYamlWith("fields: [kind, x, y]", "fields: [kind, x]")),
              HasSubstr("dataset.yaml:8: payload: fields: expected 3 names (one per capture group"));
  EXPECT_THAT(ParseError(GoodYamlWith("(\\\\d+)/", "(\\\\d+/")),
              HasSubstr("dataset.yaml:8: payload: pattern: invalid regular expression"));
  EXPECT_THAT(ParseError(GoodYamlWith("fields: [kind, x, y]", "fields: [kind, x, x]")),
              HasSubstr("payload: fields: `x` appears twice"));
  // The payload parser's own rules: a coordinate needs its partner.
  EXPECT_THAT(ParseError(GoodYamlWith("fields: [kind, x, y]", "fields: [kind, x, other]")),
              HasSubstr("dataset.yaml:8: payload: fields: `x` needs both `x` and `y`"));
  EXPECT_THAT(ParseError(GoodYamlWith("fields: [kind, x, y]", "fields: [kind, x, y], default_z_m: low")),
              HasSubstr("dataset.yaml:8: payload.default_z_m: expected a finite number, got 'low'"));
  EXPECT_THAT(ParseError(GoodYamlWith("fields: [kind, x, y]", "fields: [kind, x, y], z: 0")),
              HasSubstr("payload: unknown key 'z' (expected pattern, fields, default_z_m)"));
  EXPECT_THAT(ParseError(GoodYamlWith("motion: planar\n", "")),
              HasSubstr("dataset.yaml:1: missing key 'motion'"));
  EXPECT_THAT(ParseError("format: [\n"), HasSubstr("dataset.yaml:2: invalid YAML"));
  // Issue 18, finding 8: physically meaningless sizes and heights.
  EXPECT_THAT(ParseError(GoodYamlWith("0.10", "9223372036854775808")),
              HasSubstr("dataset.yaml:6: default_marker_size_m: expected a size between 1e-04 and 100 m"));
  EXPECT_THAT(ParseError(GoodYamlWith("fields: [kind, x, y]", "fields: [kind, x, y], default_z_m: 1e300")),
              HasSubstr("dataset.yaml:8: payload.default_z_m: expected a coordinate within +-1e+07 m"));
}

TEST(DatasetIoTest, ImagesCsv) {
  const std::vector<std::string> cameras = {"cam0"};
  const std::vector<ImageEntry> images =
      ParseImagesCsv("t,camera,path\n1.5,cam0,a,b.png\n\n2,cam0,c.png\r\n", "images.csv", &cameras);
  ASSERT_EQ(images.size(), 2u);
  EXPECT_EQ(images[0].path, "a,b.png");
  EXPECT_EQ(images[1].stamp_s, 2.0);
  EXPECT_EQ(images[1].path, "c.png");
  EXPECT_EQ(ParseImagesCsv("3,cam0,x.png\n", "images.csv", &cameras).size(), 1u);  // no header
  const auto error = [&](const std::string& text) -> std::string {
    try {
      ParseImagesCsv(text, "images.csv", &cameras);
    } catch (const FormatError& e) {
      return e.what();
    }
    return "no error";
  };
  EXPECT_THAT(error("t,camera,path\n1,cam0\n"), HasSubstr("images.csv:2: expected 3 fields 't,camera,path'"));
  EXPECT_THAT(error("nan,cam0,a.png\n"), HasSubstr("images.csv:1: t: expected a finite number, got 'nan'"));
  EXPECT_THAT(error("1,cam0,a.png\n2,cam9,b.png\n"),
              HasSubstr("images.csv:2: camera: 'cam9' is not in dataset.yaml cameras"));
  EXPECT_THAT(error("1,cam0,\n"), HasSubstr("images.csv:1: path: expected an image path"));
  EXPECT_THAT(error("1,,a.png\n"), HasSubstr("images.csv:1: camera: expected a camera name"));
  EXPECT_THAT(error("t,camera,path\n1;cam0;a.png\n"), HasSubstr("images.csv:2: expected 3 fields"));
  EXPECT_THAT(error("2,cam0,a.png\nt,camera,path\n"),
              HasSubstr("images.csv:2: t: expected a finite number, got 't'"));
}

TEST(DatasetIoTest, WriteThenLoadIsExact) {
  const TempDir dir("roundtrip");
  const Dataset dataset = MakeDataset();
  WriteDataset(dir.path, dataset);
  fs::create_directories(dir.path / "images");
  for (size_t i = 0; i < 10; ++i) AtomicWriteFile(dir.path / dataset.images[i].path, "");
  const Dataset read = LoadDataset(dir.path);
  EXPECT_EQ(read.dir, dir.path);
  EXPECT_EQ(FormatDatasetYaml(read.config), FormatDatasetYaml(dataset.config));
  EXPECT_EQ(read.config.odometry_file, "odom/wheel.tum");
  ASSERT_TRUE(read.config.payload && read.config.payload->default_z_m);
  EXPECT_EQ(*read.config.payload->default_z_m, 0.0);
  ASSERT_EQ(read.cameras.size(), 2u);
  EXPECT_EQ(read.cameras.at("cam1").model, CameraModel::kPinholeEquidistant);
  EXPECT_EQ(read.cameras.at("cam0").intrinsics, dataset.cameras.at("cam0").intrinsics);
  EXPECT_EQ(read.cameras.at("cam1").T_robot_camera.rotation().coeffs(),
            dataset.cameras.at("cam1").T_robot_camera.rotation().coeffs());
  EXPECT_TRUE(read.has_odometry_file && read.has_detections_file && read.has_images_file);
  ASSERT_EQ(read.odometry.size(), dataset.odometry.size());
  EXPECT_EQ(read.odometry.back().T.translation(), dataset.odometry.back().T.translation());
  ASSERT_EQ(read.detections.size(), dataset.detections.size());
  EXPECT_EQ(read.detections[4].markers.at(0).corners_px, dataset.detections[4].markers.at(0).corners_px);
  EXPECT_EQ(read.detections[4].image, dataset.detections[4].image);
  ASSERT_EQ(read.images.size(), dataset.images.size());
  EXPECT_EQ(read.images.back().path, dataset.images.back().path);
  ASSERT_TRUE(read.known_markers && read.groundtruth_markers && read.reference_markers);
  EXPECT_EQ(FormatMap(*read.reference_markers), FormatMap(*dataset.reference_markers));
  ASSERT_TRUE(read.groundtruth_trajectory && read.reference_trajectory);
  EXPECT_EQ(read.reference_trajectory->at(7).T.rotation().coeffs(),
            dataset.odometry.at(7).T.rotation().coeffs());
  // Only the 30 image files not created are warned about.
  EXPECT_EQ(read.warnings.Total(), 30);
  EXPECT_EQ(read.warnings.counts.at("missing image"), 30);
  EXPECT_EQ(read.MarkerSize({"qr", "0/0/1"}), 0.12);
  EXPECT_EQ(read.MarkerSize({"qr", "0/2/1"}), 0.1);

  const DatasetSummary summary = SummarizeDataset(read);
  EXPECT_EQ(summary.frames, 40);
  EXPECT_EQ(summary.detections, 20);
  EXPECT_EQ(summary.detections_per_family.at("qr"), 20);
  EXPECT_EQ(summary.distinct_markers, 10);
  EXPECT_EQ(summary.known_markers, 1);
  EXPECT_EQ(summary.odometry_poses, 20);
  EXPECT_NEAR(summary.odometry_span_s, 1.9, 1e-9);
  EXPECT_GE(summary.odometry_path_length_m, 1.9);  // x advances 0.1 m per pose
}

TEST(DatasetIoTest, WriterRejectsInconsistentDatasetsAndWritesNothing) {
  const TempDir dir("inconsistent");
  Dataset dataset = MakeDataset();
  dataset.config.cameras = {"cam0"};  // cam1 still has a CameraInfo and detections
  EXPECT_THROW(WriteDataset(dir.path / "out", dataset), std::invalid_argument);
  dataset = MakeDataset();
  dataset.odometry.push_back(dataset.odometry.back());  // repeated stamp
  EXPECT_THROW(WriteDataset(dir.path / "out", dataset), std::invalid_argument);
  EXPECT_FALSE(fs::exists(dir.path / "out"));
}

// Writes a valid dataset and returns its directory, for the error tests below.
fs::path WriteValid(const TempDir& dir) {
  Dataset dataset = MakeDataset();
  dataset.images.clear();
  for (DetectionFrame& frame : dataset.detections) frame.image.reset();
  WriteDataset(dir.path, dataset);
  return dir.path;
}

std::string LoadError(const fs::path& dir) {
  try {
    LoadDataset(dir);
  } catch (const FormatError& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected a FormatError loading " << dir;
  return "";
}

TEST(DatasetIoTest, LoadErrorsNameTheFile) {
  const TempDir dir("errors");
  const fs::path root = WriteValid(dir);
  EXPECT_EQ(LoadDataset(root).warnings.Total(), 0);

  EXPECT_THAT(LoadError(root / "nothing"), HasSubstr("nothing: not a directory"));
  fs::remove(root / "cameras" / "cam1.yaml");
  EXPECT_THAT(LoadError(root), HasSubstr("cameras/cam1.yaml: cannot open: no such file"));
  WriteValid(dir);

  // A detection for a camera not in dataset.yaml names its line.
  std::string detections = ReadTextFile(root / "detections.jsonl");
  const size_t third_line = detections.find('\n', detections.find('\n') + 1) + 1;
  detections.replace(detections.find("\"cam0\"", third_line), 6, "\"cam7\"");
  AtomicWriteFile(root / "detections.jsonl", detections);
  EXPECT_THAT(LoadError(root),
              HasSubstr("detections.jsonl:3: camera: camera \"cam7\" is not in the dataset"));
  WriteValid(dir);

  // A file named in dataset.yaml must exist.
  fs::remove(root / "odom" / "wheel.tum");
  EXPECT_THAT(LoadError(root), HasSubstr("dataset.yaml: odometry: file 'odom/wheel.tum' not found"));
  WriteValid(dir);

  AtomicWriteFile(root / "dataset.yaml", ReadTextFile(root / "dataset.yaml") + "images: frames.csv\n");
  EXPECT_THAT(LoadError(root), HasSubstr("dataset.yaml: images: file 'frames.csv' not found"));
  AtomicWriteFile(root / "frames.csv", "t,camera,path\n1,cam0,a.png\n1,cam2,b.png\n");
  EXPECT_THAT(LoadError(root), HasSubstr("frames.csv:3: camera: 'cam2' is not in dataset.yaml cameras"));
  WriteValid(dir);

  AtomicWriteFile(root / "groundtruth" / "trajectory.tum", "1 0 0 0 0 0 1\n");
  EXPECT_THAT(LoadError(root), HasSubstr("groundtruth/trajectory.tum:1: expected 8 numbers"));
  WriteValid(dir);

  AtomicWriteFile(root / "markers.json",
                  "{\"format\": \"waymark-map\", \"version\": 1, \"markers\": [\n{}]}");
  EXPECT_THAT(LoadError(root), HasSubstr("markers.json:2: markers[0]: missing key \"family\""));
}

TEST(DatasetIoTest, OutOfImageCornersAndUnsizedMarkersAreWarnings) {
  const TempDir dir("warnings");
  Dataset dataset = MakeDataset();
  dataset.images.clear();
  dataset.config.default_marker_size_m.reset();
  dataset.detections[0].markers.at(0).corners_px[1] = {5000.0, 10.0};  // cam0 is 640 wide
  WriteDataset(dir.path, dataset);
  const Dataset read = LoadDataset(dir.path);
  EXPECT_EQ(read.warnings.counts.at("corner outside image"), 1);
  EXPECT_TRUE(read.detections[0].markers.empty());
  // 10 distinct markers seen, the one kept in markers.json has a size; 0/0/1 was rejected on cam0 only.
  EXPECT_EQ(read.warnings.counts.at("marker without size"), 9);
}

// Bad input never crashes a reader and never escapes as anything but a FormatError: every
// reader is fed 400 random mutations (fixed seed) of a valid file.
TEST(DatasetIoTest, MutatedInputsOnlyThrowFormatError) {
  const Dataset dataset = MakeDataset();
  std::vector<DetectionFrame> frames(dataset.detections.begin(), dataset.detections.begin() + 4);
  const std::vector<std::pair<std::string, std::function<void(const std::string&)>>> readers = {
      {FormatDatasetYaml(dataset.config),
       [](const std::string& text) { ParseDatasetYaml(text, "dataset.yaml"); }},
      {FormatCameraYaml(dataset.cameras.at("cam0")),
       [](const std::string& text) { ParseCameraYaml(text, "cameras/cam0.yaml", "cam0"); }},
      {FormatTum(Trajectory(dataset.odometry.begin(), dataset.odometry.begin() + 3)),
       [](const std::string& text) { ParseTum(text, "odometry.tum"); }},
      {FormatDetections(frames),
       [&dataset](const std::string& text) {
         ReadWarnings warnings;
         ParseDetections(text, "detections.jsonl", &warnings, &dataset.cameras);
       }},
      {FormatMap(*dataset.known_markers), [](const std::string& text) { ParseMap(text, "markers.json"); }},
      {FormatImagesCsv(std::vector<ImageEntry>(dataset.images.begin(), dataset.images.begin() + 3)),
       [&dataset](const std::string& text) { ParseImagesCsv(text, "images.csv", &dataset.config.cameras); }},
  };
  std::mt19937 rng(2024);
  const std::string alphabet = "{}[]\":,. -+eE0123456789\n\t#'!&*|>?%@`\\nulltrueNaN\x01\xff";
  for (const auto& [good, read] : readers) {
    ASSERT_NO_THROW(read(good)) << good;
    int errors = 0;
    for (int trial = 0; trial < 400; ++trial) {
      std::string text = good;
      const int edits = 1 + static_cast<int>(rng() % 3);
      for (int e = 0; e < edits && !text.empty(); ++e) {
        const size_t at = rng() % text.size();
        const char c = alphabet[rng() % alphabet.size()];
        switch (rng() % 3) {
          case 0:
            text[at] = c;
            break;
          case 1:
            text.erase(at, 1 + rng() % 8);
            break;
          default:
            text.insert(at, 1, c);
            break;
        }
      }
      try {
        read(text);
      } catch (const FormatError&) {
        ++errors;
      } catch (const std::exception& e) {
        ADD_FAILURE() << "not a FormatError: " << e.what() << "\nfor input:\n" << text;
      }
    }
    EXPECT_GT(errors, 100) << good;  // most mutations are caught
  }
}

TEST(DatasetIoTest, LoadsTagslamDatasets) {
  const fs::path root = fs::path(WAYMARK_SHARED_DATA) / "tagslam";
  if (!fs::exists(root)) GTEST_SKIP() << "shared data absent: " << root << " (tagslam datasets not loaded)";
  struct Expected {
    const char* name;
    size_t frames;
    bool odometry;
    CameraModel model;
  };
  for (const Expected& expected : {Expected{"tagslam-test16", 297, false, CameraModel::kPinholeRadtan},
                                   Expected{"tagslam-test17", 458, false, CameraModel::kPinholeRadtan},
                                   Expected{"tagslam-test22", 115, true, CameraModel::kPinholeEquidistant}}) {
    const Dataset dataset = LoadDataset(root / expected.name);
    EXPECT_EQ(dataset.config.name, expected.name);
    EXPECT_EQ(dataset.config.motion, MotionModel::kFree);
    EXPECT_EQ(dataset.cameras.at("cam0").model, expected.model);
    EXPECT_EQ(dataset.detections.size(), expected.frames);
    EXPECT_EQ(dataset.has_odometry_file, expected.odometry);
    ASSERT_TRUE(dataset.known_markers.has_value());
    EXPECT_TRUE(dataset.reference_trajectory.has_value());
    EXPECT_TRUE(dataset.reference_markers.has_value());
    EXPECT_FALSE(dataset.groundtruth_trajectory.has_value());
    EXPECT_EQ(dataset.warnings.Total(), 0)
        << expected.name << ": "
        << (dataset.warnings.first_messages.empty() ? "" : dataset.warnings.first_messages[0]);
  }
}

}  // namespace
}  // namespace waymark
