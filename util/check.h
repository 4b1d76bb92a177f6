// The shared helper of every options struct's `bool Check(std::string* why) const`, one line per
// rule, as Ceres' Solver::Options::IsValid does with OPTION_GE (internal/ceres/solver.cc):
//
//   bool OdometryNoise::Check(std::string* why) const {
//     WAYMARK_CHECK_OPTION(IsFiniteAtLeast(trans_per_m, 0.0), "trans_per_m must be a finite number >= 0");
//     WAYMARK_CHECK_OPTION(nested.Check(why), nullptr);  // nullptr: keep the nested message
//     return true;
//   }
//
// When the condition is false, `why` (which may be null: the caller wants only the verdict)
// receives the message, and Check returns false.
#pragma once

#include <cmath>
#include <string>

namespace waymark {

// Writes `message` to *why unless why or message is null; returns false.
inline bool FailCheck(std::string* why, const char* message) {
  if (why != nullptr && message != nullptr) *why = message;
  return false;
}
inline bool FailCheck(std::string* why, const std::string& message) {
  if (why != nullptr) *why = message;
  return false;
}

// The rules most options share. NaN fails all of them.
inline bool IsFinitePositive(double value) { return std::isfinite(value) && value > 0.0; }
inline bool IsFiniteAtLeast(double value, double min_value) {
  return std::isfinite(value) && value >= min_value;
}
inline bool IsFiniteInRange(double value, double min_value, double max_value) {
  return std::isfinite(value) && value >= min_value && value <= max_value;
}

}  // namespace waymark

// One rule of a Check(std::string* why): returns false with `message` when `condition` fails.
#define WAYMARK_CHECK_OPTION(condition, message)                 \
  do {                                                           \
    if (!(condition)) return ::waymark::FailCheck(why, message); \
  } while (false)
