// The map format's rigid boards (docs/formats.md "Boards"): read, written, round-tripped, and
// every broken rule a one-line error naming the file, the line and the field.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>

#include "io/map_io.h"
#include "io/util.h"

namespace waymark {
namespace {

using ::testing::HasSubstr;

// A known-markers file: three codes of a board (size only, one anchored) and a board without pose.
const char* const kKnown = R"({"format": "waymark-map", "version": 1,
 "markers": [
  {"family": "apriltag-36h11", "id": "1", "size_m": 0.1},
  {"family": "apriltag-36h11", "id": "2", "size_m": 0.1},
  {"family": "apriltag-36h11", "id": "3", "size_m": 0.1,
   "T_world_marker": {"t": [1.3, 2, 3], "q_xyzw": [0, 0, 0, 1]}, "fixed": true},
  {"family": "qr", "id": "loose", "size_m": 0.1}
 ],
 "boards": [
  {"name": "shelf",
   "markers": [
    {"family": "apriltag-36h11", "id": "1", "T_board_marker": {"t": [0, 0, 0], "q_xyzw": [0, 0, 0, 1]}},
    {"family": "apriltag-36h11", "id": "2", "T_board_marker": {"t": [0.15, 0, 0], "q_xyzw": [0, 0, 0, 1]}},
    {"family": "apriltag-36h11", "id": "3", "T_board_marker": {"t": [0.3, 0, 0], "q_xyzw": [0, 0, 0, 1]}}
   ]}
 ]}
)";

std::string KnownWith(const std::string& from, const std::string& to) {
  std::string text = kKnown;
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return text.replace(at, from.size(), to);
}

std::string ParseError(const std::string& text, MapPoses poses = MapPoses::kOptional) {
  try {
    ParseMap(text, "markers.json", nullptr, poses);
  } catch (const FormatError& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected a FormatError for:\n" << text;
  return "";
}

TEST(MapBoardsIoTest, ReadsBoardWithoutPose) {
  ReadWarnings warnings;
  const MarkerMap map = ParseMap(kKnown, "markers.json", &warnings, MapPoses::kOptional);
  ASSERT_EQ(map.boards.size(), 1u);
  const MapBoard& board = map.boards[0];
  EXPECT_EQ(board.name, "shelf");
  EXPECT_FALSE(board.has_pose);
  ASSERT_EQ(board.members.size(), 3u);
  EXPECT_EQ(board.members[1].key.id, "2");
  EXPECT_DOUBLE_EQ(board.members[1].T_board_marker.translation().x(), 0.15);
  EXPECT_EQ(warnings.Total(), 0);
}

TEST(MapBoardsIoTest, WritesAndReadsBackExactly) {
  MarkerMap map = ParseMap(kKnown, "markers.json", nullptr, MapPoses::kOptional);
  map.boards[0].has_pose = true;
  map.boards[0].T_world_board = SE3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(1.0, 2, 3));
  map.boards[0].fixed = true;
  map.boards[0].component = 0;
  Matrix6d covariance = Matrix6d::Identity() * 1e-6;
  covariance(0, 1) = covariance(1, 0) = 1e-7;
  map.boards[0].covariance = covariance;
  const std::string text = FormatMap(map);
  EXPECT_THAT(text, HasSubstr("\"boards\": [\n  {\"name\":\"shelf\",\"T_world_board\""));
  const MarkerMap back = ParseMap(text, "map.json", nullptr, MapPoses::kOptional);
  ASSERT_EQ(back.boards.size(), 1u);
  EXPECT_TRUE(back.boards[0].fixed);
  EXPECT_EQ(*back.boards[0].covariance, covariance);
  EXPECT_EQ(FormatMap(back), text);
  // Without boards, no "boards" key: old readers see the same file as before.
  map.boards.clear();
  EXPECT_EQ(FormatMap(map).find("boards"), std::string::npos);
}

TEST(MapBoardsIoTest, OldReadersKeyIsAWarningNotAnError) {
  // What an old reader does with a new file is a counted "unknown key" warning: the same file
  // under another top-level name is read here with that warning.
  ReadWarnings warnings;
  const std::string renamed = KnownWith("\"boards\"", "\"boards_v2\"");
  const MarkerMap map = ParseMap(renamed, "markers.json", &warnings, MapPoses::kOptional);
  EXPECT_TRUE(map.boards.empty());
  EXPECT_EQ(warnings.counts["unknown key"], 1);
}

TEST(MapBoardsIoTest, BrokenRulesAreOneLineErrors) {
  EXPECT_EQ(
      ParseError(KnownWith("\"id\": \"2\", \"T_board", "\"id\": \"9\", \"T_board")),
      "markers.json:13: boards[0].markers[1]: code apriltag-36h11:9 is not in \"markers\" (every code of a "
      "board needs its entry there, with its size_m)");
  EXPECT_EQ(
      ParseError(KnownWith("\"id\": \"2\", \"T_board", "\"id\": \"1\", \"T_board")),
      "markers.json:13: boards[0].markers[1]: code apriltag-36h11:1 is already on board \"shelf\" (a code is "
      "on one board, once)");
  const std::string second_board =
      ",\n  {\"name\": \"other\", \"markers\": [{\"family\": \"apriltag-36h11\", \"id\": \"2\", "
      "\"T_board_marker\": {\"t\": [0, 0, 0], \"q_xyzw\": [0, 0, 0, 1]}}]}\n ]}";
  EXPECT_EQ(
      ParseError(KnownWith("\n ]}\n", second_board)),
      "markers.json:16: boards[1].markers[0]: code apriltag-36h11:2 is already on board \"shelf\" (a code is "
      "on one board, once)");
  const std::string same_name =
      ",\n  {\"name\": \"shelf\", \"markers\": [{\"family\": \"qr\", \"id\": \"loose\", "
      "\"T_board_marker\": {\"t\": [0, 0, 0], \"q_xyzw\": [0, 0, 0, 1]}}]}\n ]}";
  EXPECT_EQ(ParseError(KnownWith("\n ]}\n", ",\n  {\"name\": \"empty\", \"markers\": []}\n ]}")),
            "markers.json:16: boards[1].markers: expected at least one code");
  EXPECT_EQ(ParseError(KnownWith("\n ]}\n", same_name)),
            "markers.json:16: boards[1].name: duplicate board name \"shelf\"");
  EXPECT_EQ(
      ParseError(KnownWith("\"t\": [0.15, 0, 0], \"q_xyzw\": [0, 0, 0, 1]",
                           "\"t\": [0.15, 0, 0], \"q_xyzw\": [0, 0, 0, 2]")),
      "markers.json:13: boards[0].markers[1].T_board_marker.q_xyzw: expected unit norm within 0.001, got 2");
  EXPECT_EQ(ParseError(KnownWith("\"t\": [0.15, 0, 0]", "\"t\": [0.01, 0, 0]")),
            "markers.json:13: boards[0].markers[1].T_board_marker: code apriltag-36h11:2 overlaps code "
            "apriltag-36h11:1 (centres 0.01 m apart, less than half the larger size): not a rigid layout");
  EXPECT_EQ(ParseError(KnownWith("\"t\": [0.15, 0, 0]", "\"t\": [0.15, 0, \"x\"]")),
            "markers.json:13: boards[0].markers[1].T_board_marker.t[2]: expected a number, got a string");
  EXPECT_EQ(ParseError(KnownWith("\"name\": \"shelf\"", "\"name\": \"\"")),
            "markers.json:10: boards[0].name: expected a non-empty name");
  EXPECT_EQ(
      ParseError(KnownWith("\"name\": \"shelf\",", "\"name\": \"shelf\", \"fixed\": true,")),
      "markers.json:10: boards[0].T_world_board: expected a pose for a fixed board or one with a covariance");
  EXPECT_EQ(ParseError(KnownWith("\"boards\": [", "\"boards\": {\"x\": 1}, \"b\": [")),
            "markers.json:9: boards: expected an array of boards");
  // A board with a pose, and a code of it with another pose: conflicting poses.
  const std::string posed =
      KnownWith("\"name\": \"shelf\",",
                "\"name\": \"shelf\", \"T_world_board\": {\"t\": [1, 2, 3], \"q_xyzw\": [0, 0, 0, 1]}, "
                "\"fixed\": true,");
  // The fixed code 3 at 1.3 = 1 + 0.3: the same pose, and both fixed.
  EXPECT_EQ(ParseMap(posed, "markers.json", nullptr, MapPoses::kOptional).boards.size(), 1u);
  // Within 1 mm it is the same pose.
  const std::string agreeing =
      KnownWith("\"name\": \"shelf\",",
                "\"name\": \"shelf\", \"T_world_board\": {\"t\": [1, 2, 3.0005], \"q_xyzw\": [0, 0, 0, 1]}, "
                "\"fixed\": true,");
  EXPECT_EQ(ParseMap(agreeing, "markers.json", nullptr, MapPoses::kOptional).boards.size(), 1u);
  const std::string conflicting =
      KnownWith("\"name\": \"shelf\",",
                "\"name\": \"shelf\", \"T_world_board\": {\"t\": [1, 2, 3.01], \"q_xyzw\": [0, 0, 0, 1]}, "
                "\"fixed\": true,");
  EXPECT_EQ(ParseError(conflicting),
            "markers.json:14: boards[0].markers[2]: code apriltag-36h11:3: its T_world_marker is 0.01 m / 0 "
            "rad from "
            "T_world_board * T_board_marker (conflicting poses)");
  // The board a prior, the code fixed: conflicting anchors.
  const std::string prior = KnownWith(
      "\"name\": \"shelf\",",
      "\"name\": \"shelf\", \"T_world_board\": {\"t\": [1, 2, 3], \"q_xyzw\": [0, 0, 0, 1]}, "
      "\"covariance\": [1,0,0,0,0,0, 0,1,0,0,0,0, 0,0,1,0,0,0, 0,0,0,1,0,0, 0,0,0,0,1,0, 0,0,0,0,0,1],");
  EXPECT_EQ(ParseError(prior),
            "markers.json:14: boards[0].markers[2]: code apriltag-36h11:3 is fixed but its board is not "
            "(conflicting anchors)");
  // Two fixed codes of a board without pose that disagree.
  const std::string two_fixed = KnownWith("{\"family\": \"apriltag-36h11\", \"id\": \"2\", \"size_m\": 0.1}",
                                          "{\"family\": \"apriltag-36h11\", \"id\": \"2\", \"size_m\": 0.1, "
                                          "\"T_world_marker\": {\"t\": [1.2, 2, 3], "
                                          "\"q_xyzw\": [0, 0, 0, 1]}, \"fixed\": true}");
  EXPECT_EQ(
      ParseError(two_fixed),
      "markers.json:14: boards[0].markers[2]: code apriltag-36h11:3 is fixed at a board pose 0.05 m / 0 rad "
      "from the one fixed code apriltag-36h11:2 gives (conflicting anchors)");
  // A map (poses required) needs the board's pose.
  EXPECT_EQ(ParseError(kKnown, MapPoses::kRequired),
            "markers.json:3: markers[0]: missing key \"T_world_marker\"");
}

TEST(MapBoardsIoTest, PosesRequiredNeedTheBoardPose) {
  MarkerMap map = ParseMap(kKnown, "markers.json", nullptr, MapPoses::kOptional);
  map.markers.erase(map.markers.begin() + 3);
  for (MapMarker& m : map.markers) {
    m.has_pose = true;
    m.fixed = false;
    m.T_world_marker = SE3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(1.0, 2, 3)) *
                       map.boards[0].members[&m - map.markers.data()].T_board_marker;
  }
  EXPECT_EQ(ParseError(FormatMap(map), MapPoses::kRequired),
            "markers.json:8: boards[0]: missing key \"T_world_board\"");
}

TEST(MapBoardsIoTest, WriterRefusesWhatTheReaderRejects) {
  MarkerMap map = ParseMap(kKnown, "markers.json", nullptr, MapPoses::kOptional);
  map.boards[0].members[1].key.id = "9";
  EXPECT_THROW(FormatMap(map), std::invalid_argument);
  map = ParseMap(kKnown, "markers.json", nullptr, MapPoses::kOptional);
  map.boards.push_back(map.boards[0]);
  EXPECT_THROW(FormatMap(map), std::invalid_argument);
}

}  // namespace
}  // namespace waymark
