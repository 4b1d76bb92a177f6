// Rigid boards in the map build (markers.json `boards`, geometry/board.h; docs/mapping.md,
// "Boards"). A board is one SE(3) pose T_world_board in the global problem; its codes'
// observations enter on that block through their constant layout
// (T_world_marker = T_world_board * T_board_marker, factors/board_member_factor.h), so the build
// estimates one pose per board and the board cannot bend.
//
// World information of a board (AttachBoards):
//   - the board `fixed`: held constant at T_world_board;
//   - the board with a `covariance`: one pose prior on the board;
//   - a board without a pose: its codes' own anchors moved onto it (geometry/board.h): a `fixed`
//     code holds the board constant at T_world_marker * T_board_marker⁻¹, a code with a
//     covariance gives the board a prior; none: the board's pose is unknown, estimated from the
//     views alone.
// Each seen code of a board gets, as its `known` entry, the pose and covariance the board's
// world information gives it, so the initializer aligns its component onto the board like onto
// any anchor; the global problem puts the priors on the board block only (never once per code).
//
// Initialization: the initializer places the codes one by one; the board's initial pose is the
// one implied by the code whose implied pose most other codes agree with (within 5 cm + 10 % of
// the code's distance from the board's origin, and 0.1 rad), ties to the most observed code.
// Codes of one board in groups that share no observation (JoinBoardComponents): the groups are
// moved into the frame of the first (the one in the world frame, when one is) through the board
// and become one component.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "geometry/types.h"
#include "mapping/initializer.h"
#include "mapping/survey.h"

namespace waymark {

// Fills survey->boards and the board codes' `board`, `T_board_marker` and `known` from a valid
// known-markers map (geometry/board.h's rules hold; its codes not seen are left out).
void AttachBoards(const MarkerMap& known_markers, Survey* survey);

// The initial pose of board b from its codes' initial poses (header comment); nullopt when none
// of its codes is placed.
std::optional<SE3d> InitialBoardPose(const Survey& survey, const Initialization& init, int board);

// Joins the components a board's codes span (header comment); returns how many components
// were joined into others.
int JoinBoardComponents(const Survey& survey, Initialization* init);

// One summary line per board ("board A: 6 of 6 codes seen, pose unknown (estimated)").
std::vector<std::string> DescribeBoards(const Survey& survey);

}  // namespace waymark
