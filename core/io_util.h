// File helpers shared by every reader and writer of Waymark's formats (DESIGN.md
// "Contracts", docs/formats.md): one error type that names the file and the line, atomic
// writes, whole-file reads with a clear message; then the strict number, pose, YAML and JSON
// field readers that core/*_io.cc build on.
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <functional>
#include <map>
#include <nlohmann/json_fwd.hpp>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "core/geometry.h"
#include "core/types.h"

namespace YAML {
class Node;
}

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

// ---- Helpers shared by the strict readers and writers of core/*_io.cc ----

// Quaternions read from files must have unit norm within this tolerance (then are normalized).
inline constexpr double kQuaternionNormTolerance = 1e-3;

// The shortest decimal text that reads back as exactly `value` (std::to_chars), e.g. "0.1",
// "1560889276.31902", "2" for 2.0. Writers use it so round trips are exact.
std::string FormatDouble(double value);

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

// ---- Strict YAML reading (yaml-cpp). Every error is a FormatError naming `path` and the
// 1-based line of the offending node (yaml-cpp marks), with `what` naming the field. ----

// Parses the text; a syntax error becomes a FormatError with its line. The root must be a map.
YAML::Node YamlLoadMap(const std::filesystem::path& path, const std::string& text);
[[noreturn]] void ThrowYamlError(const std::filesystem::path& path, const YAML::Node& node,
                                 const std::string& message);
// map[key]; a missing key is an error ("missing key 'intrinsics'") at the map's line.
YAML::Node YamlRequire(const std::filesystem::path& path, const YAML::Node& map, const std::string& key);
double YamlNumber(const std::filesystem::path& path, const YAML::Node& node, const std::string& what);
long YamlInteger(const std::filesystem::path& path, const YAML::Node& node, const std::string& what);
std::string YamlString(const std::filesystem::path& path, const YAML::Node& node, const std::string& what);
// A sequence of finite numbers; `expected_count` (if given) must match:
// "intrinsics: expected 4 numbers, got 3".
std::vector<double> YamlNumbers(const std::filesystem::path& path, const YAML::Node& node,
                                const std::string& what, std::optional<size_t> expected_count);
// A sequence of strings.
std::vector<std::string> YamlStrings(const std::filesystem::path& path, const YAML::Node& node,
                                     const std::string& what);
// {t: [x, y, z], q_xyzw: [qx, qy, qz, qw]} (see MakePoseFromFile).
SE3d YamlPose(const std::filesystem::path& path, const YAML::Node& node, const std::string& what);
// Adds one counted warning ("unknown key") per key of `map` not in `allowed` (when
// `warnings` is not null).
void YamlWarnUnknownKeys(const std::filesystem::path& path, const YAML::Node& map,
                         const std::set<std::string>& allowed, const std::string& what,
                         ReadWarnings* warnings);

// ---- Strict JSON reading (nlohmann-json). Errors are FormatErrors "path:line: field: message",
// where `field` is a path like "markers[3].T_world_marker.q_xyzw". ----

// Where JSON values come from: the file, and the line of a field (nullopt when unknown).
struct JsonSource {
  std::filesystem::path path;
  std::function<std::optional<long>(const std::string& field)> line_of;
};

// Parses a whole JSON document. A syntax error is a FormatError with its line. When `lines`
// is not null it receives the 1-based line of every value, keyed by field path ("" for the
// root, "markers[0]", "markers[0].size_m", ...).
nlohmann::json ParseJsonDocument(const std::string& text, const std::filesystem::path& path,
                                 std::map<std::string, long>* lines);
// A JsonSource whose line_of looks `field` up in `lines`, falling back to the nearest
// enclosing field.
JsonSource JsonSourceWithLines(const std::filesystem::path& path, std::map<std::string, long> lines);

[[noreturn]] void ThrowJsonError(const JsonSource& source, const std::string& field,
                                 const std::string& message);
// The one-line text ThrowJsonError would throw ("path:line: field: message"), for warnings.
std::string JsonErrorText(const JsonSource& source, const std::string& field, const std::string& message);
// "markers" + 3 -> "markers[3]"; "" + "t" -> "t"; "a" + "t" -> "a.t".
std::string JsonField(const std::string& parent, size_t index);
std::string JsonField(const std::string& parent, const std::string& key);
// The member `key` of `object` (which must be an object); nullptr when absent and not
// required, an error when absent and required.
const nlohmann::json* JsonMember(const JsonSource& source, const nlohmann::json& object,
                                 const std::string& field, const std::string& key, bool required);
double JsonNumber(const JsonSource& source, const nlohmann::json& value, const std::string& field);
long JsonInteger(const JsonSource& source, const nlohmann::json& value, const std::string& field);
std::string JsonString(const JsonSource& source, const nlohmann::json& value, const std::string& field);
bool JsonBool(const JsonSource& source, const nlohmann::json& value, const std::string& field);
// An array of `expected_count` finite numbers ("expected 4 numbers, got 3").
std::vector<double> JsonNumbers(const JsonSource& source, const nlohmann::json& value,
                                const std::string& field, size_t expected_count);
// {"t": [x, y, z], "q_xyzw": [qx, qy, qz, qw]} (see MakePoseFromFile).
SE3d JsonPose(const JsonSource& source, const nlohmann::json& value, const std::string& field);
// Counted warning ("unknown key") per member of `object` not in `allowed`, if `warnings`.
void JsonWarnUnknownKeys(const JsonSource& source, const nlohmann::json& object, const std::string& field,
                         const std::set<std::string>& allowed, ReadWarnings* warnings);

}  // namespace waymark
