// `waymark plan-codes`: where to put the codes on a floor plan for a target error
// (plan/code_placement.h).
#include <cmath>
#include <cstdio>
#include <iostream>
#include <stdexcept>
#include <string>
#include <vector>

#include "cli/args.h"
#include "cli/command.h"
#include "io/map_io.h"
#include "io/tum_io.h"
#include "plan/code_placement.h"
#include "plan/floor_plan.h"
#include "util/format.h"

namespace waymark::cli {
namespace {

constexpr const char* kUsage = R"(Usage:
  waymark plan-codes WORLD.yaml --path PATH.tum --target-mm E --out MARKERS.json [--spacings LIST]

Chooses where to put codes on the walls of the floor plan WORLD.yaml (docs/formats.md, "Floor
plan") so that a survey driving PATH.tum (T_world_robot, TUM) gives a map, and the online
localizer a pose, whose predicted position error is at most E millimetres, with the fewest codes
(docs/planning.md). Each candidate layout (a code size of the plan's, a spacing along the walls)
is predicted by building the map of a noise-free simulated survey of it and taking the build's
own covariances (the error `waymark map build` predicts), then running the localizer on it.
Prints every layout tried, then the chosen one's prediction per metre of path; writes its codes
to MARKERS.json (map format: planned poses, predicted covariances, the anchors fixed), which
`waymark sim SCENARIO --markers MARKERS.json` surveys. Exits 2 when no layout meets E (nothing
written).

Options:
  --path FILE          the path the survey will drive (TUM), required
  --target-mm E        target position error in mm (map after alignment, and online), required
  --out FILE           the planned codes (map.json format), required
  --spacings LIST      spacings to try, m (default 4,2.8,2,1.4,1,0.7,0.5,0.35,0.25)
)";

int RunPlanCodes(const std::vector<std::string>& argv) {
  const Args args(argv, {"path", "target-mm", "out", "spacings"}, {});
  if (args.Help()) {
    std::cout << kUsage;
    return 0;
  }
  args.ExpectPositionals(1, 1, "WORLD.yaml");
  const std::string out = args.Require("out");
  const std::string path_file = args.Require("path");
  args.Require("target-mm");
  plan::PlacementOptions options;
  options.target_m = *args.GetDouble("target-mm") / 1000.0;
  if (const auto spacings = args.GetDoubleList("spacings")) options.spacings_m = *spacings;
  std::string why;
  if (!options.Check(&why)) throw std::invalid_argument("plan-codes: " + why);
  const plan::FloorPlan floor_plan = plan::ReadFloorPlan(args.positionals()[0]);
  const Trajectory path = ReadTum(path_file);
  try {
    plan::CheckPath(floor_plan, path);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(path_file + ": " + e.what());
  }
  options.progress = [](const std::string& line) { std::cerr << line << "\n"; };
  const plan::PlacementResult result = plan::PlanCodes(floor_plan, path, options);
  if (result.chosen < 0) {
    std::cerr << "no layout meets " << FormatDouble(1000.0 * options.target_m)
              << " mm: try denser spacings (--spacings) or larger code sizes\n";
    return 2;
  }
  const plan::LayoutPrediction& chosen = result.tried[result.chosen];
  std::printf(
      "chosen: %zu codes of %s m every %s m; predicted map error %.1f mm (aligned RMS), online %.1f mm "
      "(RMS; max %.1f mm) over %.1f m of path\n",
      chosen.markers.markers.size(), FormatDouble(chosen.size_m).c_str(),
      FormatDouble(chosen.spacing_m).c_str(), 1000.0 * *chosen.map_rms_m, 1000.0 * chosen.online_rms_m,
      1000.0 * chosen.online_max_m, chosen.path_length_m);
  std::printf(
      "| metre of path | codes in view | online position sigma, max (mm) | map sigma of those codes (mm) "
      "|\n");
  std::printf("|---|---|---|---|\n");
  for (const plan::MetrePrediction& m : chosen.per_metre) {
    std::printf("| %.0f-%.0f | %d | %.1f | %.1f |\n", m.from_m, m.from_m + 1, m.codes_in_view,
                1000.0 * m.online_max_sigma_m, 1000.0 * m.map_sigma_m);
  }
  WriteMap(out, chosen.markers);
  std::cerr << "plan-codes: " << chosen.markers.markers.size() << " codes -> " << out << "\n";
  return 0;
}

const CommandRegistrar kRegistrar(
    {"plan-codes", "choose where to put codes on a floor plan for a target error (docs/planning.md)", kUsage,
     RunPlanCodes});

}  // namespace
}  // namespace waymark::cli
