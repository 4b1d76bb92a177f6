#include "mapping/map_score.h"

#include <ceres/problem.h>
#include <ceres/solver.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <iomanip>
#include <limits>
#include <map>
#include <sstream>
#include <stdexcept>

#include "factors/marker_reprojection_factor.h"
#include "factors/pose_block.h"
#include "geometry/camera.h"
#include "mapping/initializer.h"
#include "mapping/residuals.h"
#include "mapping/serial_blas.h"
#include "mapping/survey.h"
#include "util/check.h"
#include "util/format.h"
#include "util/stats.h"

namespace waymark {
namespace {

// Robust scale (px) of the candidate selection, as the initializer's Cauchy scale of 3 sigmas.
constexpr double kCandidateScalePx = 3.0;
// What an observation that does not project adds to a candidate's cost (a very large error).
constexpr double kUnprojectedCost = 30.0;

// The pose of every frame and marker of a survey, where known, and the marker sizes in use.
struct Poses {
  std::vector<std::optional<SE3d>> T_world_robot;   // per frame
  std::vector<std::optional<SE3d>> T_world_marker;  // per marker
  std::vector<double> size_m;                       // per marker
};

// RMS reprojection error (px) of one observation; nullopt if a pose is unknown or a corner does
// not project.
std::optional<double> ObservationRms(const Survey& survey, const std::map<std::string, Camera>& cameras,
                                     const Poses& poses, int o, const std::optional<SE3d>& T_world_robot,
                                     const std::optional<SE3d>& T_world_marker) {
  if (!T_world_robot || !T_world_marker) return std::nullopt;
  const SurveyObservation& obs = survey.observations[o];
  const Camera& camera = cameras.at(obs.camera);
  const SE3d T_camera_marker =
      camera.info().T_robot_camera.inverse() * T_world_robot->inverse() * *T_world_marker;
  const auto corners_marker = MarkerCorners(poses.size_m[obs.marker]);
  double sum_sq = 0.0;
  for (size_t k = 0; k < 4; ++k) {
    const std::optional<Eigen::Vector2d> px = camera.Project(T_camera_marker * corners_marker[k]);
    if (!px) return std::nullopt;
    sum_sq += (*px - obs.corners_px[k]).squaredNorm();
  }
  return std::sqrt(sum_sq / 4.0);
}

double CandidateCost(std::optional<double> rms_px) {
  if (!rms_px) return kUnprojectedCost;
  return std::log1p(std::pow(*rms_px / kCandidateScalePx, 2));
}

// The pose of each frame from the trajectory pose within `tolerance_s` of its stamp.
std::vector<std::optional<SE3d>> FramesFromTrajectory(const Survey& survey, const Trajectory& trajectory,
                                                      double tolerance_s) {
  std::vector<std::optional<SE3d>> T_world_robot(survey.frames.size());
  for (size_t f = 0; f < survey.frames.size(); ++f) {
    const double t = survey.frames[f].stamp_s;
    const auto it = std::lower_bound(trajectory.begin(), trajectory.end(), t,
                                     [](const StampedSE3& p, double s) { return p.stamp_s < s; });
    double best_s = tolerance_s;
    for (auto c = (it == trajectory.begin() ? it : it - 1); c != trajectory.end() && c <= it; ++c) {
      if (std::abs(c->stamp_s - t) <= best_s) {
        best_s = std::abs(c->stamp_s - t);
        T_world_robot[f] = c->T;
      }
    }
  }
  return T_world_robot;
}

Poses MarkersFromMap(const Survey& survey, const MarkerMap& map) {
  Poses poses;
  poses.T_world_marker.resize(survey.markers.size());
  poses.size_m.resize(survey.markers.size());
  for (size_t m = 0; m < survey.markers.size(); ++m) {
    poses.size_m[m] = survey.markers[m].size_m;
    const MapMarker* mapped = map.Find(survey.markers[m].key);
    if (mapped == nullptr || !mapped->has_pose) continue;
    if (!(mapped->size_m > 0.0) || !std::isfinite(mapped->size_m)) {
      throw std::runtime_error("map: marker " + mapped->key.ToString() + " has no positive size_m");
    }
    poses.size_m[m] = mapped->size_m;
    poses.T_world_marker[m] = mapped->T_world_marker;
  }
  return poses;
}

// Least squares over one pose (frame `index` when robot_varies, else marker `index`) with every
// other pose held fixed, on the observations given. Keeps `initial` when the solve fails.
SE3d RefinePose(const Survey& survey, const Poses& poses, const std::vector<int>& observations,
                bool robot_varies, int index, const SE3d& initial, int max_iterations) {
  ceres::Problem problem;
  std::map<int, PoseBlock> robot_blocks, marker_blocks;
  for (int o : observations) {
    const SurveyObservation& obs = survey.observations[o];
    const std::optional<SE3d> T_world_robot = robot_varies ? initial : poses.T_world_robot[obs.frame];
    const std::optional<SE3d> T_world_marker = robot_varies ? poses.T_world_marker[obs.marker] : initial;
    if (!T_world_robot || !T_world_marker) continue;
    const bool new_robot = robot_blocks.count(obs.frame) == 0,
               new_marker = marker_blocks.count(obs.marker) == 0;
    PoseBlock* robot = &robot_blocks[obs.frame];
    PoseBlock* marker = &marker_blocks[obs.marker];
    if (new_robot) {
      SE3ToBlock(*T_world_robot, robot->data());
      problem.AddParameterBlock(robot->data(), kSE3BlockSize, new SE3Manifold);
      if (!robot_varies) problem.SetParameterBlockConstant(robot->data());
    }
    if (new_marker) {
      SE3ToBlock(*T_world_marker, marker->data());
      problem.AddParameterBlock(marker->data(), kSE3BlockSize, new SE3Manifold);
      if (robot_varies) problem.SetParameterBlockConstant(marker->data());
    }
    const CameraInfo& camera = survey.cameras.at(obs.camera);
    problem.AddResidualBlock(MarkerReprojectionFactor::Create(camera, poses.size_m[obs.marker],
                                                              obs.corners_px, CornerSigmaPx(camera)),
                             nullptr, robot->data(), marker->data());
  }
  if (problem.NumResidualBlocks() == 0) return initial;
  ceres::Solver::Options options;
  options.max_num_iterations = max_iterations;
  options.num_threads = 1;
  ceres::Solver::Summary summary;
  {
    const ScopedSerialLinearAlgebra serial;  // the same result at any load
    ceres::Solve(options, &problem, &summary);
  }
  if (!summary.IsSolutionUsable()) return initial;
  return SE3FromBlock(robot_varies ? robot_blocks.at(index).data() : marker_blocks.at(index).data());
}

// A frame's pose from the mapped markers it sees (see the header comment); nullopt if it sees none.
std::optional<SE3d> SolveFrame(const Survey& survey, const std::map<std::string, Camera>& cameras,
                               const std::vector<SingleView>& views, const Poses& poses, int f,
                               int max_iterations) {
  const std::vector<int>& observations = survey.frames[f].observations;
  std::optional<SE3d> best;
  double best_cost = std::numeric_limits<double>::infinity();
  for (int o : observations) {
    const std::optional<SE3d>& T_world_marker = poses.T_world_marker[survey.observations[o].marker];
    if (!T_world_marker || !views[o].usable) continue;
    for (const SE3d& T_robot_marker : views[o].T_robot_marker) {
      const SE3d candidate = *T_world_marker * T_robot_marker.inverse();
      double cost = 0.0;
      for (int other : observations) {
        if (!poses.T_world_marker[survey.observations[other].marker]) continue;
        cost += CandidateCost(ObservationRms(survey, cameras, poses, other, candidate,
                                             poses.T_world_marker[survey.observations[other].marker]));
      }
      if (cost < best_cost) {
        best_cost = cost;
        best = candidate;
      }
    }
  }
  if (!best) return std::nullopt;
  return RefinePose(survey, poses, observations, /*robot_varies=*/true, f, *best, max_iterations);
}

// Fills poses->T_world_marker for markers the map lacks, from the frames with a pose.
std::vector<MarkerKey> SolveMissingMarkers(const Survey& survey, const std::map<std::string, Camera>& cameras,
                                           const std::vector<SingleView>& views, int max_iterations,
                                           Poses* poses) {
  std::vector<MarkerKey> solved;
  for (size_t m = 0; m < survey.markers.size(); ++m) {
    if (poses->T_world_marker[m]) continue;
    const int marker = static_cast<int>(m);
    const std::optional<SE3d> initial =
        MarkerByConsensus(survey, cameras, views, poses->T_world_robot, marker, kCandidateScalePx);
    if (!initial) continue;
    poses->T_world_marker[m] = RefinePose(survey, *poses, survey.markers[m].observations,
                                          /*robot_varies=*/false, marker, *initial, max_iterations);
    solved.push_back(survey.markers[m].key);
  }
  return solved;
}

// Sums for one ReprojectionStats.
struct StatsAccumulator {
  double sum_sq = 0.0;
  std::vector<double> rms;
  void Add(double rms_px) {
    sum_sq += 4.0 * rms_px * rms_px;
    rms.push_back(rms_px);
  }
  ReprojectionStats Finish(const std::string& name) {
    ReprojectionStats stats;
    stats.name = name;
    stats.observations = rms.size();
    if (rms.empty()) return stats;
    stats.rms_px = std::sqrt(sum_sq / (4.0 * static_cast<double>(rms.size())));
    std::sort(rms.begin(), rms.end());
    stats.median_px = QuantileOfSorted(rms, 0.5);
    stats.max_px = rms.back();
    return stats;
  }
};

void ScoreObservations(const Survey& survey, const std::map<std::string, Camera>& cameras, const Poses& poses,
                       const std::vector<bool>& frame_scored, MapScore* score) {
  StatsAccumulator all;
  std::map<std::string, StatsAccumulator> per_camera;
  std::map<MarkerKey, StatsAccumulator> per_marker;
  for (size_t o = 0; o < survey.observations.size(); ++o) {
    const SurveyObservation& obs = survey.observations[o];
    if (!frame_scored[obs.frame]) {
      ++score->outside_frames_of;
      continue;
    }
    if (!poses.T_world_robot[obs.frame]) {
      ++score->without_pose;
      continue;
    }
    if (!poses.T_world_marker[obs.marker]) {
      ++score->without_marker;
      continue;
    }
    const std::optional<double> rms =
        ObservationRms(survey, cameras, poses, static_cast<int>(o), poses.T_world_robot[obs.frame],
                       poses.T_world_marker[obs.marker]);
    if (!rms) {
      ++score->not_projected;
      continue;
    }
    all.Add(*rms);
    per_camera[obs.camera].Add(*rms);
    per_marker[survey.markers[obs.marker].key].Add(*rms);
  }
  score->all = all.Finish("all");
  for (auto& [name, acc] : per_camera) score->per_camera.push_back(acc.Finish(name));
  for (auto& [key, acc] : per_marker) score->per_marker.push_back(acc.Finish(key.ToString()));
}

// The map with the solved markers added (component of the map's first marker, if any).
MarkerMap MapWithSolved(const Survey& survey, const MarkerMap& map, const Poses& poses,
                        const std::vector<MarkerKey>& solved) {
  MarkerMap out = map;
  for (const MarkerKey& key : solved) {
    const int m = survey.FindMarker(key);
    MapMarker marker;
    marker.key = key;
    marker.size_m = poses.size_m[m];
    marker.T_world_marker = *poses.T_world_marker[m];
    out.markers.push_back(marker);
  }
  return out;
}

std::string StatsLine(const std::string& label, const ReprojectionStats& s) {
  return "  " + label + ": RMS " + FormatFixed(s.rms_px, 3) + " px, median " + FormatFixed(s.median_px, 3) +
         " px, max " + FormatFixed(s.max_px, 3) + " px over " + std::to_string(s.observations) +
         " observations\n";
}

}  // namespace

bool MapScoreOptions::Check(std::string* why) const {
  WAYMARK_CHECK_OPTION(IsFiniteAtLeast(stamp_tolerance_s, 0.0), "stamp_tolerance_s must be finite and >= 0");
  WAYMARK_CHECK_OPTION(max_iterations >= 1, "max_iterations must be >= 1");
  return true;
}

MapScore ScoreMap(const Dataset& dataset, const MarkerMap& map,
                  const std::optional<Trajectory>& T_world_robot, const MapScoreOptions& options) {
  std::string why;
  if (!options.Check(&why)) throw std::runtime_error("map score options: " + why);
  IngestOptions ingest;
  const Survey survey = IngestDataset(dataset, ingest);
  const std::map<std::string, Camera> cameras = MakeCameras(survey);
  MapScore score;
  score.observations = survey.observations.size();
  Poses poses = MarkersFromMap(survey, map);
  std::vector<SingleView> views;
  if (!T_world_robot || options.solve_missing_markers) {
    views = ComputeSingleViews(survey, cameras, InitializerOptions().ambiguity_ratio);
  }
  if (T_world_robot) {
    poses.T_world_robot = FramesFromTrajectory(survey, *T_world_robot, options.stamp_tolerance_s);
  } else {
    poses.T_world_robot.resize(survey.frames.size());
    for (size_t f = 0; f < survey.frames.size(); ++f) {
      poses.T_world_robot[f] =
          SolveFrame(survey, cameras, views, poses, static_cast<int>(f), options.max_iterations);
      if (poses.T_world_robot[f]) ++score.frames_solved;
    }
  }
  if (options.solve_missing_markers) {
    score.solved_markers = SolveMissingMarkers(survey, cameras, views, options.max_iterations, &poses);
  }
  std::vector<bool> frame_scored(survey.frames.size(), true);
  if (options.frames_of) {
    const std::vector<std::optional<SE3d>> other =
        FramesFromTrajectory(survey, *options.frames_of, options.stamp_tolerance_s);
    for (size_t f = 0; f < other.size(); ++f) frame_scored[f] = other[f].has_value();
  }
  ScoreObservations(survey, cameras, poses, frame_scored, &score);
  score.map = MapWithSolved(survey, map, poses, score.solved_markers);
  return score;
}

LineFit FitLine(const std::vector<Eigen::Vector3d>& points) {
  if (points.size() < 2)
    throw std::invalid_argument("line fit: needs at least 2 points, got " + std::to_string(points.size()));
  LineFit fit;
  for (const Eigen::Vector3d& p : points) fit.point += p;
  fit.point /= static_cast<double>(points.size());
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (const Eigen::Vector3d& p : points) scatter += (p - fit.point) * (p - fit.point).transpose();
  if (!(scatter.trace() > 0.0)) throw std::invalid_argument("line fit: all points coincide");
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(scatter);
  fit.direction = solver.eigenvectors().col(2).normalized();  // largest eigenvalue last
  double sum_sq = 0.0;
  for (const Eigen::Vector3d& p : points) {
    const Eigen::Vector3d d = p - fit.point;
    const double distance_m = (d - d.dot(fit.direction) * fit.direction).norm();
    sum_sq += distance_m * distance_m;
    fit.max_m = std::max(fit.max_m, distance_m);
  }
  fit.rms_m = std::sqrt(sum_sq / static_cast<double>(points.size()));
  return fit;
}

std::string FormatMapScore(const MapScore& score) {
  std::ostringstream out;
  out << "observations: " << score.all.observations << " of " << score.observations << " scored ("
      << score.without_pose << " without a frame pose, " << score.without_marker
      << " of markers not in the map, " << score.not_projected << " not projected";
  if (score.outside_frames_of > 0)
    out << ", " << score.outside_frames_of << " in frames --frames-of has no pose for";
  out << ")\n";
  if (score.frames_solved > 0) out << "frames solved from the map: " << score.frames_solved << "\n";
  if (!score.solved_markers.empty()) {
    out << "markers solved with the frames held fixed:";
    for (const MarkerKey& key : score.solved_markers) out << " " << key.ToString();
    out << "\n";
  }
  out << "reprojection:\n" << StatsLine("all", score.all);
  for (const ReprojectionStats& s : score.per_camera) out << StatsLine("camera " + s.name, s);
  for (const ReprojectionStats& s : score.per_marker) out << StatsLine("marker " + s.name, s);
  return out.str();
}

}  // namespace waymark
