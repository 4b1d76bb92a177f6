#include "geometry/payload.h"

#include <re2/re2.h>

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

// Compiles a spec's pattern; throws on a syntax error, a pattern larger than RE2's memory
// budget (8 MiB; a repetition count is at most 1000) or invalid UTF-8.
std::shared_ptr<const re2::RE2> CompilePattern(const std::string& pattern) {
  auto regex = std::make_shared<const re2::RE2>(pattern, re2::RE2::Quiet);
  if (!regex->ok()) {
    throw std::runtime_error("payload: pattern: invalid regular expression `" + pattern +
                             "`: " + regex->error());
  }
  return regex;
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
  CheckFields(spec, static_cast<size_t>(CompilePattern(spec.pattern)->NumberOfCapturingGroups()));
}

PayloadParser::PayloadParser(PayloadSpec spec)
    : spec_(std::move(spec)), regex_(CompilePattern(spec_.pattern)) {
  CheckFields(spec_, static_cast<size_t>(regex_->NumberOfCapturingGroups()));
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
  // groups[0] is the whole match; an optional group that took no part has a null data().
  std::vector<re2::StringPiece> groups(spec_.fields.size() + 1);
  if (!regex_->Match(text, 0, text.size(), re2::RE2::UNANCHORED, groups.data(),
                     static_cast<int>(groups.size()))) {
    return std::nullopt;
  }
  PayloadData data;
  for (size_t i = 0; i < spec_.fields.size(); ++i) {
    const std::string& name = spec_.fields[i];
    const bool required = name == "x" || name == "y";
    const re2::StringPiece& group = groups[i + 1];
    if (group.data() == nullptr) {
      if (required) {
        *why = "field `" + name + "` is missing";
        return std::nullopt;
      }
      continue;
    }
    if (!StoreField(name, std::string(group.data(), group.size()), &data, why)) return std::nullopt;
  }
  if (!data.z_m && spec_.default_z_m && data.HasPosition()) data.z_m = spec_.default_z_m;
  return data;
}

}  // namespace waymark
