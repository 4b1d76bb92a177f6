#include "core/io_util.h"

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

namespace waymark {
namespace {

namespace fs = std::filesystem;

fs::path MakeTempDir(const std::string& tag) {
  const fs::path dir = fs::temp_directory_path() /
                       ("waymark_io_util_" + tag + "_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) +
                        "_" + std::to_string(reinterpret_cast<uintptr_t>(&tag)));
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

TEST(FormatErrorTest, WhatIsOneLineWithFileAndLine) {
  const FormatError with_line("cameras/cam0.yaml", 7, "intrinsics: expected 4 numbers, got 3");
  EXPECT_STREQ(with_line.what(), "cameras/cam0.yaml:7: intrinsics: expected 4 numbers, got 3");
  EXPECT_EQ(with_line.line(), 7);
  EXPECT_EQ(with_line.file(), fs::path("cameras/cam0.yaml"));
  EXPECT_EQ(with_line.message(), "intrinsics: expected 4 numbers, got 3");

  const FormatError without_line("odometry.tum", "cannot open: no such file");
  EXPECT_STREQ(without_line.what(), "odometry.tum: cannot open: no such file");
  EXPECT_FALSE(without_line.line().has_value());

  const FormatError multi_line("a.json", 2, "first\nsecond");
  EXPECT_EQ(std::string(multi_line.what()).find('\n'), std::string::npos);
}

TEST(AtomicWriteFileTest, WritesCreatesParentsAndReplaces) {
  const fs::path dir = MakeTempDir("write");
  const fs::path path = dir / "a" / "b" / "out.txt";
  AtomicWriteFile(path, "first\n");
  EXPECT_EQ(ReadTextFile(path), "first\n");
  AtomicWriteFile(path, std::string("sec\0ond", 7));
  EXPECT_EQ(ReadTextFile(path), std::string("sec\0ond", 7));
  // No temporary files are left behind.
  int entries = 0;
  for (const auto& entry : fs::directory_iterator(path.parent_path())) {
    (void)entry;
    ++entries;
  }
  EXPECT_EQ(entries, 1);
  fs::remove_all(dir);
}

TEST(AtomicWriteFileTest, FailureLeavesOldFileIntact) {
  const fs::path dir = MakeTempDir("fail");
  const fs::path path = dir / "out.txt";
  AtomicWriteFile(path, "old");
  // A directory in the way of the rename: the write must fail and keep nothing partial.
  const fs::path blocked = dir / "blocked";
  fs::create_directories(blocked / "child");
  EXPECT_THROW(AtomicWriteFile(blocked, "new"), std::runtime_error);
  EXPECT_TRUE(fs::is_directory(blocked));
  // Parent is a regular file: cannot create the directory.
  try {
    AtomicWriteFile(path / "inner.txt", "x");
    FAIL() << "expected an error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("out.txt"), std::string::npos) << e.what();
  }
  EXPECT_EQ(ReadTextFile(path), "old");
  int entries = 0;
  for (const auto& entry : fs::directory_iterator(dir)) {
    (void)entry;
    ++entries;
  }
  EXPECT_EQ(entries, 2);  // out.txt and blocked/
  fs::remove_all(dir);
}

TEST(ReadTextFileTest, MissingFileAndDirectoryAreNamed) {
  const fs::path dir = MakeTempDir("read");
  try {
    ReadTextFile(dir / "missing.yaml");
    FAIL() << "expected FormatError";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("missing.yaml"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("no such file"), std::string::npos) << e.what();
  }
  EXPECT_THROW(ReadTextFile(dir), FormatError);
  AtomicWriteFile(dir / "empty.txt", "");
  EXPECT_EQ(ReadTextFile(dir / "empty.txt"), "");
  fs::remove_all(dir);
}

}  // namespace
}  // namespace waymark
