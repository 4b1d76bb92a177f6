// Image renderer for the simulated world (sim/world.h): 8-bit gray images of what a camera
// sees, with the exact ground-truth corners of every visible code.
//
// Geometry (exact, by ray casting). For the centre of a (sub-)pixel u, the ray in the
// camera frame is r_camera = Camera::Unproject(u) = (x, y, 1) (lens distortion inverted by
// Newton, geometry/camera.h). Every scene plane P (a code with its quiet zone, a wall or rack
// face, the floor z = 0, the ceiling) is written in the camera frame as n_camera . p = d_camera;
// the hit is at depth t = d_camera / (n_camera . r_camera), t > 0, and lies on P if its point
// in the plane frame, p_plane = T_plane_camera * (t r_camera), is inside the plane's extent.
// The nearest hit wins; a code wins against a coplanar wall (it is printed on it) when
// t_code <= t_wall (1 + 1e-5). Codes are seen only from the front (their z axis, out of the
// printed face, towards the camera).
//
// Symbols. The code's payload is encoded by the real encoders (detect/synthetic.h:
// QR by cv::QRCodeEncoder, DataMatrix by libdmtx, AprilTag from libapriltag's family
// tables). The symbol's outer edge is size_m (docs/design.md) and spans [-s/2, s/2]^2 of the
// marker frame, upright (x right, y up); module (c, r) of the module image covers
//   x in [-s/2 + (c - c0) m, -s/2 + (c - c0 + 1) m],  y in [s/2 - (r - r0 + 1) m, s/2 - (r - r0) m]
// with m = s / symbol.width and (c0, r0) the symbol's top-left module; the quiet zone (the
// encoders' margin plus kExtraQuietModules of white) lies around it on the same plane.
//
// Sampling. Pixels that can see a code (inside its projected bounding box: 16 points per
// edge of its quiet-zone outline, projected, padded by 2 px; for a code crossing the camera
// plane, the pixels whose ray meets the normalized-plane box of its part in front of the
// camera) and pixels on an edge between
// two surfaces (their plane differs from a neighbour's) are averaged over
// supersample x supersample sub-pixel rays, each unprojected exactly; other pixels take one
// ray through their centre (a per-camera cache of rays). OpenCV pixel convention: the
// centre of pixel (c, r) is at (c, r).
//
// Speed (none of it changes a pixel): the image is cut into 32 px tiles and a wall takes
// part in a tile's ray casts only if its part in front of the camera, projected on the
// normalized image plane, meets the tile's rays (widened by 2 px); only the nearest
// surface's texture is evaluated; Render leaves out the pixels deeper than the blur's
// reach inside a code box (BlurAlbedo replaces the box and its blur cannot carry them
// out); tiles are shaded in parallel (cv::parallel_for_).
//
// Photometry (all render.* keys, docs/sim.md):
//   albedo   codes 0.06 dark / 0.85 light; walls, floor and ceiling a low-contrast value
//            noise texture (two octaves, +-texture_contrast/2 each) on their plane, the floor
//            with tile joints every 0.5 m
//   light    I = 255 albedo e g(u) (applied after the blur: g varies over hundreds of pixels),  e = exp(N(0,
//   exposure_sigma^2)) per image,
//            g(u) = 1 + gradient (u - c) . (cos phi, sin phi) / (width / 2), phi ~ U[0, 2 pi)
//            per image (c: image centre)
//   blur     Gaussian, blur_sigma_px (0: none), an optical blur: it acts before the pixel
//            integration. Around every code (its pixel box plus 4 sigma) the albedo is sampled
//            at n x n stratified (jittered, fixed) points per pixel, n = max(supersample, 4),
//            blurred at that resolution and averaged per pixel; elsewhere the pixel image is
//            blurred. (On a regular n x n grid a nearly axis-aligned edge moves in steps of
//            1/n px: up to 0.12 px off at n = 4; jittered, the error averages out along it.) (Blurring pixel
//            values with a sampled Gaussian of sigma < 1 px, the cheap way, moves a blurred
//            edge's centre by up to 0.06 px depending on where it falls between pixels.)
//   noise    + N(0, noise_sigma^2) gray levels per pixel, then rounded and clamped to [0, 255]
// Only the photometric draws (e, phi, noise) depend on the seed; the geometry never does.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <map>
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "geometry/camera.h"
#include "geometry/pose.h"
#include "geometry/types.h"
#include "sim/params.h"
#include "sim/world.h"

namespace waymark::sim {

struct RenderOptions {
  int supersample = 4;             // sub-pixel rays per axis on codes and edges
  double blur_sigma_px = 0.7;      // Gaussian blur (optics, motion); 0 = none
  double noise_sigma = 2.0;        // pixel noise, gray levels (of 255)
  double gradient = 0.25;          // illumination change from the image centre to its side
  double exposure_sigma = 0.15;    // per-image log-exposure spread
  double texture_contrast = 0.12;  // albedo amplitude of the wall/floor/ceiling texture

  // True if usable; otherwise false with the reason in *why (when why != nullptr).
  bool Check(std::string* why) const;
};

// Declares the render.* keys (with RenderOptions' defaults) in `params`.
void AddRenderParams(ParamSet* params);
// The options from the render.* keys of `params`.
RenderOptions RenderOptionsFromParams(const ParamSet& params);

// Extra white modules added around the encoders' own margins.
inline constexpr int kExtraQuietModules = 2;

struct CodeTexture;  // a code's symbol on its plane (sim/render.cc)

class Renderer {
 public:
  // Encodes every code of `world` (throws std::invalid_argument for a family it cannot
  // draw, e.g. "square", or a payload the encoder refuses, and for options that fail Check).
  Renderer(const World& world, const RenderOptions& options);
  ~Renderer();

  // The camera's image at T_world_camera (8-bit gray, camera.height() x camera.width()).
  // `seed` and `image_index` draw the photometric noise: the same pair gives the same image.
  cv::Mat Render(const Camera& camera, const SE3d& T_world_camera, std::uint64_t seed,
                 std::uint64_t image_index) const;

  // Noise-free albedo image in [0, 1] (CV_32F): the geometry and textures only.
  cv::Mat RenderAlbedo(const Camera& camera, const SE3d& T_world_camera) const;

  // The exact corners (docs/design.md order) of every code fully visible in the image: in front
  // of the camera, facing it (within 89 deg), all corners inside the image and no wall
  // between the camera and a corner. Same as the noiseless simulated detections.
  std::vector<MarkerObservation> GroundTruth(const Camera& camera, const SE3d& T_world_camera) const;

  double ceiling_z_m() const { return ceiling_z_m_; }

 private:
  const std::vector<Eigen::Vector3f>& PixelRays(const Camera& camera) const;
  // The albedo image; with skip_blurred_codes, the pixels that BlurAlbedo replaces and
  // that its blur cannot carry out of a code box are left at 0 (Render's shortcut).
  cv::Mat AlbedoImage(const Camera& camera, const SE3d& T_world_camera, bool skip_blurred_codes) const;
  // Applies the optical blur to an albedo image (see the header comment).
  void BlurAlbedo(const Camera& camera, const SE3d& T_world_camera, cv::Mat* albedo) const;

  World world_;
  RenderOptions options_;
  std::vector<CodeTexture> codes_;  // one per world_.markers entry
  double ceiling_z_m_ = 2.5;
  // Rays through pixel centres per camera (keyed by name and calibration text).
  mutable std::map<std::string, std::vector<Eigen::Vector3f>> ray_cache_;
};

// The largest side of a quadrilateral is not a good "width" for oblique codes; the tests and
// the docs use the shortest side (px).
double ShortestSidePx(const std::array<Eigen::Vector2d, 4>& corners_px);

}  // namespace waymark::sim
