// Writing a simulated dataset directory (docs/design.md "Dataset directory") through
// io/dataset_io.h, plus `sim_config.yaml`: the scenario, the seed and every effective key,
// so that `waymark sim SCENARIO --config sim_config.yaml --seed N` reproduces it.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>

#include "sim/params.h"
#include "sim/simulator.h"

namespace waymark::sim {

// Everything is first written into a temporary sibling directory that is renamed to
// `out_dir` at the end, so an error leaves no output directory behind. An existing
// `out_dir` that is not an empty directory is an error (std::runtime_error naming it) unless
// `force`, in which case it is replaced. `extra`, when given, writes more files into the
// temporary directory (e.g. rendered images, sim/render_io.h) before it is renamed.
void WriteSimDataset(const SimResult& result, const ParamSet& params, std::uint64_t seed,
                     const std::filesystem::path& out_dir, bool force,
                     const std::function<void(const std::filesystem::path&)>& extra = nullptr);

}  // namespace waymark::sim
