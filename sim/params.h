// A scenario's parameters: a fixed, ordered set of typed keys with defaults, bounds and a
// one-line help, overridable from a YAML file and from `key=value` strings.
//
// Keys are dotted ("detect.pixel_sigma_px"); in YAML each dot is one level of nesting:
//   detect:
//     pixel_sigma_px: 0.5
// Strictness: an unknown key, a value of the wrong type (a string or a list where a number is
// expected, 1.5 for an integer, "maybe" for a boolean) and a value outside the key's bounds
// are errors (FormatError) that name the file, the line and the key.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "util/format.h"

namespace waymark::sim {

enum class ParamType { kDouble, kInt, kBool };

struct Param {
  std::string key;
  ParamType type = ParamType::kDouble;
  double value = 0.0;  // ints and bools are stored exactly as doubles
  double min_value = 0.0;
  double max_value = 0.0;
  std::string help;
};

class ParamSet {
 public:
  // Declaring the same key twice is a programmer error (std::logic_error).
  void AddDouble(const std::string& key, double value, double min_value, double max_value,
                 const std::string& help);
  void AddInt(const std::string& key, long value, long min_value, long max_value, const std::string& help);
  void AddBool(const std::string& key, bool value, const std::string& help);

  bool Has(const std::string& key) const { return Find(key) != nullptr; }
  // Typed getters; an undeclared key or a getter of the wrong type is a programmer error.
  double Double(const std::string& key) const;
  long Int(const std::string& key) const;
  bool Bool(const std::string& key) const;

  // Sets one key from its text. `origin` names where the text came from (for messages,
  // e.g. "--set" or "cfg.yaml:4"). Throws std::invalid_argument naming origin and key.
  void SetFromText(const std::string& key, const std::string& text, const std::string& origin);
  // Applies "key=value" (the --set syntax).
  void SetAssignment(const std::string& assignment);
  // Applies every key of a YAML file (nested maps for dotted keys). Throws FormatError
  // "file:line: message" for unreadable YAML, unknown keys, wrong types and bounds.
  void LoadYamlFile(const std::filesystem::path& path);

  // The effective values as YAML, nested by the dots, in declaration order; loading this
  // text back with LoadYamlFile reproduces the same values.
  std::string ToYaml() const;
  // "  key  (default)  help" lines for --help.
  std::string Describe(const std::string& indent) const;

  const std::vector<Param>& params() const { return params_; }

 private:
  const Param* Find(const std::string& key) const;
  Param* Find(const std::string& key);
  const Param& Get(const std::string& key, ParamType type) const;
  void Add(Param param);

  std::vector<Param> params_;
};

}  // namespace waymark::sim
