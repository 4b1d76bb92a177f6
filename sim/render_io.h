// Rendering a simulated run into a dataset directory (sim/render.h for the images):
//   images/<camera>/<n>.png      n = the camera frame's number (6 digits, from 000000),
//                                every `every`-th camera frame of the run, all cameras
//   images.csv                   t,camera,path (docs/design.md), one row per image
//   groundtruth/corners.jsonl    the exact corners of every code fully visible in each image,
//                                detections.jsonl format (one line per image, empty or not)
// Files are written into `dir` as they are made; WriteSimDataset's temporary directory
// keeps a failed run from leaving anything behind.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>

#include "sim/ir_render.h"
#include "sim/render.h"
#include "sim/simulator.h"

namespace waymark::sim {

struct RenderStats {
  long images = 0;
  long codes = 0;        // ground-truth corner sets written
  double seconds = 0.0;  // wall time spent rendering and writing images
};

// `progress(done, total)` is called after each image when given. Throws
// std::invalid_argument for every < 1, std::runtime_error when a file cannot be written.
RenderStats RenderRun(const SimResult& result, const RenderOptions& options, std::uint64_t seed, long every,
                      const std::filesystem::path& dir,
                      const std::function<void(long, long)>& progress = nullptr);

// The square-ceiling scenario (SimResult::scene.ir_room set): every `every`-th camera frame as an
// infrared LED pair (sim/ir_render.h) rendered with the true cameras:
//   images/<camera>/<n>-on.png    LED on, at the frame's stamp t and true pose
//   images/<camera>/<n>-off.png   LED off, at t + ir.pair_gap_s (robot and people moved on)
//   images.csv                    both rows, on before off (docs/formats.md: LED pairs)
//   groundtruth/corners.jsonl     exact corners of every square whose four corners are in the
//                                 on image, at the on frame's stamp
RenderStats RenderIrRun(const SimResult& result, const IrOptions& options, std::uint64_t seed, long every,
                        const std::filesystem::path& dir,
                        const std::function<void(long, long)>& progress = nullptr);

// T_world_robot at `stamp_s` between the samples of `truth` (translation linear, rotation by
// slerp: InterpolateProduct of geometry/pose.h); the first or last sample outside them.
SE3d InterpolateTrajectoryClamped(const Trajectory& truth, double stamp_s);

}  // namespace waymark::sim
