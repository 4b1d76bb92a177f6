#include "sim/ir_render.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <stdexcept>

namespace waymark::sim {
namespace {

constexpr int kSub = 4;  // sub-pixel rays per axis on surface boundaries

std::mt19937_64 Rng(std::uint64_t seed, std::uint64_t a, std::uint64_t b) {
  std::seed_seq seq{static_cast<std::uint32_t>(seed), static_cast<std::uint32_t>(seed >> 32),
                    static_cast<std::uint32_t>(a), static_cast<std::uint32_t>(a >> 32),
                    static_cast<std::uint32_t>(b)};
  return std::mt19937_64(seq);
}

// x bounced between lo and hi (a triangle wave of x - lo).
double Bounce(double x, double lo, double hi) {
  const double span = hi - lo;
  if (span <= 0.0) return lo;
  double u = std::fmod(x - lo, 2.0 * span);
  if (u < 0.0) u += 2.0 * span;
  return lo + (u <= span ? u : 2.0 * span - u);
}

bool Fail(std::string* why, const std::string& reason) {
  if (why != nullptr) *why = reason;
  return false;
}

}  // namespace

bool IrOptions::Check(std::string* why) const {
  if (!(fov_deg > 0.0 && fov_deg <= 180.0)) return Fail(why, "ir.fov_deg: expected in (0, 180]");
  if (!(ambient >= 0.0) || !(led_gain >= 0.0) || !(led_diffuse >= 0.0) || !(lamp_level >= 0.0)) {
    return Fail(why, "ir: light levels must be >= 0");
  }
  for (double albedo : {ceiling_albedo, tape_albedo, person_albedo}) {
    if (!(albedo >= 0.0 && albedo <= 1.0)) return Fail(why, "ir: albedos must be in [0, 1]");
  }
  if (lamps < 0 || people < 0) return Fail(why, "ir.lamps, ir.people: expected >= 0");
  if (!(lamp_radius_m > 0.0) || !(person_radius_m > 0.0) || !(person_height_m > 0.0)) {
    return Fail(why, "ir: lamp and person sizes must be > 0");
  }
  if (!(pair_gap_s >= 0.0) || !(person_speed_mps >= 0.0) || !(lamp_flicker >= 0.0)) {
    return Fail(why, "ir.pair_gap_s, ir.person_speed_mps, ir.lamp_flicker: expected >= 0");
  }
  if (!(blur_sigma_px >= 0.0) || !(noise_sigma >= 0.0))
    return Fail(why, "ir.blur_sigma_px, ir.noise_sigma: expected >= 0");
  return true;
}

void AddIrParams(ParamSet* p) {
  const IrOptions d;
  p->AddDouble("ir.ambient", d.ambient, 0.0, 255.0,
               "gray level of a white surface in the room light (both frames)");
  p->AddDouble("ir.led_gain", d.led_gain, 0.0, 1000.0,
               "tape brightness added by the LEDs, on-axis (gray levels)");
  p->AddDouble("ir.led_exponent", d.led_exponent, -5.0, 20.0,
               "LED layout: cos(theta)^p (< 0: brighter off-axis, as the paper's tilted narrow LEDs)");
  p->AddDouble("ir.incidence_exponent", d.incidence_exponent, 0.0, 20.0, "tape reflection: cos(incidence)^q");
  p->AddDouble("ir.led_diffuse", d.led_diffuse, 0.0, 1000.0, "diffuse LED light on a white surface at 1 m");
  p->AddInt("ir.lamps", d.lamps, 0, 100, "ceiling lamps (bright discs) near the first square");
  p->AddDouble("ir.lamp_radius_m", d.lamp_radius_m, 0.01, 2.0, "lamp radius");
  p->AddDouble("ir.lamp_level", d.lamp_level, 0.0, 1000.0, "lamp brightness (gray levels; saturates at 255)");
  p->AddDouble("ir.lamp_flicker", d.lamp_flicker, 0.0, 1.0, "lamp brightness spread per frame (relative)");
  p->AddInt("ir.people", d.people, 0, 100, "people walking through the room");
  p->AddDouble("ir.person_speed_mps", d.person_speed_mps, 0.0, 5.0, "walking speed");
  p->AddDouble("ir.person_height_m", d.person_height_m, 0.1, 3.0, "person height (a vertical cylinder)");
  p->AddDouble("ir.person_radius_m", d.person_radius_m, 0.05, 1.0, "person radius");
  p->AddDouble("ir.pair_gap_s", d.pair_gap_s, 0.0, 1.0, "time from the LED-on frame to the LED-off frame");
  p->AddDouble("ir.blur_sigma_px", d.blur_sigma_px, 0.0, 10.0, "optical blur");
  p->AddDouble("ir.noise_sigma", d.noise_sigma, 0.0, 50.0, "pixel noise (gray levels)");
}

IrOptions IrOptionsFromParams(const ParamSet& p) {
  IrOptions o;
  o.fov_deg = p.Double("camera.fov_deg");
  o.ambient = p.Double("ir.ambient");
  o.led_gain = p.Double("ir.led_gain");
  o.led_exponent = p.Double("ir.led_exponent");
  o.incidence_exponent = p.Double("ir.incidence_exponent");
  o.led_diffuse = p.Double("ir.led_diffuse");
  o.lamps = static_cast<int>(p.Int("ir.lamps"));
  o.lamp_radius_m = p.Double("ir.lamp_radius_m");
  o.lamp_level = p.Double("ir.lamp_level");
  o.lamp_flicker = p.Double("ir.lamp_flicker");
  o.people = static_cast<int>(p.Int("ir.people"));
  o.person_speed_mps = p.Double("ir.person_speed_mps");
  o.person_height_m = p.Double("ir.person_height_m");
  o.person_radius_m = p.Double("ir.person_radius_m");
  o.pair_gap_s = p.Double("ir.pair_gap_s");
  o.blur_sigma_px = p.Double("ir.blur_sigma_px");
  o.noise_sigma = p.Double("ir.noise_sigma");
  return o;
}

IrRenderer::IrRenderer(const World& world, const IrRoom& room, const IrOptions& options, std::uint64_t seed)
    : room_(room), options_(options), seed_(seed) {
  std::string why;
  if (!options_.Check(&why)) throw std::invalid_argument(why);
  if (!((room_.room_max - room_.room_min).minCoeff() > 0.0))
    throw std::invalid_argument("ir: room without area");
  for (const SimMarker& m : world.markers) {
    if (m.key.family != kFamilySquare) continue;
    const SquareTape tape = m.square_tape.value_or(SquareTape{});
    squares_.push_back(
        {m.T_world_marker.inverse(), 0.5 * (m.size_m + tape.tape_width_m), SquareTapeRects(m.size_m, tape)});
  }
  std::mt19937_64 rng = Rng(seed, 0x1e0b1eULL, 0);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  for (int i = 0; i < options_.people; ++i) {
    const Eigen::Vector2d span = room_.room_max - room_.room_min;
    const Eigen::Vector2d start =
        room_.room_min + Eigen::Vector2d(uniform(rng) * span.x(), uniform(rng) * span.y());
    const double a = 2.0 * M_PI * uniform(rng);
    walkers_.push_back({start, Eigen::Vector2d(std::cos(a), std::sin(a))});
  }
}

std::vector<Eigen::Vector2d> IrRenderer::PeopleAt(double stamp_s) const {
  std::vector<Eigen::Vector2d> people;
  const double r = options_.person_radius_m;
  for (const Walker& w : walkers_) {
    const Eigen::Vector2d p = w.start + options_.person_speed_mps * stamp_s * w.direction;
    people.emplace_back(Bounce(p.x(), room_.room_min.x() + r, room_.room_max.x() - r),
                        Bounce(p.y(), room_.room_min.y() + r, room_.room_max.y() - r));
  }
  return people;
}

const std::vector<Eigen::Vector3f>& IrRenderer::PixelRays(const Camera& camera) const {
  std::string key = camera.name() + " " + CameraModelName(camera.info().model);
  for (double v : camera.info().intrinsics) key += " " + FormatDouble(v);
  for (double v : camera.info().distortion) key += " " + FormatDouble(v);
  key += " " + std::to_string(camera.width()) + "x" + std::to_string(camera.height());
  auto it = ray_cache_.find(key);
  if (it != ray_cache_.end()) return it->second;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const double max_theta = 0.5 * options_.fov_deg * M_PI / 180.0;
  std::vector<Eigen::Vector3f> rays(static_cast<size_t>(camera.width()) * camera.height());
  cv::parallel_for_(cv::Range(0, camera.height()), [&](const cv::Range& range) {
    for (int r = range.start; r < range.end; ++r) {
      for (int c = 0; c < camera.width(); ++c) {
        const std::optional<Eigen::Vector3d> ray = camera.Unproject(Eigen::Vector2d(c, r));
        Eigen::Vector3f& out = rays[static_cast<size_t>(r) * camera.width() + c];
        out = Eigen::Vector3f(nan, nan, nan);
        if (ray && std::atan(ray->head<2>().norm()) <= max_theta) out = ray->cast<float>();
      }
    }
  });
  return ray_cache_.emplace(key, std::move(rays)).first->second;
}

IrRenderer::Hit IrRenderer::Shade(const Eigen::Vector3d& c, const Eigen::Vector3d& d_in,
                                  const Eigen::Vector3d& axis, const std::vector<Eigen::Vector2d>& people,
                                  bool led_on, double lamp_level) const {
  const Eigen::Vector3d d = d_in.normalized();
  const IrOptions& o = options_;
  // People: the nearest vertical cylinder the ray enters between the floor and its top.
  double t_best = std::numeric_limits<double>::infinity();
  for (const Eigen::Vector2d& p : people) {
    const Eigen::Vector2d q = c.head<2>() - p;
    if (q.norm() <= o.person_radius_m) continue;  // the camera would be inside: nobody stands on the robot
    const double a = d.head<2>().squaredNorm(), b = q.dot(d.head<2>()),
                 cc = q.squaredNorm() - o.person_radius_m * o.person_radius_m;
    const double disc = b * b - a * cc;
    if (a <= 0.0 || disc < 0.0) continue;
    const double t = (-b - std::sqrt(disc)) / a;
    const double z = c.z() + t * d.z();
    if (t > 0.0 && t < t_best && z >= 0.0 && z <= o.person_height_m) t_best = t;
  }
  const double t_ceiling =
      d.z() > 1e-9 ? (room_.ceiling_z - c.z()) / d.z() : std::numeric_limits<double>::infinity();
  if (t_best < t_ceiling) {
    double value = o.ambient * o.person_albedo;
    if (led_on) value += o.led_diffuse * o.person_albedo / std::max(1e-2, t_best * t_best);
    return {kPerson, value};
  }
  if (!std::isfinite(t_ceiling)) return {kWall, o.ambient * 0.7};
  const Eigen::Vector3d hit = c + t_ceiling * d;
  const double dist2 = t_ceiling * t_ceiling;
  if ((hit.head<2>().array() < room_.room_min.array()).any() ||
      (hit.head<2>().array() > room_.room_max.array()).any()) {
    return {kWall, o.ambient * 0.7 + (led_on ? o.led_diffuse * 0.7 / dist2 : 0.0)};
  }
  for (const Eigen::Vector2d& lamp : room_.lamps) {
    if ((hit.head<2>() - lamp).squaredNorm() <= o.lamp_radius_m * o.lamp_radius_m) return {kLamp, lamp_level};
  }
  const double cos_incidence = d.z();
  for (const Square& square : squares_) {
    const Eigen::Vector3d p = square.T_marker_world * hit;
    if (std::abs(p.x()) > square.half_extent_m || std::abs(p.y()) > square.half_extent_m) continue;
    for (const TapeRect& rect : square.rects) {
      if (!rect.Contains(p.head<2>())) continue;
      double value = o.ambient * o.tape_albedo;
      if (led_on) {
        const double z0 = room_.ceiling_z - c.z();
        const double cos_theta = std::max(0.0, d.dot(axis));
        value += o.led_gain * (z0 * z0 / dist2) * std::pow(cos_theta, o.led_exponent) *
                 std::pow(std::max(0.0, cos_incidence), o.incidence_exponent);
      }
      return {kTape, value};
    }
  }
  double value = o.ambient * o.ceiling_albedo;
  if (led_on) value += o.led_diffuse * o.ceiling_albedo * cos_incidence / dist2;
  return {kCeiling, value};
}

cv::Mat IrRenderer::Render(const Camera& camera, const SE3d& T_world_camera, double stamp_s, bool led_on,
                           std::uint64_t frame_index) const {
  const std::vector<Eigen::Vector3f>& rays = PixelRays(camera);
  const int width = camera.width(), height = camera.height();
  const Eigen::Matrix3d R = T_world_camera.rotation_matrix();
  const Eigen::Vector3d c = T_world_camera.translation(), axis = R.col(2);
  const std::vector<Eigen::Vector2d> people = PeopleAt(stamp_s);
  std::mt19937_64 rng = Rng(seed_, frame_index, led_on ? 1 : 2);
  std::normal_distribution<double> normal(0.0, 1.0);
  const double lamp_level = options_.lamp_level * std::max(0.0, 1.0 + options_.lamp_flicker * normal(rng));

  cv::Mat value(height, width, CV_32F, cv::Scalar(0.0f));
  cv::Mat surface(height, width, CV_8U, cv::Scalar(kNone));
  cv::parallel_for_(cv::Range(0, height), [&](const cv::Range& range) {
    for (int r = range.start; r < range.end; ++r) {
      for (int col = 0; col < width; ++col) {
        const Eigen::Vector3f& ray = rays[static_cast<size_t>(r) * width + col];
        if (!ray.allFinite()) continue;
        const Hit hit = Shade(c, R * ray.cast<double>(), axis, people, led_on, lamp_level);
        value.at<float>(r, col) = static_cast<float>(hit.value);
        surface.at<std::uint8_t>(r, col) = hit.surface;
      }
    }
  });
  // Supersample where a pixel's surface differs from a neighbour's.
  cv::parallel_for_(cv::Range(1, height - 1), [&](const cv::Range& range) {
    for (int r = range.start; r < range.end; ++r) {
      for (int col = 1; col < width - 1; ++col) {
        const std::uint8_t s = surface.at<std::uint8_t>(r, col);
        if (s == kNone) continue;
        if (surface.at<std::uint8_t>(r - 1, col) == s && surface.at<std::uint8_t>(r + 1, col) == s &&
            surface.at<std::uint8_t>(r, col - 1) == s && surface.at<std::uint8_t>(r, col + 1) == s) {
          continue;
        }
        double sum = 0.0;
        int count = 0;
        for (int i = 0; i < kSub; ++i) {
          for (int j = 0; j < kSub; ++j) {
            const double dx = (j + 0.5) / kSub - 0.5, dy = (i + 0.5) / kSub - 0.5;
            // Bilinear between the pixel-centre rays around the sub-pixel.
            const int c0 = dx < 0.0 ? col - 1 : col, r0 = dy < 0.0 ? r - 1 : r;
            const double fx = dx < 0.0 ? 1.0 + dx : dx, fy = dy < 0.0 ? 1.0 + dy : dy;
            const auto at = [&](int rr, int cc) {
              return rays[static_cast<size_t>(rr) * width + cc].cast<double>();
            };
            const Eigen::Vector3d ray = (1 - fy) * ((1 - fx) * at(r0, c0) + fx * at(r0, c0 + 1)) +
                                        fy * ((1 - fx) * at(r0 + 1, c0) + fx * at(r0 + 1, c0 + 1));
            if (!ray.allFinite()) continue;
            sum += Shade(c, R * ray, axis, people, led_on, lamp_level).value;
            ++count;
          }
        }
        if (count > 0) value.at<float>(r, col) = static_cast<float>(sum / count);
      }
    }
  });
  if (options_.blur_sigma_px > 0.0) cv::GaussianBlur(value, value, cv::Size(0, 0), options_.blur_sigma_px);
  cv::Mat image(height, width, CV_8U);
  for (int r = 0; r < height; ++r) {
    for (int col = 0; col < width; ++col) {
      const double v = value.at<float>(r, col) + options_.noise_sigma * normal(rng);
      image.at<std::uint8_t>(r, col) = static_cast<std::uint8_t>(std::clamp(std::lround(v), 0L, 255L));
    }
  }
  return image;
}

}  // namespace waymark::sim
