#include "io/util.h"
#include "io/json_util.h"
#include "io/yaml_util.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <string>

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

TEST(QuoteStringTest, EscapesForYamlAndJson) {
  EXPECT_EQ(QuoteString("a\"b\\c\nd"), "\"a\\\"b\\\\c\\nd\"");
  const std::string pattern = "^(\\d+)/(-?[0-9.]+)$";
  EXPECT_EQ(nlohmann::json::parse(QuoteString(pattern)).get<std::string>(), pattern);
}

}  // namespace
}  // namespace waymark
