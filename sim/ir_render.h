// Infrared frame pairs of the square-ceiling scenario ([Seki]): an upward camera with
// infrared LEDs around its lens, retro-reflective tape on the ceiling, the LEDs on for one frame
// and off for the next. 8-bit gray images.
//
// Geometry (exact, by ray casting, as sim/render.h): the ray of a (sub-)pixel is
// r_camera = Camera::Unproject(u) (the true lens), taken to the world; it ends on the nearest of
//   people     vertical cylinders (radius person_radius_m, from the floor to person_height_m),
//   ceiling    the plane z = ceiling_z inside the room (a ray leaving the room ends on a wall).
// A ceiling point lies on a square's tape if it falls in one of geometry/square_marker.h's
// SquareTapeRects in that square's frame, on a lamp if within lamp_radius_m of a lamp centre.
// Pixels further than half the lens' field of view off-axis (fov_deg) are black. A pixel is
// the mean of 4 x 4 sub-pixel rays (bilinear between the neighbouring pixel-centre rays) where
// its centre and a neighbour's centre end on different surfaces, one ray elsewhere.
//
// Photometry (gray levels before noise; theta = angle between the ray and the camera's optical
// axis, gamma = incidence angle on the ceiling, d = distance from the camera):
//   ceiling, off     ambient ceiling_albedo
//   tape, off        ambient tape_albedo
//   LED on adds      tape:     led_gain (z0 / d)^2 cos(theta)^led_exponent cos(gamma)^incidence_exponent,
//                              z0 = the camera's height below the ceiling (the retro-reflection
//                              I_D I_L I_O of the paper's eq. 8: led_gain on-axis)
//                    ceiling:  led_diffuse ceiling_albedo cos(gamma) / d^2 (d in m)
//                    people:   led_diffuse person_albedo / d^2 (a person near the LEDs is bright)
//   people, off      ambient person_albedo
//   lamps            lamp_level (1 + lamp_flicker n), n ~ N(0, 1) per frame (mains flicker)
//   then             Gaussian blur blur_sigma_px, + N(0, noise_sigma^2), rounded, clamped to [0, 255]
// People walk straight lines across the room at person_speed_mps and turn back at its walls; the
// off frame is pair_gap_s after the on frame, with the robot and the people moved on.
// Only the draws (people's starting points and directions, flicker, noise) depend on the seed.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <map>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "geometry/camera.h"
#include "geometry/pose.h"
#include "geometry/square_marker.h"
#include "sim/params.h"
#include "sim/world.h"

namespace waymark::sim {

struct IrOptions {
  double fov_deg = 160.0;
  double ambient = 40.0;  // gray level of a white surface in the room light alone
  double ceiling_albedo = 0.8;
  double tape_albedo = 0.6;
  double person_albedo = 0.5;
  double led_gain = 200.0;  // tape, on-axis, LED on (gray levels)
  double led_exponent =
      -1.0;  // LED layout cos(theta)^p; < 0: brighter off-axis (the paper's tilted narrow LEDs)
  double incidence_exponent = 0.5;
  double led_diffuse = 60.0;  // diffuse LED light at 1 m on a white surface (gray levels)
  int lamps = 2;              // ceiling lamps near the first square
  double lamp_radius_m = 0.15;
  double lamp_level = 250.0;
  double lamp_flicker = 0.05;
  int people = 1;
  double person_radius_m = 0.25;
  double person_height_m = 1.7;
  double person_speed_mps = 1.2;
  double pair_gap_s = 0.06;  // LED on for 60 ms, then the off frame
  double blur_sigma_px = 0.7;
  double noise_sigma = 2.0;

  // True if usable; otherwise false with the reason in *why (when why != nullptr).
  bool Check(std::string* why) const;
};

// Declares the ir.* keys (IrOptions' defaults) in `params`; IrOptionsFromParams reads them.
void AddIrParams(ParamSet* params);
IrOptions IrOptionsFromParams(const ParamSet& params);

// The room (the floor rectangle [room_min, room_max], the ceiling at ceiling_z) and where its
// lamps are, as the square-ceiling scenario builds them (sim/scenarios.h).
struct IrRoom {
  Eigen::Vector2d room_min = Eigen::Vector2d::Zero();
  Eigen::Vector2d room_max = Eigen::Vector2d::Zero();
  double ceiling_z = 0.0;
  std::vector<Eigen::Vector2d> lamps;  // centres on the ceiling
};

class IrRenderer {
 public:
  // The squares are the world's markers of family square. Throws std::invalid_argument for
  // options that fail Check or a room without area.
  IrRenderer(const World& world, const IrRoom& room, const IrOptions& options, std::uint64_t seed);

  // One frame taken at `stamp_s` from T_world_camera by `camera` (the true calibration), with the
  // LEDs on or off. `frame_index` draws the flicker and the noise.
  cv::Mat Render(const Camera& camera, const SE3d& T_world_camera, double stamp_s, bool led_on,
                 std::uint64_t frame_index) const;

  // Where the people stand at `stamp_s` (floor positions).
  std::vector<Eigen::Vector2d> PeopleAt(double stamp_s) const;

  const IrOptions& options() const { return options_; }

 private:
  struct Square {
    SE3d T_marker_world;
    double half_extent_m;  // half side + half tape width
    std::vector<TapeRect> rects;
  };
  struct Walker {
    Eigen::Vector2d start, direction;  // unit direction
  };
  enum Surface : std::uint8_t { kNone, kCeiling, kTape, kLamp, kPerson, kWall };
  struct Hit {
    Surface surface = kNone;
    double value = 0.0;  // gray level
  };
  Hit Shade(const Eigen::Vector3d& c_world, const Eigen::Vector3d& d_world, const Eigen::Vector3d& axis_world,
            const std::vector<Eigen::Vector2d>& people, bool led_on, double lamp_level) const;
  const std::vector<Eigen::Vector3f>& PixelRays(const Camera& camera) const;

  IrRoom room_;
  IrOptions options_;
  std::uint64_t seed_;
  std::vector<Square> squares_;
  std::vector<Walker> walkers_;
  mutable std::map<std::string, std::vector<Eigen::Vector3f>> ray_cache_;
};

}  // namespace waymark::sim
