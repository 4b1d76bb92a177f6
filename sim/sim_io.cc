#include "sim/sim_io.h"

#include <unistd.h>

#include <stdexcept>
#include <system_error>

#include "io/dataset_io.h"
#include "io/util.h"

namespace waymark::sim {
namespace {

namespace fs = std::filesystem;

// Refuses an existing `out_dir` that is not an empty directory, unless `force`.
void CheckOutput(const fs::path& out_dir, bool force) {
  std::error_code ec;
  if (!fs::exists(out_dir, ec)) return;
  if (!fs::is_directory(out_dir, ec))
    throw std::runtime_error(out_dir.string() + ": exists and is not a directory");
  if (!fs::is_empty(out_dir, ec) && !force) {
    throw std::runtime_error(out_dir.string() + ": directory is not empty (use --force to replace it)");
  }
}

}  // namespace

void WriteSimDataset(const SimResult& result, const ParamSet& params, std::uint64_t seed,
                     const fs::path& out_dir, bool force, const std::function<void(const fs::path&)>& extra) {
  CheckOutput(out_dir, force);
  fs::path target = fs::absolute(out_dir).lexically_normal();
  if (!target.has_filename()) target = target.parent_path();  // "out/" names "out"
  if (!target.has_filename() || target == target.root_path()) {
    throw std::runtime_error(out_dir.string() + ": not usable as an output directory");
  }
  const fs::path parent = target.parent_path();
  std::error_code ec;
  fs::create_directories(parent, ec);
  if (ec) throw std::runtime_error(parent.string() + ": cannot create directory: " + ec.message());
  RemoveStaleTemporaryDirectories(parent, ".sim-tmp-");  // of a killed `waymark sim`
  const fs::path temp =
      parent / ("." + target.filename().string() + ".sim-tmp-" + std::to_string(::getpid()));
  fs::remove_all(temp, ec);
  try {
    WriteDataset(temp, result.dataset);
    AtomicWriteFile(temp / "sim_config.yaml", "# reproduce: waymark sim " + result.scenario + " --seed " +
                                                  std::to_string(seed) +
                                                  " --config sim_config.yaml --out DIR\n" + params.ToYaml());
    if (extra) extra(temp);
    if (fs::exists(target)) fs::remove_all(target);  // empty, or replaced under --force
    fs::rename(temp, target);
  } catch (...) {
    fs::remove_all(temp, ec);
    throw;
  }
}

}  // namespace waymark::sim
