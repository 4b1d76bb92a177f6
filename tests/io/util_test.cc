#include "io/util.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <string>

#include "io/json_util.h"
#include "io/yaml_util.h"

namespace waymark {
namespace {

namespace fs = std::filesystem;

fs::path MakeTempDir(const std::string& tag) {
  const fs::path dir =
      fs::temp_directory_path() /
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

// Issue 18, finding 4: several outputs are written all or nothing.
TEST(AtomicWriteFileTest, SeveralFilesAllOrNothing) {
  const fs::path dir = MakeTempDir("several");
  AtomicWriteFile(dir / "keep.txt", "old");
  AtomicWriteFile(dir / "afile", "a plain file");
  // The second path is impossible: the first is not written, nor its new directory made.
  EXPECT_THROW(
      AtomicWriteFiles({{dir / "new" / "a.txt", "a"}, {dir / "keep.txt", "new"}, {dir / "afile" / "b", "b"}}),
      std::runtime_error);
  EXPECT_FALSE(fs::exists(dir / "new"));
  EXPECT_EQ(ReadTextFile(dir / "keep.txt"), "old");
  // The same file twice, however spelled: refused before anything is written.
  EXPECT_THROW(AtomicWriteFiles({{dir / "x.txt", "1"}, {dir / "new" / ".." / "x.txt", "2"}}),
               std::invalid_argument);
  EXPECT_FALSE(fs::exists(dir / "x.txt"));
  try {
    CheckDistinctOutputs({{"--out", (dir / "x.txt").string()}, {"--poses", (dir / "." / "x.txt").string()}});
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()),
              "--out and --poses name the same file '" + (dir / "." / "x.txt").string() + "'");
  }
  AtomicWriteFiles({{dir / "new" / "a.txt", "a"}, {dir / "keep.txt", "new"}});
  EXPECT_EQ(ReadTextFile(dir / "new" / "a.txt"), "a");
  EXPECT_EQ(ReadTextFile(dir / "keep.txt"), "new");
  fs::remove_all(dir);
}

// Issue 18, finding 7: temporaries of a killed writer are removed by the next write; nothing
// else is.
TEST(AtomicWriteFileTest, StaleTemporariesOfDeadWritersAreRemoved) {
  long pid = 0;
  EXPECT_TRUE(IsTemporaryFileName(".map.json.tmp-1234-9f8e7d6c5b4a3210", &pid));
  EXPECT_EQ(pid, 1234);
  for (const char* name : {"map.json.tmp-1234-ab", ".map.json.tmp--ab", ".map.json.tmp-12x-ab",
                           ".map.json.tmp-12-", ".map.json.tmp-12-XYZ", ".tmp-12-ab", ".map.json"}) {
    EXPECT_FALSE(IsTemporaryFileName(name, &pid)) << name;
  }
  const fs::path dir = MakeTempDir("stale");
  const pid_t child = fork();
  if (child == 0) _exit(0);
  ASSERT_GT(child, 0);
  waitpid(child, nullptr, 0);
  const std::string dead = std::to_string(child);
  std::ofstream(dir / (".out.txt.tmp-" + dead + "-1a")) << "partial";
  std::ofstream(dir / (".out.txt.tmp-" + std::to_string(getpid()) + "-1a")) << "mine, in flight";
  std::ofstream(dir / ".out.txt.tmp-1-1a") << "pid 1 is alive";
  std::ofstream(dir / "out.txt.tmp-5-1a") << "not our naming";
  fs::create_directories(dir / (".sub.tmp-" + dead + "-2b"));  // a directory: never touched
  AtomicWriteFile(dir / "out.txt", "done");
  EXPECT_FALSE(fs::exists(dir / (".out.txt.tmp-" + dead + "-1a")));
  EXPECT_TRUE(fs::exists(dir / (".out.txt.tmp-" + std::to_string(getpid()) + "-1a")));
  EXPECT_TRUE(fs::exists(dir / ".out.txt.tmp-1-1a"));
  EXPECT_TRUE(fs::exists(dir / "out.txt.tmp-5-1a"));
  EXPECT_TRUE(fs::is_directory(dir / (".sub.tmp-" + dead + "-2b")));
  EXPECT_EQ(RemoveStaleTemporaries(dir), 0);
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

TEST(NumberTextTest, FormatDoubleRoundTripsExactly) {
  std::mt19937_64 rng(17);
  std::uniform_int_distribution<uint64_t> bits;
  int checked = 0;
  for (int i = 0; i < 20000; ++i) {
    const uint64_t pattern = bits(rng);
    double value;
    std::memcpy(&value, &pattern, sizeof(value));
    if (!std::isfinite(value)) continue;
    const std::optional<double> read = ParseFiniteDouble(FormatDouble(value));
    ASSERT_TRUE(read.has_value()) << FormatDouble(value);
    ASSERT_EQ(std::memcmp(&*read, &value, sizeof(value)), 0) << FormatDouble(value);
    ++checked;
  }
  EXPECT_GT(checked, 19000);
  EXPECT_EQ(FormatDouble(0.1), "0.1");
  EXPECT_EQ(FormatDouble(2.0), "2");
  EXPECT_EQ(FormatDouble(1560889276.31902), "1560889276.31902");
}

TEST(NumberTextTest, ParseIsStrict) {
  EXPECT_EQ(ParseFiniteDouble("+1.5e3"), 1500.0);
  EXPECT_EQ(ParseFiniteDouble("-0.25"), -0.25);
  for (const char* bad : {"", " 1", "1 ", "1x", "nan", "inf", "-inf", "1e999", "0x10", "+", "1,5"}) {
    EXPECT_FALSE(ParseFiniteDouble(bad).has_value()) << bad;
  }
  EXPECT_EQ(ParseInteger("1280"), 1280);
  EXPECT_EQ(ParseInteger("-3"), -3);
  for (const char* bad : {"", "1.0", "1e3", "12a", "99999999999999999999"}) {
    EXPECT_FALSE(ParseInteger(bad).has_value()) << bad;
  }
}

TEST(PoseFromFileTest, ChecksNormAndKeepsUnitQuaternionsExactly) {
  SE3d T;
  std::string why;
  EXPECT_FALSE(MakePoseFromFile(Eigen::Vector3d::Zero(), Eigen::Vector4d(0, 0, 0, 1.002), &T, &why));
  EXPECT_EQ(why, "q_xyzw: expected unit norm within 0.001, got 1.002");
  EXPECT_FALSE(MakePoseFromFile(Eigen::Vector3d(0, std::nan(""), 0), Eigen::Vector4d(0, 0, 0, 1), &T, &why));
  ASSERT_TRUE(MakePoseFromFile(Eigen::Vector3d(1, 2, 3), Eigen::Vector4d(0, 0, 0, 1.0005), &T, &why));
  EXPECT_NEAR(T.rotation().norm(), 1.0, 1e-15);
  const Eigen::Quaterniond q = Eigen::Quaterniond(0.3, -0.1, 0.7, 0.2).normalized();
  ASSERT_TRUE(MakePoseFromFile(Eigen::Vector3d::Zero(), q.coeffs(), &T, &why));
  EXPECT_EQ(T.rotation().coeffs(), q.coeffs());
}

TEST(JsonLinesTest, LinesOfValuesAndSyntaxErrors) {
  const std::string text = "{\"a\": 1,\n \"b\": [\n  {\"c\": \"x\"},\n  2]}\n";
  std::map<std::string, long> lines;
  const nlohmann::json json = ParseJsonDocument(text, "f.json", &lines);
  EXPECT_EQ(json["b"][1], 2);
  EXPECT_EQ(lines.at(""), 1);
  EXPECT_EQ(lines.at("a"), 1);
  EXPECT_EQ(lines.at("b"), 2);
  EXPECT_EQ(lines.at("b[0]"), 3);
  EXPECT_EQ(lines.at("b[0].c"), 3);
  EXPECT_EQ(lines.at("b[1]"), 4);
  const JsonSource source = JsonSourceWithLines("f.json", lines);
  EXPECT_EQ(source.line_of("b[0].c.missing"), 3);  // nearest enclosing field
  EXPECT_EQ(JsonErrorText(source, "b[1]", "expected a string"), "f.json:4: b[1]: expected a string");
  try {
    ParseJsonDocument("{\"a\": 1,\n\n \"b\": }", "f.json", nullptr);
    FAIL() << "expected FormatError";
  } catch (const FormatError& e) {
    EXPECT_EQ(e.line(), 3);
    EXPECT_THAT(e.what(), ::testing::HasSubstr("f.json:3: invalid JSON: syntax error"));
  }
}

// Issue 18: 40 000 '[' took 10 s and 4.9 GB (the field path of every level was kept); a
// depth limit makes it a one-line error at once, and any depth up to it is accepted.
TEST(JsonLinesTest, NestingDeeperThanTheLimitIsAnErrorWithItsLine) {
  const std::string deep = "{\"a\":\n" + std::string(40000, '[');
  try {
    ParseJsonDocument(deep, "n.json", nullptr);
    FAIL() << "expected FormatError";
  } catch (const FormatError& e) {
    EXPECT_STREQ(e.what(), "n.json:2: invalid JSON: arrays and objects nested deeper than 32 levels");
  }
  std::map<std::string, long> lines;
  const std::string ok = std::string(kMaxJsonDepth, '[') + std::string(kMaxJsonDepth, ']');
  EXPECT_TRUE(ParseJsonDocument(ok, "n.json", &lines).is_array());
  EXPECT_EQ(lines.size(), static_cast<size_t>(kMaxJsonDepth));
  EXPECT_THROW(ParseJsonDocument("[" + ok + "]", "n.json", &lines), FormatError);
}

TEST(JsonLinesTest, JsonLineErrorsNameTheLine) {
  EXPECT_EQ(ParseJsonLine("{\"t\": 1.5}", "in.jsonl", 7)["t"], 1.5);
  for (const std::string& bad : {std::string("{\"t\":1e400}"), std::string("{\"t\": oops"),
                                 std::string(100000, '['), std::string("")}) {
    try {
      ParseJsonLine(bad, "in.jsonl", 7);
      FAIL() << "expected FormatError for " << bad.substr(0, 20);
    } catch (const FormatError& e) {
      EXPECT_EQ(std::string(e.what()).rfind("in.jsonl:7: invalid JSON: ", 0), 0u) << e.what();
    }
  }
}

// The lines of a document's fields are found when first asked for, and match the eager ones.
TEST(JsonLinesTest, LazySourceGivesTheSameLines) {
  const std::string text = "{\"a\": 1,\n \"b\": [\n  {\"c\": \"x\"},\n  2]}\n";
  const JsonSource source = JsonSourceForText("f.json", text);
  EXPECT_EQ(source.line_of("b[0].c"), 3);
  EXPECT_EQ(source.line_of("b[1]"), 4);
  EXPECT_EQ(source.line_of("b[0].c.missing"), 3);
  EXPECT_EQ(source.line_of(""), 1);
}

// Many values on many lines: the line of each is counted on from the previous one, not from
// the start of the text (issue 18: a 20 000-marker map did not load in 60 s).
TEST(JsonLinesTest, LineRecordingIsLinear) {
  std::string text = "[\n";
  const int n = 200000;
  for (int i = 0; i < n; ++i) text += (i ? ",\n" : "") + std::to_string(i);
  text += "]\n";
  std::map<std::string, long> lines;
  const std::clock_t start = std::clock();  // processor time: the machine may be shared
  ParseJsonDocument(text, "big.json", &lines);
  const double seconds = static_cast<double>(std::clock() - start) / CLOCKS_PER_SEC;
  EXPECT_EQ(lines.at("[199999]"), n + 1);
  // Quadratic counting reads 2e10 bytes here (tens of seconds); linear takes well under 1 s.
  EXPECT_LT(seconds, 5.0);
}

TEST(QuoteStringTest, EscapesForYamlAndJson) {
  EXPECT_EQ(QuoteString("a\"b\\c\nd"), "\"a\\\"b\\\\c\\nd\"");
  const std::string pattern = "^(\\d+)/(-?[0-9.]+)$";
  EXPECT_EQ(nlohmann::json::parse(QuoteString(pattern)).get<std::string>(), pattern);
}

}  // namespace
}  // namespace waymark
