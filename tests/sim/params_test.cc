#include "sim/params.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "io/util.h"
#include "sim/scenarios.h"

namespace waymark::sim {
namespace {

using ::testing::HasSubstr;

class ParamsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("waymark_params_test_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  std::filesystem::path Write(const std::string& text) {
    const std::filesystem::path path = dir_ / "config.yaml";
    std::ofstream(path) << text;
    return path;
  }

  // The what() of the FormatError that loading `text` into the corridor params throws.
  std::string LoadError(const std::string& text) {
    ParamSet params = ScenarioParams("corridor");
    try {
      params.LoadYamlFile(Write(text));
    } catch (const FormatError& e) {
      return e.what();
    }
    return "no error";
  }

  std::filesystem::path dir_;
};

TEST_F(ParamsTest, NestedYamlOverridesDefaults) {
  ParamSet params = ScenarioParams("corridor");
  EXPECT_EQ(params.Double("place.spacing_m"), 1.0);
  params.LoadYamlFile(Write("place:\n  spacing_m: 4\n  anchors: 3\ndetect:\n  pixel_sigma_px: 0.25\n"));
  EXPECT_EQ(params.Double("place.spacing_m"), 4.0);
  EXPECT_EQ(params.Int("place.anchors"), 3);
  EXPECT_EQ(params.Double("detect.pixel_sigma_px"), 0.25);
  EXPECT_EQ(params.Double("place.marker_size_m"), 0.10);  // untouched
}

TEST_F(ParamsTest, PrintedYamlLoadsBackToTheSameValues) {
  for (const ScenarioInfo& scenario : Scenarios()) {
    ParamSet changed = ScenarioParams(scenario.name);
    changed.SetAssignment("detect.pixel_sigma_px=0.123456789012345");
    changed.SetAssignment("rate.camera_hz=5");
    ParamSet loaded = ScenarioParams(scenario.name);
    loaded.LoadYamlFile(Write(changed.ToYaml()));
    ASSERT_EQ(loaded.params().size(), changed.params().size());
    for (size_t i = 0; i < loaded.params().size(); ++i) {
      EXPECT_EQ(loaded.params()[i].value, changed.params()[i].value)
          << scenario.name << " " << loaded.params()[i].key;
    }
  }
}

TEST_F(ParamsTest, UnknownKeyNamesFileLineAndKey) {
  const std::string what = LoadError("place:\n  spacing_m: 2\n  spacing: 2\n");
  EXPECT_THAT(what, HasSubstr("config.yaml:3:"));
  EXPECT_THAT(what, HasSubstr("unknown key 'place.spacing'"));
}

TEST_F(ParamsTest, WrongTypesAreErrors) {
  EXPECT_THAT(LoadError("place:\n  spacing_m: wide\n"),
              HasSubstr("config.yaml:2: place.spacing_m: expected a number"));
  EXPECT_THAT(LoadError("place:\n  spacing_m: [1, 2]\n"),
              HasSubstr("config.yaml:2: place.spacing_m: expected a number"));
  EXPECT_THAT(LoadError("place:\n  spacing_m: \"1\"\n"), HasSubstr("place.spacing_m: expected a number"));
  EXPECT_THAT(LoadError("place:\n  anchors: 1.5\n"), HasSubstr("place.anchors: expected an integer"));
  EXPECT_THAT(LoadError("place:\n  spacing_m:\n"), HasSubstr("place.spacing_m: expected a number"));
  EXPECT_THAT(LoadError("place: 3\n"), HasSubstr("unknown key 'place'"));
}

TEST_F(ParamsTest, OutOfBoundsAndMalformedYamlAreErrors) {
  EXPECT_THAT(LoadError("detect:\n  misdecode_fraction: 1.5\n"),
              HasSubstr("config.yaml:2: detect.misdecode_fraction: 1.5 is outside [0, 1]"));
  EXPECT_THAT(LoadError("place: {spacing_m: 2\n"), HasSubstr("config.yaml:"));
  EXPECT_THAT(LoadError("- 1\n- 2\n"), HasSubstr("expected a map"));
  ParamSet params = ScenarioParams("corridor");
  EXPECT_THROW(params.LoadYamlFile(dir_ / "missing.yaml"), FormatError);
}

TEST_F(ParamsTest, SetAssignmentIsStrict) {
  ParamSet params = ScenarioParams("rooms");
  params.SetAssignment("place.unconnected_room=false");
  EXPECT_FALSE(params.Bool("place.unconnected_room"));
  EXPECT_THROW(params.SetAssignment("place.unconnected_room=maybe"), std::invalid_argument);
  EXPECT_THROW(params.SetAssignment("place.rooms"), std::invalid_argument);
  EXPECT_THROW(params.SetAssignment("place.nothing=1"), std::invalid_argument);
  EXPECT_THROW(params.SetAssignment("place.rooms=2x"), std::invalid_argument);
  try {
    params.SetAssignment("detect.pixel_sigma_px=-1");
    FAIL() << "accepted a negative sigma";
  } catch (const std::invalid_argument& e) {
    EXPECT_THAT(std::string(e.what()), HasSubstr("--set: detect.pixel_sigma_px: -1 is outside"));
  }
}

TEST_F(ParamsTest, UnknownScenarioListsTheKnownOnes) {
  try {
    ScenarioParams("hallway");
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_THAT(std::string(e.what()),
                HasSubstr("unknown scenario 'hallway' (known: corridor, ceiling-grid"));
  }
}

TEST_F(ParamsTest, DescribeListsEveryKeyWithItsDefault) {
  const ParamSet params = ScenarioParams("warehouse-drone");
  const std::string text = params.Describe("  ");
  for (const Param& p : params.params()) EXPECT_THAT(text, HasSubstr(p.key + " (")) << p.key;
  EXPECT_THAT(text, HasSubstr("odometry.scale_error (0.01)"));
}

}  // namespace
}  // namespace waymark::sim
