#include "mapping/boards.h"

#include <algorithm>
#include <map>
#include <set>

#include "geometry/board.h"

namespace waymark {
namespace {

bool IsAnchored(const SurveyMarker& marker) {
  return marker.known && (marker.known->fixed || marker.known->covariance.has_value());
}

// The board pose code m's initial pose implies.
SE3d ImpliedBoardPose(const Survey& survey, const Initialization& init, int m) {
  return *init.T_world_marker[m] * survey.markers[m].T_board_marker.inverse();
}

// How many placed codes of `board` in code m's component agree with the board pose m implies
// (header comment's gate).
size_t Agreeing(const Survey& survey, const Initialization& init, const SurveyBoard& board, int m) {
  const SE3d candidate = ImpliedBoardPose(survey, init, m);
  size_t agree = 0;
  for (int j : board.markers) {
    if (!init.T_world_marker[j] || init.marker_component[j] != init.marker_component[m]) continue;
    const SE3d predicted = candidate * survey.markers[j].T_board_marker;
    const double gate_m = 0.05 + 0.1 * survey.markers[j].T_board_marker.translation().norm();
    if ((predicted.translation() - init.T_world_marker[j]->translation()).norm() <= gate_m &&
        RotationAngleBetween(predicted, *init.T_world_marker[j]) <= 0.1)
      ++agree;
  }
  return agree;
}

// The placed code of `board` in component c (any component when c < 0) whose implied board pose
// most codes agree with, ties to the most observed; -1 when none.
int Representative(const Survey& survey, const Initialization& init, const SurveyBoard& board, int c) {
  int best = -1;
  size_t best_agree = 0;
  for (int m : board.markers) {
    if ((c >= 0 && init.marker_component[m] != c) || !init.T_world_marker[m]) continue;
    const size_t agree = Agreeing(survey, init, board, m);
    if (best < 0 || agree > best_agree ||
        (agree == best_agree &&
         survey.markers[m].observations.size() > survey.markers[best].observations.size())) {
      best = m;
      best_agree = agree;
    }
  }
  return best;
}

// Renumbers the components 0, 1, ... in the order of their first frame, dropping empty ones.
void RenumberComponents(Initialization* init, const std::vector<std::string>& gauge) {
  std::vector<int> number(init->components, -1);
  int next = 0;
  for (int c : init->frame_component) {
    if (c >= 0 && number[c] < 0) number[c] = next++;
  }
  for (int c : init->marker_component) {
    if (c >= 0 && number[c] < 0) number[c] = next++;
  }
  std::vector<std::string> renumbered(next);
  for (int c = 0; c < init->components; ++c) {
    if (number[c] >= 0) renumbered[number[c]] = c < static_cast<int>(gauge.size()) ? gauge[c] : "";
  }
  for (int& c : init->frame_component) c = c >= 0 ? number[c] : c;
  for (int& c : init->marker_component) c = c >= 0 ? number[c] : c;
  for (LocalMap& map : init->local_maps) map.component = map.component >= 0 ? number[map.component] : -1;
  init->gauge = renumbered;
  init->components = next;
}

}  // namespace

void AttachBoards(const MarkerMap& known_markers, Survey* survey) {
  std::map<MarkerKey, int> index;
  for (size_t m = 0; m < survey->markers.size(); ++m) index[survey->markers[m].key] = static_cast<int>(m);
  for (const MapBoard& board : known_markers.boards) {
    SurveyBoard sb;
    sb.name = board.name;
    sb.codes = board.members.size();
    const int b = static_cast<int>(survey->boards.size());
    if (board.has_pose && board.fixed) {
      sb.fixed_pose = board.T_world_board;
      sb.world = "pose fixed in markers.json";
    } else if (board.has_pose && board.covariance) {
      sb.priors.push_back({board.T_world_board, *board.covariance});
      sb.world = "pose prior in markers.json";
    } else {
      // The codes' own anchors, moved onto the board (geometry/board.h).
      size_t code_priors = 0;
      for (const BoardMember& member : board.members) {
        const MapMarker* marker = known_markers.Find(member.key);
        if (marker == nullptr || !marker->has_pose) continue;
        if (marker->fixed && !sb.fixed_pose) {
          sb.fixed_pose = marker->T_world_marker * member.T_board_marker.inverse();
          sb.world = "held by its code " + member.key.ToString() + ", fixed in markers.json";
        } else if (marker->covariance) {
          BoardPrior prior;
          BoardPriorFromMember(marker->T_world_marker, *marker->covariance, member.T_board_marker,
                               &prior.T_world_board, &prior.covariance);
          sb.priors.push_back(prior);
          ++code_priors;
        }
      }
      if (sb.fixed_pose) {
        sb.priors.clear();
      } else if (code_priors > 0) {
        sb.world = "prior from " + std::to_string(code_priors) + " of its codes in markers.json";
      } else {
        sb.world = "pose unknown";
      }
    }
    for (const BoardMember& member : board.members) {
      const auto it = index.find(member.key);
      if (it == index.end()) continue;
      SurveyMarker& marker = survey->markers[it->second];
      marker.board = b;
      marker.T_board_marker = member.T_board_marker;
      sb.markers.push_back(it->second);
      if (!sb.fixed_pose && sb.priors.empty()) {
        marker.known.reset();  // no world information: the code is no anchor of its own
        continue;
      }
      MapMarker known;
      known.key = marker.key;
      known.size_m = marker.size_m;
      if (sb.fixed_pose) {
        known.T_world_marker = *sb.fixed_pose * member.T_board_marker;
        known.fixed = true;
      } else {
        known.T_world_marker = sb.priors.front().T_world_board * member.T_board_marker;
        known.covariance = MemberCovariance(sb.priors.front().covariance, member.T_board_marker);
      }
      marker.known = known;
    }
    survey->boards.push_back(std::move(sb));
  }
}

std::optional<SE3d> InitialBoardPose(const Survey& survey, const Initialization& init, int board) {
  const int m = Representative(survey, init, survey.boards[board], -1);
  if (m < 0) return std::nullopt;
  return ImpliedBoardPose(survey, init, m);
}

int JoinBoardComponents(const Survey& survey, Initialization* init) {
  int joined = 0;
  for (bool changed = true; changed;) {
    changed = false;
    std::vector<bool> anchored(init->components, false);
    for (size_t m = 0; m < survey.markers.size(); ++m) {
      const int c = init->marker_component[m];
      if (c >= 0 && init->T_world_marker[m] && IsAnchored(survey.markers[m])) anchored[c] = true;
    }
    for (const SurveyBoard& board : survey.boards) {
      std::set<int> components;
      for (int m : board.markers) {
        if (init->marker_component[m] >= 0 && init->T_world_marker[m])
          components.insert(init->marker_component[m]);
      }
      if (components.size() < 2) continue;
      int target = *components.begin();
      for (int c : components) {
        if (anchored[c]) {
          target = c;
          break;
        }
      }
      const SE3d B_target = ImpliedBoardPose(survey, *init, Representative(survey, *init, board, target));
      for (int c : components) {
        if (c == target || anchored[c]) continue;  // two frames in the world already: priors reconcile them
        SE3d T_target_c =
            B_target * ImpliedBoardPose(survey, *init, Representative(survey, *init, board, c)).inverse();
        if (survey.motion == MotionModel::kPlanar) T_target_c = SE2d::FromSE3(T_target_c).ToSE3();
        for (size_t f = 0; f < init->frame_component.size(); ++f) {
          if (init->frame_component[f] != c) continue;
          init->frame_component[f] = target;
          if (init->T_world_robot[f]) init->T_world_robot[f] = T_target_c * *init->T_world_robot[f];
        }
        for (size_t m = 0; m < init->marker_component.size(); ++m) {
          if (init->marker_component[m] != c) continue;
          init->marker_component[m] = target;
          if (init->T_world_marker[m]) init->T_world_marker[m] = T_target_c * *init->T_world_marker[m];
        }
        for (LocalMap& map : init->local_maps) {
          if (map.component == c) map.component = target;
        }
        ++joined;
        changed = true;
      }
      if (changed) break;  // component numbers changed: start over
    }
    if (changed) RenumberComponents(init, init->gauge);
  }
  return joined;
}

std::vector<std::string> DescribeBoards(const Survey& survey) {
  std::vector<std::string> lines;
  for (const SurveyBoard& board : survey.boards) {
    lines.push_back("board " + board.name + ": " + std::to_string(board.markers.size()) + " of " +
                    std::to_string(board.codes) + " codes seen, rigid (one pose): " + board.world);
  }
  return lines;
}

}  // namespace waymark
