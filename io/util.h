// File helpers shared by every reader and writer of Waymark's formats (docs/design.md
// "Contracts", docs/formats.md): one error type that names the file and the line, atomic
// writes, whole-file reads with a clear message, strict numbers and poses. The strict YAML and
// JSON field readers are in io/yaml_util.h and io/json_util.h (they need yaml-cpp and
// nlohmann-json, which waymark_io links privately: include them only where you link those too).
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <functional>
#include <map>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "geometry/pose.h"
#include "util/format.h"
#include "geometry/types.h"

namespace waymark {

// A malformed or unreadable input. what() is one line:
//   "path:line: message"   when the line is known (lines count from 1),
//   "path: message"        otherwise.
class FormatError : public std::runtime_error {
 public:
  FormatError(const std::filesystem::path& file, std::optional<long> line, const std::string& message);
  FormatError(const std::filesystem::path& file, const std::string& message)
      : FormatError(file, std::nullopt, message) {}

  const std::filesystem::path& file() const { return file_; }
  const std::optional<long>& line() const { return line_; }
  // The message without the "path:line: " prefix.
  const std::string& message() const { return message_; }

 private:
  std::filesystem::path file_;
  std::optional<long> line_;
  std::string message_;
};

// Writes `contents` to `path` atomically: the bytes go to a temporary file in the same
// directory, are flushed with fsync, and the file is renamed over `path`. Parent
// directories are created. On any failure the temporary file is removed, `path` is left
// as it was, and std::runtime_error is thrown naming the path.
void AtomicWriteFile(const std::filesystem::path& path, const std::string& contents);

// The whole file as a string. Throws FormatError ("path: cannot open: <reason>") if the
// file is missing, is a directory or cannot be read.
std::string ReadTextFile(const std::filesystem::path& path);

// ---- Helpers shared by the strict readers and writers of io/*_io.cc ----

// Quaternions read from files must have unit norm within this tolerance (then are normalized).
inline constexpr double kQuaternionNormTolerance = 1e-3;


// The whole token as a finite double ("+" allowed, no spaces, no nan/inf); nullopt otherwise.
std::optional<double> ParseFiniteDouble(std::string_view token);

// Calls line_fn(line_number, line) for every line of a text file's contents, numbering from 1;
// a trailing '\r' (CRLF files) is removed. Blank and comment lines are the caller's to skip.
template <typename LineFn>
void ForEachLine(std::string_view text, LineFn line_fn) {
  long line_number = 0;
  size_t begin = 0;
  while (begin < text.size()) {
    size_t end = text.find('\n', begin);
    if (end == std::string_view::npos) end = text.size();
    std::string_view line = text.substr(begin, end - begin);
    begin = end + 1;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    line_fn(++line_number, line);
  }
}
// The whole token as a base-10 integer; nullopt otherwise.
std::optional<long> ParseInteger(std::string_view token);

// 1-based line of the byte at `offset` in `text`.
long LineOfOffset(std::string_view text, size_t offset);

// T_a_b from a translation and a q_xyzw read from a file. Returns false and sets *why
// ("q_xyzw: expected unit norm within 0.001, got 1.2") when a number is not finite or the
// quaternion is not unit within kQuaternionNormTolerance. A quaternion already unit to
// double precision is kept bit for bit (exact round trips); others are normalized.
bool MakePoseFromFile(const Eigen::Vector3d& t, const Eigen::Vector4d& q_xyzw, SE3d* T, std::string* why);

// A double-quoted YAML/JSON string literal with \\, \" and control characters escaped.
std::string QuoteString(const std::string& text);

// YAML ("key: {t: [x, y, z], q_xyzw: [qx, qy, qz, qw]}") text of a pose, full precision.
std::string FormatPoseYaml(const SE3d& T);

}  // namespace waymark
