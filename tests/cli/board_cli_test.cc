// End to end through the `waymark` binary: a survey whose markers.json holds a rigid board,
// `waymark map build` maps it (the summary names the board, the map carries it and lists every
// code as a plain marker), `waymark map info` reads the map; a broken board is a one-line error
// naming markers.json and its line, with no output written.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "io/dataset_io.h"
#include "io/map_io.h"
#include "io/util.h"
#include "tests/cli/cli_test_util.h"
#include "tests/mapping/board_survey.h"

namespace waymark {
namespace {

namespace fs = std::filesystem;

class BoardCliTest : public CliTest {
 protected:
  BoardCliTest() : CliTest("board_cli") {}

  fs::path Survey() const {
    const fs::path survey = dir_ / "survey";
    WriteDataset(survey, testing::BoardSurvey(true));
    return survey;
  }
};

TEST_F(BoardCliTest, BuildKeepsTheBoardAndListsItsCodes) {
  const fs::path survey = Survey();
  const fs::path map_path = dir_ / "map.json";
  const RunResult build = Run("map build " + survey.string() + " --out " + map_path.string());
  ASSERT_EQ(build.exit_code, 0) << build.err;
  EXPECT_NE(build.out.find("note: board shelf: 6 of 6 codes seen, rigid (one pose): pose unknown"),
            std::string::npos)
      << build.out;
  const MarkerMap map = ReadMap(map_path);
  EXPECT_EQ(map.markers.size(), 10u);
  ASSERT_EQ(map.boards.size(), 1u);
  EXPECT_EQ(map.boards[0].members.size(), 6u);
  for (const BoardMember& member : map.boards[0].members) {
    const MapMarker* marker = map.Find(member.key);
    ASSERT_NE(marker, nullptr);
    EXPECT_LT((marker->T_world_marker.translation() -
               (map.boards[0].T_world_board * member.T_board_marker).translation())
                  .norm(),
              1e-9);
  }
  const RunResult info = Run("map info " + map_path.string());
  EXPECT_EQ(info.exit_code, 0) << info.err;
  EXPECT_NE(info.out.find("board shelf: 6 codes\n"), std::string::npos) << info.out;

  // The built map as the known markers of a new build: the board is a prior now.
  fs::copy_file(map_path, survey / "markers.json", fs::copy_options::overwrite_existing);
  const RunResult again = Run("map build " + survey.string() + " --out " + (dir_ / "again.json").string());
  ASSERT_EQ(again.exit_code, 0) << again.err;
  EXPECT_NE(again.out.find("rigid (one pose): pose prior in markers.json"), std::string::npos) << again.out;
}

TEST_F(BoardCliTest, BrokenBoardIsAOneLineError) {
  const fs::path survey = Survey();
  std::string text = ReadTextFile(survey / "markers.json");
  const std::string from = "\"id\":\"B5\",\"T_board_marker\"";
  const size_t at = text.find(from);
  ASSERT_NE(at, std::string::npos) << text;
  text.replace(at, from.size(), "\"id\":\"B9\",\"T_board_marker\"");
  AtomicWriteFile(survey / "markers.json", text);
  const fs::path map_path = dir_ / "map.json";
  const RunResult build = Run("map build " + survey.string() + " --out " + map_path.string());
  EXPECT_EQ(build.exit_code, 1);
  EXPECT_NE(build.err.find("markers.json:"), std::string::npos) << build.err;
  EXPECT_NE(build.err.find(": boards[0].markers[5]: code apriltag-36h11:B9 is not in \"markers\""),
            std::string::npos)
      << build.err;
  EXPECT_EQ(build.err.find('\n'), build.err.size() - 1) << "one line: " << build.err;
  EXPECT_FALSE(fs::exists(map_path));
}

}  // namespace
}  // namespace waymark
