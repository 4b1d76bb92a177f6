#include "geometry/board.h"

#include <cmath>
#include <map>
#include <set>

#include "util/format.h"

namespace waymark {
namespace {

// "0.0012 m / 0.0003 rad" between two poses.
std::string Difference(const SE3d& a, const SE3d& b) {
  return FormatSignificant((a.translation() - b.translation()).norm(), 3) + " m / " +
         FormatSignificant(RotationAngleBetween(a, b), 3) + " rad";
}

bool Agree(const SE3d& a, const SE3d& b) {
  return (a.translation() - b.translation()).norm() <= kBoardPoseToleranceM &&
         RotationAngleBetween(a, b) <= kBoardPoseToleranceRad;
}

bool ValidLayout(const SE3d& T) {
  return T.translation().allFinite() && T.rotation().coeffs().allFinite() &&
         std::abs(T.rotation().norm() - 1.0) <= 1e-3;
}

}  // namespace

std::optional<BoardProblem> FindBoardProblem(const MarkerMap& map) {
  std::map<MarkerKey, const MapMarker*> markers;
  for (const MapMarker& m : map.markers) markers.emplace(m.key, &m);
  std::map<MarkerKey, std::string> board_of;  // code -> board name
  std::set<std::string> names;
  for (size_t bi = 0; bi < map.boards.size(); ++bi) {
    const MapBoard& board = map.boards[bi];
    const int b = static_cast<int>(bi);
    if (board.name.empty()) return BoardProblem{b, -1, "name", "expected a non-empty name"};
    if (!names.insert(board.name).second)
      return BoardProblem{b, -1, "name", "duplicate board name \"" + board.name + "\""};
    if (board.members.empty()) return BoardProblem{b, -1, "markers", "expected at least one code"};
    if (!board.has_pose && (board.fixed || board.covariance))
      return BoardProblem{b, -1, "T_world_board",
                          "expected a pose for a fixed board or one with a covariance"};
    if (board.has_pose && !ValidLayout(board.T_world_board))
      return BoardProblem{b, -1, "T_world_board", "expected a finite pose with a unit quaternion"};
    std::optional<SE3d> fixed_by;  // the board pose given by its first fixed code (board without pose)
    std::string fixed_code;
    for (size_t i = 0; i < board.members.size(); ++i) {
      const BoardMember& member = board.members[i];
      const int mi = static_cast<int>(i);
      const std::string code = member.key.ToString();
      const auto it = markers.find(member.key);
      if (it == markers.end())
        return BoardProblem{b, mi, "",
                            "code " + code +
                                " is not in \"markers\" (every code of a board needs its entry there, "
                                "with its size_m)"};
      const MapMarker& marker = *it->second;
      if (marker.is_point)
        return BoardProblem{b, mi, "",
                            "code " + code + " is a point landmark (p_world_marker): not on a board"};
      if (const auto [other, inserted] = board_of.emplace(member.key, board.name); !inserted)
        return BoardProblem{
            b, mi, "",
            "code " + code + " is already on board \"" + other->second + "\" (a code is on one board, once)"};
      if (!ValidLayout(member.T_board_marker))
        return BoardProblem{b, mi, "T_board_marker", "expected a finite pose with a unit quaternion"};
      for (size_t j = 0; j < i; ++j) {
        const BoardMember& other = board.members[j];
        const auto o = markers.find(other.key);
        if (o == markers.end()) continue;
        const double gate_m = 0.5 * std::max(marker.size_m, o->second->size_m);
        const double distance_m =
            (member.T_board_marker.translation() - other.T_board_marker.translation()).norm();
        const Eigen::Vector3d z_i = member.T_board_marker.rotation() * Eigen::Vector3d::UnitZ();
        const Eigen::Vector3d z_j = other.T_board_marker.rotation() * Eigen::Vector3d::UnitZ();
        if (distance_m < gate_m && z_i.dot(z_j) > 0.0)
          return BoardProblem{b, mi, "T_board_marker",
                              "code " + code + " overlaps code " + other.key.ToString() + " (centres " +
                                  FormatSignificant(distance_m, 3) +
                                  " m apart, less than half the larger size): not a rigid layout"};
      }
      if (!marker.has_pose) continue;
      const SE3d implied = marker.T_world_marker * member.T_board_marker.inverse();
      if (board.has_pose) {
        const SE3d expected = board.T_world_board * member.T_board_marker;
        if (!Agree(expected, marker.T_world_marker))
          return BoardProblem{b, mi, "",
                              "code " + code + ": its T_world_marker is " +
                                  Difference(expected, marker.T_world_marker) +
                                  " from T_world_board * T_board_marker (conflicting poses)"};
        if (marker.fixed && !board.fixed)
          return BoardProblem{b, mi, "",
                              "code " + code + " is fixed but its board is not (conflicting anchors)"};
      } else if (marker.fixed) {
        if (fixed_by && !Agree(*fixed_by, implied))
          return BoardProblem{b, mi, "",
                              "code " + code + " is fixed at a board pose " + Difference(*fixed_by, implied) +
                                  " from the one fixed code " + fixed_code + " gives (conflicting anchors)"};
        if (!fixed_by) fixed_by = implied, fixed_code = code;
      }
    }
  }
  return std::nullopt;
}

Matrix6d BoardToMemberJacobian(const SE3d& T_board_marker) {
  const Eigen::Matrix3d R_t = T_board_marker.rotation_matrix().transpose();
  Matrix6d J = Matrix6d::Zero();
  J.topLeftCorner<3, 3>() = R_t;
  J.bottomLeftCorner<3, 3>() = -R_t * Hat<double>(T_board_marker.translation());
  J.bottomRightCorner<3, 3>() = R_t;
  return J;
}

Matrix6d MemberCovariance(const Matrix6d& board_covariance, const SE3d& T_board_marker) {
  const Matrix6d J = BoardToMemberJacobian(T_board_marker);
  const Matrix6d sigma = J * board_covariance * J.transpose();
  return 0.5 * (sigma + sigma.transpose());
}

void BoardPriorFromMember(const SE3d& T_world_marker, const Matrix6d& marker_covariance,
                          const SE3d& T_board_marker, SE3d* T_world_board, Matrix6d* board_covariance) {
  const SE3d T_marker_board = T_board_marker.inverse();
  *T_world_board = T_world_marker * T_marker_board;
  *board_covariance = MemberCovariance(marker_covariance, T_marker_board);
}

}  // namespace waymark
