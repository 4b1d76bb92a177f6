#include "sim/scenarios.h"

#include <cmath>
#include <optional>
#include <stdexcept>

#include "geometry/square_marker.h"
#include "sim/render.h"

namespace waymark::sim {
namespace {

constexpr double kDegToRad = M_PI / 180.0;

struct CommonDefaults {
  double min_range_m, max_range_m, max_angle_deg;
  double trans_per_m, rot_per_rad;
  double speed_mps, turn_rate_dps;
};

// Keys every scenario has, after its place.* keys (groups stay contiguous for ToYaml).
void AddCommonParams(ParamSet* p, OdometryKind kind, const CommonDefaults& d) {
  p->AddDouble("rate.odometry_hz", 20.0, 1.0, 1000.0, "odometry and ground-truth rate ([Bach]: T = 50 ms)");
  p->AddDouble("rate.camera_hz", 10.0, 0.1, 1000.0, "camera frame rate; must divide rate.odometry_hz");
  if (kind == OdometryKind::kWheel) {
    p->AddDouble("robot.speed_mps", d.speed_mps, 0.01, 10.0, "forward speed on straight runs");
    p->AddDouble("robot.turn_rate_dps", d.turn_rate_dps, 1.0, 720.0, "turn rate in place");
    p->AddDouble("robot.track_width_m", 0.3, 0.05, 2.0, "distance between the wheels (true)");
  } else {
    p->AddDouble("drone.speed_mps", d.speed_mps, 0.01, 10.0, "flight speed");
    p->AddDouble("drone.yaw_rate_dps", d.turn_rate_dps, 1.0, 720.0, "yaw rate of turns in place");
    p->AddDouble("drone.wobble_deg", 2.0, 0.0, 20.0, "roll/pitch wobble amplitude");
  }
  p->AddDouble("detect.pixel_sigma_px", 0.5, 0.0, 50.0, "corner noise, per coordinate (Gaussian)");
  p->AddDouble("detect.min_range_m", d.min_range_m, 0.0, 100.0, "closest detectable camera-code distance");
  p->AddDouble("detect.max_range_m", d.max_range_m, 0.0, 100.0, "farthest detectable camera-code distance");
  p->AddDouble("detect.max_angle_deg", d.max_angle_deg, 0.0, 89.0,
               "largest angle between code normal and view ray");
  p->AddDouble("detect.border_px", 2.0, 0.0, 100.0, "corners closer to the image edge are not detected");
  p->AddDouble("detect.miss_fraction", 0.02, 0.0, 1.0, "fraction of visible codes missed at random");
  p->AddDouble("detect.misdecode_fraction", 0.0, 0.0, 1.0, "fraction of detections given a wrong id");
  p->AddDouble("detect.misdecode_random_share", 0.5, 0.0, 1.0,
               "share of wrong ids that are random text (the rest: another code's id)");
  p->AddDouble("odometry.trans_per_m", d.trans_per_m, 0.0, 1.0,
               "white translation noise per metre (per step)");
  p->AddDouble("odometry.rot_per_rad", d.rot_per_rad, 0.0, 1.0, "white rotation noise per radian (per step)");
  if (kind == OdometryKind::kWheel) {
    p->AddDouble("odometry.wheel_radius_error_left", 0.0005, -0.5, 0.5,
                 "systematic: true/nominal radius - 1");
    p->AddDouble("odometry.wheel_radius_error_right", -0.0005, -0.5, 0.5,
                 "systematic: true/nominal radius - 1");
    p->AddDouble("odometry.track_width_error", 0.005, -0.5, 0.5, "systematic: nominal/true track width - 1");
  } else {
    p->AddDouble("odometry.scale_error", 0.01, -0.5, 0.5,
                 "systematic: scale of the measured translation - 1");
    p->AddDouble("odometry.yaw_drift_deg_per_m", 0.2, -45.0, 45.0, "systematic: yaw drift per metre flown");
  }
}

CameraInfo MakeCamera(const std::string& name, int width, int height, double focal_px,
                      std::vector<double> distortion, const SE3d& T_robot_camera) {
  CameraInfo camera;
  camera.name = name;
  camera.model = CameraModel::kPinholeRadtan;
  camera.width = width;
  camera.height = height;
  camera.intrinsics = {focal_px, focal_px, 0.5 * width, 0.5 * height};
  camera.distortion = std::move(distortion);
  camera.T_robot_camera = T_robot_camera;
  return camera;
}

// Camera looking along `forward_robot` with the image's down direction `down_robot`.
SE3d Mount(const Eigen::Vector3d& t_robot, const Eigen::Vector3d& forward_robot,
           const Eigen::Vector3d& down_robot) {
  return SE3d(RotationFromZY(forward_robot, down_robot), t_robot);
}

// Positions along a wall of length `length_m`: s = spacing/2 + k spacing, at least
// `margin_m` from both ends.
std::vector<double> PositionsAlong(double length_m, double spacing_m, double margin_m) {
  std::vector<double> positions;
  for (double s = 0.5 * spacing_m; s <= length_m - margin_m + 1e-9; s += spacing_m) {
    if (s >= margin_m - 1e-9) positions.push_back(s);
  }
  return positions;
}

// Rounds to a millimetre, so that coordinates printed in payloads are exact.
double RoundMm(double x) { return std::round(x * 1000.0) / 1000.0; }

// Four walls of the axis-aligned rectangle [x0, x1] x [y0, y1], each from z = 0 to height_m.
void AddRectangleWalls(double x0, double y0, double x1, double y1, double height_m,
                       std::vector<Occluder>* out) {
  out->push_back(VerticalWall({x0, y0}, {x1, y0}, 0.0, height_m));
  out->push_back(VerticalWall({x1, y0}, {x1, y1}, 0.0, height_m));
  out->push_back(VerticalWall({x1, y1}, {x0, y1}, 0.0, height_m));
  out->push_back(VerticalWall({x0, y1}, {x0, y0}, 0.0, height_m));
}

// One face of a straight wall for placing codes: starts at `from`, runs along `direction`
// (unit), codes face `normal`.
struct WallFace {
  Eigen::Vector2d from;
  Eigen::Vector2d direction;
  Eigen::Vector2d normal;
  double length_m;
};

}  // namespace

const std::vector<ScenarioInfo>& Scenarios() {
  static const std::vector<ScenarioInfo> scenarios = {
      {"corridor",
       "10 cm QR codes in a row on the walls of a ~40 m corridor loop, two side cameras ([Bach])"},
      {"ceiling-grid", "12 cm QR codes on a 2.45 m ceiling every 1.4 m, upward camera ([Zhang])"},
      {"rooms",
       "8 cm DataMatrix codes on the walls of rooms joined by doors, plus one unconnected room ([George])"},
      {"warehouse-drone",
       "floor QR codes 0/x/y and load QR codes on racks, drone with down and front cameras ([Kang])"},
      {"square-ceiling",
       "2 m squares of reflective tape on the ceiling, upward equisolid fisheye, LED on/off pairs ([Seki])"},
  };
  return scenarios;
}

// ---------------------------------------------------------------- corridor

namespace {

ParamSet CorridorParams() {
  ParamSet p;
  p.AddDouble("place.spacing_m", 1.0, 0.05, 100.0, "distance between neighbouring codes on a wall (d)");
  p.AddDouble("place.loop_length_m", 12.0, 2.0, 500.0, "centre-line rectangle, long side");
  p.AddDouble("place.loop_width_m", 8.0, 2.0, 500.0, "centre-line rectangle, short side");
  p.AddDouble("place.corridor_width_m", 1.2, 0.4, 10.0, "wall to wall");
  p.AddDouble("place.wall_height_m", 2.5, 0.5, 10.0, "wall height");
  p.AddDouble("place.marker_size_m", 0.10, 0.01, 2.0, "code edge length");
  p.AddDouble("place.camera_height_m", 0.30, 0.05, 3.0, "camera and code-centre height");
  p.AddInt("place.anchors", 2, 0, 1000, "codes whose pose is given in markers.json (the first ones)");
  p.AddDouble("camera.image_scale", 1.0, 0.25, 4.0,
              "image size and focal length of both cameras times this (same field of view)");
  p.AddBool("path.clockwise", false, "drive the loop clockwise (default: counter-clockwise)");
  p.AddInt("path.start_corner", 0, 0, 3,
           "loop corner the robot starts and ends at: 0 = (0, 0), then counter-clockwise");
  p.AddDouble("path.inset_m", 0.0, -1.0, 1.0,
              "drive a loop this far inside the centre line (towards the inner block; < 0: outwards)");
  p.AddDouble("path.overlap_m", 0.0, 0.0, 500.0,
              "after the loop, drive this far again along the first side (re-sees the first codes, "
              "which closes the loop when codes are sparse)");
  AddCommonParams(&p, OdometryKind::kWheel, {0.2, 0.8, 60.0, 0.02, 0.02, 0.3, 45.0});
  return p;
}

// Wall faces along the loop, counter-clockwise: the inner block's (normals out of the block),
// then the outer walls' (normals inwards). The centre line is [0, L] x [0, W].
std::vector<WallFace> CorridorFaces(double L, double W, double half_w) {
  const double li = L - 2 * half_w, wi = W - 2 * half_w, lo = L + 2 * half_w, wo = W + 2 * half_w;
  return {{{half_w, half_w}, {1, 0}, {0, -1}, li},          {{L - half_w, half_w}, {0, 1}, {1, 0}, wi},
          {{L - half_w, W - half_w}, {-1, 0}, {0, 1}, li},  {{half_w, W - half_w}, {0, -1}, {-1, 0}, wi},
          {{-half_w, -half_w}, {1, 0}, {0, 1}, lo},         {{L + half_w, -half_w}, {0, 1}, {-1, 0}, wo},
          {{L + half_w, W + half_w}, {-1, 0}, {0, -1}, lo}, {{-half_w, W + half_w}, {0, -1}, {1, 0}, wo}};
}

void AddCorridorCodes(const ParamSet& p, const std::vector<WallFace>& faces, World* world) {
  const double size_m = p.Double("place.marker_size_m"), cam_h = p.Double("place.camera_height_m");
  const long anchors = p.Int("place.anchors");
  for (size_t f = 0; f < faces.size(); ++f) {
    for (double s : PositionsAlong(faces[f].length_m, p.Double("place.spacing_m"), size_m)) {
      const Eigen::Vector2d c = faces[f].from + s * faces[f].direction;
      SimMarker m;
      char id[32];
      std::snprintf(id, sizeof(id), "C%03zu", world->markers.size());
      m.key = {kFamilyQr, id};
      m.size_m = size_m;
      m.T_world_marker =
          WallMarkerPose({c.x(), c.y(), cam_h}, {faces[f].normal.x(), faces[f].normal.y(), 0.0});
      m.anchor = static_cast<long>(world->markers.size()) < anchors;
      m.region = static_cast<int>(f);
      world->markers.push_back(m);
    }
  }
}

// The side cameras sit this far left and right of the robot's centre.
constexpr double kCorridorCameraOffsetM = 0.12;

// The loop: the rectangle [i, L - i] x [i, W - i] (i = path.inset_m; i = 0 is the centre line),
// corners numbered counter-clockwise from (i, i). The robot starts at corner path.start_corner
// facing the next corner in its direction of travel, drives once round, and turns back to its
// start heading; path.overlap_m > 0 then drives on along the first side (at most its length),
// as a surveyor closes a loop by passing the first codes again. Defaults: from (0, 0) facing +x,
// counter-clockwise, no overlap.
SimTrajectory CorridorPath(const ParamSet& p, double half_w) {
  const double inset_m = p.Double("path.inset_m");
  if (std::abs(inset_m) > half_w - kCorridorCameraOffsetM - 0.05) {
    throw std::invalid_argument(
        "path.inset_m: the cameras would leave the corridor (|inset| must stay below " +
        FormatDouble(half_w - kCorridorCameraOffsetM - 0.05) + " m)");
  }
  const double x0 = inset_m, y0 = inset_m;
  const double x1 = p.Double("place.loop_length_m") - inset_m, y1 = p.Double("place.loop_width_m") - inset_m;
  const std::vector<Eigen::Vector2d> corners = {{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}};
  const int start = static_cast<int>(p.Int("path.start_corner"));
  const int step = p.Bool("path.clockwise") ? 3 : 1;  // +3 = -1 modulo 4
  const Eigen::Vector2d heading = corners[(start + step) % 4] - corners[start];
  const double start_yaw_rad = std::atan2(heading.y(), heading.x());
  PlanarPathBuilder path(SE2d(corners[start].x(), corners[start].y(), start_yaw_rad),
                         p.Double("rate.odometry_hz"), p.Double("robot.speed_mps"),
                         p.Double("robot.turn_rate_dps") * kDegToRad);
  for (int k = 1; k <= 4; ++k) path.DriveTo(corners[(start + k * step) % 4]);
  path.TurnTo(start_yaw_rad);
  const double overlap_m = std::min(p.Double("path.overlap_m"), heading.norm());
  if (overlap_m > 0.0) path.DriveTo(corners[start] + overlap_m * heading.normalized());
  return path.Build();
}

Scene BuildCorridor(const ParamSet& p) {
  Scene scene;
  World& world = scene.world;
  world.name = "sim-corridor";
  const double length_m = p.Double("place.loop_length_m"), width_m = p.Double("place.loop_width_m");
  const double half_w = 0.5 * p.Double("place.corridor_width_m");
  const double wall_h = p.Double("place.wall_height_m"), cam_h = p.Double("place.camera_height_m");
  if (2.0 * half_w >= std::min(length_m, width_m))
    throw std::invalid_argument("corridor wider than the loop");
  world.default_marker_size_m = p.Double("place.marker_size_m");
  AddRectangleWalls(half_w, half_w, length_m - half_w, width_m - half_w, wall_h,
                    &world.occluders);  // inner block
  AddRectangleWalls(-half_w, -half_w, length_m + half_w, width_m + half_w, wall_h,
                    &world.occluders);  // outer
  AddCorridorCodes(p, CorridorFaces(length_m, width_m, half_w), &world);
  const std::vector<double> mild = {-0.05, 0.01, 0.0005, -0.0003, 0.0};
  const double scale = p.Double("camera.image_scale");
  const int width_px = static_cast<int>(std::lround(640 * scale)),
            height_px = static_cast<int>(std::lround(480 * scale));
  world.cameras.push_back(MakeCamera("left", width_px, height_px, 450.0 * scale, mild,
                                     Mount({0, kCorridorCameraOffsetM, cam_h}, {0, 1, 0}, {0, 0, -1})));
  world.cameras.push_back(MakeCamera("right", width_px, height_px, 450.0 * scale, mild,
                                     Mount({0, -kCorridorCameraOffsetM, cam_h}, {0, -1, 0}, {0, 0, -1})));
  scene.truth = CorridorPath(p, half_w);
  return scene;
}

// ---------------------------------------------------------------- ceiling-grid

ParamSet CeilingParams() {
  ParamSet p;
  p.AddDouble("place.room_x_m", 8.4, 1.0, 200.0, "room size along x");
  p.AddDouble("place.room_y_m", 7.0, 1.0, 200.0, "room size along y");
  p.AddDouble("place.spacing_m", 1.4, 0.1, 100.0, "grid pitch of the ceiling codes");
  p.AddDouble("place.ceiling_height_m", 2.45, 0.5, 20.0, "ceiling height");
  p.AddDouble("place.camera_height_m", 0.6, 0.0, 10.0, "upward camera height above the floor");
  p.AddDouble("place.marker_size_m", 0.12, 0.01, 2.0, "code edge length");
  p.AddDouble("place.lane_spacing_m", 1.4, 0.1, 100.0, "distance between the lawn-mower lanes");
  AddCommonParams(&p, OdometryKind::kWheel, {0.3, 3.5, 60.0, 0.02, 0.02, 0.5, 45.0});
  return p;
}

Scene BuildCeilingGrid(const ParamSet& p) {
  Scene scene;
  World& world = scene.world;
  world.name = "sim-ceiling-grid";
  const double room_x = p.Double("place.room_x_m"), room_y = p.Double("place.room_y_m");
  const double pitch = p.Double("place.spacing_m"), size_m = p.Double("place.marker_size_m");
  const double ceiling_h = p.Double("place.ceiling_height_m"), cam_h = p.Double("place.camera_height_m");
  if (cam_h >= ceiling_h) throw std::invalid_argument("place.camera_height_m must be below the ceiling");
  world.default_marker_size_m = size_m;
  world.payload = PayloadSpec{"^(\\d+)/(-?[0-9.]+)/(-?[0-9.]+)$", {"index", "x", "y"}, std::nullopt};
  AddRectangleWalls(0, 0, room_x, room_y, ceiling_h, &world.occluders);
  for (double y : PositionsAlong(room_y, pitch, 0.0)) {
    for (double x : PositionsAlong(room_x, pitch, 0.0)) {
      SimMarker m;
      const double xr = RoundMm(x), yr = RoundMm(y);
      m.key = {kFamilyQr,
               std::to_string(world.markers.size()) + "/" + FormatDouble(xr) + "/" + FormatDouble(yr)};
      m.size_m = size_m;
      // Facing down; symbol x along world -x, y along world +y (all codes alike).
      m.T_world_marker = SE3d(RotationFromZY({0, 0, -1}, {0, 1, 0}), Eigen::Vector3d(xr, yr, ceiling_h));
      world.markers.push_back(m);
    }
  }
  world.cameras.push_back(MakeCamera("up", 640, 480, 620.0, {-0.03, 0.005, 0.0, 0.0, 0.0},
                                     Mount({0, 0, cam_h}, {0, 0, 1}, {-1, 0, 0})));
  const double margin = 0.5 * std::min(pitch, std::min(room_x, room_y));
  PlanarPathBuilder path(SE2d(margin, margin, 0), p.Double("rate.odometry_hz"), p.Double("robot.speed_mps"),
                         p.Double("robot.turn_rate_dps") * kDegToRad);
  bool forward = true;
  for (double y = margin; y <= room_y - margin + 1e-9; y += p.Double("place.lane_spacing_m")) {
    path.DriveTo({forward ? margin : room_x - margin, y});
    path.DriveTo({forward ? room_x - margin : margin, y});
    forward = !forward;
  }
  scene.truth = path.Build();
  return scene;
}

// ---------------------------------------------------------------- rooms

ParamSet RoomsParams() {
  ParamSet p;
  p.AddInt("place.rooms", 3, 1, 20, "rooms in a row joined by doors (plus the unconnected one)");
  p.AddDouble("place.room_size_m", 4.0, 1.5, 50.0, "square rooms, wall length");
  p.AddDouble("place.door_width_m", 1.0, 0.3, 5.0, "door opening in each shared wall (centred)");
  p.AddDouble("place.wall_height_m", 2.5, 0.5, 10.0, "wall height");
  p.AddInt("place.codes_per_wall", 2, 1, 20, "codes per wall, evenly spread (none in a door)");
  p.AddDouble("place.marker_size_m", 0.08, 0.01, 2.0, "code edge length");
  p.AddDouble("place.camera_height_m", 0.45, 0.05, 3.0, "camera and code-centre height");
  p.AddBool("place.unconnected_room", true, "add a room without doors that the robot is carried to");
  p.AddDouble("place.carry_time_s", 20.0, 0.0, 3600.0, "time without samples while the robot is carried");
  p.AddDouble("place.stop_s", 1.0, 0.0, 60.0, "standstill before and after each look-around");
  AddCommonParams(&p, OdometryKind::kWheel, {0.3, 2.5, 45.0, 0.02, 0.02, 0.3, 20.0});
  return p;
}

void AddRoomCodes(int room, double x0, double size_room, const ParamSet& p, World* world) {
  const double cam_h = p.Double("place.camera_height_m"), door_half = 0.5 * p.Double("place.door_width_m");
  const long per_wall = p.Int("place.codes_per_wall");
  const double s = size_room;
  // Inner faces, counter-clockwise, codes facing into the room.
  const std::vector<WallFace> faces = {{{x0, 0}, {1, 0}, {0, 1}, s},
                                       {{x0 + s, 0}, {0, 1}, {-1, 0}, s},
                                       {{x0 + s, s}, {-1, 0}, {0, -1}, s},
                                       {{x0, s}, {0, -1}, {1, 0}, s}};
  for (size_t f = 0; f < faces.size(); ++f) {
    for (long k = 1; k <= per_wall; ++k) {
      const double along = s * k / (per_wall + 1);
      const bool door_wall = faces[f].direction.y() != 0.0;  // x = const walls may hold doors
      if (door_wall && std::abs(along - 0.5 * s) < door_half + p.Double("place.marker_size_m")) continue;
      const Eigen::Vector2d c = faces[f].from + along * faces[f].direction;
      SimMarker m;
      m.key = {kFamilyDataMatrix, std::to_string(1000 + 100 * room + 10 * static_cast<int>(f) + k)};
      m.size_m = p.Double("place.marker_size_m");
      m.T_world_marker =
          WallMarkerPose({c.x(), c.y(), cam_h}, {faces[f].normal.x(), faces[f].normal.y(), 0.0});
      m.region = room;
      world->markers.push_back(m);
    }
  }
}

// A wall at x = const from y = 0 to `s`, with a centred door if `door`.
void AddCrossWall(double x, double s, bool door, double door_width_m, double height_m,
                  std::vector<Occluder>* out) {
  if (!door) {
    out->push_back(VerticalWall({x, 0}, {x, s}, 0.0, height_m));
    return;
  }
  out->push_back(VerticalWall({x, 0}, {x, 0.5 * (s - door_width_m)}, 0.0, height_m));
  out->push_back(VerticalWall({x, 0.5 * (s + door_width_m)}, {x, s}, 0.0, height_m));
}

Scene BuildRooms(const ParamSet& p) {
  Scene scene;
  World& world = scene.world;
  world.name = "sim-rooms";
  const int rooms = static_cast<int>(p.Int("place.rooms"));
  const double s = p.Double("place.room_size_m"), h = p.Double("place.wall_height_m");
  const double door_w = p.Double("place.door_width_m");
  if (door_w >= s - 0.2) throw std::invalid_argument("place.door_width_m must be smaller than the room");
  world.default_marker_size_m = p.Double("place.marker_size_m");
  for (int r = 0; r <= rooms; ++r) {  // x = const walls of the connected row
    AddCrossWall(r * s, s, r > 0 && r < rooms, door_w, h, &world.occluders);
  }
  world.occluders.push_back(VerticalWall({0, 0}, {rooms * s, 0}, 0.0, h));
  world.occluders.push_back(VerticalWall({rooms * s, s}, {0, s}, 0.0, h));
  const bool unconnected = p.Bool("place.unconnected_room");
  const double x_far = (rooms + 1) * s;  // one room size of solid ground between
  if (unconnected) AddRectangleWalls(x_far, 0, x_far + s, s, h, &world.occluders);
  for (int r = 0; r < rooms; ++r) AddRoomCodes(r, r * s, s, p, &world);
  if (unconnected) AddRoomCodes(rooms, x_far, s, p, &world);
  world.cameras.push_back(
      MakeCamera("front", 1280, 960, 1100.0, {-0.08, 0.02, 0.0, 0.0, 0.0},
                 Mount({0.05, 0, p.Double("place.camera_height_m")}, {1, 0, 0}, {0, 0, -1})));
  PlanarPathBuilder path(SE2d(0.5 * s, 0.5 * s, 0), p.Double("rate.odometry_hz"), p.Double("robot.speed_mps"),
                         p.Double("robot.turn_rate_dps") * kDegToRad);
  auto look_around = [&] {
    path.Wait(p.Double("place.stop_s"));
    path.TurnBy(2.0 * M_PI);
    path.Wait(p.Double("place.stop_s"));
  };
  look_around();
  for (int r = 1; r < rooms; ++r) {
    path.DriveTo({(r + 0.5) * s, 0.5 * s});
    look_around();
  }
  if (unconnected) {
    path.CarryTo(SE2d(x_far + 0.5 * s, 0.5 * s, 0.0), p.Double("place.carry_time_s"));
    look_around();
  }
  scene.truth = path.Build();
  return scene;
}

// ---------------------------------------------------------------- warehouse-drone

ParamSet DroneParams() {
  ParamSet p;
  p.AddInt("place.racks", 3, 2, 20, "parallel racks along x (aisles between them)");
  p.AddDouble("place.rack_length_m", 8.0, 1.0, 200.0, "rack length along x");
  p.AddDouble("place.rack_depth_m", 1.0, 0.2, 10.0, "rack depth along y");
  p.AddDouble("place.rack_height_m", 2.4, 0.5, 20.0, "rack height");
  p.AddDouble("place.aisle_width_m", 3.0, 1.0, 50.0, "free width between racks");
  p.AddDouble("place.bay_spacing_m", 1.0, 0.2, 50.0, "load codes along a rack face");
  p.AddInt("place.load_levels", 2, 1, 20, "shelf levels with a load code");
  p.AddDouble("place.level_spacing_m", 0.9, 0.1, 10.0, "height between shelf levels (first at 0.5 m)");
  p.AddDouble("place.marker_size_m", 0.15, 0.01, 2.0, "edge length of every code, floor and load");
  p.AddDouble("place.floor_spacing_m", 1.0, 0.2, 50.0, "floor codes along an aisle");
  p.AddDouble("place.floor_row_offset_m", 0.4, 0.0, 10.0, "floor code rows at aisle centre +- this");
  p.AddDouble("place.altitude_low_m", 1.0, 0.2, 20.0, "first pass of each aisle, facing +y");
  p.AddDouble("place.altitude_high_m", 1.6, 0.2, 20.0, "second pass, facing -y");
  AddCommonParams(&p, OdometryKind::kVisual, {0.3, 3.0, 60.0, 0.01, 0.01, 0.5, 30.0});
  return p;
}

void AddLoadCodes(const ParamSet& p, int rack, double y_face, double normal_y, World* world) {
  const double size_m = p.Double("place.marker_size_m");
  const std::vector<double> bays =
      PositionsAlong(p.Double("place.rack_length_m"), p.Double("place.bay_spacing_m"), size_m);
  for (size_t b = 0; b < bays.size(); ++b) {
    for (long level = 0; level < p.Int("place.load_levels"); ++level) {
      const double z = 0.5 + level * p.Double("place.level_spacing_m");
      if (z + size_m > p.Double("place.rack_height_m")) continue;
      char id[96];
      std::snprintf(id, sizeof(id), "1/R%d%c-B%02zu-L%ld", rack, normal_y > 0 ? 'N' : 'S', b, level);
      SimMarker m;
      m.key = {kFamilyQr, id};
      m.size_m = size_m;
      m.T_world_marker = WallMarkerPose({bays[b], y_face, z}, {0, normal_y, 0});
      m.region = rack;
      world->markers.push_back(m);
    }
  }
}

// Racks (solid boxes) with load codes on the faces that look into an aisle.
void AddRacks(const ParamSet& p, World* world) {
  const int racks = static_cast<int>(p.Int("place.racks"));
  const double depth_m = p.Double("place.rack_depth_m"), pitch_m = depth_m + p.Double("place.aisle_width_m");
  for (int r = 0; r < racks; ++r) {
    const double y0 = r * pitch_m;
    AddRectangleWalls(0, y0, p.Double("place.rack_length_m"), y0 + depth_m, p.Double("place.rack_height_m"),
                      &world->occluders);
    if (r > 0) AddLoadCodes(p, r, y0, -1.0, world);
    if (r + 1 < racks) AddLoadCodes(p, r, y0 + depth_m, 1.0, world);
  }
}

// Floor codes "0/x/y": two rows per aisle (one when the offset is zero), facing up.
void AddFloorCodes(const ParamSet& p, World* world) {
  const double depth_m = p.Double("place.rack_depth_m"), aisle_m = p.Double("place.aisle_width_m");
  const double size_m = p.Double("place.marker_size_m"), offset_m = p.Double("place.floor_row_offset_m");
  for (int a = 0; a + 1 < p.Int("place.racks"); ++a) {
    const double y_centre = a * (depth_m + aisle_m) + depth_m + 0.5 * aisle_m;
    for (double dy : {-offset_m, offset_m}) {
      for (double x :
           PositionsAlong(p.Double("place.rack_length_m"), p.Double("place.floor_spacing_m"), size_m)) {
        const double xr = RoundMm(x), yr = RoundMm(y_centre + dy);
        SimMarker m;
        m.key = {kFamilyQr, "0/" + FormatDouble(xr) + "/" + FormatDouble(yr)};
        m.size_m = size_m;
        m.T_world_marker = SE3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(xr, yr, 0.0));
        m.region = -1 - a;
        world->markers.push_back(m);
      }
      if (offset_m == 0.0) break;
    }
  }
}

// Each aisle: low pass facing +y, climb, high pass facing -y; between aisles around the rack ends.
SimTrajectory FlyAisles(const ParamSet& p) {
  const double depth_m = p.Double("place.rack_depth_m"), aisle_m = p.Double("place.aisle_width_m");
  const double length_m = p.Double("place.rack_length_m");
  const double low = p.Double("place.altitude_low_m"), high = p.Double("place.altitude_high_m");
  const double y_first = depth_m + 0.5 * aisle_m;
  FlightPathBuilder flight({-0.5, y_first, low}, 0.5 * M_PI, p.Double("rate.odometry_hz"),
                           p.Double("drone.speed_mps"), p.Double("drone.yaw_rate_dps") * kDegToRad,
                           p.Double("drone.wobble_deg") * kDegToRad);
  for (int a = 0; a + 1 < p.Int("place.racks"); ++a) {
    const double y = a * (depth_m + aisle_m) + y_first;
    flight.FlyTo({-0.5, y, low});
    flight.YawTo(0.5 * M_PI);
    flight.FlyTo({length_m + 0.5, y, low});
    flight.FlyTo({length_m + 0.5, y, high});
    flight.YawTo(-0.5 * M_PI);
    flight.FlyTo({-0.5, y, high});
  }
  return flight.Build();
}

Scene BuildWarehouseDrone(const ParamSet& p) {
  Scene scene;
  scene.odometry = OdometryKind::kVisual;
  World& world = scene.world;
  world.name = "sim-warehouse-drone";
  world.motion = MotionModel::kFree;
  // Floor codes "0/x/y" lie on the floor, z = 0 (their payload gives no z).
  world.payload = PayloadSpec{"^(\\d+)/(-?[0-9.]+)/(-?[0-9.]+)$", {"kind", "x", "y"}, 0.0};
  world.default_marker_size_m = p.Double("place.marker_size_m");
  AddRacks(p, &world);
  AddFloorCodes(p, &world);
  const std::vector<double> mild = {-0.04, 0.008, 0.0, 0.0, 0.0};
  world.cameras.push_back(
      MakeCamera("down", 640, 480, 380.0, mild, Mount({0, 0, -0.05}, {0, 0, -1}, {-1, 0, 0})));
  world.cameras.push_back(
      MakeCamera("front", 640, 480, 500.0, mild, Mount({0.1, 0, 0}, {1, 0, 0}, {0, 0, -1})));
  scene.truth = FlyAisles(p);
  return scene;
}

// ---------------------------------------------------------------- square-ceiling

ParamSet SquareCeilingParams() {
  ParamSet p;
  const SquareTape tape;
  p.AddInt("place.squares", 1, 1, 50, "squares in a row along x (several: a larger room)");
  p.AddDouble("place.square_spacing_m", 6.0, 0.5, 100.0, "distance between neighbouring squares' centres");
  p.AddDouble("place.square_side_m", 2.0, 0.2, 20.0, "side between the tape's centrelines");
  p.AddDouble("place.tape_width_m", tape.tape_width_m, 0.001, 1.0, "tape width");
  p.AddDouble("place.dash_m", tape.dash_m, 0.001, 10.0, "dash length on the three dotted sides");
  p.AddDouble("place.gap_m", tape.gap_m, 0.001, 10.0, "gap between dashes (at least; spread to fit)");
  p.AddInt("place.solid_side", 0, 0, 3, "solid side: 0 top (marker +y), 1 right, 2 bottom, 3 left");
  p.AddDouble("place.camera_height_m", 0.3, 0.0, 10.0, "camera height above the floor");
  p.AddDouble("place.ceiling_above_camera_m", 2.0, 0.3, 20.0, "ceiling height above the camera (paper: 2 m)");
  p.AddDouble("place.room_margin_m", 3.0, 0.5, 100.0, "room walls this far beyond the squares");
  p.AddDouble("camera.focal_mm", 2.3, 0.1, 100.0, "focal length (FIT FI-23: 2.3 mm)");
  p.AddDouble("camera.pixel_um", 6.7, 0.5, 50.0, "pixel pitch (Marlin F-131B: 6.7 um)");
  p.AddInt("camera.width", 1280, 16, 10000, "image width");
  p.AddInt("camera.height", 1024, 16, 10000, "image height");
  p.AddDouble("camera.fov_deg", 160.0, 10.0, 180.0, "lens field of view (black beyond)");
  p.AddDouble("camera.tilt_deg", 0.0, 0.0, 20.0,
              "true mount tilt off vertical; the calibration says upright");
  p.AddDouble("camera.tilt_azimuth_deg", 0.0, -360.0, 360.0, "direction of the tilt (0: towards robot +x)");
  p.AddDouble("camera.lens_error_k1", 0.0, -1.0, 1.0,
              "true lens k1 (equisolid polynomial); the calibration says 0");
  p.AddDouble("camera.focal_error", 0.0, -0.5, 0.5, "true focal length / calibrated one - 1");
  p.AddDouble("path.half_side_m", 1.2, 0.0, 50.0, "loop: rectangle this far around the squares' centres");
  p.AddInt("path.loops", 1, 1, 100, "times round the loop");
  AddCommonParams(&p, OdometryKind::kWheel, {0.3, 6.0, 75.0, 0.02, 0.02, 0.3, 45.0});
  AddIrParams(&p);
  return p;
}

Scene BuildSquareCeiling(const ParamSet& p) {
  Scene scene;
  World& world = scene.world;
  world.name = "sim-square-ceiling";
  const int squares = static_cast<int>(p.Int("place.squares"));
  const double spacing = p.Double("place.square_spacing_m"), side = p.Double("place.square_side_m");
  const double cam_h = p.Double("place.camera_height_m"),
               ceiling_z = cam_h + p.Double("place.ceiling_above_camera_m");
  SquareTape tape;
  tape.tape_width_m = p.Double("place.tape_width_m");
  tape.dash_m = p.Double("place.dash_m");
  tape.gap_m = p.Double("place.gap_m");
  tape.solid_side = static_cast<SquareSide>(p.Int("place.solid_side"));
  std::string why;
  if (!CheckSquareTape(tape, side, &why)) throw std::invalid_argument("place: " + why);
  if (squares > 1 && spacing < side + tape.tape_width_m + 0.1) {
    throw std::invalid_argument("place.square_spacing_m: squares would overlap");
  }
  world.default_marker_size_m = side;
  for (int i = 0; i < squares; ++i) {
    SimMarker m;
    m.key = {kFamilySquare, "S" + std::to_string(i)};
    m.size_m = side;
    // Facing down; marker x along world +x, y along world -y (seen from below, upright).
    m.T_world_marker =
        SE3d(RotationFromZY({0, 0, -1}, {0, -1, 0}), Eigen::Vector3d(i * spacing, 0.0, ceiling_z));
    m.anchor = true;  // the squares' positions are known (the paper measures them)
    m.square_tape = tape;
    world.markers.push_back(m);
  }
  const double margin = p.Double("place.room_margin_m"), half = 0.5 * side;
  IrRoom room;
  room.room_min = Eigen::Vector2d(-half - margin, -half - margin);
  room.room_max = Eigen::Vector2d((squares - 1) * spacing + half + margin, half + margin);
  room.ceiling_z = ceiling_z;
  const int lamps = static_cast<int>(p.Int("ir.lamps"));
  for (int k = 0; k < lamps; ++k) {  // around the first square, 0.4 m outside its tape
    const double a = 2.0 * M_PI * k / std::max(1, lamps) + 0.3;
    room.lamps.emplace_back((half + 0.4) * std::sqrt(2.0) * std::cos(a),
                            (half + 0.4) * std::sqrt(2.0) * std::sin(a));
  }
  AddRectangleWalls(room.room_min.x(), room.room_min.y(), room.room_max.x(), room.room_max.y(), ceiling_z,
                    &world.occluders);
  scene.ir_room = room;

  // The camera: equisolid, fx = focal / pixel pitch; truly tilted and with the lens' own error,
  // while the calibration the dataset gets is the nominal one, upright.
  CameraInfo nominal;
  nominal.name = "up";
  nominal.model = CameraModel::kEquisolid;
  nominal.width = static_cast<int>(p.Int("camera.width"));
  nominal.height = static_cast<int>(p.Int("camera.height"));
  const double f_px = p.Double("camera.focal_mm") * 1e-3 / (p.Double("camera.pixel_um") * 1e-6);
  nominal.intrinsics = {f_px, f_px, 0.5 * nominal.width, 0.5 * nominal.height};
  nominal.distortion = {0.0, 0.0, 0.0, 0.0};
  nominal.T_robot_camera = Mount({0, 0, cam_h}, {0, 0, 1}, {-1, 0, 0});
  CameraInfo truth = nominal;
  truth.intrinsics[0] = truth.intrinsics[1] = f_px * (1.0 + p.Double("camera.focal_error"));
  truth.distortion[0] = p.Double("camera.lens_error_k1");
  const double tilt = p.Double("camera.tilt_deg") * kDegToRad,
               azimuth = p.Double("camera.tilt_azimuth_deg") * kDegToRad;
  // Tilt the optical axis towards robot direction (cos azimuth, sin azimuth, 0).
  const Eigen::Vector3d tilt_axis(-std::sin(azimuth), std::cos(azimuth), 0.0);
  truth.T_robot_camera =
      SE3d(Eigen::Quaterniond(Eigen::AngleAxisd(tilt, tilt_axis)) * nominal.T_robot_camera.rotation(),
           nominal.T_robot_camera.translation());
  Camera{truth};  // checks the true calibration (throws std::runtime_error if unusable)
  world.cameras.push_back(truth);
  world.calibrated_cameras.push_back(nominal);

  // The loop: a rectangle path.half_side_m around the squares' centres, counter-clockwise from
  // its corner (-a, -a) facing +x, path.loops times, then back to the start heading.
  const double a = p.Double("path.half_side_m");
  const double x1 = (squares - 1) * spacing + a;
  if (a + 0.3 > margin + half) throw std::invalid_argument("path.half_side_m: the loop leaves the room");
  PlanarPathBuilder path(SE2d(-a, -a, 0.0), p.Double("rate.odometry_hz"), p.Double("robot.speed_mps"),
                         p.Double("robot.turn_rate_dps") * kDegToRad);
  for (long loop = 0; loop < p.Int("path.loops"); ++loop) {
    if (a > 0.0) {
      path.DriveTo({x1, -a});
      path.DriveTo({x1, a});
      path.DriveTo({-a, a});
      path.DriveTo({-a, -a});
    } else {
      path.TurnBy(M_PI);  // a loop of no size: turn round on the spot under the square
      path.TurnBy(M_PI);
    }
  }
  path.TurnTo(0.0);
  scene.truth = path.Build();
  return scene;
}

// The scenario's own keys, without the render.* keys.
std::optional<ParamSet> PlaceParams(const std::string& scenario) {
  if (scenario == "corridor") return CorridorParams();
  if (scenario == "ceiling-grid") return CeilingParams();
  if (scenario == "rooms") return RoomsParams();
  if (scenario == "warehouse-drone") return DroneParams();
  if (scenario == "square-ceiling") return SquareCeilingParams();
  return std::nullopt;
}

}  // namespace

ParamSet ScenarioParams(const std::string& scenario) {
  if (std::optional<ParamSet> params = PlaceParams(scenario)) {
    if (scenario != "square-ceiling") AddRenderParams(&*params);  // it has its ir.* keys instead
    return *params;
  }
  std::string known;
  for (const ScenarioInfo& s : Scenarios()) known += (known.empty() ? "" : ", ") + s.name;
  throw std::invalid_argument("unknown scenario '" + scenario + "' (known: " + known + ")");
}

Scene BuildScene(const std::string& scenario, const ParamSet& params) {
  if (scenario == "corridor") return BuildCorridor(params);
  if (scenario == "ceiling-grid") return BuildCeilingGrid(params);
  if (scenario == "rooms") return BuildRooms(params);
  if (scenario == "warehouse-drone") return BuildWarehouseDrone(params);
  if (scenario == "square-ceiling") return BuildSquareCeiling(params);
  ScenarioParams(scenario);  // throws the message that lists the known scenarios
  throw std::logic_error("scenario without a builder: " + scenario);
}

}  // namespace waymark::sim
