#include "sim/render.h"

#include <algorithm>
#include <cmath>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <sstream>
#include <stdexcept>

#include "detect/synthetic.h"
#include "util/check.h"

namespace waymark::sim {

// A code's symbol as a texture on its marker plane (see the header for the mapping).
struct CodeTexture {
  cv::Mat modules;        // 0 dark, 255 light, quiet zone included
  cv::Rect symbol;        // in modules
  double module_m = 0.0;  // module edge on the plane
  double size_m = 0.0;
};

namespace {

constexpr float kDarkAlbedo = 0.06f;
constexpr float kLightAlbedo = 0.85f;
constexpr double kCodeWinsRelative = 1e-5;  // coplanar code vs wall: the printed code wins
constexpr int kOutlineSamplesPerEdge = 16;
constexpr double kMinRayDepth = 1e-9;  // nearest hit along a ray (z = 1 normalized)
// Pixels per side of the tiles over which the background surfaces are culled.
constexpr int kTilePx = 32;
constexpr double kBoxPaddingPx = 2.0;
// Sub-samples per pixel axis of the optical blur around codes (see BlurAlbedo).
constexpr int kBlurSupersample = 4;

// Pixels around a code that its optical blur reaches: 4 sigma + 1, more than the radius of
// OpenCV's float Gaussian kernel (ksize = round(8 sigma + 1) | 1).
int BlurReachPx(double sigma_px) { return static_cast<int>(std::ceil(4.0 * sigma_px)) + 1; }

enum class SurfaceKind { kWall, kFloor, kCeiling, kCode };

// A plane in the camera frame: n_camera . p = d_camera; points map into the plane frame by
// p_plane = R_plane_camera p_camera + t_plane_camera.
struct Surface {
  SurfaceKind kind = SurfaceKind::kWall;
  int index = 0;  // occluder or code index
  Eigen::Matrix3d R_plane_camera;
  Eigen::Vector3d t_plane_camera;
  Eigen::Vector3d n_camera;
  double d_camera = 0.0;
  double half_width_m = 0.0;  // walls only; floor and ceiling are unbounded
  double half_height_m = 0.0;
  cv::Rect box_px;  // codes only: pixels that can see it
  int id = 0;       // background only: its index in FramePlanes::background
  // Walls only: bounding box of the wall's part in front of the camera, projected on the
  // normalized image plane (x/z, y/z), where the cached rays (x, y, 1) live; a ray outside
  // it cannot hit the wall. Empty when the wall is wholly behind the camera.
  bool bounded = false;
  Eigen::AlignedBox2d view_box;
};

Surface MakeSurface(SurfaceKind kind, int index, const SE3d& T_camera_world, const SE3d& T_world_plane) {
  const SE3d T_camera_plane = T_camera_world * T_world_plane;
  const SE3d T_plane_camera = T_camera_plane.inverse();
  Surface s;
  s.kind = kind;
  s.index = index;
  s.R_plane_camera = T_plane_camera.rotation();
  s.t_plane_camera = T_plane_camera.translation();
  s.n_camera = T_camera_plane.rotation() * Eigen::Vector3d::UnitZ();
  s.d_camera = s.n_camera.dot(T_camera_plane.translation());
  return s;
}

// Integer lattice hash -> [0, 1).
float Hash(int ix, int iy, int salt) {
  std::uint32_t h = static_cast<std::uint32_t>(ix) * 0x8da6b343u ^
                    static_cast<std::uint32_t>(iy) * 0xd8163841u ^
                    static_cast<std::uint32_t>(salt) * 0xcb1ab31fu;
  h ^= h >> 13;
  h *= 0x5bd1e995u;
  h ^= h >> 15;
  return static_cast<float>(h & 0xffffffu) / 16777216.0f;
}

// Smooth value noise in [0, 1) at (x, y) / cell_m.
float ValueNoise(double x, double y, double cell_m, int salt) {
  const double u = x / cell_m, v = y / cell_m;
  const double fu = std::floor(u), fv = std::floor(v);
  const int iu = static_cast<int>(fu), iv = static_cast<int>(fv);
  const double a = u - fu, b = v - fv;
  const double sa = a * a * (3.0 - 2.0 * a), sb = b * b * (3.0 - 2.0 * b);
  const double top = Hash(iu, iv, salt) * (1.0 - sa) + Hash(iu + 1, iv, salt) * sa;
  const double bottom = Hash(iu, iv + 1, salt) * (1.0 - sa) + Hash(iu + 1, iv + 1, salt) * sa;
  return static_cast<float>(top * (1.0 - sb) + bottom * sb);
}

float BackgroundAlbedo(const Surface& s, const Eigen::Vector3d& p_plane, double contrast) {
  const double x = p_plane.x(), y = p_plane.y();
  const int salt = static_cast<int>(s.kind) * 1000 + s.index;
  const double texture =
      contrast * (ValueNoise(x, y, 0.06, salt) - 0.5 + ValueNoise(x, y, 0.45, salt + 7) - 0.5);
  switch (s.kind) {
    case SurfaceKind::kFloor: {
      const double jx = std::abs(x - 0.5 * std::round(x / 0.5)), jy = std::abs(y - 0.5 * std::round(y / 0.5));
      const double joint = (jx < 0.004 || jy < 0.004) ? -0.12 : 0.0;
      return static_cast<float>(0.38 + texture + joint);
    }
    case SurfaceKind::kCeiling:
      return static_cast<float>(0.72 + texture);
    default:
      return static_cast<float>(0.55 + texture);
  }
}

CodeTexture MakeCodeTexture(const SimMarker& marker) {
  const std::string& family = marker.key.family;
  SymbolImage symbol;
  if (family == "qr") {
    symbol = QrSymbol(marker.key.id);
  } else if (family == "datamatrix") {
    symbol = DataMatrixSymbol(marker.key.id);
  } else if (family.rfind("apriltag-", 0) == 0) {
    size_t used = 0;
    int id = -1;
    try {
      id = std::stoi(marker.key.id, &used);
    } catch (const std::exception&) {
    }
    if (id < 0 || used != marker.key.id.size()) {
      throw std::invalid_argument("render: AprilTag id '" + marker.key.id + "' is not a tag number");
    }
    symbol = AprilTagSymbol(family, id);
  } else {
    throw std::invalid_argument("render: cannot draw family '" + family + "'");
  }
  if (!(marker.size_m > 0.0))
    throw std::invalid_argument("render: code " + marker.key.ToString() + " has no size");
  CodeTexture texture;
  cv::copyMakeBorder(symbol.modules, texture.modules, kExtraQuietModules, kExtraQuietModules,
                     kExtraQuietModules, kExtraQuietModules, cv::BORDER_CONSTANT, cv::Scalar(255));
  texture.symbol = symbol.symbol + cv::Point(kExtraQuietModules, kExtraQuietModules);
  texture.module_m = marker.size_m / symbol.symbol.width;
  texture.size_m = marker.size_m;
  return texture;
}

// Module of the code texture at p_marker, or -1 outside the quiet zone.
int CodeModule(const CodeTexture& code, const Eigen::Vector3d& p_marker) {
  const double col = code.symbol.x + (p_marker.x() + 0.5 * code.size_m) / code.module_m;
  const double row = code.symbol.y + (0.5 * code.size_m - p_marker.y()) / code.module_m;
  if (!(col >= 0.0 && row >= 0.0 && col < code.modules.cols && row < code.modules.rows)) return -1;
  return code.modules.at<std::uint8_t>(static_cast<int>(row), static_cast<int>(col));
}

// The part of a wall in front of the camera (z >= kMinRayDepth), projected on the
// normalized image plane: its bounding box (empty if none). The polygon is clipped against
// the plane z = kMinRayDepth (Sutherland-Hodgman with one plane).
Eigen::AlignedBox2d WallViewBox(const SE3d& T_camera_panel, double half_width_m, double half_height_m) {
  const double sx[4] = {-1.0, 1.0, 1.0, -1.0}, sy[4] = {-1.0, -1.0, 1.0, 1.0};
  Eigen::Vector3d corner_camera[4];
  for (int k = 0; k < 4; ++k) {
    corner_camera[k] = T_camera_panel * Eigen::Vector3d(sx[k] * half_width_m, sy[k] * half_height_m, 0.0);
  }
  Eigen::AlignedBox2d box;  // empty
  for (int k = 0; k < 4; ++k) {
    const Eigen::Vector3d& a = corner_camera[k];
    const Eigen::Vector3d& b = corner_camera[(k + 1) % 4];
    if (a.z() >= kMinRayDepth) box.extend(Eigen::Vector2d(a.x() / a.z(), a.y() / a.z()));
    if ((a.z() >= kMinRayDepth) != (b.z() >= kMinRayDepth)) {  // the edge crosses the clip plane
      const Eigen::Vector3d c = a + (kMinRayDepth - a.z()) / (b.z() - a.z()) * (b - a);
      box.extend(Eigen::Vector2d(c.x() / kMinRayDepth, c.y() / kMinRayDepth));
    }
  }
  return box;
}

// Pixel box of the rays (cached, through pixel centres) inside the normalized-plane box
// `view` widened by `margin`; empty if none. Rays outside the lens' field of view are NaN
// and never inside.
cv::Rect RayBoxPixels(const Camera& camera, const std::vector<Eigen::Vector3f>& rays,
                      const Eigen::AlignedBox2d& view, double margin) {
  int min_c = camera.width(), min_r = camera.height(), max_c = -1, max_r = -1;
  const double x0 = view.min().x() - margin, x1 = view.max().x() + margin;
  const double y0 = view.min().y() - margin, y1 = view.max().y() + margin;
  for (int r = 0; r < camera.height(); ++r) {
    const Eigen::Vector3f* row = &rays[static_cast<size_t>(r) * camera.width()];
    for (int c = 0; c < camera.width(); ++c) {
      if (!(row[c].x() >= x0 && row[c].x() <= x1 && row[c].y() >= y0 && row[c].y() <= y1)) continue;
      min_c = std::min(min_c, c), max_c = std::max(max_c, c);
      min_r = std::min(min_r, r), max_r = std::max(max_r, r);
    }
  }
  if (max_c < 0) return cv::Rect();
  return cv::Rect(cv::Point(min_c, min_r), cv::Point(max_c + 1, max_r + 1));
}

// Pixel box that can see the code's quiet-zone outline; empty if none. A code wholly in
// front of the camera: the outline sampled at 16 points per edge, projected, padded by
// kBoxPaddingPx. A code crossing the camera plane: the pixels whose ray meets the view box
// of its part in front (WallViewBox), widened by kBoxPaddingPx pixels' worth.
cv::Rect CodeBox(const Camera& camera, const std::vector<Eigen::Vector3f>& rays, const CodeTexture& code,
                 const SE3d& T_camera_marker) {
  const double m = code.module_m;
  const double x0 = -0.5 * code.size_m - code.symbol.x * m;
  const double y1 = 0.5 * code.size_m + code.symbol.y * m;
  const double x1 = x0 + code.modules.cols * m, y0 = y1 - code.modules.rows * m;
  const Eigen::Vector2d outline[4] = {{x0, y1}, {x1, y1}, {x1, y0}, {x0, y0}};
  const cv::Rect image(0, 0, camera.width(), camera.height());
  double min_x = 1e18, min_y = 1e18, max_x = -1e18, max_y = -1e18;
  int behind = 0;
  for (int corner = 0; corner < 4; ++corner) {
    behind +=
        (T_camera_marker * Eigen::Vector3d(outline[corner].x(), outline[corner].y(), 0.0)).z() <= kMinDepth;
  }
  if (behind == 4) return cv::Rect();  // wholly behind the camera
  if (behind > 0) {                    // straddles the camera plane
    const SE3d T_camera_outline =
        T_camera_marker *
        SE3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.5 * (x0 + x1), 0.5 * (y0 + y1), 0.0));
    const Eigen::AlignedBox2d view = WallViewBox(T_camera_outline, 0.5 * (x1 - x0), 0.5 * (y1 - y0));
    const auto& k = camera.info().intrinsics;
    return view.isEmpty() ? cv::Rect()
                          : RayBoxPixels(camera, rays, view, (kBoxPaddingPx + 1.0) / std::min(k[0], k[1]));
  }
  for (int edge = 0; edge < 4; ++edge) {
    for (int k = 0; k < kOutlineSamplesPerEdge; ++k) {
      const double a = static_cast<double>(k) / kOutlineSamplesPerEdge;
      const Eigen::Vector2d q = (1.0 - a) * outline[edge] + a * outline[(edge + 1) % 4];
      const Eigen::Vector3d p_camera = T_camera_marker * Eigen::Vector3d(q.x(), q.y(), 0.0);
      const std::optional<Eigen::Vector2d> px = camera.Project(p_camera);
      if (!px) continue;  // beyond the lens model's field of view: no pixel sees it
      min_x = std::min(min_x, px->x()), max_x = std::max(max_x, px->x());
      min_y = std::min(min_y, px->y()), max_y = std::max(max_y, px->y());
    }
  }
  if (min_x > max_x) return cv::Rect();
  const double lo_x = std::max(-1.0, min_x - kBoxPaddingPx), lo_y = std::max(-1.0, min_y - kBoxPaddingPx);
  const double hi_x = std::min(camera.width() + 1.0, max_x + kBoxPaddingPx);
  const double hi_y = std::min(camera.height() + 1.0, max_y + kBoxPaddingPx);
  if (lo_x > hi_x || lo_y > hi_y) return cv::Rect();
  const cv::Rect box(cv::Point(static_cast<int>(std::floor(lo_x)), static_cast<int>(std::floor(lo_y))),
                     cv::Point(static_cast<int>(std::ceil(hi_x)) + 1, static_cast<int>(std::ceil(hi_y)) + 1));
  return box & image;
}

// Depth of the ray's hit with `s`, or +inf; *p_plane receives the point on the plane.
double Intersect(const Surface& s, const Eigen::Vector3d& ray_camera, Eigen::Vector3d* p_plane) {
  const double denom = s.n_camera.dot(ray_camera);
  if (std::abs(denom) < 1e-12) return INFINITY;
  const double t = s.d_camera / denom;
  if (!(t > kMinRayDepth)) return INFINITY;
  *p_plane = s.R_plane_camera * (t * ray_camera) + s.t_plane_camera;
  if (s.kind == SurfaceKind::kWall &&
      (std::abs(p_plane->x()) > s.half_width_m || std::abs(p_plane->y()) > s.half_height_m)) {
    return INFINITY;
  }
  return t;
}

// The surfaces of one frame: background (walls, floor, ceiling) and the codes facing the
// camera whose box is not empty.
struct FramePlanes {
  std::vector<Surface> background;
  std::vector<Surface> codes;
};

// Albedo seen along ray_camera (z = 1 normalized), and the id of the surface it hit
// (-1: nothing; codes are numbered after the background surfaces). `background` holds the
// surfaces the ray can hit, in FramePlanes order (the first of equal depths wins).
float Shade(const Eigen::Vector3d& ray_camera, const std::vector<const Surface*>& background,
            const std::vector<const Surface*>& codes, const std::vector<CodeTexture>& textures,
            int background_count, double contrast, int* surface_id) {
  double best_t = INFINITY;
  const Surface* best = nullptr;
  Eigen::Vector3d p_plane, best_p_plane;
  for (const Surface* s : background) {
    const double t = Intersect(*s, ray_camera, &p_plane);
    if (t < best_t) {
      best_t = t;
      best = s;
      best_p_plane = p_plane;
    }
  }
  float albedo = best != nullptr ? BackgroundAlbedo(*best, best_p_plane, contrast) : 0.0f;
  *surface_id = best != nullptr ? best->id : -1;
  double best_code_t = INFINITY;
  for (const Surface* s : codes) {
    const double t = Intersect(*s, ray_camera, &p_plane);
    if (!(t <= best_t * (1.0 + kCodeWinsRelative)) || t >= best_code_t) continue;
    const int module = CodeModule(textures[s->index], p_plane);
    if (module < 0) continue;
    best_code_t = t;
    albedo = module < 128 ? kDarkAlbedo : kLightAlbedo;
    *surface_id = background_count + s->index;
  }
  return albedo;
}

}  // namespace

bool RenderOptions::Check(std::string* why) const {
  WAYMARK_CHECK_OPTION(supersample >= 1 && supersample <= 16, "render.supersample must be in [1, 16]");
  WAYMARK_CHECK_OPTION(blur_sigma_px >= 0.0 && blur_sigma_px <= 20.0,
                       "render.blur_sigma_px must be in [0, 20]");
  WAYMARK_CHECK_OPTION(noise_sigma >= 0.0 && noise_sigma <= 100.0, "render.noise_sigma must be in [0, 100]");
  WAYMARK_CHECK_OPTION(gradient >= 0.0 && gradient < 1.0, "render.gradient must be in [0, 1)");
  WAYMARK_CHECK_OPTION(exposure_sigma >= 0.0 && exposure_sigma <= 2.0,
                       "render.exposure_sigma must be in [0, 2]");
  WAYMARK_CHECK_OPTION(texture_contrast >= 0.0 && texture_contrast <= 0.5,
                       "render.texture_contrast must be in [0, 0.5]");
  return true;
}

void AddRenderParams(ParamSet* params) {
  const RenderOptions d;
  params->AddInt("render.supersample", d.supersample, 1, 16, "sub-pixel rays per axis on codes and edges");
  params->AddDouble("render.blur_sigma_px", d.blur_sigma_px, 0.0, 20.0, "Gaussian blur sigma (px); 0 = none");
  params->AddDouble("render.noise_sigma", d.noise_sigma, 0.0, 100.0,
                    "pixel noise sigma (gray levels of 255)");
  params->AddDouble("render.gradient", d.gradient, 0.0, 0.99,
                    "illumination change from the image centre to its side (relative)");
  params->AddDouble("render.exposure_sigma", d.exposure_sigma, 0.0, 2.0, "per-image log-exposure sigma");
  params->AddDouble("render.texture_contrast", d.texture_contrast, 0.0, 0.5,
                    "albedo amplitude of the wall, floor and ceiling texture");
}

RenderOptions RenderOptionsFromParams(const ParamSet& params) {
  RenderOptions o;
  o.supersample = static_cast<int>(params.Int("render.supersample"));
  o.blur_sigma_px = params.Double("render.blur_sigma_px");
  o.noise_sigma = params.Double("render.noise_sigma");
  o.gradient = params.Double("render.gradient");
  o.exposure_sigma = params.Double("render.exposure_sigma");
  o.texture_contrast = params.Double("render.texture_contrast");
  return o;
}

Renderer::Renderer(const World& world, const RenderOptions& options) : world_(world), options_(options) {
  std::string why;
  if (!options_.Check(&why)) throw std::invalid_argument(why);
  double top_m = 0.0;
  for (const SimMarker& m : world_.markers) {
    codes_.push_back(MakeCodeTexture(m));
    top_m = std::max(top_m, m.T_world_marker.translation().z());
  }
  for (const Occluder& o : world_.occluders) {
    for (double sy : {-1.0, 1.0}) {
      top_m = std::max(top_m, (o.T_world_panel * Eigen::Vector3d(0.0, sy * o.half_height_m, 0.0)).z());
    }
  }
  ceiling_z_m_ = top_m < 2.0 ? 2.5 : top_m;
}

Renderer::~Renderer() = default;

const std::vector<Eigen::Vector3f>& Renderer::PixelRays(const Camera& camera) const {
  std::ostringstream key;
  key.precision(17);
  key << camera.name() << " " << camera.width() << "x" << camera.height();
  for (double v : camera.info().intrinsics) key << " " << v;
  for (double v : camera.info().distortion) key << " " << v;
  auto [it, inserted] = ray_cache_.emplace(key.str(), std::vector<Eigen::Vector3f>());
  if (!inserted) return it->second;
  std::vector<Eigen::Vector3f>& rays = it->second;
  rays.resize(static_cast<size_t>(camera.width()) * camera.height());
  for (int r = 0; r < camera.height(); ++r) {
    for (int c = 0; c < camera.width(); ++c) {
      const std::optional<Eigen::Vector3d> ray = camera.Unproject(Eigen::Vector2d(c, r));
      rays[static_cast<size_t>(r) * camera.width() + c] =
          ray ? Eigen::Vector3f(ray->cast<float>()) : Eigen::Vector3f::Constant(NAN);
    }
  }
  return rays;
}

namespace {

// The planes a camera at T_world_camera sees: walls, floor, ceiling, and the codes facing it.
FramePlanes MakeFramePlanes(const World& world, const std::vector<CodeTexture>& textures, double ceiling_z_m,
                            const Camera& camera, const std::vector<Eigen::Vector3f>& rays,
                            const SE3d& T_world_camera) {
  const SE3d T_camera_world = T_world_camera.inverse();
  FramePlanes planes;
  for (size_t i = 0; i < world.occluders.size(); ++i) {
    const Occluder& o = world.occluders[i];
    Surface s = MakeSurface(SurfaceKind::kWall, static_cast<int>(i), T_camera_world, o.T_world_panel);
    s.half_width_m = o.half_width_m;
    s.half_height_m = o.half_height_m;
    s.bounded = true;
    s.view_box = WallViewBox(T_camera_world * o.T_world_panel, o.half_width_m, o.half_height_m);
    planes.background.push_back(s);
  }
  planes.background.push_back(MakeSurface(SurfaceKind::kFloor, 0, T_camera_world, SE3d()));
  planes.background.push_back(
      MakeSurface(SurfaceKind::kCeiling, 0, T_camera_world,
                  SE3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.0, 0.0, ceiling_z_m))));
  for (size_t i = 0; i < planes.background.size(); ++i) planes.background[i].id = static_cast<int>(i);
  for (size_t i = 0; i < world.markers.size(); ++i) {
    const SE3d T_camera_marker = T_camera_world * world.markers[i].T_world_marker;
    Surface s =
        MakeSurface(SurfaceKind::kCode, static_cast<int>(i), T_camera_world, world.markers[i].T_world_marker);
    if (s.t_plane_camera.z() <= 0.0) continue;  // seen from behind (or edge-on)
    s.box_px = CodeBox(camera, rays, textures[i], T_camera_marker);
    if (!s.box_px.empty()) planes.codes.push_back(s);
  }
  return planes;
}

// The background surfaces that a ray through the pixels of `tile_px` (sub-pixel positions
// included) can hit, in FramePlanes order. The tile's rays lie in the bounding box of the
// cached rays of its pixels, widened by two pixels' worth (2 / f: sub-pixel offsets, the
// image border where rays are unprojected directly, rounding); a wall whose view box misses
// it is left out. A tile with a ray outside the lens' field of view keeps every surface.
std::vector<const Surface*> TileBackground(const Camera& camera, const std::vector<Eigen::Vector3f>& rays,
                                           const FramePlanes& planes, const cv::Rect& tile_px) {
  const cv::Rect tile = tile_px & cv::Rect(0, 0, camera.width(), camera.height());
  Eigen::AlignedBox2d ray_box;
  bool all_finite = !tile.empty();
  for (int r = tile.y; r < tile.y + tile.height && all_finite; ++r) {
    const Eigen::Vector3f* row = &rays[static_cast<size_t>(r) * camera.width()];
    for (int c = tile.x; c < tile.x + tile.width; ++c) {
      if (!std::isfinite(row[c].x() + row[c].y())) all_finite = false;
      ray_box.extend(Eigen::Vector2d(row[c].x(), row[c].y()));
    }
  }
  const auto& k = camera.info().intrinsics;
  const double margin = 2.0 / std::min(k[0], k[1]);
  ray_box.min().array() -= margin;
  ray_box.max().array() += margin;
  std::vector<const Surface*> out;
  for (const Surface& s : planes.background) {
    if (all_finite && s.bounded && !s.view_box.intersects(ray_box)) continue;
    out.push_back(&s);
  }
  return out;
}

// The codes whose pixel box meets `rect`.
std::vector<const Surface*> CodesIn(const FramePlanes& planes, const cv::Rect& rect) {
  std::vector<const Surface*> codes;
  for (const Surface& s : planes.codes) {
    if ((s.box_px & rect).area() > 0) codes.push_back(&s);
  }
  return codes;
}

// Calls body(tile) for the kTilePx tiles covering `rect`, rows of tiles in parallel (every
// pixel is computed on its own: the result does not depend on the split).
template <typename Body>
void ForEachTile(const cv::Rect& rect, const Body& body) {
  const int tiles_x = (rect.width + kTilePx - 1) / kTilePx, tiles_y = (rect.height + kTilePx - 1) / kTilePx;
  cv::parallel_for_(cv::Range(0, tiles_y), [&](const cv::Range& range) {
    for (int ty = range.start; ty < range.end; ++ty) {
      for (int tx = 0; tx < tiles_x; ++tx) {
        body(cv::Rect(rect.x + tx * kTilePx, rect.y + ty * kTilePx, kTilePx, kTilePx) & rect);
      }
    }
  });
}

// Ray through pixel (x, y): bilinear between the cached rays of the four nearest pixel
// centres (the lens model is smooth: the interpolation error is under 1e-4 px at 0.05 of
// k1), or Camera::Unproject at the image border and outside the lens' field of view.
std::optional<Eigen::Vector3d> InterpolatedRay(const Camera& camera, const std::vector<Eigen::Vector3f>& rays,
                                               double x, double y) {
  const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  if (x0 < 0 || y0 < 0 || x0 + 1 >= camera.width() || y0 + 1 >= camera.height()) {
    return camera.Unproject(Eigen::Vector2d(x, y));
  }
  const size_t i = static_cast<size_t>(y0) * camera.width() + x0;
  const Eigen::Vector3f& r00 = rays[i];
  const Eigen::Vector3f& r01 = rays[i + 1];
  const Eigen::Vector3f& r10 = rays[i + camera.width()];
  const Eigen::Vector3f& r11 = rays[i + camera.width() + 1];
  if (!std::isfinite(r00.x() + r01.x() + r10.x() + r11.x())) return camera.Unproject(Eigen::Vector2d(x, y));
  const double fx = x - x0, fy = y - y0;
  return (1.0 - fy) * ((1.0 - fx) * r00.cast<double>() + fx * r01.cast<double>()) +
         fy * ((1.0 - fx) * r10.cast<double>() + fx * r11.cast<double>());
}

// Albedo of `rect` (image pixels) at n x n points per pixel: an image n times the size of
// `rect` whose sample (i, j) is taken at a fixed pseudo-random point of the cell
// [rect.x - 0.5 + i / n, + 1 / n) x [rect.y - 0.5 + j / n, + 1 / n) (stratified: on a regular grid a
// nearly horizontal edge would move in steps of 1 / n px; jittered, it is right on average).
cv::Mat SupersampledAlbedo(const Camera& camera, const std::vector<Eigen::Vector3f>& rays,
                           const FramePlanes& planes, const std::vector<CodeTexture>& textures,
                           double contrast, const cv::Rect& rect, int n) {
  cv::Mat fine(rect.height * n, rect.width * n, CV_32F, cv::Scalar(0.0f));
  const std::vector<const Surface*> codes = CodesIn(planes, rect);
  const int background_count = static_cast<int>(planes.background.size());
  ForEachTile(rect, [&](const cv::Rect& tile) {
    const std::vector<const Surface*> background = TileBackground(camera, rays, planes, tile);
    int id = -1;
    for (int j = (tile.y - rect.y) * n; j < (tile.y - rect.y + tile.height) * n; ++j) {
      float* row = fine.ptr<float>(j);
      const int gj = rect.y * n + j;  // global sub-sample indices: the jitter does not depend on rect
      for (int i = (tile.x - rect.x) * n; i < (tile.x - rect.x + tile.width) * n; ++i) {
        const int gi = rect.x * n + i;
        const double x = -0.5 + (gi + Hash(gi, gj, 17)) / n;
        const double y = -0.5 + (gj + Hash(gi, gj, 29)) / n;
        const std::optional<Eigen::Vector3d> ray = InterpolatedRay(camera, rays, x, y);
        if (ray) row[i] = Shade(*ray, background, codes, textures, background_count, contrast, &id);
      }
    }
  });
  return fine;
}

// Pixels whose value cannot reach the image: deeper than `reach` inside a code box, when
// the optical blur (kernel radius < reach) later replaces the whole box (BlurAlbedo).
cv::Mat HiddenByCodeBlur(const FramePlanes& planes, cv::Size size, int reach) {
  cv::Mat hidden(size, CV_8U, cv::Scalar(0));
  for (const Surface& s : planes.codes) {
    const cv::Rect inner = cv::Rect(s.box_px.x + reach, s.box_px.y + reach, s.box_px.width - 2 * reach,
                                    s.box_px.height - 2 * reach);
    if (inner.width > 0 && inner.height > 0) hidden(inner & cv::Rect(cv::Point(), size)).setTo(1);
  }
  return hidden;
}

// Pixels to average over several rays: those that can see a code, and both pixels of every
// horizontally or vertically adjacent pair whose centres hit different surfaces.
cv::Mat FinePixels(const FramePlanes& planes, const cv::Mat& surface_id) {
  const int width = surface_id.cols, height = surface_id.rows;
  cv::Mat fine(height, width, CV_8U, cv::Scalar(0));
  for (const Surface& s : planes.codes) fine(s.box_px).setTo(1);
  for (int r = 0; r < height; ++r) {
    const int* id = surface_id.ptr<int>(r);
    const int* below = r + 1 < height ? surface_id.ptr<int>(r + 1) : nullptr;
    std::uint8_t* f = fine.ptr<std::uint8_t>(r);
    std::uint8_t* f_below = below != nullptr ? fine.ptr<std::uint8_t>(r + 1) : nullptr;
    for (int c = 0; c < width; ++c) {
      if (c + 1 < width && id[c + 1] != id[c]) f[c] = f[c + 1] = 1;
      if (below != nullptr && below[c] != id[c]) f[c] = f_below[c] = 1;
    }
  }
  return fine;
}

// Albedo of every pixel for one ray through its centre (cached rays); the id of the surface
// hit into *surface_id. Pixels marked in `skip` are left at 0 (id -1).
void CentreRayAlbedo(const Camera& camera, const std::vector<Eigen::Vector3f>& rays,
                     const FramePlanes& planes, const std::vector<CodeTexture>& textures, double contrast,
                     const cv::Mat& skip, cv::Mat* albedo, cv::Mat* surface_id) {
  const std::vector<const Surface*> no_codes;
  const int background_count = static_cast<int>(planes.background.size());
  ForEachTile(cv::Rect(0, 0, camera.width(), camera.height()), [&](const cv::Rect& tile) {
    const std::vector<const Surface*> background = TileBackground(camera, rays, planes, tile);
    for (int r = tile.y; r < tile.y + tile.height; ++r) {
      for (int c = tile.x; c < tile.x + tile.width; ++c) {
        const Eigen::Vector3f& ray = rays[static_cast<size_t>(r) * camera.width() + c];
        if (!std::isfinite(ray.x()) || skip.at<std::uint8_t>(r, c)) continue;
        albedo->at<float>(r, c) = Shade(ray.cast<double>(), background, no_codes, textures, background_count,
                                        contrast, &surface_id->at<int>(r, c));
      }
    }
  });
}

// The pixels marked in `fine` (and not in `skip`) averaged over n x n rays on a regular
// sub-pixel grid, each unprojected exactly.
void FineAlbedo(const Camera& camera, const std::vector<Eigen::Vector3f>& rays, const FramePlanes& planes,
                const std::vector<CodeTexture>& textures, double contrast, int n, const cv::Mat& fine,
                const cv::Mat& skip, cv::Mat* albedo) {
  const int background_count = static_cast<int>(planes.background.size());
  ForEachTile(cv::Rect(0, 0, camera.width(), camera.height()), [&](const cv::Rect& tile) {
    const std::vector<const Surface*> background = TileBackground(camera, rays, planes, tile);
    std::vector<const Surface*> codes_here;
    for (int r = tile.y; r < tile.y + tile.height; ++r) {
      for (int c = tile.x; c < tile.x + tile.width; ++c) {
        if (!fine.at<std::uint8_t>(r, c) || skip.at<std::uint8_t>(r, c)) continue;
        codes_here.clear();
        for (const Surface& s : planes.codes) {
          if (s.box_px.contains(cv::Point(c, r))) codes_here.push_back(&s);
        }
        double sum = 0.0;
        int id = -1;
        for (int k = 0; k < n * n; ++k) {
          const Eigen::Vector2d px(c - 0.5 + (k % n + 0.5) / n, r - 0.5 + (k / n + 0.5) / n);
          const std::optional<Eigen::Vector3d> ray = camera.Unproject(px);
          if (ray) sum += Shade(*ray, background, codes_here, textures, background_count, contrast, &id);
        }
        albedo->at<float>(r, c) = static_cast<float>(sum / (n * n));
      }
    }
  });
}

}  // namespace

cv::Mat Renderer::AlbedoImage(const Camera& camera, const SE3d& T_world_camera,
                              bool skip_blurred_codes) const {
  const std::vector<Eigen::Vector3f>& rays = PixelRays(camera);
  const FramePlanes planes = MakeFramePlanes(world_, codes_, ceiling_z_m_, camera, rays, T_world_camera);
  const cv::Size size(camera.width(), camera.height());
  cv::Mat albedo(size, CV_32F, cv::Scalar(0.0f));
  cv::Mat surface_id(size, CV_32S, cv::Scalar(-1));
  const bool skip = skip_blurred_codes && options_.blur_sigma_px > 0.0;
  const cv::Mat hidden = skip ? HiddenByCodeBlur(planes, size, BlurReachPx(options_.blur_sigma_px))
                              : cv::Mat(size, CV_8U, cv::Scalar(0));
  CentreRayAlbedo(camera, rays, planes, codes_, options_.texture_contrast, hidden, &albedo, &surface_id);
  FineAlbedo(camera, rays, planes, codes_, options_.texture_contrast, options_.supersample,
             FinePixels(planes, surface_id), hidden, &albedo);
  return albedo;
}

cv::Mat Renderer::RenderAlbedo(const Camera& camera, const SE3d& T_world_camera) const {
  return AlbedoImage(camera, T_world_camera, false);
}

void Renderer::BlurAlbedo(const Camera& camera, const SE3d& T_world_camera, cv::Mat* albedo) const {
  const double sigma = options_.blur_sigma_px;
  if (!(sigma > 0.0)) return;
  cv::GaussianBlur(*albedo, *albedo, cv::Size(0, 0), sigma, sigma, cv::BORDER_REPLICATE);
  // Around each code, the optical blur before the pixel integration: the albedo at n x n
  // points per pixel (over the code box plus the blur's reach), blurred at that resolution,
  // then averaged per pixel. Only the box is replaced: its border is quiet zone or background.
  const std::vector<Eigen::Vector3f>& rays = PixelRays(camera);
  const FramePlanes planes = MakeFramePlanes(world_, codes_, ceiling_z_m_, camera, rays, T_world_camera);
  const int n = std::max(options_.supersample, kBlurSupersample);
  const int reach = BlurReachPx(sigma);
  const cv::Rect image(0, 0, camera.width(), camera.height());
  for (const Surface& code : planes.codes) {
    const cv::Rect inner = code.box_px & image;
    const cv::Rect outer =
        cv::Rect(inner.x - reach, inner.y - reach, inner.width + 2 * reach, inner.height + 2 * reach) & image;
    if (inner.empty()) continue;
    cv::Mat fine = SupersampledAlbedo(camera, rays, planes, codes_, options_.texture_contrast, outer, n);
    cv::GaussianBlur(fine, fine, cv::Size(0, 0), sigma * n, sigma * n, cv::BORDER_REPLICATE);
    cv::Mat coarse;
    cv::resize(fine, coarse, outer.size(), 0.0, 0.0, cv::INTER_AREA);  // exact n x n means
    coarse(cv::Rect(inner.tl() - outer.tl(), inner.size())).copyTo((*albedo)(inner));
  }
}

cv::Mat Renderer::Render(const Camera& camera, const SE3d& T_world_camera, std::uint64_t seed,
                         std::uint64_t image_index) const {
  // The pixels deep inside a code box are replaced by BlurAlbedo: not computed here.
  cv::Mat radiance = AlbedoImage(camera, T_world_camera, true);
  BlurAlbedo(camera, T_world_camera, &radiance);
  std::seed_seq seq{static_cast<std::uint32_t>(seed), static_cast<std::uint32_t>(seed >> 32),
                    static_cast<std::uint32_t>(image_index), static_cast<std::uint32_t>(image_index >> 32),
                    0x52454e44u};
  std::mt19937_64 rng(seq);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(0.0, 2.0 * M_PI);
  const double exposure = std::exp(options_.exposure_sigma * normal(rng));
  const double phi = uniform(rng);
  const double gx = std::cos(phi) * options_.gradient / (0.5 * camera.width());
  const double gy = std::sin(phi) * options_.gradient / (0.5 * camera.width());
  const double cx = 0.5 * (camera.width() - 1), cy = 0.5 * (camera.height() - 1);
  cv::Mat image(radiance.rows, radiance.cols, CV_8U);
  for (int r = 0; r < radiance.rows; ++r) {
    const float* in = radiance.ptr<float>(r);
    std::uint8_t* out = image.ptr<std::uint8_t>(r);
    for (int c = 0; c < radiance.cols; ++c) {
      // The illumination varies over hundreds of pixels: applying it after the blur
      // instead of before changes nothing measurable.
      const double value = 255.0 * in[c] * exposure * (1.0 + gx * (c - cx) + gy * (r - cy));
      const double noise = options_.noise_sigma > 0.0 ? options_.noise_sigma * normal(rng) : 0.0;
      out[c] = static_cast<std::uint8_t>(std::clamp(std::lround(value + noise), 0L, 255L));
    }
  }
  return image;
}

std::vector<MarkerObservation> Renderer::GroundTruth(const Camera& camera, const SE3d& T_world_camera) const {
  const VisibilityLimits limits{0.0, 1e9, 89.0, 1.0};
  std::vector<MarkerObservation> out;
  for (const SimMarker& m : world_.markers) {
    const auto corners = VisibleCorners(camera, T_world_camera, m, world_.occluders, limits);
    if (!corners) continue;
    MarkerObservation obs;
    obs.key = m.key;
    obs.corners_px = *corners;
    out.push_back(obs);
  }
  return out;
}

double ShortestSidePx(const std::array<Eigen::Vector2d, 4>& corners_px) {
  double shortest = INFINITY;
  for (int i = 0; i < 4; ++i) shortest = std::min(shortest, (corners_px[(i + 1) % 4] - corners_px[i]).norm());
  return shortest;
}

}  // namespace waymark::sim
