// Payload patterns and texts (geometry/payload.h, dataset.yaml `payload`): the input's first line
// is the pattern, its second the field names (comma-separated), every further line a code's
// text to parse.
#include <sstream>

#include "fuzz/fuzz_util.h"
#include "geometry/payload.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::istringstream in(waymark::fuzz::Text(data, size));
  waymark::PayloadSpec spec;
  std::string fields;
  if (!std::getline(in, spec.pattern) || !std::getline(in, fields)) return 0;
  std::istringstream names(fields);
  for (std::string name; std::getline(names, name, ',');) spec.fields.push_back(name);
  try {
    const waymark::PayloadParser parser(spec);
    std::string why;
    for (std::string text; std::getline(in, text);) parser.Parse(text, &why);
  } catch (const std::runtime_error&) {
  }
  return 0;
}
