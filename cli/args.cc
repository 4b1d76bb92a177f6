#include "cli/args.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <stdexcept>

#include "io/util.h"

namespace waymark::cli {

Args::Args(const std::vector<std::string>& argv, const std::set<std::string>& value_options,
           const std::set<std::string>& flag_options) {
  bool options_done = false;
  for (size_t i = 0; i < argv.size(); ++i) {
    const std::string& arg = argv[i];
    if (options_done || arg.size() < 2 || arg[0] != '-' || (arg[1] != '-' && arg != "-h")) {
      positionals_.push_back(arg);
      continue;
    }
    if (arg == "--") {
      options_done = true;
      continue;
    }
    if (arg == "-h" || arg == "--help") {
      flags_.insert("help");
      continue;
    }
    std::string name = arg.substr(2);
    std::optional<std::string> inline_value;
    if (const size_t eq = name.find('='); eq != std::string::npos) {
      inline_value = name.substr(eq + 1);
      name = name.substr(0, eq);
    }
    if (value_options.count(name)) {
      if (inline_value) {
        values_[name] = *inline_value;
      } else if (i + 1 < argv.size()) {
        values_[name] = argv[++i];
      } else {
        throw std::invalid_argument("option --" + name + " needs a value");
      }
    } else if (flag_options.count(name)) {
      if (inline_value) throw std::invalid_argument("option --" + name + " takes no value");
      flags_.insert(name);
    } else {
      throw std::invalid_argument("unknown option " + arg + " (see --help)");
    }
  }
}

std::optional<std::string> Args::Get(const std::string& name) const {
  const auto it = values_.find(name);
  if (it == values_.end()) return std::nullopt;
  return it->second;
}

std::string Args::GetOr(const std::string& name, const std::string& fallback) const {
  return Get(name).value_or(fallback);
}

std::string Args::Require(const std::string& name) const {
  const auto value = Get(name);
  if (!value) throw std::invalid_argument("missing required option --" + name + " (see --help)");
  return *value;
}

namespace {

// The whole of `text` as a finite number (strtod), or nullopt.
std::optional<double> ParseFinite(const std::string& text) {
  char* end = nullptr;
  errno = 0;
  const double x = std::strtod(text.c_str(), &end);
  if (text.empty() || *end != '\0' || errno != 0 || !std::isfinite(x)) return std::nullopt;
  return x;
}

}  // namespace

std::optional<double> Args::GetDouble(const std::string& name) const {
  const auto value = Get(name);
  if (!value) return std::nullopt;
  const std::optional<double> x = ParseFinite(*value);
  if (!x)
    throw std::invalid_argument("option --" + name + ": expected a finite number, got '" + *value + "'");
  return x;
}

std::optional<std::vector<double>> Args::GetDoubleList(const std::string& name) const {
  const auto value = Get(name);
  if (!value) return std::nullopt;
  std::vector<double> numbers;
  size_t begin = 0;
  while (true) {
    const size_t comma = value->find(',', begin);
    const std::optional<double> x =
        ParseFinite(value->substr(begin, comma == std::string::npos ? std::string::npos : comma - begin));
    if (!x) {
      throw std::invalid_argument("option --" + name + ": expected comma-separated finite numbers, got '" +
                                  *value + "'");
    }
    numbers.push_back(*x);
    if (comma == std::string::npos) return numbers;
    begin = comma + 1;
  }
}

std::optional<long> Args::GetInt(const std::string& name) const {
  const auto value = Get(name);
  if (!value) return std::nullopt;
  char* end = nullptr;
  errno = 0;
  const long x = std::strtol(value->c_str(), &end, 10);
  if (value->empty() || *end != '\0' || errno != 0) {
    throw std::invalid_argument("option --" + name + ": expected an integer, got '" + *value + "'");
  }
  return x;
}

void Args::ExpectPositionals(size_t min_count, size_t max_count, const std::string& what) const {
  if (positionals_.size() < min_count) throw std::invalid_argument("missing " + what + " (see --help)");
  if (positionals_.size() > max_count) {
    throw std::invalid_argument("unexpected argument '" + positionals_[max_count] + "' (see --help)");
  }
}

void Args::ExpectDistinctOutputs(const std::vector<std::string>& names) const {
  std::vector<std::pair<std::string, std::string>> given;
  for (const std::string& name : names) {
    if (const auto value = Get(name)) given.emplace_back("--" + name, *value);
  }
  CheckDistinctOutputs(given);
}

}  // namespace waymark::cli
