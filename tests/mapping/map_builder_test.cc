// Map learning on simulated surveys with exact ground truth (sim/), measured with eval/.
#include "mapping/map_builder.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <set>

#include "eval/map_metrics.h"
#include "eval/trajectory_eval.h"
#include "mapping/build_report.h"
#include "sim/simulator.h"
#include "tests/heap_shuffle.h"

namespace waymark {
namespace {

using testing::BitIdentical;
using testing::ShuffleTheHeap;

sim::SimResult Simulate(const std::string& scenario, std::uint64_t seed,
                        const std::vector<std::string>& settings = {}) {
  sim::ParamSet params = sim::ScenarioParams(scenario);
  for (const std::string& s : settings) params.SetAssignment(s);
  return sim::Simulate(scenario, params, seed);
}

double TrajectoryAte(const MapBuildResult& result, const Dataset& dataset) {
  eval::TrajectoryEvalOptions options;
  return eval::EvaluateTrajectory(*dataset.groundtruth_trajectory, result.trajectory, std::nullopt, options)
      .ate.translation_m.rmse;
}

TEST(MapBuilderTest, CorridorReachesCentimetreTargets) {
  const sim::SimResult sim = Simulate("corridor", 1);
  MapBuildOptions options;
  const MapBuildResult result = BuildMap(sim.dataset, options);
  std::cerr << FormatBuildSummary(result);
  ASSERT_EQ(result.components.size(), 1u);
  const eval::MapEvalResult map_error = eval::EvaluateMap(result.map, *sim.dataset.groundtruth_markers);
  EXPECT_EQ(map_error.missing_in_groundtruth.size(), 0u);
  EXPECT_LE(map_error.position_rmse_m, 0.01);
  EXPECT_LE(TrajectoryAte(result, sim.dataset), 0.01);
  // Gauss-Newton-like steps from the first iteration (map_builder.cc, kInitialTrustRegionRadius):
  // with Ceres' default trust region this survey took 24 iterations, 16 of them in the final
  // solve, creeping along the loop's drift modes.
  ASSERT_FALSE(result.solves.empty());
  EXPECT_EQ(result.solves.back().stage, "final");
  EXPECT_LE(result.solves.back().iterations, 4);
  EXPECT_LE(result.iterations, 12);
  std::cerr << "marker RMS " << map_error.position_rmse_m << " m, ATE " << TrajectoryAte(result, sim.dataset)
            << " m\n";
}

// The Schur solves (no odometry; a camera's per-frame wiggle) eliminate the parameter blocks in
// the order of their addresses (Ceres keeps an elimination group as std::set<double*>), and the
// rounding of a solve follows that order. The blocks live in one buffer in a fixed order
// (mapping/global_problem.h), so the map does not depend on where the allocator puts things:
// before, two builds of this survey with the heap in different states differed in their last
// bits (the sanitizer build showed it as MapCliTest.BuildIsTheSameAtAnyLoad failing).
TEST(MapBuilderTest, BuildDoesNotDependOnWhereTheHeapPutsItsBlocks) {
  sim::SimResult sim =
      Simulate("corridor", 5, {"place.loop_length_m=4", "place.loop_width_m=3", "place.spacing_m=0.5"});
  sim.dataset.odometry.clear();
  sim.dataset.has_odometry_file = false;
  sim.dataset.config.odometry_sigma.reset();
  for (auto& [name, camera] : sim.dataset.cameras)
    camera.frame_wiggle_sigma = std::array<double, 2>{0.01, 0.01};
  MapBuildOptions options;
  options.compute_covariance = false;
  const MapBuildResult first = BuildMap(sim.dataset, options);
  ASSERT_GT(first.map.markers.size(), 10u);
  for (std::uint64_t seed = 1; seed <= 2; ++seed) {
    ShuffleTheHeap(seed);
    const MapBuildResult again = BuildMap(sim.dataset, options);
    ASSERT_EQ(again.map.markers.size(), first.map.markers.size());
    for (size_t m = 0; m < first.map.markers.size(); ++m)
      EXPECT_TRUE(BitIdentical(first.map.markers[m].T_world_marker, again.map.markers[m].T_world_marker))
          << "heap " << seed << ", " << first.map.markers[m].key.ToString();
    ASSERT_EQ(again.trajectory.size(), first.trajectory.size());
    size_t differ = 0;
    for (size_t f = 0; f < first.trajectory.size(); ++f)
      differ += BitIdentical(first.trajectory[f].T, again.trajectory[f].T) ? 0 : 1;
    EXPECT_EQ(differ, 0u) << "heap " << seed;
  }
}

TEST(MapBuilderTest, RoomsGiveOneComponentPerConnectedGroup) {
  const sim::SimResult sim = Simulate("rooms", 3);
  std::set<int> true_components;
  for (const MapMarker& m : sim.dataset.groundtruth_markers->markers) {
    if (m.component) true_components.insert(*m.component);
  }
  const MapBuildResult result = BuildMap(sim.dataset);
  std::cerr << FormatBuildSummary(result);
  EXPECT_EQ(result.components.size(), true_components.size());
  const eval::MapEvalResult map_error = eval::EvaluateMap(result.map, *sim.dataset.groundtruth_markers);
  ASSERT_EQ(map_error.components.size(), true_components.size());
  for (const eval::ComponentResult& c : map_error.components) {
    EXPECT_LE(c.position_rmse_m, 0.01) << "component " << c.component;
    std::cerr << "component " << c.component << ": marker RMS " << c.position_rmse_m << " m\n";
  }
  // One smoothed trajectory per component, each pose in its own component's frame.
  ASSERT_EQ(result.trajectories.size(), result.components.size());
  for (const ComponentSummary& c : result.components) {
    EXPECT_GT(result.trajectories[c.component].size(), 0u);
    EXPECT_EQ(result.trajectories[c.component].size(), c.trajectory_poses);
  }
  EXPECT_EQ(result.trajectory.size(), result.trajectories[0].size());
  // The carry shows as an odometry gap, reported.
  EXPECT_TRUE(std::any_of(result.notes.begin(), result.notes.end(),
                          [](const std::string& n) { return n.find("odometry: gap") != std::string::npos; }));
}

// The odometry calibration a build prints: the true values of the sim's wheel errors
// (sim/motion.cc: unequal wheel radii bend straight runs, the nominal track width scales turns).
struct TrueWheelCalibration {
  double k_rad_per_m = 0.0;
  double turn_scale = 0.0;
};
TrueWheelCalibration TrueCalibration(const std::string& scenario) {
  const sim::ParamSet p = sim::ScenarioParams(scenario);
  const double left = 1.0 + p.Double("odometry.wheel_radius_error_left");
  const double right = 1.0 + p.Double("odometry.wheel_radius_error_right");
  const double nominal_track_m =
      p.Double("robot.track_width_m") * (1.0 + p.Double("odometry.track_width_error"));
  return {(1.0 / right - 1.0 / left) / nominal_track_m,
          1.0 / (1.0 + p.Double("odometry.track_width_error")) - 1.0};
}

// A loop survey estimates the wheel errors (reported with sigmas); a survey of rooms joined by
// doors barely sees them (codes only at the ends of each 4 m crossing: on seed 1 its own estimate
// is 1.8 sigma off in heading drift and component 0 is 18 mm off), and reaches the centimetre
// with the loop's estimate as its prior. Held as given, the calibration is reported unchanged.
TEST(MapBuilderTest, OdometryCalibrationFromOneSurveyServesAnother) {
  const TrueWheelCalibration truth = TrueCalibration("corridor");
  const MapBuildResult loop = BuildMap(Simulate("corridor", 1).dataset);
  ASSERT_TRUE(loop.odometry_calibration && loop.odometry_calibration_covariance);
  EXPECT_FALSE(loop.odometry_calibration_given);
  const Eigen::Vector3d c = *loop.odometry_calibration;
  const Eigen::Vector3d sigma = loop.odometry_calibration_covariance->diagonal().cwiseSqrt();
  std::cerr << FormatOdometryCalibration(loop) << "\n";
  EXPECT_NEAR(c[0], truth.k_rad_per_m, 4.0 * sigma[0]);
  EXPECT_NEAR(c[1], truth.turn_scale, 4.0 * sigma[1]);
  EXPECT_NEAR(c[2], 0.0, 4.0 * sigma[2]);
  EXPECT_LT(sigma[0], 0.1 * truth.k_rad_per_m);
  EXPECT_NE(FormatOdometryCalibration(loop).find("--odometry-calibration "), std::string::npos);

  const sim::SimResult rooms = Simulate("rooms", 1);
  MapBuildOptions options;
  options.odometry_calibration = c;
  options.odometry_calibration_sigma = sigma;
  const MapBuildResult with_prior = BuildMap(rooms.dataset, options);
  ASSERT_TRUE(with_prior.odometry_calibration && with_prior.odometry_calibration_covariance);
  EXPECT_FALSE(with_prior.odometry_calibration_given);
  // The rooms' look-arounds measure the turn scale better than the loop's four corners.
  EXPECT_LT(std::sqrt((*with_prior.odometry_calibration_covariance)(1, 1)), sigma[1]);
  const eval::MapEvalResult error = eval::EvaluateMap(with_prior.map, *rooms.dataset.groundtruth_markers);
  ASSERT_EQ(error.components.size(), 2u);
  for (const eval::ComponentResult& component : error.components) {
    EXPECT_LE(component.position_rmse_m, 0.01) << "component " << component.component;
  }

  options.odometry_calibration_sigma.reset();
  const MapBuildResult held = BuildMap(rooms.dataset, options);
  ASSERT_TRUE(held.odometry_calibration);
  EXPECT_TRUE(held.odometry_calibration_given);
  EXPECT_EQ(*held.odometry_calibration, c);
  EXPECT_FALSE(held.odometry_calibration_covariance);
  EXPECT_NE(FormatOdometryCalibration(held).find("(given)"), std::string::npos);

  options.calibrate_odometry = false;
  EXPECT_THROW(BuildMap(rooms.dataset, options), std::runtime_error);
  options.calibrate_odometry = true;
  options.odometry_calibration = Eigen::Vector3d(0.0, -1.0, 0.0);
  EXPECT_THROW(BuildMap(rooms.dataset, options), std::runtime_error);
  options.odometry_calibration.reset();
  options.odometry_calibration_sigma = Eigen::Vector3d::Constant(0.01);
  EXPECT_THROW(BuildMap(rooms.dataset, options), std::runtime_error);
}

// Covariance against Monte Carlo: a small corridor whose anchors fix the frame to the truth, so
// the error needs no alignment and is comparable to the covariance. The errors of one survey
// are strongly correlated (the whole map drifts away from its anchors together), so a few
// seeds give a noisy ratio: 0.67 on these 4 seeds, 0.72 on seeds 10..17, 1.03 on seeds
// 100..129 (bench/mapping_bench.cc runs the >= 20-seed figure). This test only guards against
// a gross error of the covariance (0.5..1.5 on 4 seeds).
TEST(MapBuilderTest, CovarianceMatchesMonteCarloSpread) {
  double squared_error = 0.0, predicted_variance = 0.0;
  long n = 0;
  for (std::uint64_t seed = 10; seed < 14; ++seed) {
    const sim::SimResult sim =
        Simulate("corridor", seed, {"place.loop_length_m=4", "place.loop_width_m=3", "place.spacing_m=0.5"});
    const MapBuildResult result = BuildMap(sim.dataset);
    ASSERT_TRUE(result.covariance_computed);
    for (const MapMarker& m : result.map.markers) {
      if (m.fixed) continue;
      const MapMarker* truth = sim.dataset.groundtruth_markers->Find(m.key);
      ASSERT_NE(truth, nullptr);
      squared_error += (m.T_world_marker.translation() - truth->T_world_marker.translation()).squaredNorm();
      predicted_variance += m.covariance->bottomRightCorner<3, 3>().trace();
      ++n;
    }
  }
  const double ratio = std::sqrt(squared_error / predicted_variance);
  std::cerr << "measured / predicted position RMS over " << n << " codes: " << ratio << "\n";
  EXPECT_GT(ratio, 0.5);
  EXPECT_LT(ratio, 1.5);
}

// 10 % misdecoded ids (half random text, half another code's id): the map stays within 20 % of
// the clean run's marker RMS (mean over seeds; each seed's own noise differs between the two
// runs) and the swapped views are reported as outliers by code.
TEST(MapBuilderTest, MisdecodedIdsAreSetAsideAndReported) {
  double clean_sum = 0.0, misdecoded_sum = 0.0;
  for (std::uint64_t seed = 1; seed <= 3; ++seed) {
    const sim::SimResult clean = Simulate("corridor", seed);
    const sim::SimResult bad = Simulate("corridor", seed, {"detect.misdecode_fraction=0.1"});
    const MapBuildResult clean_result = BuildMap(clean.dataset);
    const MapBuildResult bad_result = BuildMap(bad.dataset);
    clean_sum += eval::EvaluateMap(clean_result.map, *clean.dataset.groundtruth_markers).position_rmse_m;
    const eval::MapEvalResult bad_error = eval::EvaluateMap(bad_result.map, *bad.dataset.groundtruth_markers);
    misdecoded_sum += bad_error.position_rmse_m;
    EXPECT_EQ(bad_error.missing_in_groundtruth.size(), 0u) << "a misread id was mapped, seed " << seed;
    EXPECT_EQ(bad_result.components.size(), 1u);
    const size_t id_outliers =
        std::count_if(bad_result.outliers.begin(), bad_result.outliers.end(),
                      [](const auto& o) { return o.reason.find("misdecoded?") != std::string::npos; });
    EXPECT_GE(id_outliers, static_cast<size_t>(0.8 * bad.stats.misdecoded)) << "seed " << seed;
    EXPECT_NE(FormatBuildSummary(bad_result).find("by code:"), std::string::npos);
  }
  std::cerr << "mean marker RMS clean " << clean_sum / 3 << " m, 10 % misdecoded " << misdecoded_sum / 3
            << " m\n";
  EXPECT_LE(misdecoded_sum, 1.2 * clean_sum);
}

}  // namespace
}  // namespace waymark
