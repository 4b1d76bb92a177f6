// Initialization at scale: one sim corridor loop (the settings of bench/mapping_bench.cc's
// BuildTime: centre-line rectangle L x W, W = max(2, path / 8), 2 (L + W) = path, codes every
// spacing_m on both walls, seed 1), then
//   (1) the initialization alone (mapping/initializer.h): time, codes placed, their position
//       error against the truth after a per-component alignment (eval/map_metrics.h), the worst
//       code and the codes more than 10 cm off;
//   (2) the full build from that initialization (OptimizeSurvey): codes mapped, marker RMS
//       against the truth, solver iterations, solve and covariance time.
//   bench_mapping_init_bench [--path M] [--spacing M] [--seed N] [--threads N] [--init-only]
//                            [--from-truth] [--out FILE]
// --from-truth starts (2) from the true frame and code poses instead (the anchors put the map in
// the truth's frame): a build that lands on the same map from both starts is at the optimum of
// its cost, and what error remains is the survey's information, not the initialization.
// Default: the 1 km loop (about 2000 codes, 33 000 frames), 1 thread. Prints the figures and,
// with --out, writes them as JSON atomically (io/util.h).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "eval/map_metrics.h"
#include "io/util.h"
#include "mapping/id_consistency.h"
#include "mapping/map_builder.h"
#include "sim/simulator.h"

namespace waymark {
namespace {

struct Settings {
  double path_m = 1000.0;
  double spacing_m = 1.0;
  std::uint64_t seed = 1;
  int threads = 1;
  bool init_only = false;
  bool from_truth = false;
  std::string out;
};

double Seconds(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

sim::SimResult SimulateLoop(const Settings& s) {
  const double width_m = std::max(2.0, s.path_m / 8.0), length_m = s.path_m / 2.0 - width_m;
  sim::ParamSet params = sim::ScenarioParams("corridor");
  params.SetAssignment("place.loop_length_m=" + std::to_string(length_m));
  params.SetAssignment("place.loop_width_m=" + std::to_string(width_m));
  params.SetAssignment("place.spacing_m=" + std::to_string(s.spacing_m));
  return sim::Simulate("corridor", params, s.seed);
}

// `init` with every placed frame and code moved to its true pose.
Initialization AtTruth(const sim::SimResult& sim, const Survey& survey, Initialization init) {
  for (size_t f = 0; f < survey.frames.size(); ++f) {
    if (init.T_world_robot[f]) {
      init.T_world_robot[f] =
          InterpolateTrajectory(*sim.dataset.groundtruth_trajectory, survey.frames[f].stamp_s, 1.0);
    }
  }
  for (size_t m = 0; m < survey.markers.size(); ++m) {
    const MapMarker* truth = sim.dataset.groundtruth_markers->Find(survey.markers[m].key);
    if (init.T_world_marker[m] && truth != nullptr) init.T_world_marker[m] = truth->T_world_marker;
  }
  return init;
}

// The placed codes of an initialization as a map (component numbers kept).
MarkerMap InitialMap(const Survey& survey, const Initialization& init) {
  MarkerMap map;
  for (size_t m = 0; m < survey.markers.size(); ++m) {
    if (!init.T_world_marker[m]) continue;
    MapMarker marker;
    marker.key = survey.markers[m].key;
    marker.size_m = survey.markers[m].size_m;
    marker.T_world_marker = *init.T_world_marker[m];
    marker.component = init.marker_component[m];
    map.markers.push_back(marker);
  }
  return map;
}

nlohmann::json MapErrors(const MarkerMap& map, const MarkerMap& truth, const char* what) {
  const eval::MapEvalResult eval = eval::EvaluateMap(map, truth);
  double worst_m = 0.0;
  size_t over_10cm = 0;
  for (const eval::MarkerError& e : eval.per_marker) {
    worst_m = std::max(worst_m, e.position_error_m);
    over_10cm += e.position_error_m > 0.1 ? 1 : 0;
  }
  std::printf(
      "%s: %zu codes matched in %zu component(s), position RMS %.4f m, worst %.3f m, %zu over 10 cm, "
      "orientation RMS %.3f deg\n",
      what, eval.markers, eval.components.size(), eval.position_rmse_m, worst_m, over_10cm,
      eval.orientation_rmse_deg);
  return {{"markers", eval.markers},
          {"components", eval.components.size()},
          {"position_rmse_m", eval.position_rmse_m},
          {"worst_position_m", worst_m},
          {"over_10cm", over_10cm},
          {"orientation_rmse_deg", eval.orientation_rmse_deg}};
}

// The built map against the truth in the map's own (anchored) frame, without alignment, beside
// what the map's covariances predict for that error: sqrt(mean trace of the position blocks).
nlohmann::json AnchoredErrors(const MarkerMap& map, const MarkerMap& truth) {
  double sum_sq = 0.0, sum_trace = 0.0;
  size_t n = 0, with_covariance = 0;
  for (const MapMarker& m : map.markers) {
    const MapMarker* t = truth.Find(m.key);
    if (t == nullptr) continue;
    sum_sq += (m.T_world_marker.translation() - t->T_world_marker.translation()).squaredNorm();
    ++n;
    if (m.covariance) {
      sum_trace += m.covariance->bottomRightCorner<3, 3>().trace();
      ++with_covariance;
    }
  }
  const double rms = n ? std::sqrt(sum_sq / n) : 0.0;
  const double predicted = with_covariance ? std::sqrt(sum_trace / with_covariance) : 0.0;
  std::printf(
      "in the anchors' frame (no alignment): position RMS %.4f m, predicted by the covariances %.4f m\n", rms,
      predicted);
  return {{"position_rmse_m", rms}, {"predicted_rmse_m", predicted}};
}

int Run(const Settings& s) {
  auto start = std::chrono::steady_clock::now();
  const sim::SimResult sim = SimulateLoop(s);
  std::printf("%s (simulated in %.1f s)\n", sim::SummaryLine(sim).c_str(), Seconds(start));
  MapBuildOptions options;
  options.num_threads = s.threads;
  start = std::chrono::steady_clock::now();
  const Survey survey = IngestDataset(sim.dataset, options.ingest);
  const double ingest_s = Seconds(start);
  start = std::chrono::steady_clock::now();
  const Survey checked =
      WithoutObservations(survey, FindInconsistentIds(survey, MakeCameras(survey), options.id_check));
  Initialization init = Initialize(checked, options.initializer);
  const double init_s = Seconds(start);
  if (s.from_truth) init = AtTruth(sim, checked, std::move(init));
  for (const std::string& note : init.notes) std::printf("  %s\n", note.c_str());
  std::printf("ingest %.2f s, id check + initialization %.2f s: %zu frames, %zu codes, %d component(s)\n",
              ingest_s, init_s, survey.frames.size(), survey.markers.size(), init.components);
  nlohmann::json report = {{"path_m", s.path_m},
                           {"spacing_m", s.spacing_m},
                           {"seed", s.seed},
                           {"threads", s.threads},
                           {"frames", survey.frames.size()},
                           {"codes", survey.markers.size()},
                           {"ingest_s", ingest_s},
                           {"init_s", init_s},
                           {"init_components", init.components}};
  report["from_truth"] = s.from_truth;
  report["init"] = MapErrors(InitialMap(checked, init), *sim.dataset.groundtruth_markers, "initial codes");
  if (!s.init_only) {
    MapBuildResult result;
    result.init_time_s = init_s;
    result = OptimizeSurvey(checked, init, options, std::move(result));
    std::printf(
        "build: %zu codes mapped, %zu unmapped, %zu outliers, %d iterations, solve %.2f s, covariance %.2f "
        "s\n"
        "  %s\n",
        result.map.markers.size(), result.unmapped.size(), result.outliers.size(), result.iterations,
        result.solver_time_s, result.covariance_time_s, result.termination.c_str());
    report["build"] = MapErrors(result.map, *sim.dataset.groundtruth_markers, "mapped codes");
    report["build"]["anchored"] = AnchoredErrors(result.map, *sim.dataset.groundtruth_markers);
    report["build"]["mapped"] = result.map.markers.size();
    report["build"]["outliers"] = result.outliers.size();
    report["build"]["iterations"] = result.iterations;
    report["build"]["solve_s"] = result.solver_time_s;
    report["build"]["covariance_s"] = result.covariance_time_s;
  }
  if (!s.out.empty()) AtomicWriteFile(s.out, report.dump(1) + "\n");
  return 0;
}

}  // namespace
}  // namespace waymark

int main(int argc, char** argv) {
  waymark::Settings s;
  for (int i = 1; i < argc; ++i) {
    const bool has_value = i + 1 < argc;
    if (std::strcmp(argv[i], "--init-only") == 0) {
      s.init_only = true;
    } else if (std::strcmp(argv[i], "--from-truth") == 0) {
      s.from_truth = true;
    } else if (std::strcmp(argv[i], "--path") == 0 && has_value) {
      s.path_m = std::atof(argv[++i]);
    } else if (std::strcmp(argv[i], "--spacing") == 0 && has_value) {
      s.spacing_m = std::atof(argv[++i]);
    } else if (std::strcmp(argv[i], "--seed") == 0 && has_value) {
      s.seed = std::strtoull(argv[++i], nullptr, 10);
    } else if (std::strcmp(argv[i], "--threads") == 0 && has_value) {
      s.threads = std::atoi(argv[++i]);
    } else if (std::strcmp(argv[i], "--out") == 0 && has_value) {
      s.out = argv[++i];
    } else {
      std::fprintf(
          stderr,
          "usage: %s [--path M] [--spacing M] [--seed N] [--threads N] [--init-only] [--from-truth]\n"
          "       [--out FILE]\n",
          argv[0]);
      return 2;
    }
  }
  try {
    return waymark::Run(s);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mapping_init_bench: %s\n", e.what());
    return 1;
  }
}
