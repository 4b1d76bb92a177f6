// plan/floor_plan.h and plan/code_placement.h on a short straight corridor.
#include "plan/code_placement.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "io/util.h"
#include "plan/floor_plan.h"
#include "sim/scenarios.h"

namespace waymark::plan {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

// Walls at y = -0.6 and y = 0.6 from x = -1 to 5, the corridor scenario's side cameras.
FloorPlan Corridor() {
  FloorPlan plan;
  plan.walls = {{{-1, -0.6}, {5, -0.6}, 2.5}, {{5, 0.6}, {-1, 0.6}, 2.5}};
  plan.ceiling_height_m = 2.5;
  plan.code_sizes_m = {0.10};
  plan.code_height_m = 0.30;
  plan.cameras = sim::BuildScene("corridor", sim::ScenarioParams("corridor")).world.cameras;
  return plan;
}

// 4 m along y = 0 at 0.3 m/s, 20 Hz.
Trajectory Path() {
  Trajectory path;
  for (int k = 0; k <= 267; ++k) path.push_back({k * 0.05, SE3d::FromXYZYaw(0.3 * k * 0.05, 0.0, 0.0, 0.0)});
  return path;
}

TEST(CodePlacementTest, DenserLayoutsHaveMoreCodesAndSmallerPredictedErrors) {
  const FloorPlan plan = Corridor();
  const LayoutPrediction sparse = PredictLayout(plan, Path(), 0.10, 1.0);
  const LayoutPrediction dense = PredictLayout(plan, Path(), 0.10, 0.5);
  ASSERT_TRUE(sparse.map_rms_m && dense.map_rms_m);
  EXPECT_GT(dense.markers.markers.size(), sparse.markers.markers.size());
  EXPECT_LT(*dense.map_rms_m, *sparse.map_rms_m);
  EXPECT_GT(*sparse.map_rms_m, 0.0);
  EXPECT_EQ(sparse.components, 1);
  EXPECT_EQ(sparse.per_metre.size(), 5u);  // 4.0 m: bins 0-1 ... 4-5
  // Only the faces the path sees carry codes; the first two are anchors with no covariance.
  for (const MapMarker& m : sparse.markers.markers) {
    EXPECT_NEAR(std::abs(m.T_world_marker.translation().y()), 0.6, 1e-12);
    EXPECT_EQ(m.fixed, m.key.id == "P000" || m.key.id == "P001");
  }
}

TEST(CodePlacementTest, PlanChoosesTheSparsestLayoutThatMeetsTheTarget) {
  const FloorPlan plan = Corridor();
  PlacementOptions options;
  options.spacings_m = {2.0, 1.0, 0.5};
  const LayoutPrediction at_one = PredictLayout(plan, Path(), 0.10, 1.0);
  // A target just above the 1 m layout's larger error: 1 m is the sparsest that meets it unless 2 m does.
  options.target_m = 1.0001 * std::max(*at_one.map_rms_m, at_one.online_rms_m);
  const PlacementResult result = PlanCodes(plan, Path(), options);
  ASSERT_GE(result.chosen, 0);
  EXPECT_LE(result.tried[result.chosen].spacing_m, 2.0);
  EXPECT_GE(result.tried[result.chosen].spacing_m, 1.0);
  options.target_m = 1e-6;
  EXPECT_EQ(PlanCodes(plan, Path(), options).chosen, -1);
}

TEST(CodePlacementTest, PathOutsideOrThroughAWallIsAnError) {
  const FloorPlan plan = Corridor();
  Trajectory path = Path();
  path[10].T = SE3d::FromXYZYaw(7.0, 0.0, 0.0, 0.0);
  try {
    CheckPath(plan, path);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_THAT(e.what(),
                HasSubstr("pose 11 of the path (t = 0.500 s) at (7.00, 0.00) is outside the floor plan"));
  }
  path = Path();
  path[10].T = SE3d::FromXYZYaw(0.5, -0.8, 0.0, 0.0);  // outside the bounding box? no: y -0.8 < -0.6
  EXPECT_THROW(CheckPath(plan, path), std::invalid_argument);
  FloorPlan wide = plan;
  wide.walls.push_back({{2, -3}, {2, 3}, 2.5});  // across the corridor
  try {
    CheckPath(wide, Path());
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_THAT(e.what(), HasSubstr("is behind wall 3: the path crosses it"));
  }
}

class FloorPlanFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("waymark_floor_plan_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_ / "rig" / "cameras");
    std::ofstream(dir_ / "rig" / "dataset.yaml")
        << "format: waymark-dataset\nversion: 1\nmotion: planar\ncameras: [left]\n"
           "odometry_sigma: {trans_per_m: 0.03, rot_per_rad: 0.01}\n";
    std::ofstream(dir_ / "rig" / "cameras" / "left.yaml")
        << "model: pinhole-radtan\nwidth: 640\nheight: 480\nintrinsics: [450, 450, 320, 240]\n"
           "distortion: [0, 0, 0, 0, 0]\nT_robot_camera: {t: [0, 0.12, 0.3], q_xyzw: [0, 0, 0, 1]}\n";
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string Error(const std::string& text) {
    std::ofstream(dir_ / "world.yaml") << text;
    try {
      ReadFloorPlan(dir_ / "world.yaml");
    } catch (const FormatError& e) {
      return e.what();
    }
    return "no error";
  }
  fs::path dir_;
};

constexpr const char* kHeader =
    "format: waymark-floor-plan\nversion: 1\nceiling_height_m: 2.5\nrig: rig\ncode_sizes_m: [0.1, 0.15]\n"
    "code_height_m: 0.3\n";

TEST_F(FloorPlanFileTest, ReadsAndRejects) {
  std::ofstream(dir_ / "world.yaml")
      << kHeader << "walls:\n  - {from: [0, 0], to: [4, 0]}\n  - {from: [4, 1], to: [0, 1], height_m: 2}\n";
  const FloorPlan plan = ReadFloorPlan(dir_ / "world.yaml");
  ASSERT_EQ(plan.walls.size(), 2u);
  EXPECT_EQ(plan.walls[0].height_m, 2.5);
  EXPECT_EQ(plan.walls[1].height_m, 2.0);
  EXPECT_EQ(plan.cameras.size(), 1u);
  EXPECT_EQ(plan.odometry_sigma.trans_per_m, 0.03);
  EXPECT_EQ(plan.code_sizes_m, (std::vector<double>{0.1, 0.15}));
  EXPECT_THAT(Error(std::string(kHeader) + "walls: []\n"),
              HasSubstr("world.yaml:7: walls: expected a list of at least one wall"));
  EXPECT_THAT(Error(std::string(kHeader)), HasSubstr("missing key 'walls'"));
  EXPECT_THAT(Error(std::string(kHeader) + "walls:\n  - {from: [0, 0], to: [0, 0]}\n"),
              HasSubstr("walls[0]: zero length"));
  EXPECT_THAT(Error(std::string(kHeader) + "walls:\n  - {from: [0, 0, 1], to: [1, 0]}\n"),
              HasSubstr("walls[0].from: expected 2 numbers, got 3"));
  EXPECT_THAT(
      Error("format: waymark-floor-plan\nversion: 1\nceiling_height_m: 2.5\nrig: rig\ncode_sizes_m: []\n"),
      HasSubstr("code_sizes_m: expected at least one size"));
}

}  // namespace
}  // namespace waymark::plan
