// Shared by the libFuzzer targets (docs/reliability.md): a reader may throw only the errors
// its contract names (FormatError, std::invalid_argument, std::runtime_error); anything else
// (another exception type, a crash, a sanitizer finding, a hang) is a finding.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

namespace waymark::fuzz {

inline std::string Text(const uint8_t* data, size_t size) {
  return std::string(reinterpret_cast<const char*>(data), size);
}

}  // namespace waymark::fuzz
