#include "mapping/square_association.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>
#include <set>
#include <stdexcept>

#include "geometry/camera.h"
#include "geometry/marker_pose.h"
#include "geometry/square_marker.h"

namespace waymark {
namespace {

struct Square {
  std::string id;
  SE3d T_world_square;
};

// T_odom_robot at a stamp; outside the odometry's span its nearest end (standing still).
SE3d OdometryAt(const Trajectory& odometry, double stamp_s) {
  if (stamp_s <= odometry.front().stamp_s) return odometry.front().T;
  if (stamp_s >= odometry.back().stamp_s) return odometry.back().T;
  return *InterpolateTrajectory(odometry, stamp_s, std::numeric_limits<double>::infinity());
}

// x, y and yaw of a pose (the robot level at z = 0).
SE3d Planar(const SE3d& T) { return SE2d::FromSE3(T).ToSE3(); }

std::string NewName(const std::set<std::string>& used) {
  for (int n = 0;; ++n) {
    const std::string name = "S" + std::to_string(n);
    if (used.count(name) == 0) return name;
  }
}

}  // namespace

bool HasSquareDetections(const Dataset& dataset) {
  for (const DetectionFrame& frame : dataset.detections) {
    for (const MarkerObservation& m : frame.markers) {
      if (m.key.family == kFamilySquare) return true;
    }
  }
  return false;
}

Dataset AssociateSquares(const Dataset& input, SquareAssociationStats* stats) {
  const std::string where = "dataset " + input.dir.string();
  Dataset dataset = input;
  SquareAssociationStats counts;
  if (input.odometry.empty()) {
    throw std::runtime_error(where + ": square detections carry no id; the map build tells them apart by " +
                             "the odometry, and the dataset has none");
  }
  // The squares' look (alike) and the known ones.
  std::vector<Square> squares;
  std::set<std::string> used;
  double side_m = 0.0;
  SquareTape tape;
  bool have_look = false;
  if (input.known_markers) {
    for (const MapMarker& m : input.known_markers->markers) {
      if (m.key.family != kFamilySquare) continue;
      used.insert(m.key.id);
      if (!have_look && m.size_m > 0.0) {
        side_m = m.size_m;
        tape = TapeOf(m);
        have_look = true;
      }
      if (m.has_pose) squares.push_back({m.key.id, m.T_world_marker});
    }
  }
  const size_t known = squares.size();
  if (!have_look) {
    if (!input.config.default_marker_size_m) {
      throw std::runtime_error(where + ": square detections need the squares' side: a square in " +
                               input.config.markers_file + " or default_marker_size_m in dataset.yaml");
    }
    side_m = *input.config.default_marker_size_m;
  }
  const double gate_m = 0.5 * side_m;

  for (const DetectionFrame& frame : input.detections) {
    if (!std::isfinite(frame.stamp_s)) return dataset;  // the ingest's error (survey.h)
  }
  std::vector<size_t> order(dataset.detections.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    return dataset.detections[a].stamp_s < dataset.detections[b].stamp_s;
  });
  std::map<std::string, Camera> cameras;
  for (const auto& [name, info] : dataset.cameras) cameras.emplace(name, Camera(info));
  // The single-image pose of every square sighting (nullopt: unknown camera or no pose), the
  // corners of "*" detections first put in the squares' order.
  std::map<std::pair<size_t, size_t>, SE3d> T_robot_square;  // (line, index in the frame)
  for (const size_t line : order) {
    DetectionFrame& frame = dataset.detections[line];
    const auto camera = cameras.find(frame.camera);
    for (size_t k = 0; k < frame.markers.size(); ++k) {
      MarkerObservation& m = frame.markers[k];
      if (m.key.family != kFamilySquare) continue;
      if (m.key.id == kUnidentifiedSquareId)
        m.corners_px = SolidFirstToMarkerOrder(m.corners_px, tape.solid_side);
      if (camera == cameras.end()) continue;
      try {
        const MarkerPoseEstimate pose = EstimateMarkerPose(m.corners_px, side_m, camera->second);
        T_robot_square[{line, k}] = camera->second.info().T_robot_camera * pose.best().T_camera_marker;
      } catch (const std::runtime_error&) {
      }
    }
  }
  // Pass 1: the robot's path from the odometry, anchored and re-anchored by near sightings only
  // (the square's centre within one side of the robot: a steep view's pose can be decimetres and
  // degrees off), which also find the squares.
  std::vector<std::optional<SE3d>> T_world_robot(dataset.detections.size());
  std::optional<SE3d> pose;
  SE3d last_odom;
  std::optional<size_t> first_anchor;
  std::set<size_t> seen_known;
  for (const size_t line : order) {
    const DetectionFrame& frame = dataset.detections[line];
    const SE3d T_odom = OdometryAt(input.odometry, frame.stamp_s);
    if (pose) *pose = Planar(*pose * (last_odom.inverse() * T_odom));
    last_odom = T_odom;
    for (size_t k = 0; k < frame.markers.size(); ++k) {
      const auto it = T_robot_square.find({line, k});
      if (it == T_robot_square.end() || it->second.translation().head<2>().norm() > side_m) continue;
      const SE3d& T_r_s = it->second;
      size_t match = squares.size();
      if (!pose) {  // the first near sighting anchors
        for (size_t i = 0; i < known && match == squares.size(); ++i) {
          if (squares[i].id == frame.markers[k].key.id) match = i;
        }
        if (match == squares.size() && known > 0) match = 0;
        if (match == squares.size()) squares.push_back({NewName(used), T_r_s});
        first_anchor = line;
      } else {
        const Eigen::Vector3d p = (*pose * T_r_s).translation();
        double best = gate_m;
        for (size_t i = 0; i < squares.size(); ++i) {
          const double d = (squares[i].T_world_square.translation() - p).head<2>().norm();
          if (d < best) {
            best = d;
            match = i;
          }
        }
        if (match == squares.size()) squares.push_back({NewName(used), *pose * T_r_s});
      }
      used.insert(squares[match].id);
      if (match < known) seen_known.insert(match);
      pose = Planar(squares[match].T_world_square * T_r_s.inverse());
    }
    T_world_robot[line] = pose;
  }
  // Frames before the first anchor: the odometry backwards from it.
  if (first_anchor) {
    const SE3d anchor_odom = OdometryAt(input.odometry, dataset.detections[*first_anchor].stamp_s);
    for (const size_t line : order) {
      if (T_world_robot[line]) break;
      T_world_robot[line] = Planar(*T_world_robot[*first_anchor] * anchor_odom.inverse() *
                                   OdometryAt(input.odometry, dataset.detections[line].stamp_s));
    }
  }
  // Pass 2: every sighting is the square nearest its predicted centre, within half a side.
  for (const size_t line : order) {
    DetectionFrame& frame = dataset.detections[line];
    std::vector<MarkerObservation> kept;
    for (size_t k = 0; k < frame.markers.size(); ++k) {
      MarkerObservation& m = frame.markers[k];
      const auto it = T_robot_square.find({line, k});
      if (m.key.family != kFamilySquare || cameras.count(frame.camera) == 0) {
        kept.push_back(m);  // an unknown camera is the ingest's error
        continue;
      }
      size_t match = squares.size();
      if (it != T_robot_square.end() && T_world_robot[line]) {
        const Eigen::Vector3d p = (*T_world_robot[line] * it->second).translation();
        double best = gate_m;
        for (size_t i = 0; i < squares.size(); ++i) {
          const double d = (squares[i].T_world_square.translation() - p).head<2>().norm();
          if (d < best) {
            best = d;
            match = i;
          }
        }
      }
      if (match == squares.size()) {
        ++counts.unplaced;
        continue;
      }
      m.key.id = squares[match].id;
      ++counts.sightings;
      kept.push_back(m);
    }
    frame.markers = std::move(kept);
  }
  counts.new_squares = static_cast<int>(squares.size() - known);
  counts.known_used = static_cast<int>(seen_known.size());
  if (!dataset.known_markers) dataset.known_markers.emplace();
  for (size_t i = known; i < squares.size(); ++i) {
    MapMarker entry;
    entry.key = {kFamilySquare, squares[i].id};
    entry.size_m = side_m;
    entry.has_pose = false;
    entry.square_tape = tape;
    dataset.known_markers->markers.push_back(entry);
  }
  if (stats) *stats = counts;
  return dataset;
}

}  // namespace waymark
