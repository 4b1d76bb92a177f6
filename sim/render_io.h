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

#include "sim/render.h"
#include "sim/simulator.h"

namespace waymark::sim {

struct RenderStats {
  long images = 0;
  long codes = 0;  // ground-truth corner sets written
  double seconds = 0.0;  // wall time spent rendering and writing images
};

// `progress(done, total)` is called after each image when given. Throws
// std::invalid_argument for every < 1, std::runtime_error when a file cannot be written.
RenderStats RenderRun(const SimResult& result, const RenderOptions& options, std::uint64_t seed, long every,
                      const std::filesystem::path& dir,
                      const std::function<void(long, long)>& progress = nullptr);

}  // namespace waymark::sim
