// The built-in scenarios. Each is a set of parameters with defaults (ScenarioParams) and a
// builder that turns them into a place and a path (BuildScene). The place (codes, walls,
// cameras) and the path are functions of the parameters only: the seed draws only the noise
// (sim/simulator.h), so two seeds give two runs through the same place.
//
//   corridor         [Bach]: 10 cm QR codes in a row on both walls of a rectangular corridor
//                    loop, at camera height, every place.spacing_m; differential drive on the
//                    centre line; two side cameras; detectable between 0.2 and 0.8 m. The path.*
//                    keys change only the path (direction, start corner, a loop inset from the
//                    centre line): a second, different run through the same place.
//   ceiling-grid     [Zhang]: 12 cm QR codes on a 2.45 m ceiling every 1.4 m, payload
//                    "i/x/y"; an upward camera 0.6 m above the floor; a lawn-mower path.
//   rooms            [George]: 8 cm DataMatrix codes on the walls of rooms joined by doors;
//                    stops at each room's centre and turns in place; the last room has no
//                    door and the robot is carried there (odometry restarts).
//   warehouse-drone  [Kang]: floor QR codes "0/x/y" in the aisles, load QR codes on the rack
//                    faces; a down-looking and a front-looking camera; 6-DoF flight.
//   square-ceiling   [Seki]: one (or several) large squares of retro-reflective tape on the
//                    ceiling, an upward equisolid fisheye with blinking infrared LEDs, a loop under
//                    the squares; rendered as LED-on/LED-off pairs (sim/ir_render.h).
// docs/sim.md gives every key, the geometry and the noise models.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "sim/ir_render.h"
#include "sim/motion.h"
#include "sim/params.h"
#include "sim/world.h"

namespace waymark::sim {

struct ScenarioInfo {
  std::string name;
  std::string summary;
};

// The built-in scenarios, in the order `waymark sim --help` lists them.
const std::vector<ScenarioInfo>& Scenarios();

// A scenario's parameters with their defaults. Unknown name: std::invalid_argument
// ("unknown scenario 'x' (known: corridor, ...)").
ParamSet ScenarioParams(const std::string& scenario);

// The odometry a scenario's vehicle has.
enum class OdometryKind { kWheel, kVisual };

struct Scene {
  World world;
  SimTrajectory truth;  // T_world_robot at the odometry rate
  OdometryKind odometry = OdometryKind::kWheel;
  // Set for a scene rendered as infrared LED pairs (square-ceiling) instead of by sim/render.h.
  std::optional<IrRoom> ir_room;
};

// The place and the path of `scenario` for `params` (deterministic; no noise).
Scene BuildScene(const std::string& scenario, const ParamSet& params);

}  // namespace waymark::sim
