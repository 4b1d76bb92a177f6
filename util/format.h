// Numbers as text, in one place: every message, report and file Waymark writes formats its
// numbers with these three functions.
#pragma once

#include <string>

namespace waymark {

// The shortest text that reads back to exactly `value` (std::to_chars): "0.1", "1e-09", "12345",
// "nan", "inf". For files and error messages.
std::string FormatDouble(double value);

// Fixed-point with `digits` decimals ("%.*f"): FormatFixed(3.14159, 2) == "3.14". For tables.
std::string FormatFixed(double value, int digits);

// At most `digits` significant digits, trailing zeros dropped ("%.*g"): FormatSignificant(
// 0.30000000000000004, 6) == "0.3". For plot axes.
std::string FormatSignificant(double value, int digits);

}  // namespace waymark
