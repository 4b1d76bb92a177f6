// End-to-end tests of `waymark sim` through the built binary (WAYMARK_BINARY).
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "io/dataset_io.h"

namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

struct Outcome {
  int exit_code = -1;
  std::string out, err;
};

std::string Slurp(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

class SimCliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("waymark_sim_cli_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // Runs `waymark <args>` in dir_, capturing stdout and stderr.
  Outcome Waymark(const std::string& args) {
    const std::string command =
        "cd '" + dir_.string() + "' && '" + WAYMARK_BINARY + "' " + args + " > stdout.txt 2> stderr.txt";
    const int status = std::system(command.c_str());
    Outcome outcome;
    outcome.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    outcome.out = Slurp(dir_ / "stdout.txt");
    outcome.err = Slurp(dir_ / "stderr.txt");
    fs::remove(dir_ / "stdout.txt");
    fs::remove(dir_ / "stderr.txt");
    return outcome;
  }

  void WriteFile(const std::string& name, const std::string& text) { std::ofstream(dir_ / name) << text; }

  // Expects a one-line error, a non-zero exit and no `out` directory (nor a temporary one).
  void ExpectCleanFailure(const Outcome& o, const std::string& message) {
    EXPECT_NE(o.exit_code, 0);
    EXPECT_THAT(o.err, HasSubstr(message));
    EXPECT_EQ(std::count(o.err.begin(), o.err.end(), '\n'), 1) << o.err;
    EXPECT_FALSE(fs::exists(dir_ / "out"));
    for (const auto& entry : fs::directory_iterator(dir_)) {
      const std::string name = entry.path().filename().string();
      if (name.rfind("out", 0) == 0 || name.rfind(".out", 0) == 0) ADD_FAILURE() << "left behind: " << name;
    }
  }

  fs::path dir_;
};

TEST_F(SimCliTest, WritesALoadableDatasetAndASummaryLine) {
  const Outcome o = Waymark("sim warehouse-drone --out out --seed 5 --misdecode 0.01");
  ASSERT_EQ(o.exit_code, 0) << o.err;
  EXPECT_THAT(o.err, HasSubstr("warehouse-drone: "));
  EXPECT_THAT(o.err, HasSubstr(" frames (2 cameras), "));
  EXPECT_THAT(o.err, HasSubstr(" m path"));
  EXPECT_EQ(std::count(o.err.begin(), o.err.end(), '\n'), 1);
  const waymark::Dataset dataset = waymark::LoadDataset(dir_ / "out");
  EXPECT_EQ(dataset.config.motion, waymark::MotionModel::kFree);
  EXPECT_EQ(dataset.cameras.size(), 2u);
  ASSERT_TRUE(dataset.groundtruth_trajectory && dataset.groundtruth_markers);
  EXPECT_EQ(dataset.groundtruth_markers->markers.size(), 96u);
  EXPECT_EQ(dataset.odometry.size(), dataset.groundtruth_trajectory->size());
  EXPECT_EQ(dataset.detections.size(), 2 * ((dataset.odometry.size() + 1) / 2));
  EXPECT_TRUE(dataset.config.payload.has_value());
  // Misdecoded ids are read, except where a misdecode gave the id of another code in the same
  // frame: that sighting is ambiguous and both copies are dropped (issue 18).
  const auto duplicates = dataset.warnings.counts.find("duplicate marker in frame");
  EXPECT_EQ(dataset.warnings.Total(), duplicates == dataset.warnings.counts.end() ? 0 : duplicates->second);
  EXPECT_LE(dataset.warnings.Total(), 5);
  EXPECT_TRUE(fs::exists(dir_ / "out" / "sim_config.yaml"));
}

TEST_F(SimCliTest, SameSeedSameFilesOtherSeedSamePlace) {
  ASSERT_EQ(Waymark("sim corridor --out a --seed 11").exit_code, 0);
  ASSERT_EQ(Waymark("sim corridor --out b --seed 11").exit_code, 0);
  ASSERT_EQ(Waymark("sim corridor --out c --seed 12").exit_code, 0);
  for (const char* file : {"dataset.yaml", "cameras/left.yaml", "odometry.tum", "detections.jsonl",
                           "markers.json", "groundtruth/trajectory.tum", "groundtruth/markers.json"}) {
    EXPECT_EQ(Slurp(dir_ / "a" / file), Slurp(dir_ / "b" / file)) << file;
  }
  EXPECT_EQ(Slurp(dir_ / "a" / "groundtruth/markers.json"), Slurp(dir_ / "c" / "groundtruth/markers.json"));
  EXPECT_EQ(Slurp(dir_ / "a" / "groundtruth/trajectory.tum"),
            Slurp(dir_ / "c" / "groundtruth/trajectory.tum"));
  EXPECT_NE(Slurp(dir_ / "a" / "detections.jsonl"), Slurp(dir_ / "c" / "detections.jsonl"));
  EXPECT_NE(Slurp(dir_ / "a" / "odometry.tum"), Slurp(dir_ / "c" / "odometry.tum"));
}

TEST_F(SimCliTest, PrintedConfigReproducesTheRun) {
  const Outcome printed = Waymark("sim rooms --print-config --set place.rooms=2 --pixel-sigma 0.8");
  ASSERT_EQ(printed.exit_code, 0) << printed.err;
  EXPECT_THAT(printed.out, HasSubstr("  rooms: 2"));
  EXPECT_THAT(printed.out, HasSubstr("  pixel_sigma_px: 0.8"));
  WriteFile("cfg.yaml", printed.out);
  ASSERT_EQ(Waymark("sim rooms --out a --seed 3 --set place.rooms=2 --pixel-sigma 0.8").exit_code, 0);
  ASSERT_EQ(Waymark("sim rooms --out b --seed 3 --config cfg.yaml").exit_code, 0);
  EXPECT_EQ(Slurp(dir_ / "a" / "detections.jsonl"), Slurp(dir_ / "b" / "detections.jsonl"));
  // The copy written next to the data reproduces it too.
  ASSERT_EQ(Waymark("sim rooms --out c --seed 3 --config a/sim_config.yaml").exit_code, 0);
  EXPECT_EQ(Slurp(dir_ / "a" / "detections.jsonl"), Slurp(dir_ / "c" / "detections.jsonl"));
}

TEST_F(SimCliTest, BadConfigFailsCleanly) {
  WriteFile("bad.yaml", "place:\n  spacing_m: 2\n  spacing: 4\n");
  ExpectCleanFailure(Waymark("sim corridor --out out --config bad.yaml"),
                     "bad.yaml:3: unknown key 'place.spacing'");
  fs::remove(dir_ / "bad.yaml");
  WriteFile("bad.yaml", "detect:\n  pixel_sigma_px: [1]\n");
  ExpectCleanFailure(Waymark("sim corridor --out out --config bad.yaml"),
                     "bad.yaml:2: detect.pixel_sigma_px: expected a number");
  fs::remove(dir_ / "bad.yaml");
  ExpectCleanFailure(Waymark("sim corridor --out out --config missing.yaml"), "missing.yaml");
  ExpectCleanFailure(Waymark("sim corridor --out out --set rate.camera_hz=7"), "rate.camera_hz must divide");
  ExpectCleanFailure(Waymark("sim corridor --out out --spacing wide"), "place.spacing_m: expected a number");
  ExpectCleanFailure(Waymark("sim ceiling-grid --out out --set place.anchors=1"),
                     "unknown key 'place.anchors'");
}

TEST_F(SimCliTest, RenderWritesImagesAndGroundTruthCorners) {
  const Outcome o = Waymark("sim corridor --render --render-every 500 --out out");
  ASSERT_EQ(o.exit_code, 0) << o.err;
  EXPECT_THAT(o.err, HasSubstr("ms per image"));
  const std::string images = Slurp(dir_ / "out" / "images.csv");
  EXPECT_THAT(images,
              HasSubstr("t,camera,path\n0,left,images/left/000000.png\n0,right,images/right/000000.png\n"));
  EXPECT_TRUE(fs::exists(dir_ / "out" / "images" / "left" / "000000.png"));
  const long lines = std::count(images.begin(), images.end(), '\n') - 1;
  const std::string corners = Slurp(dir_ / "out" / "groundtruth" / "corners.jsonl");
  EXPECT_EQ(std::count(corners.begin(), corners.end(), '\n'), lines);
}

TEST_F(SimCliTest, RenderOptionsAreChecked) {
  ExpectCleanFailure(Waymark("sim corridor --render-every 2 --out out"), "--render-every needs --render");
  ExpectCleanFailure(Waymark("sim corridor --render --render-every 0 --out out"), "--render-every");
  ExpectCleanFailure(Waymark("sim corridor --render --set render.supersample=0 --out out"),
                     "render.supersample");
}

TEST_F(SimCliTest, UnknownScenarioFailsCleanly) {
  ExpectCleanFailure(
      Waymark("sim hallway --out out"),
      "unknown scenario 'hallway' (known: corridor, ceiling-grid, rooms, warehouse-drone, square-ceiling)");
  ExpectCleanFailure(Waymark("sim --out out"), "missing scenario");
}

// Issue 18, finding 7: a `waymark sim` killed mid-write left its ".out.sim-tmp-PID" staging
// directory behind; the next sim into the same parent removes those of dead processes only.
TEST_F(SimCliTest, StagingOfAKilledRunIsRemovedByTheNext) {
  const pid_t child = fork();
  if (child == 0) _exit(0);
  ASSERT_GT(child, 0);
  waitpid(child, nullptr, 0);
  const fs::path stale = dir_ / (".out.sim-tmp-" + std::to_string(child));
  const fs::path live = dir_ / (".out.sim-tmp-" + std::to_string(getpid()));
  fs::create_directories(stale / "images");
  fs::create_directories(live);
  WriteFile(".out.sim-tmp-" + std::to_string(child) + "/images/0.png", "half");
  fs::create_directories(dir_ / "notes.sim-tmp-1");  // not our naming
  ASSERT_EQ(Waymark("sim corridor --out out").exit_code, 0);
  EXPECT_FALSE(fs::exists(stale));
  EXPECT_TRUE(fs::exists(live));
  EXPECT_TRUE(fs::exists(dir_ / "notes.sim-tmp-1"));
}

TEST_F(SimCliTest, RefusesANonEmptyOutputUnlessForced) {
  fs::create_directories(dir_ / "out");
  WriteFile("out/keep.txt", "mine");
  const Outcome refused = Waymark("sim corridor --out out");
  EXPECT_NE(refused.exit_code, 0);
  EXPECT_THAT(refused.err, HasSubstr("not empty (use --force"));
  EXPECT_EQ(Slurp(dir_ / "out" / "keep.txt"), "mine");
  const Outcome forced = Waymark("sim corridor --out out --force");
  ASSERT_EQ(forced.exit_code, 0) << forced.err;
  EXPECT_FALSE(fs::exists(dir_ / "out" / "keep.txt"));
  EXPECT_TRUE(fs::exists(dir_ / "out" / "dataset.yaml"));
  fs::remove_all(dir_ / "empty");
  fs::create_directories(dir_ / "empty");
  EXPECT_EQ(Waymark("sim corridor --out empty").exit_code, 0);  // an empty directory is fine
  EXPECT_EQ(Waymark("sim corridor --out slash/ --seed 2").exit_code, 0);
  EXPECT_TRUE(fs::exists(dir_ / "slash" / "dataset.yaml"));
}

TEST_F(SimCliTest, HelpListsScenariosAndEveryKey) {
  const Outcome o = Waymark("sim --help");
  ASSERT_EQ(o.exit_code, 0);
  for (const char* text : {"corridor:", "ceiling-grid:", "rooms:", "warehouse-drone:", "place.spacing_m (1)",
                           "place.spacing_m (1.4)", "detect.misdecode_fraction (0)",
                           "odometry.yaw_drift_deg_per_m (0.2)", "--print-config", "--force"}) {
    EXPECT_THAT(o.out, HasSubstr(text));
  }
  const Outcome list = Waymark("sim list");
  EXPECT_EQ(list.exit_code, 0);
  EXPECT_THAT(list.out, HasSubstr("warehouse-drone\t"));
}

}  // namespace
