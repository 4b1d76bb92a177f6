// A small, strict command-line parser shared by the subcommands:
//   --name VALUE, --name=VALUE, boolean --flag, positionals, `--` ends options.
// Unknown options, a missing value or a malformed number are errors (std::invalid_argument)
// whose message names the option.
#pragma once

#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

namespace waymark::cli {

class Args {
 public:
  // `value_options`: options that take a value; `flag_options`: boolean options.
  // Names are given without the leading dashes. --help / -h is always accepted as a flag.
  Args(const std::vector<std::string>& argv, const std::set<std::string>& value_options,
       const std::set<std::string>& flag_options);

  bool Help() const { return flags_.count("help") > 0; }
  bool Flag(const std::string& name) const { return flags_.count(name) > 0; }
  bool Has(const std::string& name) const { return values_.count(name) > 0; }
  std::optional<std::string> Get(const std::string& name) const;
  std::string GetOr(const std::string& name, const std::string& fallback) const;
  std::string Require(const std::string& name) const;  // throws if absent
  std::optional<double> GetDouble(const std::string& name) const;
  // Comma-separated finite numbers ("1.5,-2,0"); throws on anything else.
  std::optional<std::vector<double>> GetDoubleList(const std::string& name) const;
  std::optional<long> GetInt(const std::string& name) const;
  const std::vector<std::string>& positionals() const { return positionals_; }
  // Throws unless the number of positionals is within [min_count, max_count].
  void ExpectPositionals(size_t min_count, size_t max_count, const std::string& what) const;
  // Throws "--out and --poses name the same file 'X'" when two of the given output options
  // (those present among `names`) name the same file; commands call it before their work.
  void ExpectDistinctOutputs(const std::vector<std::string>& names) const;

 private:
  std::map<std::string, std::string> values_;
  std::set<std::string> flags_;
  std::vector<std::string> positionals_;
};

}  // namespace waymark::cli
