// Mapping bench: (1) covariance honesty, Monte Carlo over seeds: measured marker position RMS
// against the RMS the map's covariances predict, on a small anchored corridor (no alignment
// needed: the anchors fix the frame to the truth), and after alignment on the default sim
// corridor and rooms (seeds 1..N, per component, eval::PredictMapError); (2) build time against survey size
// (sim corridor loops of growing length), split into init / solve / covariance, with the solver iterations
// and the observations counted (one observation = one code's 4 corners), and per Ceres solve its iterations
// and where its time went (linear solver, Jacobian and residual evaluations).
//   bench_mapping_bench [--quick] [--seeds N] [--max-path M] [--out bench/results/mapping.json]
// Quick: 6 seeds, loop paths of 10, 40 and 160 m. Full: 24 seeds, loop paths 10 m .. 1 km
// (the 1 km loop: about 2000 codes and 150 000 corner observations); --max-path M skips longer loops.
// Prints a table and writes the JSON atomically (io/util.h).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "eval/map_metrics.h"
#include "io/util.h"
#include "mapping/map_builder.h"
#include "mapping/survey.h"
#include "sim/simulator.h"

namespace waymark {
namespace {

sim::SimResult Simulate(std::uint64_t seed, const std::vector<std::string>& settings) {
  sim::ParamSet params = sim::ScenarioParams("corridor");
  for (const std::string& s : settings) params.SetAssignment(s);
  return sim::Simulate("corridor", params, seed);
}

// Pooled ratio sqrt(sum |e|^2 / sum trace(Sigma_t)) over the non-fixed codes of every seed,
// and the same for rotation; per-seed ratios show how correlated one survey's errors are.
nlohmann::json CovarianceMonteCarlo(int seeds) {
  double e_t = 0.0, v_t = 0.0, e_r = 0.0, v_r = 0.0;
  nlohmann::json per_seed = nlohmann::json::array();
  for (int seed = 100; seed < 100 + seeds; ++seed) {
    const sim::SimResult sim =
        Simulate(seed, {"place.loop_length_m=4", "place.loop_width_m=3", "place.spacing_m=0.5"});
    const MapBuildResult result = BuildMap(sim.dataset);
    if (!result.covariance_computed)
      throw std::runtime_error("covariance not computed, seed " + std::to_string(seed));
    double seed_e = 0.0, seed_v = 0.0;
    for (const MapMarker& m : result.map.markers) {
      if (m.fixed || !m.covariance) continue;
      const MapMarker* truth = sim.dataset.groundtruth_markers->Find(m.key);
      if (truth == nullptr) continue;
      const double e2 = (m.T_world_marker.translation() - truth->T_world_marker.translation()).squaredNorm();
      const double v = m.covariance->bottomRightCorner<3, 3>().trace();
      seed_e += e2;
      seed_v += v;
      e_r += LogSO3(truth->T_world_marker.rotation().conjugate() * m.T_world_marker.rotation()).squaredNorm();
      v_r += m.covariance->topLeftCorner<3, 3>().trace();
    }
    e_t += seed_e;
    v_t += seed_v;
    per_seed.push_back(std::sqrt(seed_e / seed_v));
    std::printf("  seed %d: measured/predicted position RMS %.3f\n", seed, std::sqrt(seed_e / seed_v));
  }
  const double ratio = std::sqrt(e_t / v_t), rot_ratio = std::sqrt(e_r / v_r);
  std::printf(
      "covariance Monte Carlo over %d seeds: position ratio %.3f, rotation ratio %.3f (target 0.8..1.25)\n",
      seeds, ratio, rot_ratio);
  return {{"seeds", seeds},
          {"position_ratio", ratio},
          {"rotation_ratio", rot_ratio},
          {"per_seed_position_ratio", per_seed}};
}

// The issue's own settings, scenario defaults (sim corridor, sim rooms), seeds 1..N: the marker
// position RMS after the per-component alignment (eval/map_metrics.h) against what the map's
// covariances predict for it (eval::PredictMapError), per component: the pooled ratio
// sqrt(sum measured^2 / sum predicted^2), the mean and worst measured RMS and how many runs
// exceed 1 cm. A ratio near 1 says the error is the survey's information, not the method.
nlohmann::json AlignedPredictionMonteCarlo(const std::string& scenario, int seeds) {
  std::map<int, std::vector<std::pair<double, double>>> runs;  // component -> (measured, predicted)
  for (int seed = 1; seed <= seeds; ++seed) {
    const sim::SimResult sim = sim::Simulate(scenario, sim::ScenarioParams(scenario), seed);
    const MapBuildResult result = BuildMap(sim.dataset);
    const eval::MapEvalResult measured = eval::EvaluateMap(result.map, *sim.dataset.groundtruth_markers);
    for (const eval::PredictedComponentError& p : eval::PredictMapError(result.map)) {
      for (const eval::ComponentResult& c : measured.components) {
        if (c.component == p.component) runs[c.component].push_back({c.position_rmse_m, p.aligned_rms_m});
      }
    }
  }
  nlohmann::json report = nlohmann::json::array();
  for (const auto& [component, pairs] : runs) {
    double m2 = 0.0, p2 = 0.0, sum = 0.0, worst = 0.0;
    int over = 0;
    for (const auto& [m, p] : pairs) {
      m2 += m * m;
      p2 += p * p;
      sum += m;
      worst = std::max(worst, m);
      over += m > 0.01 ? 1 : 0;
    }
    const double n = static_cast<double>(pairs.size());
    std::printf(
        "%s component %d, %zu seeds: aligned marker RMS mean %.1f mm, worst %.1f mm, %d over 1 cm; "
        "predicted by the covariance %.1f mm RMS, measured/predicted %.3f\n",
        scenario.c_str(), component, pairs.size(), 1e3 * sum / n, 1e3 * worst, over, 1e3 * std::sqrt(p2 / n),
        std::sqrt(m2 / p2));
    report.push_back({{"scenario", scenario},
                      {"component", component},
                      {"seeds", pairs.size()},
                      {"mean_rmse_m", sum / n},
                      {"worst_rmse_m", worst},
                      {"over_1cm", over},
                      {"predicted_rmse_m", std::sqrt(p2 / n)},
                      {"measured_over_predicted", std::sqrt(m2 / p2)}});
  }
  return report;
}

// The Ceres solves of a build: iterations and seconds per stage, split into the linear solver
// and the residual / Jacobian evaluations.
nlohmann::json SolveStages(const MapBuildResult& result) {
  nlohmann::json stages = nlohmann::json::array();
  for (const SolveStageSummary& s : result.solves) {
    stages.push_back({{"stage", s.stage},
                      {"iterations", s.iterations},
                      {"total_s", s.total_s},
                      {"linear_solver_s", s.linear_solver_s},
                      {"jacobian_s", s.jacobian_s},
                      {"residual_s", s.residual_s}});
    std::printf("          %-24s %3d its %6.2f s: linear solver %5.2f, Jacobians %5.2f, residuals %5.2f\n",
                s.stage.c_str(), s.iterations, s.total_s, s.linear_solver_s, s.jacobian_s, s.residual_s);
  }
  return stages;
}

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// One corridor loop of the given path length (centre-line rectangle L x W with W = L / 3, W >=
// 2 m; 2 (L + W) = path), codes every spacing_m on both walls, mapped with 2 threads. "ingest"
// is IngestDataset (mapping/survey.h: odometry interpolation and covariances, the time-offset
// check; "offset" is what the time-offset check alone costs, measured by a second ingest
// without it); "other" is what the build does outside its timed stages (usable observations,
// reprojection summary, outputs).
nlohmann::json BuildTime(double path_m, double spacing_m) {
  const double width_m = std::max(2.0, path_m / 8.0), length_m = path_m / 2.0 - width_m;
  const sim::SimResult sim = Simulate(
      1, {"place.loop_length_m=" + std::to_string(length_m), "place.loop_width_m=" + std::to_string(width_m),
          "place.spacing_m=" + std::to_string(spacing_m)});
  MapBuildOptions options;
  options.num_threads = 2;
  IngestOptions no_offset = options.ingest;
  no_offset.estimate_time_offset = false;
  const auto no_offset_start = std::chrono::steady_clock::now();
  IngestDataset(sim.dataset, no_offset);
  const double no_offset_s = SecondsSince(no_offset_start);
  const auto start = std::chrono::steady_clock::now();
  const Survey survey = IngestDataset(sim.dataset, options.ingest);
  const double ingest_s = SecondsSince(start);
  const MapBuildResult result = BuildMapFromSurvey(survey, options);
  const double total_s = SecondsSince(start);
  const double other_s =
      total_s - ingest_s - result.init_time_s - result.solver_time_s - result.covariance_time_s;
  std::printf("%7.0f m %5.2f m %6zu %6zu %7zu %8zu %4d %8.2f %7.2f %7.2f %7.2f %7.2f %6.2f %6.2f\n", path_m,
              spacing_m, result.frames, result.map.markers.size(), result.observations,
              4 * result.observations, result.iterations, total_s, ingest_s, result.init_time_s,
              result.solver_time_s, result.covariance_time_s, other_s, std::max(0.0, ingest_s - no_offset_s));
  nlohmann::json stages = SolveStages(result);
  std::fflush(stdout);
  return {{"loop_path_m", path_m},
          {"spacing_m", spacing_m},
          {"frames", result.frames},
          {"markers", result.map.markers.size()},
          {"observations", result.observations},
          {"corner_observations", 4 * result.observations},
          {"iterations", result.iterations},
          {"threads", options.num_threads},
          {"total_s", total_s},
          {"ingest_s", ingest_s},
          {"ingest_time_offset_check_s", std::max(0.0, ingest_s - no_offset_s)},
          {"init_s", result.init_time_s},
          {"solve_s", result.solver_time_s},
          {"solves", stages},
          {"covariance_s", result.covariance_time_s},
          {"other_s", other_s},
          {"covariance_computed", result.covariance_computed},
          {"termination", result.termination}};
}

int Run(int argc, char** argv) {
  bool quick = false;
  int seeds = 0;
  double max_path_m = 1e9;
  std::string out = std::string(WAYMARK_SOURCE_DIR) + "/bench/results/mapping.json";
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--quick") == 0) {
      quick = true;
    } else if (std::strcmp(argv[i], "--seeds") == 0 && i + 1 < argc) {
      seeds = std::atoi(argv[++i]);
    } else if (std::strcmp(argv[i], "--out") == 0 && i + 1 < argc) {
      out = argv[++i];
    } else if (std::strcmp(argv[i], "--max-path") == 0 && i + 1 < argc) {
      max_path_m = std::atof(argv[++i]);
    } else {
      std::fprintf(stderr, "usage: %s [--quick] [--seeds N] [--max-path M] [--out FILE]\n", argv[0]);
      return 2;
    }
  }
  if (seeds <= 0) seeds = quick ? 6 : 24;
  nlohmann::json report = {{"quick", quick}, {"max_path_m", max_path_m}};
  report["covariance"] = CovarianceMonteCarlo(seeds);
  for (const char* scenario : {"corridor", "rooms"}) {
    for (const nlohmann::json& row : AlignedPredictionMonteCarlo(scenario, seeds))
      report["aligned_prediction"].push_back(row);
  }
  // Path lengths 10 m .. 1 km at 1 m spacing; the 1 km loop is also the large case (>= 1000
  // codes, >= 100 000 corner observations).
  const std::vector<double> paths =
      quick ? std::vector<double>{10.0, 40.0, 160.0}
            : std::vector<double>{10.0, 20.0, 40.0, 80.0, 160.0, 320.0, 640.0, 1000.0};
  std::printf(
      "build time, 2 threads (offset: the ingest's time-offset check)\n"
      "   path spacing frames  codes     obs  corners  its    total  ingest    init   solve   covar  other "
      "offset\n");
  for (double path_m : paths) {
    if (path_m <= max_path_m) report["build_time"].push_back(BuildTime(path_m, 1.0));
  }
  AtomicWriteFile(out, report.dump(1) + "\n");
  std::printf("wrote %s\n", out.c_str());
  return 0;
}

}  // namespace
}  // namespace waymark

int main(int argc, char** argv) {
  try {
    return waymark::Run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mapping_bench: %s\n", e.what());
    return 1;
  }
}
