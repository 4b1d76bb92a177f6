// `waymark sim`: writes a simulated dataset directory with exact ground truth (sim/).
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <iostream>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "cli/args.h"
#include "cli/command.h"
#include "io/map_io.h"
#include "io/tum_io.h"
#include "io/util.h"
#include "plan/drive.h"
#include "plan/route_io.h"
#include "sim/params.h"
#include "sim/render.h"
#include "sim/render_io.h"
#include "sim/scenarios.h"
#include "sim/sim_io.h"
#include "sim/simulator.h"

namespace waymark::cli {
namespace {

// Named shortcuts for frequent keys: --spacing 2 is --set place.spacing_m=2.
const std::vector<std::pair<std::string, std::string>> kShortcuts = {
    {"spacing", "place.spacing_m"},
    {"pixel-sigma", "detect.pixel_sigma_px"},
    {"misdecode", "detect.misdecode_fraction"},
};

std::string Usage() {
  std::ostringstream out;
  out << "Usage: waymark sim SCENARIO --out DIR [--seed N] [--config FILE.yaml] [--set key=value ...] "
         "[--force]\n"
         "                   [--render [--render-every N]]\n"
         "       waymark sim SCENARIO --drive ROUTE.json --localize MAP.json --out DIR [--seed N] [keys]\n"
         "       waymark sim SCENARIO --print-config [--config FILE.yaml] [--set key=value ...]\n"
         "       waymark sim list\n\n"
         "Writes a dataset directory (docs/design.md) with detections, odometry and exact ground truth.\n"
         "The place (codes, walls, path) is fixed by the scenario and its keys; --seed draws only the\n"
         "noise, so two seeds are two runs through the same place (a survey and a run to localize).\n\n"
         "Options:\n"
         "  --out DIR           output directory; must be absent or empty unless --force\n"
         "  --force             replace a non-empty --out\n"
         "  --seed N            noise seed (default 0)\n"
         "  --config FILE.yaml  keys to override (nested by the dots; unknown keys are errors)\n"
         "  --set key=value     one key (repeatable; applied after --config, in order)\n"
         "  --print-config      print the effective keys as YAML and exit\n"
         "  --render            also render PNG images of the camera frames (images/<camera>/<n>.png,\n"
         "                      images.csv) and their exact code corners (groundtruth/corners.jsonl);\n"
         "                      photometry from the render.* keys; square-ceiling: infrared LED pairs\n"
         "                      images/<camera>/<n>-on.png and <n>-off.png, photometry from the ir.* keys\n"
         "  --render-every N    render every N-th camera frame only (default 1)\n"
         "  --drive ROUTE.json  closed loop (docs/planning.md): instead of the scenario's path, drive the\n"
         "                      route from `waymark route` with a pure-pursuit controller fed by the\n"
         "                      online localizer's pose against --localize (never the truth), with the\n"
         "                      scenario's odometry and detection noise; DIR is a dataset as usual plus\n"
         "                      online/trajectory.tum (the localizer's poses) and drive.json (the\n"
         "                      outcome: goal error, frames lost); planar wheel scenarios only\n"
         "  --localize MAP.json the map the robot localizes against (required with --drive)\n"
         "  --cold-start        --drive: the robot is set down at the route's start within 5 cm and 0.05 "
         "rad\n"
         "                      (drawn from the seed); by default the localizer starts from the route's\n"
         "                      start with that uncertainty, with --cold-start from its first code\n"
         "  --markers FILE      replace the scenario's codes by FILE's (map format, every code with its\n"
         "                      pose; `fixed` ones are anchors): a survey of a layout from\n"
         "                      `waymark plan-codes` in the same walls, cameras and path\n";
  for (const auto& [flag, key] : kShortcuts) {
    out << "  --" << flag << " V" << std::string(16 - flag.size(), ' ') << "same as --set " << key << "=V\n";
  }
  out << "\nScenarios and their keys (default in parentheses):\n";
  for (const sim::ScenarioInfo& s : sim::Scenarios()) {
    out << "\n" << s.name << ": " << s.summary << "\n" << sim::ScenarioParams(s.name).Describe("  ");
  }
  out << "\nDetails: docs/sim.md\n";
  return out.str();
}

// "rendering 12/40" on a terminal, rewritten in place; nothing in pipes.
void ShowProgress(long done, long total) {
  if (!::isatty(STDERR_FILENO)) return;
  std::fprintf(stderr, "\rrendering %ld/%ld", done, total);
  if (done >= total) std::fprintf(stderr, "\n");
}

// The key a shortcut option stands for, "" for --set itself, nullopt for other arguments.
std::optional<std::string> AssignmentOption(const std::string& name) {
  if (name == "--set") return std::string();
  for (const auto& [flag, key] : kShortcuts) {
    if (name == "--" + flag) return key;
  }
  return std::nullopt;
}

// Pulls every --set (and shortcut) out of argv, in order, leaving the rest for Args.
std::vector<std::string> ExtractAssignments(const std::vector<std::string>& argv,
                                            std::vector<std::string>* rest) {
  std::vector<std::string> assignments;
  for (size_t i = 0; i < argv.size(); ++i) {
    const size_t eq = argv[i].rfind("--", 0) == 0 ? argv[i].find('=') : std::string::npos;
    const std::string name = argv[i].substr(0, eq);
    const std::optional<std::string> key = AssignmentOption(name);
    if (!key) {
      rest->push_back(argv[i]);
      continue;
    }
    std::string value;
    if (eq != std::string::npos) {
      value = argv[i].substr(eq + 1);
    } else if (i + 1 < argv.size()) {
      value = argv[++i];
    } else {
      throw std::invalid_argument("option " + name + " needs a value");
    }
    assignments.push_back(key->empty() ? value : *key + "=" + value);
  }
  return assignments;
}

// --markers: the codes of a map file (with poses) as the place's codes; fixed ones are anchors.
std::vector<sim::SimMarker> PlannedMarkers(const std::string& file) {
  const MarkerMap map = ReadMap(file);
  if (map.markers.empty()) throw std::invalid_argument(file + ": no code to place");
  std::vector<sim::SimMarker> markers;
  for (const MapMarker& m : map.markers) {
    if (!m.has_pose) throw std::invalid_argument(file + ": " + m.key.ToString() + " has no pose");
    sim::SimMarker s;
    s.key = m.key;
    s.size_m = m.size_m;
    s.T_world_marker = m.T_world_marker;
    s.anchor = m.fixed;
    markers.push_back(s);
  }
  return markers;
}

// --drive: the closed loop of plan/drive.h.
int RunDrive(const Args& args, const std::string& scenario, const sim::ParamSet& params, long seed) {
  const plan::Route route = plan::ReadRoute(args.Require("drive"));
  const MarkerMap map = ReadMap(args.Require("localize"));
  plan::DriveOptions options;
  options.start_pose_known = !args.Flag("cold-start");
  if (params.Has("robot.speed_mps")) options.speed_mps = params.Double("robot.speed_mps");
  if (params.Has("robot.turn_rate_dps"))
    options.turn_rate_radps = params.Double("robot.turn_rate_dps") * M_PI / 180.0;
  const plan::DriveResult drive =
      plan::DriveRoute(scenario, params, static_cast<std::uint64_t>(seed), route, map, std::nullopt, options);
  const std::string out_dir = args.Require("out");
  sim::WriteSimDataset(drive.sim, params, static_cast<std::uint64_t>(seed), out_dir, args.Flag("force"),
                       [&](const std::filesystem::path& dir) {
                         std::filesystem::create_directories(dir / "online");
                         WriteTum(dir / "online" / "trajectory.tum", drive.online,
                                  "waymark sim --drive: the online localizer's T_world_robot while tracking");
                         AtomicWriteFile(dir / "drive.json", plan::FormatDriveReport(drive.report));
                       });
  std::cerr << sim::SummaryLine(drive.sim) << " -> " << out_dir << "\n"
            << "drive: " << plan::DriveSummaryLine(drive.report) << "\n";
  return drive.report.reached ? 0 : 2;
}

int RunSim(const std::vector<std::string>& argv) {
  std::vector<std::string> rest;
  const std::vector<std::string> assignments = ExtractAssignments(argv, &rest);
  const Args args(rest, {"out", "seed", "config", "render-every", "drive", "localize", "markers"},
                  {"force", "print-config", "render", "cold-start"});
  if (args.Help()) {
    std::cout << Usage();
    return 0;
  }
  args.ExpectPositionals(1, 1, "scenario (see `waymark sim --help`)");
  const std::string scenario = args.positionals()[0];
  if (scenario == "list") {
    for (const sim::ScenarioInfo& s : sim::Scenarios()) std::cout << s.name << "\t" << s.summary << "\n";
    return 0;
  }
  sim::ParamSet params = sim::ScenarioParams(scenario);
  if (const auto config = args.Get("config")) params.LoadYamlFile(*config);
  for (const std::string& assignment : assignments) params.SetAssignment(assignment);
  if (args.Flag("print-config")) {
    std::cout << "# waymark sim " << scenario << ": effective keys (load with --config)\n" << params.ToYaml();
    return 0;
  }
  const std::string out_dir = args.Require("out");
  const long seed = args.GetInt("seed").value_or(0);
  if (seed < 0) throw std::invalid_argument("option --seed: expected a non-negative integer");
  const long render_every = args.GetInt("render-every").value_or(1);
  if (render_every < 1) throw std::invalid_argument("option --render-every: expected a positive integer");
  if (args.Get("render-every") && !args.Flag("render")) {
    throw std::invalid_argument("option --render-every needs --render");
  }
  if (args.Flag("cold-start") && !args.Has("drive"))
    throw std::invalid_argument("--cold-start needs --drive");
  if (args.Has("drive") || args.Has("localize")) {
    if (!args.Has("drive") || !args.Has("localize"))
      throw std::invalid_argument("--drive and --localize go together");
    if (args.Flag("render")) throw std::invalid_argument("--drive does not render (no --render)");
    if (args.Has("markers")) throw std::invalid_argument("--drive does not take --markers");
    return RunDrive(args, scenario, params, seed);
  }
  std::optional<std::vector<sim::SimMarker>> markers;
  if (const auto file = args.Get("markers")) markers = PlannedMarkers(*file);
  const sim::SimResult result =
      sim::Simulate(scenario, params, static_cast<std::uint64_t>(seed), markers ? &*markers : nullptr);
  sim::RenderStats render_stats;
  std::function<void(const std::filesystem::path&)> render;
  if (args.Flag("render") && result.scene.ir_room) {
    const sim::IrOptions options = sim::IrOptionsFromParams(params);
    render = [&, options](const std::filesystem::path& dir) {
      render_stats = sim::RenderIrRun(result, options, static_cast<std::uint64_t>(seed), render_every, dir,
                                      ShowProgress);
    };
  } else if (args.Flag("render")) {
    const sim::RenderOptions options = sim::RenderOptionsFromParams(params);
    render = [&, options](const std::filesystem::path& dir) {
      render_stats =
          sim::RenderRun(result, options, static_cast<std::uint64_t>(seed), render_every, dir, ShowProgress);
    };
  }
  sim::WriteSimDataset(result, params, static_cast<std::uint64_t>(seed), out_dir, args.Flag("force"), render);
  std::cerr << sim::SummaryLine(result) << " -> " << out_dir << "\n";
  if (render_stats.images > 0) {
    std::fprintf(stderr, "rendered %ld images (%ld visible codes) in %.1f s: %.0f ms per image\n",
                 render_stats.images, render_stats.codes, render_stats.seconds,
                 1000.0 * render_stats.seconds / render_stats.images);
  }
  return 0;
}

const CommandRegistrar kRegistrar({"sim", "simulate a dataset with exact ground truth (corridor, rooms, ...)",
                                   Usage(), RunSim});

}  // namespace
}  // namespace waymark::cli
