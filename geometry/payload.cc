#include "geometry/payload.h"

#include <charconv>
#include <cmath>
#include <set>
#include <stdexcept>
#include <utility>
#include <vector>

#include "geometry/pose.h"

namespace waymark {
namespace {

bool IsCoordinateField(const std::string& name) {
  return name == "x" || name == "y" || name == "z" || name == "yaw_deg";
}

// Whether the quantifier at pattern[i] repeats without bound: *, + or {n,}.
bool UnboundedQuantifierAt(const std::string& pattern, size_t i) {
  if (i >= pattern.size()) return false;
  if (pattern[i] == '*' || pattern[i] == '+') return true;
  if (pattern[i] != '{') return false;
  const size_t close = pattern.find('}', i);
  return close != std::string::npos && pattern[close - 1] == ',';
}

// Throws when a group that repeats without bound holds a repetition without bound itself
// ("(a+)+", "(?:[^;]*)*"): std::regex takes exponential time on such patterns.
void RejectNestedRepetition(const std::string& pattern) {
  std::vector<bool> holds_repetition;  // one per open group
  for (size_t i = 0; i < pattern.size(); ++i) {
    const char c = pattern[i];
    if (c == '\\') {
      ++i;                  // an escaped character
    } else if (c == '[') {  // a class: up to its closing ']' (a leading ']' or '^]' is literal)
      size_t j = i + 1;
      if (j < pattern.size() && pattern[j] == '^') ++j;
      if (j < pattern.size() && pattern[j] == ']') ++j;
      while (j < pattern.size() && pattern[j] != ']') j += pattern[j] == '\\' ? 2 : 1;
      i = j;
      if (UnboundedQuantifierAt(pattern, i + 1) && !holds_repetition.empty()) holds_repetition.back() = true;
    } else if (c == '(') {
      holds_repetition.push_back(false);
    } else if (c == ')' && !holds_repetition.empty()) {
      const bool inner = holds_repetition.back();
      holds_repetition.pop_back();
      if (UnboundedQuantifierAt(pattern, i + 1)) {
        if (inner) {
          throw std::runtime_error("payload: pattern: a repeated group holds a repetition itself (`" +
                                   pattern.substr(0, i + 2) +
                                   "`): std::regex can take exponential time on it; repeat only one of them");
        }
        if (!holds_repetition.empty()) holds_repetition.back() = true;
      } else if (inner && !holds_repetition.empty()) {
        holds_repetition.back() = true;
      }
    } else if (UnboundedQuantifierAt(pattern, i) && !holds_repetition.empty()) {
      holds_repetition.back() = true;
    }
  }
}

// Throws on a run of more than 6 digits: libstdc++'s regex compiler reads a repetition count or
// a back-reference number into an int without an overflow check (fuzz/payload_fuzz.cc:
// `\\777777777777777777777`, undefined behaviour); no payload needs such a number.
void RejectLongNumbers(const std::string& pattern) {
  size_t run = 0;
  for (size_t i = 0; i < pattern.size(); ++i) {
    run = (pattern[i] >= '0' && pattern[i] <= '9') ? run + 1 : 0;
    if (run > 6) {
      throw std::runtime_error("payload: pattern: a number of more than 6 digits at `" +
                               pattern.substr(i + 1 - run, run) + "` (a repetition count or back-reference)");
    }
  }
}

std::regex CompilePattern(const std::string& pattern) {
  RejectLongNumbers(pattern);
  RejectNestedRepetition(pattern);
  try {
    return std::regex(pattern, std::regex::ECMAScript);
  } catch (const std::regex_error& e) {
    throw std::runtime_error("payload: pattern: invalid ECMAScript regular expression `" + pattern +
                             "`: " + e.what());
  }
}

void CheckFields(const PayloadSpec& spec, size_t groups) {
  if (spec.fields.size() != groups) {
    throw std::runtime_error("payload: fields: expected " + std::to_string(groups) +
                             " names (one per capture group of `" + spec.pattern + "`), got " +
                             std::to_string(spec.fields.size()));
  }
  std::set<std::string> seen;
  for (const std::string& name : spec.fields) {
    if (name.empty()) throw std::runtime_error("payload: fields: expected non-empty names");
    if (!seen.insert(name).second) throw std::runtime_error("payload: fields: `" + name + "` appears twice");
  }
  const bool has_xy = seen.count("x") > 0 && seen.count("y") > 0;
  if (spec.default_z_m && (!std::isfinite(*spec.default_z_m) || !has_xy)) {
    throw std::runtime_error("payload: default_z_m: expected a finite height, with fields `x` and `y`");
  }
  for (const char* name : {"x", "y", "z", "yaw_deg"}) {
    if (seen.count(name) > 0 && !has_xy) {
      throw std::runtime_error(std::string("payload: fields: `") + name + "` needs both `x` and `y`");
    }
  }
}

// A finite decimal number filling the whole string ("-1.5", "+2", "3e-2"); nullopt otherwise.
std::optional<double> ParseFiniteNumber(const std::string& text) {
  const char* begin = text.data();
  const char* end = text.data() + text.size();
  if (begin != end && *begin == '+') ++begin;
  if (begin == end || *begin == '+' || *begin == ' ') return std::nullopt;
  double value = 0.0;
  const auto [ptr, ec] = std::from_chars(begin, end, value);
  if (ec != std::errc() || ptr != end || !std::isfinite(value)) return std::nullopt;
  return value;
}

// Stores one named group in `data`; false (with *why) if a coordinate is not a number.
bool StoreField(const std::string& name, const std::string& value, PayloadData* data, std::string* why) {
  if (!IsCoordinateField(name)) {
    data->attributes[name] = value;
    return true;
  }
  const std::optional<double> number = ParseFiniteNumber(value);
  if (!number) {
    *why = "field `" + name + "` is not a finite number: `" + value.substr(0, 64) +
           (value.size() > 64 ? "...`" : "`");
    return false;
  }
  if (name == "x") data->x_m = *number;
  if (name == "y") data->y_m = *number;
  if (name == "z") data->z_m = *number;
  if (name == "yaw_deg") data->yaw_rad = WrapAngle(*number * M_PI / 180.0);
  return true;
}

}  // namespace

void ValidatePayloadSpec(const PayloadSpec& spec) {
  CheckFields(spec, CompilePattern(spec.pattern).mark_count());
}

PayloadParser::PayloadParser(PayloadSpec spec)
    : spec_(std::move(spec)), regex_(CompilePattern(spec_.pattern)) {
  CheckFields(spec_, regex_.mark_count());
}

std::optional<PayloadData> PayloadParser::Parse(const std::string& text, std::string* why) const {
  std::string reason;
  if (why == nullptr) why = &reason;
  why->clear();
  if (text.size() > kMaxPayloadBytes) {
    *why = "payload of " + std::to_string(text.size()) + " bytes is longer than " +
           std::to_string(kMaxPayloadBytes);
    return std::nullopt;
  }
  std::smatch match;
  try {
    if (!std::regex_search(text, match, regex_)) return std::nullopt;
  } catch (const std::regex_error& e) {
    *why = std::string("regular expression engine error: ") + e.what();
    return std::nullopt;
  }
  PayloadData data;
  for (size_t i = 0; i < spec_.fields.size(); ++i) {
    const std::string& name = spec_.fields[i];
    const bool required = name == "x" || name == "y";
    if (!match[i + 1].matched) {
      if (required) {
        *why = "field `" + name + "` is missing";
        return std::nullopt;
      }
      continue;
    }
    if (!StoreField(name, match[i + 1].str(), &data, why)) return std::nullopt;
  }
  if (!data.z_m && spec_.default_z_m && data.HasPosition()) data.z_m = spec_.default_z_m;
  return data;
}

}  // namespace waymark
