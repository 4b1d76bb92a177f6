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
#include <utility>
#include <vector>

#include "geometry/pose.h"
#include "geometry/types.h"
#include "util/format.h"

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

// Several files as one (a command with several outputs): every file is written to its
// temporary and flushed before the first is renamed into place, so an output that cannot be
// written (an impossible path, a full disk) leaves every named path as it was, and no
// directory this call created. Two paths naming the same file are an error
// (std::invalid_argument) before anything is written. AtomicWriteFile is the case of one.
void AtomicWriteFiles(const std::vector<std::pair<std::filesystem::path, std::string>>& files);

// Throws std::invalid_argument "--out and --poses name the same file 'X'" when two of the
// given (option, path) pairs name the same file (after making them absolute and resolving
// symbolic links and ".."). Commands call it before their work, with every output option given.
void CheckDistinctOutputs(const std::vector<std::pair<std::string, std::string>>& options);

// Temporary files of a writer that was killed (kill -9, power loss) stay behind. Every
// atomic write first removes, in its directory, the regular files named as this writer names
// its temporaries (".<name>.tmp-<pid>-<hex>") whose process <pid> no longer exists; files of
// any other name, and those of a live process, are never touched. Returns how many it removed.
int RemoveStaleTemporaries(const std::filesystem::path& dir);
// True when `name` has the form of a temporary file of AtomicWriteFile (then *pid is its writer).
bool IsTemporaryFileName(const std::string& name, long* pid);
// True when no process `pid` exists (kill(pid, 0) fails with ESRCH): its temporaries are stale.
bool ProcessIsGone(long pid);
// Removes (recursively) the directories in `dir` named `<prefix><pid>` or `<anything><prefix><pid>`
// (pid in decimal, nothing after it) whose process is gone: the staging directories other
// writers name that way (`waymark sim`'s ".<name>.sim-tmp-<pid>", `waymark detect --annotate`'s
// ".partial-<pid>"). Returns how many it removed.
int RemoveStaleTemporaryDirectories(const std::filesystem::path& dir, const std::string& prefix);

// The whole file as a string. Throws FormatError ("path: cannot open: <reason>") if the
// file is missing, is a directory or cannot be read.
std::string ReadTextFile(const std::filesystem::path& path);

// ---- Helpers shared by the strict readers and writers of io/*_io.cc ----

// Quaternions read from files must have unit norm within this tolerance (then are normalized).
inline constexpr double kQuaternionNormTolerance = 1e-3;

// Physical ranges (docs/formats.md "General rules"): a value outside them is meaningless and
// an error of its reader (and its writer), not a number the solvers are left to choke on.
// Each coordinate of a position in metres (poses in maps, TUM files, camera mounts): ECEF
// and UTM coordinates fit.
inline constexpr double kMaxCoordinateM = 1e7;
// A camera's distance from the robot's origin (|T_robot_camera.t|).
inline constexpr double kMaxCameraOffsetM = 100.0;
// The side of a printed code.
inline constexpr double kMinMarkerSizeM = 1e-4;
inline constexpr double kMaxMarkerSizeM = 100.0;
// Focal lengths, and each distortion coefficient by absolute value.
inline constexpr double kMaxFocalLengthPx = 1e6;
inline constexpr double kMaxDistortionCoefficient = 100.0;
// A detector's corner noise.
inline constexpr double kMaxPixelSigmaPx = 1e3;
// "" when kMinMarkerSizeM <= size_m <= kMaxMarkerSizeM, else the message
// "expected a size between 1e-04 and 100 m, got 9223372036854775808".
std::string CheckMarkerSize(double size_m);

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

// 1-based line of the byte at `offset` in `text` (counts from the start: for one position,
// not for many).
long LineOfOffset(std::string_view text, size_t offset);

// T_a_b from a translation and a q_xyzw read from a file. Returns false and sets *why
// ("q_xyzw: expected unit norm within 0.001, got 1.2") when a number is not finite, a
// coordinate of t is beyond kMaxCoordinateM, or the quaternion is not unit within
// kQuaternionNormTolerance. A quaternion already unit to
// double precision is kept bit for bit (exact round trips); others are normalized.
bool MakePoseFromFile(const Eigen::Vector3d& t, const Eigen::Vector4d& q_xyzw, SE3d* T, std::string* why);

// A double-quoted YAML/JSON string literal with \\, \" and control characters escaped.
std::string QuoteString(const std::string& text);

// YAML ("key: {t: [x, y, z], q_xyzw: [qx, qy, qz, qw]}") text of a pose, full precision.
std::string FormatPoseYaml(const SE3d& T);

}  // namespace waymark
