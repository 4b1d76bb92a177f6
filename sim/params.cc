#include "sim/params.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <optional>
#include <sstream>
#include <stdexcept>

#include "io/util.h"
#include "io/yaml_util.h"

namespace waymark::sim {
namespace {

const char* TypeName(ParamType type) {
  switch (type) {
    case ParamType::kDouble:
      return "a number";
    case ParamType::kInt:
      return "an integer";
    case ParamType::kBool:
      return "true or false";
  }
  return "?";
}

// Parses `text` as the param's type; nullopt when malformed.
std::optional<double> ParseValue(ParamType type, const std::string& text) {
  if (text.empty()) return std::nullopt;
  if (type == ParamType::kBool) {
    if (text == "true") return 1.0;
    if (text == "false") return 0.0;
    return std::nullopt;
  }
  char* end = nullptr;
  errno = 0;
  if (type == ParamType::kInt) {
    const long x = std::strtol(text.c_str(), &end, 10);
    if (*end != '\0' || errno != 0) return std::nullopt;
    return static_cast<double>(x);
  }
  const double x = std::strtod(text.c_str(), &end);
  if (*end != '\0' || errno != 0 || !std::isfinite(x)) return std::nullopt;
  return x;
}

std::string ValueText(const Param& p) {
  if (p.type == ParamType::kBool) return p.value != 0.0 ? "true" : "false";
  if (p.type == ParamType::kInt) return std::to_string(static_cast<long>(p.value));
  return FormatDouble(p.value);
}

// Collects every scalar leaf of a YAML map as dotted key -> node.
void Flatten(const YAML::Node& node, const std::string& prefix, const std::filesystem::path& path,
             std::vector<std::pair<std::string, YAML::Node>>* leaves) {
  for (const auto& entry : node) {
    const YAML::Node& key_node = entry.first;
    const YAML::Node& value = entry.second;
    if (!key_node.IsScalar()) {
      throw FormatError(path, key_node.Mark().line + 1, "expected a key name");
    }
    const std::string key = prefix.empty() ? key_node.Scalar() : prefix + "." + key_node.Scalar();
    if (value.IsMap()) {
      Flatten(value, key, path, leaves);
    } else {
      leaves->emplace_back(key, value);
    }
  }
}

}  // namespace

void ParamSet::Add(Param param) {
  if (Find(param.key) != nullptr) throw std::logic_error("parameter declared twice: " + param.key);
  params_.push_back(std::move(param));
}

void ParamSet::AddDouble(const std::string& key, double value, double min_value, double max_value,
                         const std::string& help) {
  Add({key, ParamType::kDouble, value, min_value, max_value, help});
}

void ParamSet::AddInt(const std::string& key, long value, long min_value, long max_value,
                      const std::string& help) {
  Add({key, ParamType::kInt, static_cast<double>(value), static_cast<double>(min_value),
       static_cast<double>(max_value), help});
}

void ParamSet::AddBool(const std::string& key, bool value, const std::string& help) {
  Add({key, ParamType::kBool, value ? 1.0 : 0.0, 0.0, 1.0, help});
}

const Param* ParamSet::Find(const std::string& key) const {
  for (const Param& p : params_) {
    if (p.key == key) return &p;
  }
  return nullptr;
}

Param* ParamSet::Find(const std::string& key) {
  for (Param& p : params_) {
    if (p.key == key) return &p;
  }
  return nullptr;
}

const Param& ParamSet::Get(const std::string& key, ParamType type) const {
  const Param* p = Find(key);
  if (p == nullptr || p->type != type)
    throw std::logic_error("parameter not declared with this type: " + key);
  return *p;
}

double ParamSet::Double(const std::string& key) const { return Get(key, ParamType::kDouble).value; }
long ParamSet::Int(const std::string& key) const {
  return static_cast<long>(Get(key, ParamType::kInt).value);
}
bool ParamSet::Bool(const std::string& key) const { return Get(key, ParamType::kBool).value != 0.0; }

void ParamSet::SetFromText(const std::string& key, const std::string& text, const std::string& origin) {
  Param* p = Find(key);
  if (p == nullptr) {
    throw std::invalid_argument(origin + ": unknown key '" + key + "' (see `waymark sim --help`)");
  }
  const std::optional<double> value = ParseValue(p->type, text);
  if (!value) {
    throw std::invalid_argument(origin + ": " + key + ": expected " + TypeName(p->type) + ", got '" + text +
                                "'");
  }
  if (p->type != ParamType::kBool && (*value < p->min_value || *value > p->max_value)) {
    throw std::invalid_argument(origin + ": " + key + ": " + text + " is outside [" +
                                FormatDouble(p->min_value) + ", " + FormatDouble(p->max_value) + "]");
  }
  p->value = *value;
}

void ParamSet::SetAssignment(const std::string& assignment) {
  const size_t eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0) {
    throw std::invalid_argument("--set " + assignment + ": expected key=value");
  }
  SetFromText(assignment.substr(0, eq), assignment.substr(eq + 1), "--set");
}

void ParamSet::LoadYamlFile(const std::filesystem::path& path) {
  const std::string text = ReadTextFile(path);
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw FormatError(path, e.mark.line + 1, "malformed YAML: " + e.msg);
  }
  if (root.IsNull()) return;  // an empty file changes nothing
  if (!root.IsMap()) throw FormatError(path, root.Mark().line + 1, "expected a map of keys");
  std::vector<std::pair<std::string, YAML::Node>> leaves;
  Flatten(root, "", path, &leaves);
  for (const auto& [key, node] : leaves) {
    const long line = node.Mark().line + 1;
    const Param* p = Find(key);
    if (p == nullptr) throw FormatError(path, line, "unknown key '" + key + "' (see `waymark sim --help`)");
    // Quoted scalars ("0.5") are strings: the wrong type, as are lists and nulls.
    if (!node.IsScalar() || node.Tag() == "!") {
      throw FormatError(path, line, key + ": expected " + TypeName(p->type));
    }
    try {
      SetFromText(key, node.Scalar(), key);
    } catch (const std::invalid_argument& e) {
      std::string message = e.what();
      message = message.substr(key.size() + 2);  // drop the "key: " origin, FormatError adds file:line
      throw FormatError(path, line, message);
    }
  }
}

std::string ParamSet::ToYaml() const {
  std::ostringstream out;
  std::vector<std::string> open;  // the groups of the previous key
  for (const Param& p : params_) {
    std::vector<std::string> parts;
    std::stringstream ss(p.key);
    for (std::string part; std::getline(ss, part, '.');) parts.push_back(part);
    size_t common = 0;
    while (common < open.size() && common + 1 < parts.size() && open[common] == parts[common]) ++common;
    for (size_t i = common; i + 1 < parts.size(); ++i) {
      out << std::string(2 * i, ' ') << parts[i] << ":\n";
    }
    out << std::string(2 * (parts.size() - 1), ' ') << parts.back() << ": " << ValueText(p) << "  # "
        << p.help << "\n";
    open.assign(parts.begin(), parts.end() - 1);
  }
  return out.str();
}

std::string ParamSet::Describe(const std::string& indent) const {
  size_t width = 0;
  for (const Param& p : params_) width = std::max(width, p.key.size() + ValueText(p).size() + 3);
  std::ostringstream out;
  for (const Param& p : params_) {
    const std::string head = p.key + " (" + ValueText(p) + ")";
    out << indent << head << std::string(width + 2 - head.size(), ' ') << p.help << "\n";
  }
  return out.str();
}

}  // namespace waymark::sim
