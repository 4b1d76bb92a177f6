// Coordinates printed inside a code's payload (dataset.yaml `payload`, docs/design.md).
//
// A PayloadSpec is a regular expression over the decoded text of a QR or DataMatrix code plus
// one name per capture group. Groups named
//   x, y, z   position of the code in the world frame (m)
//   yaw_deg   heading of the code about world z (degrees; returned wrapped, in radians)
// give a prior on the code's pose; every other group is kept as a string attribute.
// Example (seed paper 004, "0/2/10" = kind 0 at x = 2, y = 10):
//   pattern: "^(\\d+)/(-?[0-9.]+)/(-?[0-9.]+)$", fields: [kind, x, y]
//
// The syntax is RE2's (the common subset of ECMAScript and PCRE: classes, \d \w \s, (?:...),
// lazy quantifiers, {n,m} up to 1000; no back-references, no look-arounds). RE2 matches in time
// linear in the text whatever the pattern, so a hostile text printed on a code cannot stall
// the localizer (a backtracking engine such as std::regex takes exponential time on patterns
// like "^(a+)+$"). The pattern is searched for in the text: anchor it with ^...$ to require the
// whole text to match. Payload text comes from the outside world: parsing never throws on it.
// Only the spec (written by the dataset's author) is validated with errors.
#pragma once

#include <cstddef>
#include <map>
#include <memory>
#include <optional>
#include <string>

#include "geometry/types.h"

namespace re2 {
class RE2;
}  // namespace re2

namespace waymark {

// Longer texts are rejected before matching (a QR code holds at most 2953 bytes; coordinate
// payloads are a few dozen).
inline constexpr size_t kMaxPayloadBytes = 1024;

// What a payload says. Coordinates are present only when their group is in the spec and
// took part in the match.
struct PayloadData {
  std::optional<double> x_m;
  std::optional<double> y_m;
  std::optional<double> z_m;
  std::optional<double> yaw_rad;                  // from yaw_deg, wrapped to (-pi, pi]
  std::map<std::string, std::string> attributes;  // other named groups that took part

  bool HasPosition() const { return x_m.has_value() && y_m.has_value(); }
};

class PayloadParser {
 public:
  // Throws std::runtime_error ("payload: ...") for an invalid regular expression, a number of
  // field names different from the number of capture groups, an empty or repeated field
  // name, or z / yaw_deg without both x and y.
  explicit PayloadParser(PayloadSpec spec);

  const PayloadSpec& spec() const { return spec_; }

  // The payload's data, or nullopt. When the text does not match (an ordinary code without
  // coordinates) *why is set to ""; when it matches but cannot be used (a coordinate that is
  // not a finite number, an over-long text) *why says why. Thread-safe.
  std::optional<PayloadData> Parse(const std::string& text, std::string* why = nullptr) const;

 private:
  PayloadSpec spec_;
  std::shared_ptr<const re2::RE2> regex_;  // compiled once; shared by copies
};

// Throws like PayloadParser's constructor; returns normally for a valid spec.
void ValidatePayloadSpec(const PayloadSpec& spec);

}  // namespace waymark
