#include "mapping/range_bearing_map.h"

#include <ceres/ceres.h>
#include <ceres/covariance.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <set>
#include <stdexcept>

#include "factors/calibrated_odometry_factor.h"
#include "factors/pose_prior_se2_factor.h"
#include "factors/range_bearing_factor.h"
#include "geometry/pose.h"
#include "mapping/marginal_covariance.h"
#include "mapping/serial_blas.h"
#include "util/check.h"
#include "util/format.h"
#include "util/stats.h"

namespace waymark {

bool RangeBearingBuildOptions::Check(std::string* why) const {
  WAYMARK_CHECK_OPTION(IsFinitePositive(keyframe_interval_s), "keyframe_interval_s must be > 0");
  WAYMARK_CHECK_OPTION(IsFinitePositive(window_s), "window_s must be > 0");
  WAYMARK_CHECK_OPTION(IsFinitePositive(cauchy_scale), "cauchy_scale must be > 0");
  WAYMARK_CHECK_OPTION(IsFinitePositive(outlier_chi2), "outlier_chi2 must be > 0");
  WAYMARK_CHECK_OPTION(min_observations >= 1, "min_observations must be >= 1");
  WAYMARK_CHECK_OPTION(noise_rounds >= 0, "noise_rounds must be >= 0");
  WAYMARK_CHECK_OPTION(IsFinitePositive(noise_window_s), "noise_window_s must be > 0");
  WAYMARK_CHECK_OPTION(IsFinitePositive(calibration_sigma), "calibration_sigma must be > 0");
  WAYMARK_CHECK_OPTION(IsFiniteAtLeast(sensor_depth_share_sigma, 0.0),
                       "sensor_depth_share_sigma must be >= 0");
  WAYMARK_CHECK_OPTION(IsFiniteAtLeast(sensor_range_scale_sigma, 0.0),
                       "sensor_range_scale_sigma must be >= 0");
  WAYMARK_CHECK_OPTION(IsFiniteAtLeast(max_odometry_delay_s, 0.0) && max_odometry_delay_s <= 10.0,
                       "max_odometry_delay_s must be in [0, 10]");
  WAYMARK_CHECK_OPTION(IsFinitePositive(odometry_delay_step_s), "odometry_delay_step_s must be > 0");
  WAYMARK_CHECK_OPTION(IsFinitePositive(calibration_time_step_s) &&
                           IsFiniteAtLeast(calibration_time_max_lag_s, calibration_time_step_s),
                       "calibration_time_step_s must be > 0 and calibration_time_max_lag_s >= it");
  WAYMARK_CHECK_OPTION(max_iterations >= 1, "max_iterations must be >= 1");
  WAYMARK_CHECK_OPTION(num_threads >= 1, "num_threads must be >= 1");
  const RangeBearingNoise& n = initial_noise;
  WAYMARK_CHECK_OPTION(IsFinitePositive(n.range_a_m) && IsFiniteAtLeast(n.range_b, 0.0) &&
                           IsFinitePositive(n.bearing_rad) && IsFinitePositive(n.odometry_q_t) &&
                           IsFinitePositive(n.odometry_q_r) && IsFiniteAtLeast(n.odometry_c_d, 0.0),
                       "initial_noise: sigmas and q must be finite and > 0 (range_b, c_d >= 0)");
  return true;
}

bool HasRangeBearing(const std::vector<const Dataset*>& datasets) {
  for (const Dataset* dataset : datasets) {
    if (dataset->has_range_bearing_file || !dataset->range_bearing.empty()) return true;
  }
  return false;
}

namespace {

constexpr double kLinkFloorM = 1e-3;    // d0 of the header
constexpr double kLinkFloorRad = 1e-3;  // th0
constexpr int kMinRangeBinCount = 30;
constexpr double kDelayTestChi2 = 3.841;          // chi-square, 1 dof, 95 %
constexpr double kNormal975 = 1.959963984540054;  // the standard normal's 97.5 % quantile

// The parameter blocks (`block`, `calibration`, `sensor`) point into the Builder's one buffer
// (Builder::AllocateBlocks).
struct Node {
  double stamp_s = 0.0;
  SE2d T_odom_robot;
  double* block = nullptr;  // x, y, theta
  SE2d Pose() const { return SE2d(block[0], block[1], block[2]); }
  void Set(const SE2d& T) {
    block[0] = T.x();
    block[1] = T.y();
    block[2] = T.theta();
  }
};

struct Observation {
  size_t dataset = 0, node = 0;
  MarkerKey key;
  double range_m = 0.0, bearing_rad = 0.0;
  std::optional<double> sigma_range_m, sigma_bearing_rad;
  bool outlier = false;
  bool range_outlier = false;  // its range set aside, its bearing kept (not an `outlier`)
};

struct Landmark {
  double* block = nullptr;  // x, y
  bool placed = false;
  int count = 0;
};

struct DatasetState {
  const Dataset* dataset = nullptr;
  std::vector<Node> nodes;
  double* calibration = nullptr;  // 3 (factors/calibrated_odometry_factor.h)
  // Range offset, bearing offset, bearing scale, depth share, range scale
  // (factors/range_bearing_factor.h).
  double* sensor = nullptr;
  RangeBearingNoise noise;  // this dataset's own, estimated in stage (2)
  double delay_s = 0.0;     // the odometry's lag (stage 2b); nodes' T_odom_robot use it
  bool placed = false;      // nodes have world poses
  size_t active = 0;        // nodes [0, active) are in the problem
  RangeBearingDatasetSummary summary;
};

// T_odom_robot at `stamp_s`, interpolated in SE(2) between the surrounding odometry samples.
SE2d OdometryAt(const Trajectory& odometry, double stamp_s) {
  const std::optional<SE3d> T = InterpolateTrajectory(odometry, stamp_s, 1e9);
  if (!T) throw std::runtime_error("odometry does not cover stamp " + FormatDouble(stamp_s));
  return SE2d::FromSE3(*T);
}

// The measured increment corrected by the calibration c (factors/calibrated_odometry_factor.h).
SE2d CorrectedIncrement(const SE2d& M, const double* c) {
  const double s = M.translation().norm();
  const double theta_c = (M.theta() - c[0] * s) / (1.0 + c[1]);
  const double half = 0.5 * (theta_c - M.theta());
  const Eigen::Vector2d t = Eigen::Rotation2Dd(half) * M.translation() / (1.0 + c[2]);
  return SE2d(t.x(), t.y(), theta_c);
}

Eigen::Matrix3d LinkCovariance(const SE2d& M, double dt_s, const RangeBearingNoise& noise) {
  (void)dt_s;
  const double d = M.translation().norm();
  const double var_t = noise.odometry_q_t * (d + kLinkFloorM);
  const double var_r = noise.odometry_q_r * (std::abs(M.theta()) + noise.odometry_c_d * d + kLinkFloorRad);
  return Eigen::Vector3d(var_t, var_t, var_r).asDiagonal();
}

double SigmaRange(const Observation& obs, const RangeBearingNoise& noise) {
  return obs.sigma_range_m ? *obs.sigma_range_m : noise.range_a_m + noise.range_b * obs.range_m;
}
double SigmaBearing(const Observation& obs, const RangeBearingNoise& noise) {
  return obs.sigma_bearing_rad ? *obs.sigma_bearing_rad : noise.bearing_rad;
}

// Range and bearing of `p_world` from `T_world_robot`.
Eigen::Vector2d Predict(const SE2d& T_world_robot, const Eigen::Vector2d& p_world) {
  const Eigen::Vector2d p =
      T_world_robot.rotation_matrix().transpose() * (p_world - T_world_robot.translation());
  return Eigen::Vector2d(p.norm(), std::atan2(p.y(), p.x()));
}

// Residual [range error, wrapped bearing error] of an observation at the current state.
Eigen::Vector2d Error(const Observation& obs, const std::vector<DatasetState>& states,
                      const std::map<MarkerKey, Landmark>& landmarks) {
  const Landmark& l = landmarks.at(obs.key);
  const DatasetState& state = states[obs.dataset];
  const Eigen::Vector2d predicted =
      Predict(state.nodes[obs.node].Pose(), Eigen::Vector2d(l.block[0], l.block[1]));
  return Eigen::Vector2d(
      SensedRange(predicted[0], predicted[1], state.sensor) + state.sensor[0] - obs.range_m,
      WrapAngle((1.0 + state.sensor[2]) * predicted[1] + state.sensor[1] - obs.bearing_rad));
}

// The range sigma line and the bearing sigma from residuals (the header's stage 2); false (and
// `noise` unchanged) when there are too few.
bool FitMeasurementNoise(std::vector<std::pair<double, double>> range_errors,
                         std::vector<double> bearing_errors, RangeBearingNoise* noise);

// The range sigma line a + b r by least squares through (range, sigma) points (a bin each), its
// intercept kept >= 1 cm and its slope >= 0.
void FitSigmaLine(const std::vector<double>& x, const std::vector<double>& y, RangeBearingNoise* noise);

// The 97.5 % quantile of Student's t with `dof` >= 1 degrees of freedom (a table to 30, then the
// first two terms of its expansion about the normal quantile).
double StudentT975(int dof) {
  static const double kTable[] = {12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228,
                                  2.201,  2.179, 2.160, 2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086,
                                  2.080,  2.074, 2.069, 2.064, 2.060, 2.056, 2.052, 2.048, 2.045, 2.042};
  if (dof <= 30) return kTable[std::max(dof, 1) - 1];
  const double z = kNormal975;
  return z + (z * z * z + z) / (4.0 * dof);
}

// Rigid 2-D fit dst ~ R src + t (Kabsch); needs >= 2 points.
SE2d FitRigid2D(const std::vector<Eigen::Vector2d>& src, const std::vector<Eigen::Vector2d>& dst) {
  Eigen::Vector2d mean_src = Eigen::Vector2d::Zero(), mean_dst = Eigen::Vector2d::Zero();
  for (size_t i = 0; i < src.size(); ++i) {
    mean_src += src[i];
    mean_dst += dst[i];
  }
  mean_src /= static_cast<double>(src.size());
  mean_dst /= static_cast<double>(dst.size());
  double sxx = 0.0, sxy = 0.0;
  for (size_t i = 0; i < src.size(); ++i) {
    const Eigen::Vector2d a = src[i] - mean_src, b = dst[i] - mean_dst;
    sxx += a.dot(b);
    sxy += a.x() * b.y() - a.y() * b.x();
  }
  const double theta = std::atan2(sxy, sxx);
  const Eigen::Vector2d t = mean_dst - Eigen::Rotation2Dd(theta) * mean_src;
  return SE2d(t.x(), t.y(), theta);
}

class Builder {
 public:
  Builder(const std::vector<const Dataset*>& datasets, const RangeBearingBuildOptions& options)
      : options_(options), noise_(options.initial_noise) {
    for (size_t k = 0; k < datasets.size(); ++k) Ingest(k, *datasets[k]);
    AllocateBlocks();
    for (DatasetState& state : states_) PlaceByStartPrior(&state);
  }

  RangeBearingBuildResult Run();

 private:
  void Ingest(size_t k, const Dataset& dataset);
  // Every parameter block in `parameters_`, zeroed, in a fixed order: per dataset its odometry
  // calibration, sensor and nodes, then the landmarks by key. Ceres starts its fill-reducing
  // ordering from the blocks' address order, so blocks placed by the allocator (per-dataset
  // vectors, map nodes) made the solve's rounding, and the map's last digits, vary from run to run.
  void AllocateBlocks();
  void PlaceByStartPrior(DatasetState* state);
  void Progress(const std::string& line) const {
    if (options_.progress) options_.progress(line);
  }
  // Extends every dataset's active nodes to stamps <= end_s, placing what is new.
  void Activate(double end_s);
  bool TryPlace(DatasetState* state, double end_s);
  void PlaceLandmarks();
  // With `covariance`: also the mapped landmarks' covariance (stage 3b) at the solution.
  struct ProblemBlocks {
    std::vector<std::vector<ceres::ResidualBlockId>> per_dataset;  // each dataset's residuals
    std::vector<ceres::ResidualBlockId> observation;  // per observation (nullptr: not in the problem)
  };
  // The problem over the active nodes (Cauchy loss on the observations when `robust`).
  void BuildProblem(bool robust, ceres::Problem* problem, ProblemBlocks* blocks);
  double Solve(bool robust, bool covariance = false);
  void LandmarkCovariance(ceres::Problem* problem);
  size_t MarkOutliers();
  // The odometry's q always; the measurement sigmas (robust spreads) when `measurement_sigmas`.
  void EstimateNoise(bool measurement_sigmas);
  // False (nothing changed) when H is singular.
  bool EstimateNoiseByRedundancy();
  void SetDelay(DatasetState* state, double delay_s);
  void EstimateDelays();
  void EstimateRangeScale();
  void NoiseRound(int round);
  RangeBearingBuildResult Collect();
  RangeBearingSensorModel SensorModel(const std::vector<RangeBearingDatasetSummary>& datasets) const;

  RangeBearingBuildOptions options_;
  RangeBearingNoise noise_;
  std::vector<DatasetState> states_;
  std::vector<Observation> observations_;
  std::map<MarkerKey, Landmark> landmarks_;
  std::vector<double> parameters_;  // never resized after AllocateBlocks: the blocks' addresses are fixed
  double solver_time_s_ = 0.0;
  std::vector<std::string> notes_;
  std::vector<double> dataset_cost_;  // each dataset's share of the last Solve's cost
  std::map<MarkerKey, Eigen::Matrix2d> landmark_covariance_;
  std::map<MarkerKey, Eigen::Matrix<double, 2, Eigen::Dynamic>> landmark_factor_;
};

void Builder::Ingest(size_t k, const Dataset& dataset) {
  const std::string& name = dataset.config.name;
  if (dataset.config.motion != MotionModel::kPlanar)
    throw std::runtime_error(name + ": range-bearing maps need motion: planar");
  if (dataset.odometry.size() < 2)
    throw std::runtime_error(name + ": range-bearing maps need odometry (at least 2 poses)");
  DatasetState state;
  state.dataset = &dataset;
  state.noise = options_.initial_noise;
  state.summary.name = name;
  const Trajectory& odometry = dataset.odometry;
  const double t_first = odometry.front().stamp_s, t_last = odometry.back().stamp_s;
  std::vector<double> stamps;
  for (double t = t_first; t < t_last; t += options_.keyframe_interval_s) stamps.push_back(t);
  stamps.push_back(t_last);
  for (const RangeBearingFrame& frame : dataset.range_bearing) {
    if (frame.stamp_s >= t_first && frame.stamp_s <= t_last && !frame.landmarks.empty())
      stamps.push_back(frame.stamp_s);
  }
  std::sort(stamps.begin(), stamps.end());
  stamps.erase(std::unique(stamps.begin(), stamps.end()), stamps.end());
  for (const double t : stamps) {
    Node node;
    node.stamp_s = t;
    node.T_odom_robot = OdometryAt(odometry, t);  // delay 0 until stage (2b)
    state.nodes.push_back(node);
  }
  for (const RangeBearingFrame& frame : dataset.range_bearing) {
    if (frame.stamp_s < t_first || frame.stamp_s > t_last) continue;
    const size_t node =
        static_cast<size_t>(std::lower_bound(stamps.begin(), stamps.end(), frame.stamp_s) - stamps.begin());
    for (const RangeBearingObservation& rb : frame.landmarks) {
      Observation obs;
      obs.dataset = k;
      obs.node = node;
      obs.key = rb.key;
      obs.range_m = rb.elevation_rad ? rb.range_m * std::cos(*rb.elevation_rad) : rb.range_m;
      obs.bearing_rad = rb.bearing_rad;
      obs.sigma_range_m = rb.sigma_range_m;
      obs.sigma_bearing_rad = rb.sigma_bearing_rad;
      observations_.push_back(obs);
      ++landmarks_[rb.key].count;
    }
  }
  states_.push_back(std::move(state));
}

void Builder::AllocateBlocks() {
  size_t size = 2 * landmarks_.size();
  for (const DatasetState& state : states_) size += 3 + kRangeBearingSensorSize + 3 * state.nodes.size();
  parameters_.assign(size, 0.0);
  double* next = parameters_.data();
  const auto take = [&next](size_t count) {
    double* block = next;
    next += count;
    return block;
  };
  for (DatasetState& state : states_) {
    state.calibration = take(3);
    state.sensor = take(kRangeBearingSensorSize);
    for (Node& node : state.nodes) node.block = take(3);
  }
  for (auto& [key, landmark] : landmarks_) landmark.block = take(2);
}

void Builder::PlaceByStartPrior(DatasetState* state) {
  const auto& prior = state->dataset->config.start_prior;
  if (!options_.use_start_priors || !prior) return;
  const SE2d T_world_start = SE2d::FromSE3(prior->T_world_robot);
  const SE2d T_world_odom = T_world_start * state->nodes.front().T_odom_robot.inverse();
  state->nodes.front().Set(T_world_odom * state->nodes.front().T_odom_robot);
  state->placed = true;
  state->summary.gauge = "start prior";
}

bool Builder::TryPlace(DatasetState* state, double end_s) {
  // Dead-reckoned landmark positions (mean of the first sightings) in the dataset's odometry frame.
  std::map<MarkerKey, std::pair<Eigen::Vector2d, int>> seen;
  const size_t k = static_cast<size_t>(state - states_.data());
  for (const Observation& obs : observations_) {
    if (obs.dataset != k || state->nodes[obs.node].stamp_s > end_s) continue;
    const Landmark& l = landmarks_.at(obs.key);
    if (!l.placed) continue;
    const SE2d& T = state->nodes[obs.node].T_odom_robot;
    const Eigen::Vector2d p =
        T * Eigen::Vector2d(obs.range_m * std::cos(obs.bearing_rad), obs.range_m * std::sin(obs.bearing_rad));
    auto& [sum, count] = seen[obs.key];
    if (count == 0) sum.setZero();
    sum += p;
    ++count;
  }
  std::vector<Eigen::Vector2d> src, dst;
  for (const auto& [key, sum_count] : seen) {
    src.push_back(sum_count.first / sum_count.second);
    const Landmark& l = landmarks_.at(key);
    dst.push_back(Eigen::Vector2d(l.block[0], l.block[1]));
  }
  if (src.size() < 2) return false;
  const SE2d T_world_odom = FitRigid2D(src, dst);
  state->nodes.front().Set(T_world_odom * state->nodes.front().T_odom_robot);
  state->placed = true;
  state->summary.gauge = "placed by " + std::to_string(src.size()) +
                         " shared landmarks at t=" + FormatFixed(end_s - state->nodes.front().stamp_s, 1) +
                         " s";
  return true;
}

void Builder::Activate(double end_s) {
  for (size_t k = 0; k < states_.size(); ++k) {
    DatasetState& state = states_[k];
    if (!state.placed) {
      if (k == 0) {
        state.nodes.front().Set(SE2d());
        state.placed = true;
        state.summary.gauge = "first node held at the identity";
      } else if (!TryPlace(&state, end_s)) {
        continue;
      }
    }
    if (state.active == 0) state.active = 1;
    while (state.active < state.nodes.size() && state.nodes[state.active].stamp_s <= end_s) {
      const Node& previous = state.nodes[state.active - 1];
      Node& node = state.nodes[state.active];
      const SE2d M = previous.T_odom_robot.inverse() * node.T_odom_robot;
      node.Set(previous.Pose() * CorrectedIncrement(M, state.calibration));
      ++state.active;
    }
  }
  PlaceLandmarks();
}

void Builder::PlaceLandmarks() {
  for (const Observation& obs : observations_) {
    const DatasetState& state = states_[obs.dataset];
    if (obs.node >= state.active) continue;
    Landmark& l = landmarks_.at(obs.key);
    if (l.placed) continue;
    const Eigen::Vector2d p =
        state.nodes[obs.node].Pose() *
        Eigen::Vector2d(obs.range_m * std::cos(obs.bearing_rad), obs.range_m * std::sin(obs.bearing_rad));
    l.block[0] = p.x();
    l.block[1] = p.y();
    l.placed = true;
  }
}

void Builder::BuildProblem(bool robust, ceres::Problem* problem, ProblemBlocks* blocks) {
  bool any_prior = false;
  blocks->per_dataset.assign(states_.size(), {});
  blocks->observation.assign(observations_.size(), nullptr);
  for (size_t k = 0; k < states_.size(); ++k) {
    DatasetState& state = states_[k];
    if (state.active == 0) continue;
    for (size_t i = 0; i < state.active; ++i) problem->AddParameterBlock(state.nodes[i].block, 3);
    bool links = false;
    for (size_t i = 1; i < state.active; ++i) {
      const Node& a = state.nodes[i - 1];
      const Node& b = state.nodes[i];
      const SE2d M = a.T_odom_robot.inverse() * b.T_odom_robot;
      blocks->per_dataset[k].push_back(problem->AddResidualBlock(
          CalibratedOdometrySE2Factor::Create(M, LinkCovariance(M, b.stamp_s - a.stamp_s, state.noise),
                                              options_.odometry_measurement_space),
          nullptr, state.nodes[i - 1].block, state.nodes[i].block, state.calibration));
      links = true;
    }
    if (links) {
      blocks->per_dataset[k].push_back(problem->AddResidualBlock(
          OdometryCalibrationPrior::Create(Eigen::Vector3d::Constant(options_.calibration_sigma)), nullptr,
          state.calibration));
    }
    const auto& prior = state.dataset->config.start_prior;
    if (options_.use_start_priors && prior) {
      const Eigen::Vector3d sigma(prior->sigma_m, prior->sigma_m, prior->sigma_rad);
      problem->AddResidualBlock(PosePriorSE2Factor::Create(SE2d::FromSE3(prior->T_world_robot),
                                                           Eigen::Matrix3d(sigma.cwiseAbs2().asDiagonal())),
                                nullptr, state.nodes.front().block);
      any_prior = true;
    }
  }
  if (!any_prior) problem->SetParameterBlockConstant(states_.front().nodes.front().block);
  for (size_t o = 0; o < observations_.size(); ++o) {
    const Observation& obs = observations_[o];
    if (obs.outlier || obs.node >= states_[obs.dataset].active) continue;
    Landmark& l = landmarks_.at(obs.key);
    DatasetState& state = states_[obs.dataset];
    ceres::LossFunction* loss = robust ? new ceres::CauchyLoss(options_.cauchy_scale) : nullptr;
    if (obs.range_outlier) {
      blocks->observation[o] = problem->AddResidualBlock(
          BiasedBearingFactor::Create(obs.range_m, obs.bearing_rad, SigmaRange(obs, state.noise),
                                      SigmaBearing(obs, state.noise)),
          loss, state.nodes[obs.node].block, l.block, state.sensor);
    } else {
      blocks->observation[o] = problem->AddResidualBlock(
          BiasedRangeBearingFactor::Create(obs.range_m, obs.bearing_rad, SigmaRange(obs, state.noise),
                                           SigmaBearing(obs, state.noise)),
          loss, state.nodes[obs.node].block, l.block, state.sensor);
    }
    blocks->per_dataset[obs.dataset].push_back(blocks->observation[o]);
  }
  for (DatasetState& state : states_) {
    if (problem->HasParameterBlock(state.sensor)) {
      problem->AddResidualBlock(
          SensorBiasPrior::Create(
              options_.sensor_bias_sigma_m, options_.sensor_bias_sigma_rad,
              options_.sensor_bearing_scale_sigma,
              options_.sensor_depth_share_sigma > 0.0 ? options_.sensor_depth_share_sigma : 1.0,
              options_.sensor_range_scale_sigma > 0.0 ? options_.sensor_range_scale_sigma : 1.0),
          nullptr, state.sensor);
      std::vector<int> held;
      if (!(options_.sensor_depth_share_sigma > 0.0)) held.push_back(3);
      if (!(options_.sensor_range_scale_sigma > 0.0)) held.push_back(4);
      if (!held.empty())
        problem->SetManifold(state.sensor, new ceres::SubsetManifold(kRangeBearingSensorSize, held));
    }
  }
}

double Builder::Solve(bool robust, bool covariance) {
  ceres::Problem::Options problem_options;
  problem_options.loss_function_ownership = ceres::TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  ProblemBlocks problem_blocks;
  BuildProblem(robust, &problem, &problem_blocks);
  const std::vector<std::vector<ceres::ResidualBlockId>>& blocks = problem_blocks.per_dataset;
  ceres::Solver::Options solver_options;
  solver_options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  solver_options.max_num_iterations = options_.max_iterations;
  solver_options.num_threads = options_.num_threads;
  solver_options.function_tolerance = 1e-8;
  ceres::Solver::Summary summary;
  const auto start = std::chrono::steady_clock::now();
  {
    const ScopedSerialLinearAlgebra serial;  // the same result at any load
    ceres::Solve(solver_options, &problem, &summary);
  }
  solver_time_s_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (covariance) LandmarkCovariance(&problem);
  dataset_cost_.assign(states_.size(), 0.0);
  for (size_t k = 0; k < states_.size(); ++k) {
    if (blocks[k].empty()) continue;
    ceres::Problem::EvaluateOptions evaluate;
    evaluate.residual_blocks = blocks[k];
    evaluate.num_threads = options_.num_threads;
    problem.Evaluate(evaluate, &dataset_cost_[k], nullptr, nullptr, nullptr);
  }
  return summary.final_cost;
}

// Stage (3b), header. Landmarks with fewer than min_observations inlier sightings are in H but
// get no covariance (they are not mapped).
void Builder::LandmarkCovariance(ceres::Problem* problem) {
  landmark_covariance_.clear();
  landmark_factor_.clear();
  std::map<MarkerKey, int> inliers;
  for (const Observation& obs : observations_) {
    if (!obs.outlier && obs.node < states_[obs.dataset].active) ++inliers[obs.key];
  }
  std::vector<MarkerKey> keys;
  std::vector<const double*> blocks;
  for (const auto& [key, landmark] : landmarks_) {
    if (inliers[key] < options_.min_observations || !problem->HasParameterBlock(landmark.block)) continue;
    keys.push_back(key);
    blocks.push_back(landmark.block);
  }
  if (keys.empty()) return;
  MarginalCovarianceOptions covariance_options;
  covariance_options.num_threads = options_.num_threads;
  const ScopedSerialLinearAlgebra serial;
  const InformationFactor information(problem, blocks, covariance_options);
  if (!information.positive_definite()) {
    notes_.push_back("landmark covariance: the problem's information is singular (no covariance written)");
    return;
  }
  const int n = static_cast<int>(keys.size());
  if (n > options_.max_joint_covariance_landmarks) {
    const std::vector<Eigen::MatrixXd> marginals = information.Marginals();
    for (int i = 0; i < n; ++i) landmark_covariance_[keys[i]] = marginals[i];
    notes_.push_back("landmark covariance: " + std::to_string(n) + " landmarks, more than " +
                     std::to_string(options_.max_joint_covariance_landmarks) +
                     ": marginals only, no joint factor");
    return;
  }
  Eigen::MatrixXd B = Eigen::MatrixXd::Zero(information.size(), 2 * n);
  for (int i = 0; i < n; ++i) {
    const int first = information.FirstColumn(blocks[i]);
    B(first, 2 * i) = 1.0;
    B(first + 1, 2 * i + 1) = 1.0;
  }
  const Eigen::MatrixXd X = information.Solve(B);  // H^-1 B
  Eigen::MatrixXd sigma = B.transpose() * X;
  sigma = 0.5 * (sigma + sigma.transpose()).eval();
  for (int i = 0; i < n; ++i) landmark_covariance_[keys[i]] = sigma.block<2, 2>(2 * i, 2 * i);
  const int k = std::min(options_.covariance_rank, 2 * n);
  if (k <= 0) return;
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(sigma);
  if (eigen.info() != Eigen::Success) return;
  // Eigenvalues ascending: the last k columns, largest first.
  Eigen::MatrixXd F(2 * n, k);
  for (int c = 0; c < k; ++c) {
    const int j = 2 * n - 1 - c;
    F.col(c) = eigen.eigenvectors().col(j) * std::sqrt(std::max(0.0, eigen.eigenvalues()[j]));
  }
  for (int i = 0; i < n; ++i) landmark_factor_[keys[i]] = F.middleRows(2 * i, 2);
}

size_t Builder::MarkOutliers() {
  size_t outliers = 0;
  for (Observation& obs : observations_) {
    const Eigen::Vector2d e = Error(obs, states_, landmarks_);
    const RangeBearingNoise& noise = states_[obs.dataset].noise;
    const double range_chi2 = std::pow(e[0] / SigmaRange(obs, noise), 2);
    const double bearing_chi2 = std::pow(e[1] / SigmaBearing(obs, noise), 2);
    if (options_.separate_range_outliers) {
      obs.outlier = bearing_chi2 > options_.outlier_chi2_1dof;
      obs.range_outlier = !obs.outlier && range_chi2 > options_.outlier_chi2_1dof;
    } else {
      obs.outlier = range_chi2 + bearing_chi2 > options_.outlier_chi2;
    }
    outliers += obs.outlier;
  }
  return outliers;
}

bool FitMeasurementNoise(std::vector<std::pair<double, double>> range_errors,
                         std::vector<double> bearing_errors, RangeBearingNoise* noise) {
  if (range_errors.size() < 2 * kMinRangeBinCount) return false;
  // Bins of equal count along the range; sigma of each bin = 1.4826 MAD; a line through them by
  // least squares, its intercept kept >= 1 cm and its slope >= 0.
  std::sort(range_errors.begin(), range_errors.end());
  const size_t bins = std::min<size_t>(8, range_errors.size() / kMinRangeBinCount);
  std::vector<double> x, y;
  for (size_t b = 0; b < bins; ++b) {
    const size_t begin = b * range_errors.size() / bins, end = (b + 1) * range_errors.size() / bins;
    std::vector<double> errors, ranges;
    for (size_t i = begin; i < end; ++i) {
      errors.push_back(range_errors[i].second);
      ranges.push_back(range_errors[i].first);
    }
    const double median = Median(errors);
    for (double& e : errors) e = std::abs(e - median);
    x.push_back(Median(ranges));
    y.push_back(1.4826 * Median(errors));
  }
  FitSigmaLine(x, y, noise);
  const double median = Median(bearing_errors);
  for (double& e : bearing_errors) e = std::abs(e - median);
  noise->bearing_rad = std::max(1e-3, 1.4826 * Median(bearing_errors));
  return true;
}

void FitSigmaLine(const std::vector<double>& x, const std::vector<double>& y, RangeBearingNoise* noise) {
  const double n = static_cast<double>(x.size());
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (size_t i = 0; i < x.size(); ++i) {
    sx += x[i];
    sy += y[i];
    sxx += x[i] * x[i];
    sxy += x[i] * y[i];
  }
  const double denominator = n * sxx - sx * sx;
  double b = denominator > 1e-12 ? std::max(0.0, (n * sxy - sx * sy) / denominator) : 0.0;
  double a = (sy - b * sx) / n;
  if (a < 0.01) {  // refit the slope through the floor
    a = 0.01;
    b = sxx > 0 ? std::max(0.0, (sxy - a * sx) / sxx) : 0.0;
  }
  noise->range_a_m = a;
  noise->range_b = b;
}

// The header's stage (2), per dataset (a dataset with too few residuals takes the pooled
// figures): measurement sigmas from the robust spread of every observation's residuals, the
// odometry's q from its disagreement with the solved trajectory over noise_window_s.
void Builder::EstimateNoise(bool measurement_sigmas) {
  std::vector<std::vector<std::pair<double, double>>> range_errors(states_.size());
  std::vector<std::vector<double>> bearing_errors(states_.size());
  std::vector<std::pair<double, double>> all_range;
  std::vector<double> all_bearing;
  // Every observation: the robust spread ignores the outliers, and leaving them out would
  // truncate the distribution (and shrink the sigmas round after round).
  for (const Observation& obs : observations_) {
    if (obs.node >= states_[obs.dataset].active) continue;
    const Eigen::Vector2d e = Error(obs, states_, landmarks_);
    range_errors[obs.dataset].emplace_back(obs.range_m, e[0]);
    bearing_errors[obs.dataset].push_back(e[1]);
    all_range.emplace_back(obs.range_m, e[0]);
    all_bearing.push_back(e[1]);
  }
  if (measurement_sigmas) FitMeasurementNoise(all_range, all_bearing, &noise_);
  // Odometry: over windows of noise_window_s, the solved increment against the calibrated
  // odometry increment; the mean normalized squared error per axis scales q_t and q_r.
  std::vector<double> sum_t(states_.size(), 0.0), sum_r(states_.size(), 0.0);
  std::vector<long> windows(states_.size(), 0);
  for (size_t k = 0; k < states_.size(); ++k) {
    DatasetState& state = states_[k];
    size_t i = 0;
    while (i + 1 < state.active) {
      size_t j = i + 1;
      double var_t = 0.0, var_r = 0.0;
      SE2d odometry_increment;
      while (true) {
        const SE2d M = state.nodes[j - 1].T_odom_robot.inverse() * state.nodes[j].T_odom_robot;
        const Eigen::Matrix3d covariance = LinkCovariance(M, 0.0, state.noise);
        var_t += covariance(0, 0);
        var_r += covariance(2, 2);
        odometry_increment = odometry_increment * CorrectedIncrement(M, state.calibration);
        if (j + 1 >= state.active ||
            state.nodes[j].stamp_s - state.nodes[i].stamp_s >= options_.noise_window_s)
          break;
        ++j;
      }
      const SE2d solved = state.nodes[i].Pose().inverse() * state.nodes[j].Pose();
      const SE2d error = odometry_increment.inverse() * solved;
      sum_t[k] += error.translation().squaredNorm() / (2.0 * var_t);
      sum_r[k] += error.theta() * error.theta() / var_r;
      ++windows[k];
      i = j;
    }
  }
  for (size_t k = 0; k < states_.size(); ++k) {
    DatasetState& state = states_[k];
    if (measurement_sigmas && !FitMeasurementNoise(range_errors[k], bearing_errors[k], &state.noise)) {
      state.noise.range_a_m = noise_.range_a_m;
      state.noise.range_b = noise_.range_b;
      state.noise.bearing_rad = noise_.bearing_rad;
    }
    if (windows[k] >= 10) {
      state.noise.odometry_q_t *= std::clamp(sum_t[k] / windows[k], 1e-3, 1e3);
      state.noise.odometry_q_r *= std::clamp(sum_r[k] / windows[k], 1e-3, 1e3);
    }
  }
  // The map's odometry figures: the median over the datasets.
  std::vector<double> q_t, q_r;
  for (const DatasetState& state : states_) {
    q_t.push_back(state.noise.odometry_q_t);
    q_r.push_back(state.noise.odometry_q_r);
  }
  noise_.odometry_q_t = Median(q_t);
  noise_.odometry_q_r = Median(q_r);
}

// The header's stage (2), measurement sigmas, from the second round on (redundancy_noise):
// variance components. At the solution of the problem with the squared loss, every observation's
// residual row r (whitened, r_w) has a leverage h_r = J_r H^-1 J_r^T (mapping/marginal_covariance.h,
// exact, from the selected inverse) and a redundancy u_r = 1 - h_r: the poses, landmarks and
// sensor offsets fitted to the data absorb the share h_r of that row's noise, so E[r_w^2] = u_r
// when the row's sigma is right. The robust spreads of EstimateNoise ignore this and come out too
// small (a node seen once has its heading fitted to that very bearing). Each group's variance is
// re-estimated as
//   sigma^2 = sum_r (r_w sigma_r)^2 / sum_r u_r           (Helmert's estimate; a step of REML)
// per dataset: the bearing sigma; the range sigma in up to 8 equal-count range bins (the line
// a + b r through them, as in EstimateNoise). The inliers only (outliers are not in the problem;
// a range outlier's bearing row counts). A group whose redundancy sums to less than 10 keeps its
// figure; a dataset with too few range rows takes the pooled line. The odometry's q stays with
// EstimateNoise's windows (its variance components, tried, made q_t six times larger and every
// trajectory worse: docs/accuracy.md, MRCLAM).
bool Builder::EstimateNoiseByRedundancy() {
  ceres::Problem::Options problem_options;
  problem_options.loss_function_ownership = ceres::TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  ProblemBlocks blocks;
  BuildProblem(false, &problem, &blocks);
  MarginalCovarianceOptions covariance_options;
  covariance_options.num_threads = options_.num_threads;
  const ScopedSerialLinearAlgebra serial;
  const InformationFactor information(&problem, {}, covariance_options);
  if (!information.positive_definite()) return false;
  std::vector<ceres::ResidualBlockId> ids;
  for (const ceres::ResidualBlockId id : blocks.observation) {
    if (id != nullptr) ids.push_back(id);
  }
  std::vector<double> residuals;
  ceres::CRSMatrix J;
  if (!ResidualJacobian(&problem, ids, options_.num_threads, &residuals, &J)) return false;
  const std::vector<double> leverage = information.Leverages(J);
  struct Sums {
    double squares = 0.0, redundancy = 0.0;
    void Add(double square, double h) {
      squares += square;
      redundancy += 1.0 - h;
    }
  };
  struct Row {
    double range, square, h;
  };
  const size_t n = states_.size();
  std::vector<std::vector<Row>> range_rows(n);
  std::vector<Row> all_range_rows;
  std::vector<Sums> bearing(n);
  Sums all_bearing;
  size_t row = 0;
  for (size_t o = 0; o < observations_.size(); ++o) {
    if (blocks.observation[o] == nullptr) continue;
    const Observation& obs = observations_[o];
    const RangeBearingNoise& noise = states_[obs.dataset].noise;
    if (!obs.range_outlier) {
      const double e = residuals[row] * SigmaRange(obs, noise);
      range_rows[obs.dataset].push_back({obs.range_m, e * e, leverage[row]});
      all_range_rows.push_back(range_rows[obs.dataset].back());
      ++row;
    }
    const double e = residuals[row] * SigmaBearing(obs, noise);
    bearing[obs.dataset].Add(e * e, leverage[row]);
    all_bearing.Add(e * e, leverage[row]);
    ++row;
  }
  constexpr double kMinRedundancy = 10.0;
  // The range line through bins of equal count: each bin's sigma from its rows.
  const auto fit_range = [&](std::vector<Row> rows, RangeBearingNoise* noise) {
    if (rows.size() < 2 * kMinRangeBinCount) return false;
    std::sort(rows.begin(), rows.end(), [](const Row& a, const Row& b) { return a.range < b.range; });
    const size_t bins = std::min<size_t>(8, rows.size() / kMinRangeBinCount);
    std::vector<double> x, y;
    for (size_t b = 0; b < bins; ++b) {
      const size_t begin = b * rows.size() / bins, end = (b + 1) * rows.size() / bins;
      Sums sums;
      std::vector<double> ranges;
      for (size_t i = begin; i < end; ++i) {
        sums.Add(rows[i].square, rows[i].h);
        ranges.push_back(rows[i].range);
      }
      if (sums.redundancy < 0.1 * static_cast<double>(end - begin)) continue;
      x.push_back(Median(ranges));
      y.push_back(std::sqrt(sums.squares / sums.redundancy));
    }
    if (x.size() < 2) return false;
    FitSigmaLine(x, y, noise);
    return true;
  };
  const auto sigma = [&](const Sums& sums, double* value) {
    if (sums.redundancy >= kMinRedundancy) *value = std::max(1e-4, std::sqrt(sums.squares / sums.redundancy));
  };
  fit_range(all_range_rows, &noise_);
  sigma(all_bearing, &noise_.bearing_rad);
  for (size_t k = 0; k < n; ++k) {
    DatasetState& state = states_[k];
    if (!fit_range(range_rows[k], &state.noise)) {
      state.noise.range_a_m = noise_.range_a_m;
      state.noise.range_b = noise_.range_b;
    }
    if (bearing[k].redundancy >= kMinRedundancy)
      sigma(bearing[k], &state.noise.bearing_rad);
    else
      state.noise.bearing_rad = noise_.bearing_rad;
  }
  return true;
}

void Builder::NoiseRound(int round) {
  // Round 0 starts from the incremental solve's state, outliers not yet marked: the robust spreads.
  const bool by_redundancy = round > 0 && options_.redundancy_noise && EstimateNoiseByRedundancy();
  EstimateNoise(!by_redundancy);
  const size_t outliers = MarkOutliers();
  Solve(true);
  Progress("noise round " + std::to_string(round + 1) + ": sigma_range " +
           FormatSignificant(noise_.range_a_m, 3) + " m + " + FormatSignificant(noise_.range_b, 3) +
           " r, sigma_bearing " + FormatSignificant(noise_.bearing_rad, 3) + " rad, q_t " +
           FormatSignificant(noise_.odometry_q_t, 3) + ", q_r " + FormatSignificant(noise_.odometry_q_r, 3) +
           ", " + std::to_string(outliers) + " outliers");
}

void Builder::SetDelay(DatasetState* state, double delay_s) {
  state->delay_s = delay_s;
  const Trajectory& odometry = state->dataset->odometry;
  for (Node& node : state->nodes) {
    // Held at the odometry's ends beyond them.
    const double stamp_s =
        std::clamp(node.stamp_s - delay_s, odometry.front().stamp_s, odometry.back().stamp_s);
    node.T_odom_robot = OdometryAt(odometry, stamp_s);
  }
}

// Stage (2b): the profile of each dataset's own cost (its odometry links and observations, the
// noise held) over delays on a grid of odometry_delay_step_s in [-max, max], every dataset shifted
// by the same grid delay and the problem re-solved from the last solution; each dataset's delay is
// its grid minimum refined by a parabola through it and its two neighbours, kept only when a
// likelihood-ratio test prefers it to no delay. The map's delay is
// the median of the datasets'.
void Builder::EstimateDelays() {
  const double step = options_.odometry_delay_step_s, max = options_.max_odometry_delay_s;
  const int half = static_cast<int>(std::floor(max / step + 1e-9));
  if (half < 1) return;
  std::vector<double> grid;
  for (int i = -half; i <= half; ++i) grid.push_back(i * step);
  std::vector<std::vector<double>> cost(states_.size(), std::vector<double>(grid.size(), 0.0));
  for (size_t g = 0; g < grid.size(); ++g) {
    for (DatasetState& state : states_) SetDelay(&state, grid[g]);
    Solve(true);
    for (size_t k = 0; k < states_.size(); ++k) cost[k][g] = dataset_cost_[k];
  }
  std::vector<double> delays;
  for (size_t k = 0; k < states_.size(); ++k) {
    const std::vector<double>& c = cost[k];
    const size_t best = static_cast<size_t>(std::min_element(c.begin(), c.end()) - c.begin());
    double delay = grid[best];
    // A likelihood-ratio test against no delay (1 degree of freedom, 95 %: 2 delta cost > 3.84):
    // a delay the data do not call for (e.g. motion at constant velocity) stays 0.
    if (2.0 * (c[static_cast<size_t>(half)] - c[best]) <= kDelayTestChi2) {
      delay = 0.0;
    } else if (best > 0 && best + 1 < grid.size()) {
      const double curvature = c[best - 1] - 2.0 * c[best] + c[best + 1];
      if (curvature > 0.0) delay += 0.5 * step * (c[best - 1] - c[best + 1]) / curvature;
    }
    SetDelay(&states_[k], delay);
    delays.push_back(delay);
    Progress(states_[k].summary.name + ": odometry delay " + FormatFixed(delay, 3) + " s");
  }
  noise_.odometry_delay_s = Median(delays);
  Solve(true);
}

// Stage (4): the range error common to a frame's landmarks, from the final residuals of each
// dataset's frames with two or more inlier landmarks: u = range residual / range per
// observation, m_f its mean over frame f (k_f observations), w the pooled within-frame variance
// of u; the common part's variance sigma_s^2 = var(m_f) - mean(w / k_f); its correlation between
// consecutive such frames (dt apart, at most 2 s), rho = cov(m_f, m_g) / sigma_s^2, gives the
// correlation time tau = mean(dt) / -ln(rho) (rho clamped to [0.01, 0.99]). The map's: the median
// over the datasets that have at least 30 such frames (none: no common part).
void Builder::EstimateRangeScale() {
  std::vector<double> sigmas, times;
  for (size_t k = 0; k < states_.size(); ++k) {
    std::map<size_t, std::vector<double>> frames;
    for (const Observation& obs : observations_) {
      if (obs.dataset != k || obs.outlier || obs.range_outlier || obs.node >= states_[k].active ||
          obs.range_m <= 0.0)
        continue;
      frames[obs.node].push_back(Error(obs, states_, landmarks_)[0] / obs.range_m);
    }
    std::vector<std::pair<double, double>> means;  // (stamp, m_f)
    double within_sum = 0.0, within_dof = 0.0, within_over_k = 0.0;
    std::vector<size_t> sizes;
    for (const auto& [node, u] : frames) {
      if (u.size() < 2) continue;
      double mean = 0.0;
      for (const double v : u) mean += v;
      mean /= static_cast<double>(u.size());
      for (const double v : u) within_sum += (v - mean) * (v - mean);
      within_dof += static_cast<double>(u.size() - 1);
      means.emplace_back(states_[k].nodes[node].stamp_s, mean);
      sizes.push_back(u.size());
    }
    if (means.size() < 30) continue;
    const double within = within_sum / within_dof;
    double grand = 0.0;
    for (const auto& m : means) grand += m.second;
    grand /= static_cast<double>(means.size());
    double var_m = 0.0;
    for (size_t i = 0; i < means.size(); ++i) {
      var_m += (means[i].second - grand) * (means[i].second - grand);
      within_over_k += within / static_cast<double>(sizes[i]);
    }
    var_m /= static_cast<double>(means.size() - 1);
    const double var_s = var_m - within_over_k / static_cast<double>(means.size());
    if (!(var_s > 0.0)) {
      sigmas.push_back(0.0);
      continue;
    }
    double cov = 0.0, dt = 0.0;
    long pairs = 0;
    for (size_t i = 1; i < means.size(); ++i) {
      const double gap = means[i].first - means[i - 1].first;
      if (gap > 2.0) continue;
      cov += (means[i].second - grand) * (means[i - 1].second - grand);
      dt += gap;
      ++pairs;
    }
    sigmas.push_back(std::sqrt(var_s));
    if (pairs >= 10) {
      const double rho = std::clamp(cov / pairs / var_s, 0.01, 0.99);
      times.push_back(dt / pairs / -std::log(rho));
    }
    states_[k].noise.range_scale_sigma = sigmas.back();
    if (pairs >= 10) states_[k].noise.range_scale_time_s = times.back();
  }
  if (!sigmas.empty()) noise_.range_scale_sigma = Median(sigmas);
  if (!times.empty()) noise_.range_scale_time_s = Median(times);
}

RangeBearingBuildResult Builder::Run() {
  double t_begin = std::numeric_limits<double>::infinity(), t_end = -t_begin;
  for (const DatasetState& state : states_) {
    t_begin = std::min(t_begin, state.nodes.front().stamp_s);
    t_end = std::max(t_end, state.nodes.back().stamp_s);
  }
  // (1) growing windows.
  for (double end_s = t_begin + options_.window_s;; end_s += options_.window_s) {
    Activate(end_s);
    Solve(true);
    Progress("window to t=" + FormatFixed(end_s - t_begin, 0) + " s solved");
    if (end_s >= t_end) break;
  }
  for (const DatasetState& state : states_) {
    if (!state.placed) {
      throw std::runtime_error(
          state.summary.name +
          ": shares fewer than two landmarks with the other datasets and has no start prior: "
          "it cannot be placed in their map");
    }
  }
  // (2) outliers and noise; (2b) the odometry's delay, then one more round of (2) with it.
  for (int round = 0; round < options_.noise_rounds; ++round) NoiseRound(round);
  if (options_.max_odometry_delay_s > 0.0) {
    EstimateDelays();
    if (options_.noise_rounds > 0) NoiseRound(options_.noise_rounds);
  }
  // (3) final.
  MarkOutliers();
  Solve(false, options_.landmark_covariance);
  MarkOutliers();
  EstimateRangeScale();
  return Collect();
}

RangeBearingBuildResult Builder::Collect() {
  RangeBearingBuildResult result;
  result.noise = noise_;
  result.map.range_bearing_noise = noise_;
  result.solver_time_s = solver_time_s_;
  std::map<MarkerKey, int> inliers;
  double sum_range = 0.0, sum_bearing = 0.0;
  for (const Observation& obs : observations_) {
    DatasetState& state = states_[obs.dataset];
    if (obs.outlier) {
      ++state.summary.outliers;
      ++result.outliers;
      continue;
    }
    ++inliers[obs.key];
    ++state.summary.observations;
    ++result.observations;
    const Eigen::Vector2d e = Error(obs, states_, landmarks_);
    if (obs.range_outlier) {
      ++state.summary.range_outliers;
      ++result.range_outliers;
    } else {
      sum_range += e[0] * e[0];
    }
    sum_bearing += e[1] * e[1];
  }
  if (result.observations > result.range_outliers)
    result.range_rms_m = std::sqrt(sum_range / (result.observations - result.range_outliers));
  if (result.observations > 0) {
    result.bearing_rms_rad = std::sqrt(sum_bearing / result.observations);
  }
  for (const auto& [key, landmark] : landmarks_) {
    const int count = inliers.count(key) ? inliers.at(key) : 0;
    if (count < options_.min_observations) {
      result.unmapped.emplace_back(key, "seen " + std::to_string(count) + " times (inliers), fewer than " +
                                            std::to_string(options_.min_observations));
      continue;
    }
    MapMarker marker;
    marker.is_point = true;
    marker.key = key;
    marker.T_world_marker =
        SE3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(landmark.block[0], landmark.block[1], 0.0));
    marker.component = 0;
    if (const auto c = landmark_covariance_.find(key); c != landmark_covariance_.end()) {
      marker.position_covariance = Eigen::Matrix3d::Zero();
      marker.position_covariance->topLeftCorner<2, 2>() = c->second;
      if (const auto f = landmark_factor_.find(key); f != landmark_factor_.end()) {
        // map.json position_covariance_factor: the translation rows of covariance_factor (x, y; z 0).
        marker.covariance_factor = CovarianceFactor::Zero(6, f->second.cols());
        marker.covariance_factor->middleRows<2>(3) = f->second;
      }
    }
    result.map.markers.push_back(marker);
  }
  for (DatasetState& state : states_) {
    Trajectory trajectory;
    for (size_t i = 0; i < state.active; ++i) {
      trajectory.push_back({state.nodes[i].stamp_s, state.nodes[i].Pose().ToSE3()});
    }
    state.summary.nodes = state.active;
    state.summary.odometry_calibration =
        Eigen::Vector3d(state.calibration[0], state.calibration[1], state.calibration[2]);
    state.summary.sensor_bias = Eigen::Vector2d(state.sensor[0], state.sensor[1]);
    state.summary.bearing_scale = state.sensor[2];
    state.summary.depth_share = state.sensor[3];
    state.summary.range_scale = state.sensor[4];
    state.summary.noise = state.noise;
    state.summary.noise.odometry_delay_s = state.delay_s;
    result.trajectories[state.summary.name] = std::move(trajectory);
    result.datasets.push_back(state.summary);
  }
  result.map.range_bearing_sensor = SensorModel(result.datasets);
  result.notes = notes_;
  return result;
}

// map.json range_bearing_sensor (the header's "Sensor model"): each dataset's values and noise,
// and the prior for a robot not in the map.
RangeBearingSensorModel Builder::SensorModel(const std::vector<RangeBearingDatasetSummary>& datasets) const {
  RangeBearingSensorModel model;
  model.depth_ranges = options_.sensor_depth_share_sigma > 0.0 || options_.sensor_range_scale_sigma > 0.0;
  std::vector<RangeBearingSensorValues> values;
  for (const RangeBearingDatasetSummary& summary : datasets) {
    RangeBearingSensorModel::Dataset dataset;
    dataset.name = summary.name;
    dataset.values.range_offset_m = summary.sensor_bias[0];
    dataset.values.bearing_offset_rad = summary.sensor_bias[1];
    dataset.values.bearing_scale = summary.bearing_scale;
    dataset.values.depth_share = summary.depth_share;
    dataset.values.range_scale = summary.range_scale;
    dataset.values.odometry_calibration = summary.odometry_calibration;
    dataset.noise = summary.noise;
    model.datasets.push_back(dataset);
    values.push_back(dataset.values);
  }
  // One entry: mean over the datasets; sigma the spread of a new draw from them (the Student-t
  // predictive interval, header), at most the build's own prior sigma; the build's prior sigma
  // with fewer than two datasets; 0 for an entry the build held (it is held in the EKF too).
  const auto entry = [&](const std::function<double(const RangeBearingSensorValues&)>& get,
                         double build_sigma, double* mean, double* sigma) {
    const double n = static_cast<double>(values.size());
    *mean = 0.0;
    for (const RangeBearingSensorValues& v : values) *mean += get(v) / n;
    if (!(build_sigma > 0.0)) {
      *mean = 0.0;
      *sigma = 0.0;
      return;
    }
    if (values.size() < 2) {
      *sigma = build_sigma;
      return;
    }
    double squares = 0.0;
    for (const RangeBearingSensorValues& v : values) squares += (get(v) - *mean) * (get(v) - *mean);
    const double t = StudentT975(static_cast<int>(values.size()) - 1);
    *sigma = std::min(build_sigma, std::sqrt(squares / (n - 1.0) * (1.0 + 1.0 / n)) * t / kNormal975);
  };
  RangeBearingSensorValues& m = model.prior_mean;
  RangeBearingSensorValues& sd = model.prior_sigma;
  entry([](const auto& v) { return v.range_offset_m; }, options_.sensor_bias_sigma_m, &m.range_offset_m,
        &sd.range_offset_m);
  entry([](const auto& v) { return v.bearing_offset_rad; }, options_.sensor_bias_sigma_rad,
        &m.bearing_offset_rad, &sd.bearing_offset_rad);
  entry([](const auto& v) { return v.bearing_scale; }, options_.sensor_bearing_scale_sigma, &m.bearing_scale,
        &sd.bearing_scale);
  entry([](const auto& v) { return v.depth_share; }, options_.sensor_depth_share_sigma, &m.depth_share,
        &sd.depth_share);
  entry([](const auto& v) { return v.range_scale; }, options_.sensor_range_scale_sigma, &m.range_scale,
        &sd.range_scale);
  for (int i = 0; i < 3; ++i) {
    entry([i](const auto& v) { return v.odometry_calibration[i]; }, options_.calibration_sigma,
          &m.odometry_calibration[i], &sd.odometry_calibration[i]);
  }
  return model;
}

}  // namespace

RangeBearingBuildResult BuildRangeBearingMap(const std::vector<const Dataset*>& datasets,
                                             const RangeBearingBuildOptions& options) {
  std::string why;
  if (!options.Check(&why)) throw std::invalid_argument("range-bearing map build: " + why);
  if (datasets.empty()) throw std::runtime_error("range-bearing map build: no dataset");
  std::set<std::string> names;
  for (const Dataset* dataset : datasets) {
    if (!names.insert(dataset->config.name).second)
      throw std::runtime_error("two datasets are named " + dataset->config.name + " (dataset.yaml name)");
  }
  Builder builder(datasets, options);
  RangeBearingBuildResult result = builder.Run();
  if (options.calibration_time) {
    // Stage (5): every dataset's smoothed trajectory against its odometry, in the datasets' order.
    std::vector<std::vector<TurnStep>> turns;
    for (const Dataset* dataset : datasets) {
      const auto trajectory = result.trajectories.find(dataset->config.name);
      const auto summary =
          std::find_if(result.datasets.begin(), result.datasets.end(),
                       [&](const RangeBearingDatasetSummary& s) { return s.name == dataset->config.name; });
      if (trajectory == result.trajectories.end() || summary == result.datasets.end()) continue;
      turns.push_back(TurnSteps(trajectory->second, dataset->odometry, summary->noise.odometry_delay_s,
                                options.calibration_time_step_s));
    }
    CalibrationTimeOptions fit_options;
    fit_options.step_s = options.calibration_time_step_s;
    fit_options.max_lag_s = options.calibration_time_max_lag_s;
    result.calibration_time = FitTurnScaleCorrelation(turns, fit_options);
    if (result.calibration_time.fitted && result.map.range_bearing_sensor) {
      result.map.range_bearing_sensor->calibration_time = RangeBearingSensorModel::CalibrationTime{
          result.calibration_time.time_s, result.calibration_time.sigma};
    }
  }
  return result;
}

}  // namespace waymark
