// Strict JSON field readers (nlohmann-json) for Waymark's formats; see io/util.h.
#pragma once

#include <filesystem>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <string>
#include <string_view>

#include "io/util.h"

namespace waymark {

// ---- Strict JSON reading (nlohmann-json). Errors are FormatErrors "path:line: field: message",
// where `field` is a path like "markers[3].T_world_marker.q_xyzw". ----

// Where JSON values come from: the file, and the line of a field (nullopt when unknown).
struct JsonSource {
  std::filesystem::path path;
  std::function<std::optional<long>(const std::string& field)> line_of;
};

// The deepest nesting of arrays and objects a JSON reader accepts (Waymark's formats use at
// most 5); deeper text is an error "invalid JSON: arrays and objects nested deeper than 32
// levels" at its line. It keeps the line recording below linear in the text.
inline constexpr int kMaxJsonDepth = 32;

// Parses a whole JSON document in time and memory linear in its size. A syntax error, a
// number out of double range or nesting deeper than kMaxJsonDepth is a FormatError with its
// line. When `lines` is not null it receives the 1-based line of every value, keyed by field
// path ("" for the root, "markers[0]", "markers[0].size_m", ...).
nlohmann::json ParseJsonDocument(const std::string& text, const std::filesystem::path& path,
                                 std::map<std::string, long>* lines);
// One JSON value on one line of a JSON-lines input (line `line_number` of `path`), with the
// same checks; every error is a FormatError "path:line_number: invalid JSON: ...".
nlohmann::json ParseJsonLine(std::string_view line, const std::filesystem::path& path, long line_number);
// A JsonSource for a document parsed from `text` (which must outlive it): the lines of its
// fields are recorded only when the first one is asked for (an error or a warning), so
// reading a valid file costs no line bookkeeping.
JsonSource JsonSourceForText(const std::filesystem::path& path, std::string_view text);
// A JsonSource whose line_of looks `field` up in `lines`, falling back to the nearest
// enclosing field.
JsonSource JsonSourceWithLines(const std::filesystem::path& path, std::map<std::string, long> lines);

[[noreturn]] void ThrowJsonError(const JsonSource& source, const std::string& field,
                                 const std::string& message);
// The one-line text ThrowJsonError would throw ("path:line: field: message"), for warnings.
std::string JsonErrorText(const JsonSource& source, const std::string& field, const std::string& message);
// "markers" + 3 -> "markers[3]"; "" + "t" -> "t"; "a" + "t" -> "a.t".
std::string JsonField(const std::string& parent, size_t index);
std::string JsonField(const std::string& parent, const std::string& key);
// The member `key` of `object` (which must be an object); nullptr when absent and not
// required, an error when absent and required.
const nlohmann::json* JsonMember(const JsonSource& source, const nlohmann::json& object,
                                 const std::string& field, const std::string& key, bool required);
double JsonNumber(const JsonSource& source, const nlohmann::json& value, const std::string& field);
long JsonInteger(const JsonSource& source, const nlohmann::json& value, const std::string& field);
std::string JsonString(const JsonSource& source, const nlohmann::json& value, const std::string& field);
bool JsonBool(const JsonSource& source, const nlohmann::json& value, const std::string& field);
// An array of `expected_count` finite numbers ("expected 4 numbers, got 3").
std::vector<double> JsonNumbers(const JsonSource& source, const nlohmann::json& value,
                                const std::string& field, size_t expected_count);
// {"t": [x, y, z], "q_xyzw": [qx, qy, qz, qw]} (see MakePoseFromFile).
SE3d JsonPose(const JsonSource& source, const nlohmann::json& value, const std::string& field);
// Counted warning ("unknown key") per member of `object` not in `allowed`, if `warnings`.
void JsonWarnUnknownKeys(const JsonSource& source, const nlohmann::json& object, const std::string& field,
                         const std::set<std::string>& allowed, ReadWarnings* warnings);

}  // namespace waymark
