// Rigid boards (geometry/types.h MapBoard): the rules a map's boards obey, and the math that
// derives a member code's pose and covariance from its board's.
//
// Member pose:   T_world_marker = T_world_board * T_board_marker.
// Perturbation:  with T_world_board = T̂_world_board * Exp(δ_b) (right perturbation, product map,
// geometry/pose.h), the member moves by
//   δ_m = J(C) δ_b,   J(C) = [[R_Cᵀ, 0], [-R_Cᵀ [t_C]×, R_Cᵀ]],   C = T_board_marker = (R_C, t_C),
// so a member's covariance is Σ_m = J(C) Σ_b J(C)ᵀ, and a member's pose prior (T_world_marker, Σ_m)
// is the board prior (T_world_marker * C⁻¹, J(C⁻¹) Σ_m J(C⁻¹)ᵀ), J(C⁻¹) = J(C)⁻¹.
//
// Rules (FindBoardProblem; io/map_io.cc turns a problem into "path:line: field: message"):
//   - a board has a non-empty name, unique in the map, and at least one code;
//   - each code of a board is a marker of the map (with a pose or size only; not a point
//     landmark), on one board only, listed once; T_board_marker is finite with a unit quaternion;
//   - no two codes of a board overlap: centres closer than half the larger code's size while
//     facing the same way (normals at less than 90 degrees; codes printed back to back on a thin
//     board face away from each other) is not a rigid layout;
//   - a board with a pose (fixed or a prior) and a member code that also has a pose in "markers":
//     the two agree within kBoardPoseToleranceM / kBoardPoseToleranceRad, and the code is not
//     `fixed` unless the board is (conflicting anchors);
//   - a board without a pose: its `fixed` codes give the board's pose; they agree with each other
//     within the same tolerance.
#pragma once

#include <optional>
#include <string>

#include "geometry/pose.h"
#include "geometry/types.h"

namespace waymark {

inline constexpr double kBoardPoseToleranceM = 1e-3;
inline constexpr double kBoardPoseToleranceRad = 1e-3;

// A broken rule: board `board`, its code `member` (-1: the board itself), the field below the
// board ("name", "markers", "T_world_board", or below the code: "T_board_marker", "" for the
// code's entry) and the one-line message.
struct BoardProblem {
  int board = 0;
  int member = -1;
  std::string field;
  std::string message;
};

// The first broken rule of the header comment, nullopt when the map's boards are valid.
std::optional<BoardProblem> FindBoardProblem(const MarkerMap& map);

// δ_m = J(C) δ_b of the header comment.
Matrix6d BoardToMemberJacobian(const SE3d& T_board_marker);

// Σ_m = J(C) Σ_b J(C)ᵀ, symmetrized.
Matrix6d MemberCovariance(const Matrix6d& board_covariance, const SE3d& T_board_marker);

// The board prior a member's pose prior gives: mean T_world_marker * C⁻¹, covariance
// J(C⁻¹) Σ_m J(C⁻¹)ᵀ.
void BoardPriorFromMember(const SE3d& T_world_marker, const Matrix6d& marker_covariance,
                          const SE3d& T_board_marker, SE3d* T_world_board, Matrix6d* board_covariance);

}  // namespace waymark
