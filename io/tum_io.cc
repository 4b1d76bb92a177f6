#include "io/tum_io.h"

#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string_view>
#include <vector>

#include "io/util.h"

namespace waymark {
namespace {

// Splits on spaces and tabs.
std::vector<std::string_view> SplitWhitespace(std::string_view line) {
  std::vector<std::string_view> tokens;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    const size_t start = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t') ++i;
    if (i > start) tokens.push_back(line.substr(start, i - start));
  }
  return tokens;
}

// One data line: 8 finite numbers with a unit quaternion.
StampedSE3 ParseTumLine(std::string_view line, const std::filesystem::path& path, long line_number) {
  const std::vector<std::string_view> tokens = SplitWhitespace(line);
  if (tokens.size() != 8) {
    throw FormatError(
        path, line_number,
        "expected 8 numbers 't tx ty tz qx qy qz qw', got " + std::to_string(tokens.size()) + " fields");
  }
  static const char* const kNames[8] = {"t", "tx", "ty", "tz", "qx", "qy", "qz", "qw"};
  double values[8];
  for (int i = 0; i < 8; ++i) {
    const std::optional<double> value = ParseFiniteDouble(tokens[i]);
    if (!value) {
      throw FormatError(
          path, line_number,
          std::string(kNames[i]) + ": expected a finite number, got '" + std::string(tokens[i]) + "'");
    }
    values[i] = *value;
  }
  StampedSE3 pose;
  pose.stamp_s = values[0];
  std::string why;
  if (!MakePoseFromFile(Eigen::Vector3d(values[1], values[2], values[3]),
                        Eigen::Vector4d(values[4], values[5], values[6], values[7]), &pose.T, &why)) {
    throw FormatError(path, line_number, why);
  }
  return pose;
}

}  // namespace

Trajectory ParseTum(const std::string& text, const std::filesystem::path& path) {
  Trajectory trajectory;
  ForEachLine(text, [&](long line_number, std::string_view line) {
    const size_t first = line.find_first_not_of(" \t");
    if (first == std::string_view::npos || line[first] == '#') return;
    StampedSE3 pose = ParseTumLine(line, path, line_number);
    if (!trajectory.empty() && !(pose.stamp_s > trajectory.back().stamp_s)) {
      throw FormatError(path, line_number,
                        "t: expected stamps strictly increasing, got " + FormatDouble(pose.stamp_s) +
                            " after " + FormatDouble(trajectory.back().stamp_s));
    }
    trajectory.push_back(pose);
  });
  return trajectory;
}

Trajectory ReadTum(const std::filesystem::path& path) { return ParseTum(ReadTextFile(path), path); }

std::string FormatTum(const Trajectory& trajectory, const std::string& comment) {
  std::ostringstream out;
  if (!comment.empty()) {
    std::istringstream lines(comment);
    for (std::string line; std::getline(lines, line);) out << "# " << line << "\n";
  }
  for (size_t i = 0; i < trajectory.size(); ++i) {
    const StampedSE3& pose = trajectory[i];
    if (!std::isfinite(pose.stamp_s) || !pose.T.IsFinite()) {
      throw std::invalid_argument("TUM writer: pose " + std::to_string(i) + " is not finite");
    }
    if (i > 0 && !(pose.stamp_s > trajectory[i - 1].stamp_s)) {
      throw std::invalid_argument("TUM writer: stamps not strictly increasing at pose " + std::to_string(i) +
                                  " (" + FormatDouble(pose.stamp_s) + " after " +
                                  FormatDouble(trajectory[i - 1].stamp_s) + ")");
    }
    const Eigen::Vector3d& t = pose.T.translation();
    const Eigen::Quaterniond& q = pose.T.rotation();
    out << FormatDouble(pose.stamp_s) << ' ' << FormatDouble(t.x()) << ' ' << FormatDouble(t.y()) << ' '
        << FormatDouble(t.z()) << ' ' << FormatDouble(q.x()) << ' ' << FormatDouble(q.y()) << ' '
        << FormatDouble(q.z()) << ' ' << FormatDouble(q.w()) << '\n';
  }
  return out.str();
}

void WriteTum(const std::filesystem::path& path, const Trajectory& trajectory, const std::string& comment) {
  std::string text;
  try {
    text = FormatTum(trajectory, comment);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(path.string() + ": " + e.what());
  }
  AtomicWriteFile(path, text);
}

}  // namespace waymark
