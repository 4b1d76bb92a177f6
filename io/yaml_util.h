// Strict YAML field readers (yaml-cpp) for Waymark's formats; see io/util.h.
#pragma once

#include <yaml-cpp/yaml.h>

#include <filesystem>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "io/util.h"

namespace waymark {

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

}  // namespace waymark
