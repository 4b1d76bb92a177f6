// End to end: `waymark dataset info` through the built binary, on a real tagslam set and on
// broken copies of it in a temporary directory.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <string>

#include "io/util.h"

namespace waymark {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::Not;

struct RunResult {
  int exit_code = -1;
  std::string out;
  std::string err;
};

// Runs `waymark ARGS`, capturing stdout and stderr.
RunResult RunWaymark(const std::string& args) {
  const fs::path err_path =
      fs::temp_directory_path() / ("waymark_dataset_info_err_" + std::to_string(::getpid()));
  const std::string command =
      std::string("'") + WAYMARK_BINARY + "' " + args + " 2>'" + err_path.string() + "'";
  RunResult result;
  FILE* pipe = ::popen(command.c_str(), "r");
  if (pipe == nullptr) return result;
  char buffer[4096];
  size_t n = 0;
  while ((n = std::fread(buffer, 1, sizeof(buffer), pipe)) > 0) result.out.append(buffer, n);
  const int status = ::pclose(pipe);
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  result.err = ReadTextFile(err_path);
  fs::remove(err_path);
  return result;
}

fs::path TagslamSet(const std::string& name) { return fs::path(WAYMARK_SHARED_DATA) / "tagslam" / name; }

// A writable copy of a tagslam set, removed at the end of the test.
class BrokenCopy {
 public:
  explicit BrokenCopy(const std::string& name)
      : dir_(fs::temp_directory_path() /
             ("waymark_dataset_info_" + name + "_" + std::to_string(::getpid()))) {
    fs::remove_all(dir_);
    fs::copy(TagslamSet(name), dir_, fs::copy_options::recursive);
    for (const auto& entry : fs::recursive_directory_iterator(dir_)) {
      fs::permissions(entry.path(), fs::perms::owner_write, fs::perm_options::add);
    }
    fs::permissions(dir_, fs::perms::owner_write, fs::perm_options::add);
  }
  ~BrokenCopy() { fs::remove_all(dir_); }
  const fs::path& dir() const { return dir_; }
  // Replaces the first `from` in the file by `to`.
  void Edit(const std::string& file, const std::string& from, const std::string& to) const {
    std::string text = ReadTextFile(dir_ / file);
    const size_t at = text.find(from);
    ASSERT_NE(at, std::string::npos) << from;
    AtomicWriteFile(dir_ / file, text.replace(at, from.size(), to));
  }

 private:
  fs::path dir_;
};

#define SKIP_WITHOUT_TAGSLAM()                                                                   \
  if (!fs::exists(TagslamSet("tagslam-test16"))) {                                               \
    GTEST_SKIP() << "shared data absent: " << TagslamSet("tagslam-test16") << " (test not run)"; \
  }

TEST(DatasetInfoCliTest, SummarizesTagslamSets) {
  SKIP_WITHOUT_TAGSLAM();
  const RunResult r16 = RunWaymark("dataset info '" + TagslamSet("tagslam-test16").string() + "'");
  EXPECT_EQ(r16.exit_code, 0) << r16.err;
  EXPECT_THAT(r16.out, HasSubstr("dataset: tagslam-test16 ("));
  EXPECT_THAT(r16.out, HasSubstr("motion: free\n"));
  EXPECT_THAT(r16.out, HasSubstr("  cam0: pinhole-radtan 1280x1024\n"));
  EXPECT_THAT(r16.out, HasSubstr("frames: 297 (detections.jsonl)\n"));
  EXPECT_THAT(r16.out, HasSubstr("detections: 1471 (apriltag-36h11: 1471)\n"));
  EXPECT_THAT(r16.out, HasSubstr("distinct markers: 5\n"));
  EXPECT_THAT(r16.out, HasSubstr("known markers: 1 (markers.json)\n"));
  EXPECT_THAT(r16.out, HasSubstr("odometry: none\n"));
  EXPECT_THAT(r16.out, HasSubstr("ground truth: absent\n"));
  EXPECT_THAT(r16.out, HasSubstr("reference: trajectory 297 poses over"));
  EXPECT_THAT(r16.out, HasSubstr("warnings: 0\n"));
  EXPECT_EQ(r16.err, "");

  const RunResult r22 = RunWaymark("dataset info '" + TagslamSet("tagslam-test22").string() + "'");
  EXPECT_EQ(r22.exit_code, 0) << r22.err;
  EXPECT_THAT(r22.out, HasSubstr("  cam0: pinhole-equidistant 848x800\n"));
  EXPECT_THAT(r22.out, HasSubstr("odometry: 115 poses, "));
  EXPECT_THAT(r22.out, HasSubstr(" m (odometry.tum)\n"));
}

TEST(DatasetInfoCliTest, BrokenCopiesFailWithOneLineNamingFileAndLine) {
  SKIP_WITHOUT_TAGSLAM();
  {
    const BrokenCopy copy("tagslam-test16");
    copy.Edit("cameras/cam0.yaml", "641.176, 524.495]", "641.176]");
    const RunResult r = RunWaymark("dataset info '" + copy.dir().string() + "'");
    EXPECT_EQ(r.exit_code, 1);
    EXPECT_EQ(r.out, "");
    EXPECT_THAT(r.err, HasSubstr("cameras/cam0.yaml:4: intrinsics: expected 4 numbers, got 3\n"));
    EXPECT_EQ(r.err.find('\n'), r.err.size() - 1) << r.err;  // one line
  }
  {
    const BrokenCopy copy("tagslam-test17");
    copy.Edit("detections.jsonl", "}]}\n{\"t\": 1560889537.615191, \"camera\": \"cam0\"",
              "}]}\n{\"t\": 1560889537.615191, \"camera\": \"cam3\"");
    const RunResult r = RunWaymark("dataset info '" + copy.dir().string() + "'");
    EXPECT_EQ(r.exit_code, 1);
    EXPECT_THAT(r.err, HasSubstr("detections.jsonl:2: camera: camera \"cam3\" is not in the dataset"));
  }
  {
    const BrokenCopy copy("tagslam-test22");
    copy.Edit("odometry.tum", "0.671328", "nan");
    const RunResult r = RunWaymark("dataset info '" + copy.dir().string() + "'");
    EXPECT_EQ(r.exit_code, 1);
    EXPECT_THAT(r.err, HasSubstr("odometry.tum:1: tz: expected a finite number, got 'nan'"));
  }
}

TEST(DatasetInfoCliTest, WarningsAreCountedAndStrictFails) {
  SKIP_WITHOUT_TAGSLAM();
  const BrokenCopy copy("tagslam-test16");
  copy.Edit("detections.jsonl", "[[529.04, 321.199]", "[[1529.04, 321.199]");  // outside the 1280 px width
  copy.Edit("dataset.yaml", "motion: free", "motion: free\ncomment: hello");
  const RunResult r = RunWaymark("dataset info '" + copy.dir().string() + "'");
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("detections: 1470 (apriltag-36h11: 1470)\n"));
  EXPECT_THAT(r.out, HasSubstr("warnings: 2 (corner outside image: 1, unknown key: 1)\n"));
  EXPECT_THAT(r.err, HasSubstr("warning: "));
  EXPECT_THAT(r.err,
              HasSubstr("detections.jsonl:1: markers[0].corners_px: corner (1529.04, 321.199) outside"));
  const RunResult strict = RunWaymark("dataset info --strict '" + copy.dir().string() + "'");
  EXPECT_EQ(strict.exit_code, 1);
  EXPECT_THAT(strict.out, HasSubstr("warnings: 2"));
}

TEST(DatasetInfoCliTest, HelpAndUsageErrors) {
  const RunResult help = RunWaymark("dataset --help");
  EXPECT_EQ(help.exit_code, 0);
  EXPECT_THAT(help.out, HasSubstr("waymark dataset info DIR"));
  const RunResult info_help = RunWaymark("dataset info --help");
  EXPECT_EQ(info_help.exit_code, 0);
  EXPECT_THAT(info_help.out, HasSubstr("waymark dataset info DIR"));
  const RunResult no_verb = RunWaymark("dataset");
  EXPECT_EQ(no_verb.exit_code, 1);
  EXPECT_THAT(no_verb.err, HasSubstr("missing verb"));
  const RunResult no_dir = RunWaymark("dataset info");
  EXPECT_EQ(no_dir.exit_code, 1);
  EXPECT_THAT(no_dir.err, HasSubstr("missing dataset directory DIR"));
  const RunResult missing = RunWaymark("dataset info /nonexistent/waymark-dataset");
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_THAT(missing.err, HasSubstr("/nonexistent/waymark-dataset: not a directory"));
  EXPECT_THAT(missing.out, Not(HasSubstr("dataset:")));
}

}  // namespace
}  // namespace waymark
