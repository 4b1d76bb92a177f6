// Running the `waymark` binary from a test: its exit code, stdout and stderr, and a scratch
// directory per test.
#pragma once

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include "io/util.h"

namespace waymark {

struct RunResult {
  int exit_code = -1;
  std::string out, err;
};

// Runs `waymark ARGUMENTS [<STDIN_FILE]`, capturing stdout and stderr through files in
// `scratch_dir` (which must exist).
inline RunResult RunWaymark(const std::string& arguments, const std::filesystem::path& scratch_dir,
                            const std::string& stdin_file = "") {
  const std::filesystem::path out = scratch_dir / "stdout.txt", err = scratch_dir / "stderr.txt";
  std::string command =
      std::string(WAYMARK_BINARY) + " " + arguments + " >" + out.string() + " 2>" + err.string();
  if (!stdin_file.empty()) command += " <" + stdin_file;
  RunResult result;
  const int status = std::system(command.c_str());
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  result.out = ReadTextFile(out);
  result.err = ReadTextFile(err);
  return result;
}

// A fresh, empty temporary directory "waymark_<prefix>_<pid>[_<suffix>]".
inline std::filesystem::path FreshTestDir(const std::string& prefix, const std::string& suffix = "") {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() /
      ("waymark_" + prefix + "_" + std::to_string(::getpid()) + (suffix.empty() ? "" : "_" + suffix));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

// A test with its own scratch directory dir_, removed afterwards.
class CliTest : public ::testing::Test {
 protected:
  explicit CliTest(std::string prefix) : prefix_(std::move(prefix)) {}
  void SetUp() override {
    dir_ = FreshTestDir(prefix_, ::testing::UnitTest::GetInstance()->current_test_info()->name());
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  RunResult Run(const std::string& arguments) const { return RunWaymark(arguments, dir_); }

  std::string prefix_;
  std::filesystem::path dir_;
};

// Busy threads on every core while they live (a machine under full load).
class CpuHog {
 public:
  CpuHog() {
    const unsigned n = std::max(2u, std::thread::hardware_concurrency());
    for (unsigned i = 0; i < n; ++i) {
      threads_.emplace_back([this] {
        volatile double x = 1.0;
        while (!stop_.load()) x = x * 1.0000001 + 1e-9;
      });
    }
  }
  ~CpuHog() {
    stop_ = true;
    for (std::thread& t : threads_) t.join();
  }

 private:
  std::atomic<bool> stop_{false};
  std::vector<std::thread> threads_;
};

}  // namespace waymark
