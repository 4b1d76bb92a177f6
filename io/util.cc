#include "io/util.h"

#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <system_error>

#include "io/json_util.h"
#include "io/yaml_util.h"

namespace waymark {
namespace {

std::string FormatWhat(const std::filesystem::path& file, const std::optional<long>& line,
                       const std::string& message) {
  std::string what = file.string();
  if (line) what += ":" + std::to_string(*line);
  what += ": " + message;
  // One line: embedded newlines (e.g. from a parser's message) become spaces.
  for (char& c : what) {
    if (c == '\n' || c == '\r') c = ' ';
  }
  return what;
}

std::string ErrnoText() { return std::strerror(errno); }

// A name that no other writer uses at the same time: ".<name>.tmp-<pid>-<random>".
std::filesystem::path TempPathFor(const std::filesystem::path& path) {
  static thread_local std::mt19937_64 rng(std::random_device{}() ^ static_cast<unsigned long>(::getpid()));
  std::ostringstream name;
  name << "." << path.filename().string() << ".tmp-" << ::getpid() << "-" << std::hex << rng();
  return path.parent_path() / name.str();
}

// Writes all bytes to fd; false on error (errno set).
bool WriteAll(int fd, const std::string& contents) {
  const char* data = contents.data();
  size_t left = contents.size();
  while (left > 0) {
    const ssize_t n = ::write(fd, data, left);
    if (n < 0) {
      if (errno == EINTR) continue;
      return false;
    }
    data += n;
    left -= static_cast<size_t>(n);
  }
  return true;
}

// fsync of the directory, so the rename itself is durable. Best effort.
void SyncDirectory(const std::filesystem::path& dir) {
  const int fd = ::open(dir.empty() ? "." : dir.c_str(), O_RDONLY | O_DIRECTORY);
  if (fd < 0) return;
  ::fsync(fd);
  ::close(fd);
}

}  // namespace

FormatError::FormatError(const std::filesystem::path& file, std::optional<long> line,
                         const std::string& message)
    : std::runtime_error(FormatWhat(file, line, message)), file_(file), line_(line), message_(message) {}

namespace {

// Creates the missing directories above `path`, recording each one made (outermost first)
// in *created so that a failed write can remove them again.
void CreateParents(const std::filesystem::path& path, std::vector<std::filesystem::path>* created) {
  const std::filesystem::path parent = path.parent_path();
  if (parent.empty()) return;
  std::vector<std::filesystem::path> missing;
  std::error_code ec;
  for (std::filesystem::path dir = parent; !dir.empty() && !std::filesystem::exists(dir, ec);
       dir = dir.parent_path()) {
    missing.push_back(dir);
    if (dir == dir.parent_path()) break;
  }
  for (auto it = missing.rbegin(); it != missing.rend(); ++it) {
    if (!std::filesystem::create_directory(*it, ec) && ec) {
      throw std::runtime_error(path.string() + ": cannot create directory: " + ec.message());
    }
    created->push_back(*it);
  }
}

// Writes `contents` to a new temporary file beside `path` (fsync'ed) and returns its path.
std::filesystem::path WriteTemporary(const std::filesystem::path& path, const std::string& contents) {
  if (path.empty() || !path.has_filename()) {
    throw std::runtime_error("cannot write '" + path.string() + "': not a file path");
  }
  const std::filesystem::path temp = TempPathFor(path);
  const int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd < 0) throw std::runtime_error(path.string() + ": cannot create temporary file: " + ErrnoText());
  if (!WriteAll(fd, contents) || ::fsync(fd) != 0) {
    const std::string reason = ErrnoText();
    ::close(fd);
    ::unlink(temp.c_str());
    throw std::runtime_error(path.string() + ": cannot write: " + reason);
  }
  if (::close(fd) != 0) {
    const std::string reason = ErrnoText();
    ::unlink(temp.c_str());
    throw std::runtime_error(path.string() + ": cannot write: " + reason);
  }
  return temp;
}

// The identity of an output path for comparison: absolute, with symlinks and ".." resolved
// as far as the path exists.
std::filesystem::path OutputIdentity(const std::filesystem::path& path) {
  std::error_code ec;
  std::filesystem::path resolved = std::filesystem::weakly_canonical(std::filesystem::absolute(path, ec), ec);
  return ec ? std::filesystem::absolute(path).lexically_normal() : resolved;
}

}  // namespace

void AtomicWriteFile(const std::filesystem::path& path, const std::string& contents) {
  AtomicWriteFiles({{path, contents}});
}

void AtomicWriteFiles(const std::vector<std::pair<std::filesystem::path, std::string>>& files) {
  std::set<std::filesystem::path> identities;
  for (const auto& [path, contents] : files) {
    if (!identities.insert(OutputIdentity(path)).second) {
      throw std::invalid_argument(path.string() + ": the same file is given twice as an output");
    }
  }
  std::vector<std::filesystem::path> created_dirs;
  std::vector<std::filesystem::path> temps;
  try {
    for (const auto& [path, contents] : files) {
      CreateParents(path, &created_dirs);
      RemoveStaleTemporaries(path.parent_path());
      temps.push_back(WriteTemporary(path, contents));
    }
  } catch (...) {
    for (const std::filesystem::path& temp : temps) ::unlink(temp.c_str());
    std::error_code ec;
    for (auto it = created_dirs.rbegin(); it != created_dirs.rend(); ++it) std::filesystem::remove(*it, ec);
    throw;
  }
  // Every file is written: only renames are left (in the same directory: they do not fail
  // for want of space or permission once the temporary could be created).
  for (size_t i = 0; i < files.size(); ++i) {
    const std::filesystem::path& path = files[i].first;
    if (::rename(temps[i].c_str(), path.c_str()) != 0) {
      const std::string reason = ErrnoText();
      for (size_t k = i; k < temps.size(); ++k) ::unlink(temps[k].c_str());
      throw std::runtime_error(path.string() + ": cannot rename temporary file into place: " + reason);
    }
  }
  std::set<std::filesystem::path> dirs;
  for (const auto& [path, contents] : files) dirs.insert(path.parent_path());
  for (const std::filesystem::path& dir : dirs) SyncDirectory(dir);
}

void CheckDistinctOutputs(const std::vector<std::pair<std::string, std::string>>& options) {
  std::map<std::filesystem::path, std::string> seen;  // identity -> option
  for (const auto& [option, path] : options) {
    const auto [it, inserted] = seen.emplace(OutputIdentity(path), option);
    if (!inserted) {
      throw std::invalid_argument(it->second + " and " + option + " name the same file '" + path + "'");
    }
  }
}

bool IsTemporaryFileName(const std::string& name, long* pid) {
  // ".<name>.tmp-<pid>-<hex>" as TempPathFor makes it.
  if (name.size() < 2 || name[0] != '.') return false;
  const size_t tmp = name.rfind(".tmp-");
  if (tmp == std::string::npos || tmp == 0) return false;
  const size_t dash = name.find('-', tmp + 5);
  if (dash == std::string::npos) return false;
  const std::string pid_text = name.substr(tmp + 5, dash - tmp - 5);
  const std::string hex = name.substr(dash + 1);
  if (pid_text.empty() || pid_text.size() > 10 || hex.empty() || hex.size() > 16) return false;
  if (pid_text.find_first_not_of("0123456789") != std::string::npos) return false;
  if (hex.find_first_not_of("0123456789abcdef") != std::string::npos) return false;
  *pid = std::stol(pid_text);
  return *pid > 0;
}

bool ProcessIsGone(long pid) {
  if (pid <= 0 || pid == ::getpid()) return false;
  return ::kill(static_cast<pid_t>(pid), 0) != 0 && errno == ESRCH;
}

int RemoveStaleTemporaryDirectories(const std::filesystem::path& dir, const std::string& prefix) {
  std::error_code ec;
  std::filesystem::directory_iterator it(dir.empty() ? std::filesystem::path(".") : dir, ec);
  if (ec) return 0;
  std::vector<std::filesystem::path> stale;
  for (const std::filesystem::directory_entry& entry : it) {
    const std::string name = entry.path().filename().string();
    const size_t at = name.rfind(prefix);
    if (at == std::string::npos || (at != 0 && name[0] != '.')) continue;
    const std::string pid_text = name.substr(at + prefix.size());
    if (pid_text.empty() || pid_text.size() > 10 ||
        pid_text.find_first_not_of("0123456789") != std::string::npos) {
      continue;
    }
    if (!entry.is_directory(ec) || entry.is_symlink(ec)) continue;
    if (ProcessIsGone(std::stol(pid_text))) stale.push_back(entry.path());
  }
  int removed = 0;
  for (const std::filesystem::path& path : stale) {
    if (std::filesystem::remove_all(path, ec) > 0) ++removed;
  }
  return removed;
}

int RemoveStaleTemporaries(const std::filesystem::path& dir) {
  std::error_code ec;
  std::filesystem::directory_iterator it(dir.empty() ? std::filesystem::path(".") : dir, ec);
  if (ec) return 0;
  int removed = 0;
  for (const std::filesystem::directory_entry& entry : it) {
    long pid = 0;
    if (!IsTemporaryFileName(entry.path().filename().string(), &pid)) continue;
    if (!entry.is_regular_file(ec) || entry.is_symlink(ec)) continue;
    if (!ProcessIsGone(pid)) continue;  // only a writer that is gone
    if (std::filesystem::remove(entry.path(), ec)) ++removed;
  }
  return removed;
}

std::string ReadTextFile(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw FormatError(path, "cannot open: no such file");
  if (std::filesystem::is_directory(path, ec)) throw FormatError(path, "cannot open: is a directory");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw FormatError(path, "cannot open: " + ErrnoText());
  std::ostringstream buffer;
  buffer << in.rdbuf();
  if (in.bad()) throw FormatError(path, "cannot read: " + ErrnoText());
  return buffer.str();
}

std::optional<double> ParseFiniteDouble(std::string_view token) {
  if (!token.empty() && token.front() == '+') token.remove_prefix(1);
  if (token.empty()) return std::nullopt;
  double value = 0.0;
  const auto result = std::from_chars(token.data(), token.data() + token.size(), value);
  if (result.ec != std::errc() || result.ptr != token.data() + token.size() || !std::isfinite(value)) {
    return std::nullopt;
  }
  return value;
}

std::optional<long> ParseInteger(std::string_view token) {
  if (!token.empty() && token.front() == '+') token.remove_prefix(1);
  if (token.empty()) return std::nullopt;
  long value = 0;
  const auto result = std::from_chars(token.data(), token.data() + token.size(), value);
  if (result.ec != std::errc() || result.ptr != token.data() + token.size()) return std::nullopt;
  return value;
}

long LineOfOffset(std::string_view text, size_t offset) {
  offset = std::min(offset, text.size());
  return 1 + static_cast<long>(std::count(text.begin(), text.begin() + offset, '\n'));
}

std::string CheckMarkerSize(double size_m) {
  if (size_m >= kMinMarkerSizeM && size_m <= kMaxMarkerSizeM) return "";
  return "expected a size between " + FormatDouble(kMinMarkerSizeM) + " and " +
         FormatDouble(kMaxMarkerSizeM) + " m, got " + FormatDouble(size_m);
}

bool MakePoseFromFile(const Eigen::Vector3d& t, const Eigen::Vector4d& q_xyzw, SE3d* T, std::string* why) {
  if (!t.allFinite()) {
    *why = "t: expected 3 finite numbers";
    return false;
  }
  if (t.cwiseAbs().maxCoeff() > kMaxCoordinateM) {
    *why = "t: expected coordinates within +-" + FormatDouble(kMaxCoordinateM) + " m, got " +
           FormatDouble(t.cwiseAbs().maxCoeff());
    return false;
  }
  if (!q_xyzw.allFinite()) {
    *why = "q_xyzw: expected 4 finite numbers";
    return false;
  }
  const double norm = q_xyzw.norm();
  if (std::abs(norm - 1.0) > kQuaternionNormTolerance) {
    *why = "q_xyzw: expected unit norm within " + FormatDouble(kQuaternionNormTolerance) + ", got " +
           FormatDouble(norm);
    return false;
  }
  const Eigen::Quaterniond q(q_xyzw[3], q_xyzw[0], q_xyzw[1], q_xyzw[2]);
  // Within a few ulps of 1: already normalized by a writer, keep it exactly.
  *T = std::abs(norm - 1.0) <= 4.0 * std::numeric_limits<double>::epsilon() ? SE3d::FromUnitQuaternion(q, t)
                                                                            : SE3d(q, t);
  return true;
}

std::string QuoteString(const std::string& text) {
  std::string quoted = "\"";
  for (const char c : text) {
    switch (c) {
      case '"':
        quoted += "\\\"";
        break;
      case '\\':
        quoted += "\\\\";
        break;
      case '\n':
        quoted += "\\n";
        break;
      case '\t':
        quoted += "\\t";
        break;
      case '\r':
        quoted += "\\r";
        break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          char buffer[8];
          std::snprintf(buffer, sizeof(buffer), "\\u%04x", static_cast<unsigned>(c));
          quoted += buffer;
        } else {
          quoted += c;
        }
    }
  }
  return quoted + "\"";
}

std::string FormatPoseYaml(const SE3d& T) {
  const Eigen::Vector3d& t = T.translation();
  const Eigen::Quaterniond& q = T.rotation();
  return "{t: [" + FormatDouble(t.x()) + ", " + FormatDouble(t.y()) + ", " + FormatDouble(t.z()) +
         "], q_xyzw: [" + FormatDouble(q.x()) + ", " + FormatDouble(q.y()) + ", " + FormatDouble(q.z()) +
         ", " + FormatDouble(q.w()) + "]}";
}

// ---- YAML ----

namespace {

std::optional<long> YamlLine(const YAML::Node& node) {
  if (!node.IsDefined()) return std::nullopt;
  const YAML::Mark mark = node.Mark();
  if (mark.line < 0) return std::nullopt;
  return static_cast<long>(mark.line) + 1;
}

const char* YamlTypeName(const YAML::Node& node) {
  switch (node.Type()) {
    case YAML::NodeType::Null:
      return "null";
    case YAML::NodeType::Scalar:
      return "a scalar";
    case YAML::NodeType::Sequence:
      return "a list";
    case YAML::NodeType::Map:
      return "a map";
    case YAML::NodeType::Undefined:
      break;
  }
  return "nothing";
}

}  // namespace

YAML::Node YamlLoadMap(const std::filesystem::path& path, const std::string& text) {
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    std::optional<long> line;
    if (e.mark.line >= 0) line = e.mark.line + 1;
    throw FormatError(path, line, "invalid YAML: " + e.msg);
  }
  if (!root.IsMap())
    ThrowYamlError(path, root, std::string("expected a map of keys, got ") + YamlTypeName(root));
  return root;
}

void ThrowYamlError(const std::filesystem::path& path, const YAML::Node& node, const std::string& message) {
  throw FormatError(path, YamlLine(node), message);
}

YAML::Node YamlRequire(const std::filesystem::path& path, const YAML::Node& map, const std::string& key) {
  const YAML::Node value = map[key];
  if (!value.IsDefined() || value.IsNull()) ThrowYamlError(path, map, "missing key '" + key + "'");
  return value;
}

double YamlNumber(const std::filesystem::path& path, const YAML::Node& node, const std::string& what) {
  if (!node.IsScalar()) ThrowYamlError(path, node, what + ": expected a number, got " + YamlTypeName(node));
  if (node.Tag() == "!") ThrowYamlError(path, node, what + ": expected a number, got a quoted string");
  const std::optional<double> value = ParseFiniteDouble(node.Scalar());
  if (!value) ThrowYamlError(path, node, what + ": expected a finite number, got '" + node.Scalar() + "'");
  return *value;
}

long YamlInteger(const std::filesystem::path& path, const YAML::Node& node, const std::string& what) {
  if (!node.IsScalar()) ThrowYamlError(path, node, what + ": expected an integer, got " + YamlTypeName(node));
  if (node.Tag() == "!") ThrowYamlError(path, node, what + ": expected an integer, got a quoted string");
  const std::optional<long> value = ParseInteger(node.Scalar());
  if (!value) ThrowYamlError(path, node, what + ": expected an integer, got '" + node.Scalar() + "'");
  return *value;
}

std::string YamlString(const std::filesystem::path& path, const YAML::Node& node, const std::string& what) {
  if (!node.IsScalar()) ThrowYamlError(path, node, what + ": expected a string, got " + YamlTypeName(node));
  return node.Scalar();
}

std::vector<double> YamlNumbers(const std::filesystem::path& path, const YAML::Node& node,
                                const std::string& what, std::optional<size_t> expected_count) {
  if (!node.IsSequence()) {
    ThrowYamlError(path, node, what + ": expected a list of numbers, got " + YamlTypeName(node));
  }
  if (expected_count && node.size() != *expected_count) {
    ThrowYamlError(path, node,
                   what + ": expected " + std::to_string(*expected_count) + " numbers, got " +
                       std::to_string(node.size()));
  }
  std::vector<double> values;
  for (size_t i = 0; i < node.size(); ++i) {
    values.push_back(YamlNumber(path, node[i], what + "[" + std::to_string(i) + "]"));
  }
  return values;
}

std::vector<std::string> YamlStrings(const std::filesystem::path& path, const YAML::Node& node,
                                     const std::string& what) {
  if (!node.IsSequence()) {
    ThrowYamlError(path, node, what + ": expected a list of strings, got " + YamlTypeName(node));
  }
  std::vector<std::string> values;
  for (size_t i = 0; i < node.size(); ++i) {
    values.push_back(YamlString(path, node[i], what + "[" + std::to_string(i) + "]"));
  }
  return values;
}

SE3d YamlPose(const std::filesystem::path& path, const YAML::Node& node, const std::string& what) {
  if (!node.IsMap())
    ThrowYamlError(path, node, what + ": expected a map {t, q_xyzw}, got " + YamlTypeName(node));
  const YAML::Node t_node = YamlRequire(path, node, "t");
  const std::vector<double> t = YamlNumbers(path, t_node, what + ".t", 3);
  const YAML::Node q_node = YamlRequire(path, node, "q_xyzw");
  const std::vector<double> q = YamlNumbers(path, q_node, what + ".q_xyzw", 4);
  for (const auto& key_value : node) {
    const std::string key = key_value.first.Scalar();
    if (key != "t" && key != "q_xyzw")
      ThrowYamlError(path, key_value.first, what + ": unknown key '" + key + "'");
  }
  SE3d T;
  std::string why;
  if (!MakePoseFromFile(Eigen::Vector3d(t[0], t[1], t[2]), Eigen::Vector4d(q[0], q[1], q[2], q[3]), &T,
                        &why)) {
    ThrowYamlError(path, why.rfind("t:", 0) == 0 ? t_node : q_node, what + "." + why);
  }
  return T;
}

void YamlWarnUnknownKeys(const std::filesystem::path& path, const YAML::Node& map,
                         const std::set<std::string>& allowed, const std::string& what,
                         ReadWarnings* warnings) {
  if (warnings == nullptr) return;
  for (const auto& key_value : map) {
    const std::string key = key_value.first.Scalar();
    if (allowed.count(key)) continue;
    const std::optional<long> line = YamlLine(key_value.first);
    const std::string prefix = what.empty() ? "" : what + ": ";
    warnings->Add("unknown key",
                  FormatError(path, line, prefix + "unknown key '" + key + "' ignored").what());
  }
}

// ---- JSON ----

namespace {

// Iterator over the text that remembers the furthest byte the JSON lexer has read, so the
// SAX callbacks below know where in the text they are.
class TrackingIterator {
 public:
  using iterator_category = std::input_iterator_tag;
  using value_type = char;
  using difference_type = std::ptrdiff_t;
  using pointer = const char*;
  using reference = const char&;

  TrackingIterator(const char* begin, const char* current, size_t* furthest)
      : begin_(begin), current_(current), furthest_(furthest) {}
  reference operator*() const {
    const size_t offset = static_cast<size_t>(current_ - begin_) + 1;
    if (offset > *furthest_) *furthest_ = offset;
    return *current_;
  }
  TrackingIterator& operator++() {
    ++current_;
    return *this;
  }
  TrackingIterator operator++(int) {
    TrackingIterator copy = *this;
    ++current_;
    return copy;
  }
  bool operator==(const TrackingIterator& o) const { return current_ == o.current_; }
  bool operator!=(const TrackingIterator& o) const { return current_ != o.current_; }

 private:
  const char* begin_;
  const char* current_;
  size_t* furthest_;
};

// SAX handler that checks the nesting depth (kMaxJsonDepth) and, when `lines` is not null,
// records the line where every value is (the line of its last character read). Lines are
// counted incrementally (the lexer only moves forward), so the pass is linear in the text.
class LineRecorder {
 public:
  using number_integer_t = nlohmann::json::number_integer_t;
  using number_unsigned_t = nlohmann::json::number_unsigned_t;
  using number_float_t = nlohmann::json::number_float_t;
  using string_t = nlohmann::json::string_t;
  using binary_t = nlohmann::json::binary_t;

  LineRecorder(std::string_view text, const size_t* furthest, std::map<std::string, long>* lines)
      : text_(text), furthest_(furthest), lines_(lines) {}

  bool null() { return Value(); }
  bool boolean(bool) { return Value(); }
  bool number_integer(number_integer_t) { return Value(); }
  bool number_unsigned(number_unsigned_t) { return Value(); }
  bool number_float(number_float_t, const string_t&) { return Value(); }
  bool string(string_t&) { return Value(); }
  bool binary(binary_t&) { return Value(); }
  bool start_object(std::size_t) { return Open(false); }
  bool start_array(std::size_t) { return Open(true); }
  bool end_object() { return Close(); }
  bool end_array() { return Close(); }
  bool key(string_t& key) {
    if (lines_ != nullptr) stack_.back().key = key;
    return true;
  }
  bool parse_error(std::size_t position, const std::string&, const nlohmann::detail::exception& e) {
    error_offset_ = position;
    error_message_ = ShortMessage(e.what());
    return false;
  }
  // Set when the text is not valid JSON or nests too deep: the byte count read when it
  // failed, and the message (nlohmann's without its prefix, or ours).
  const std::optional<size_t>& error_offset() const { return error_offset_; }
  const std::string& error_message() const { return error_message_; }

  // 1-based line of the byte at `offset`, counting on from the last offset asked for.
  long LineAt(size_t offset) {
    offset = std::min(offset, text_.size());
    if (offset < counted_to_) {  // not expected: the lexer only moves forward
      counted_to_ = 0;
      counted_line_ = 1;
    }
    counted_line_ += static_cast<long>(std::count(text_.begin() + counted_to_, text_.begin() + offset, '\n'));
    counted_to_ = offset;
    return counted_line_;
  }

 private:
  struct Level {
    std::string field;
    bool is_array = false;
    size_t next_index = 0;
    std::string key;
  };

  // nlohmann's message without the "[json.exception...] parse error at line L, column C: " prefix.
  static std::string ShortMessage(const std::string& what) {
    const size_t column = what.find("column ");
    if (column != std::string::npos) {
      const size_t colon = what.find(": ", column);
      if (colon != std::string::npos) return what.substr(colon + 2);
    }
    const size_t bracket = what.find("] ");
    return bracket == std::string::npos ? what : what.substr(bracket + 2);
  }

  // Field path of the value about to be recorded.
  std::string CurrentField() {
    if (stack_.empty()) return "";
    Level& level = stack_.back();
    return level.is_array ? JsonField(level.field, level.next_index++) : JsonField(level.field, level.key);
  }
  long CurrentLine() { return LineAt(*furthest_ > 0 ? *furthest_ - 1 : 0); }
  bool Value() {
    if (lines_ != nullptr) (*lines_)[CurrentField()] = CurrentLine();
    return true;
  }
  bool Open(bool is_array) {
    if (depth_ >= kMaxJsonDepth) {
      error_offset_ = *furthest_;
      error_message_ = "arrays and objects nested deeper than " + std::to_string(kMaxJsonDepth) + " levels";
      return false;
    }
    ++depth_;
    if (lines_ == nullptr) return true;
    Level level;
    level.field = CurrentField();
    level.is_array = is_array;
    (*lines_)[level.field] = CurrentLine();
    stack_.push_back(level);
    return true;
  }
  bool Close() {
    --depth_;
    if (lines_ != nullptr) stack_.pop_back();
    return true;
  }

  std::string_view text_;
  const size_t* furthest_;
  std::map<std::string, long>* lines_;
  std::vector<Level> stack_;
  int depth_ = 0;
  size_t counted_to_ = 0;
  long counted_line_ = 1;
  std::optional<size_t> error_offset_;
  std::string error_message_;
};

// A SAX pass over `text`: checks syntax, number range and depth, and fills `lines` if not
// null. Returns the error (its 1-based line within `text` and its message) if any.
std::optional<std::pair<long, std::string>> CheckJson(std::string_view text,
                                                      std::map<std::string, long>* lines) {
  size_t furthest = 0;
  LineRecorder recorder(text, &furthest, lines);
  const char* begin = text.data();
  const bool valid =
      nlohmann::json::sax_parse(TrackingIterator(begin, begin, &furthest),
                                TrackingIterator(begin, begin + text.size(), &furthest), &recorder);
  if (valid) return std::nullopt;
  const size_t offset = recorder.error_offset().value_or(furthest);
  return std::make_pair(recorder.LineAt(offset > 0 ? offset - 1 : 0), recorder.error_message());
}

const char* JsonTypeName(const nlohmann::json& value) {
  if (value.is_null()) return "null";
  if (value.is_boolean()) return "a boolean";
  if (value.is_number()) return "a number";
  if (value.is_string()) return "a string";
  if (value.is_array()) return "an array";
  if (value.is_object()) return "an object";
  return "an unsupported value";
}

}  // namespace

nlohmann::json ParseJsonDocument(const std::string& text, const std::filesystem::path& path,
                                 std::map<std::string, long>* lines) {
  // A first pass with a SAX handler checks the depth and gives the line of every value, and
  // of a syntax error (including numbers out of double range, which nlohmann's DOM parser
  // reports without a position).
  if (const auto error = CheckJson(text, lines)) {
    throw FormatError(path, error->first, "invalid JSON: " + error->second);
  }
  try {
    return nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {  // not expected after the first pass
    throw FormatError(path, std::string("invalid JSON: ") + e.what());
  }
}

nlohmann::json ParseJsonLine(std::string_view line, const std::filesystem::path& path, long line_number) {
  if (const auto error = CheckJson(line, nullptr)) {
    throw FormatError(path, line_number, "invalid JSON: " + error->second);
  }
  try {
    return nlohmann::json::parse(line);
  } catch (const nlohmann::json::exception& e) {  // not expected after the first pass
    throw FormatError(path, line_number, std::string("invalid JSON: ") + e.what());
  }
}

JsonSource JsonSourceForText(const std::filesystem::path& path, std::string_view text) {
  // Built at the first question: reading a valid file records no line at all.
  auto lines = std::make_shared<std::optional<JsonSource>>();
  JsonSource source;
  source.path = path;
  source.line_of = [path, text, lines](const std::string& field) -> std::optional<long> {
    if (!*lines) {
      std::map<std::string, long> all;
      if (CheckJson(text, &all)) all.clear();  // not valid JSON: no line is known
      *lines = JsonSourceWithLines(path, std::move(all));
    }
    return (*lines)->line_of(field);
  };
  return source;
}

JsonSource JsonSourceWithLines(const std::filesystem::path& path, std::map<std::string, long> lines) {
  JsonSource source;
  source.path = path;
  source.line_of = [lines = std::move(lines)](const std::string& field) -> std::optional<long> {
    std::string key = field;
    while (true) {
      if (const auto it = lines.find(key); it != lines.end()) return it->second;
      if (key.empty()) return std::nullopt;
      const size_t cut = key.find_last_of(".[");
      key = cut == std::string::npos ? "" : key.substr(0, cut);
    }
  };
  return source;
}

void ThrowJsonError(const JsonSource& source, const std::string& field, const std::string& message) {
  const std::optional<long> line = source.line_of ? source.line_of(field) : std::nullopt;
  throw FormatError(source.path, line, field.empty() ? message : field + ": " + message);
}

std::string JsonErrorText(const JsonSource& source, const std::string& field, const std::string& message) {
  const std::optional<long> line = source.line_of ? source.line_of(field) : std::nullopt;
  return FormatError(source.path, line, field.empty() ? message : field + ": " + message).what();
}

std::string JsonField(const std::string& parent, size_t index) {
  return parent + "[" + std::to_string(index) + "]";
}

std::string JsonField(const std::string& parent, const std::string& key) {
  return parent.empty() ? key : parent + "." + key;
}

const nlohmann::json* JsonMember(const JsonSource& source, const nlohmann::json& object,
                                 const std::string& field, const std::string& key, bool required) {
  if (!object.is_object()) {
    ThrowJsonError(source, field, std::string("expected an object, got ") + JsonTypeName(object));
  }
  const auto it = object.find(key);
  if (it == object.end()) {
    if (required) ThrowJsonError(source, field, "missing key \"" + key + "\"");
    return nullptr;
  }
  return &*it;
}

double JsonNumber(const JsonSource& source, const nlohmann::json& value, const std::string& field) {
  if (!value.is_number())
    ThrowJsonError(source, field, std::string("expected a number, got ") + JsonTypeName(value));
  const double x = value.get<double>();
  if (!std::isfinite(x)) ThrowJsonError(source, field, "expected a finite number, got " + value.dump());
  return x;
}

long JsonInteger(const JsonSource& source, const nlohmann::json& value, const std::string& field) {
  if (!value.is_number_integer()) {
    ThrowJsonError(
        source, field,
        std::string("expected an integer, got ") + (value.is_number() ? value.dump() : JsonTypeName(value)));
  }
  return value.get<long>();
}

std::string JsonString(const JsonSource& source, const nlohmann::json& value, const std::string& field) {
  if (!value.is_string())
    ThrowJsonError(source, field, std::string("expected a string, got ") + JsonTypeName(value));
  return value.get<std::string>();
}

bool JsonBool(const JsonSource& source, const nlohmann::json& value, const std::string& field) {
  if (!value.is_boolean()) {
    ThrowJsonError(source, field, std::string("expected true or false, got ") + JsonTypeName(value));
  }
  return value.get<bool>();
}

std::vector<double> JsonNumbers(const JsonSource& source, const nlohmann::json& value,
                                const std::string& field, size_t expected_count) {
  if (!value.is_array()) {
    ThrowJsonError(
        source, field,
        "expected an array of " + std::to_string(expected_count) + " numbers, got " + JsonTypeName(value));
  }
  if (value.size() != expected_count) {
    ThrowJsonError(
        source, field,
        "expected " + std::to_string(expected_count) + " numbers, got " + std::to_string(value.size()));
  }
  std::vector<double> numbers;
  for (size_t i = 0; i < value.size(); ++i)
    numbers.push_back(JsonNumber(source, value[i], JsonField(field, i)));
  return numbers;
}

SE3d JsonPose(const JsonSource& source, const nlohmann::json& value, const std::string& field) {
  const std::vector<double> t =
      JsonNumbers(source, *JsonMember(source, value, field, "t", true), JsonField(field, "t"), 3);
  const std::vector<double> q =
      JsonNumbers(source, *JsonMember(source, value, field, "q_xyzw", true), JsonField(field, "q_xyzw"), 4);
  for (const auto& item : value.items()) {
    if (item.key() != "t" && item.key() != "q_xyzw") {
      ThrowJsonError(source, field, "unknown key \"" + item.key() + "\" (expected t and q_xyzw)");
    }
  }
  SE3d T;
  std::string why;
  if (!MakePoseFromFile(Eigen::Vector3d(t[0], t[1], t[2]), Eigen::Vector4d(q[0], q[1], q[2], q[3]), &T,
                        &why)) {
    const std::string key = why.substr(0, why.find(": "));  // "t" or "q_xyzw"
    ThrowJsonError(source, JsonField(field, key), why.substr(why.find(": ") + 2));
  }
  return T;
}

void JsonWarnUnknownKeys(const JsonSource& source, const nlohmann::json& object, const std::string& field,
                         const std::set<std::string>& allowed, ReadWarnings* warnings) {
  if (warnings == nullptr || !object.is_object()) return;
  for (const auto& item : object.items()) {
    if (allowed.count(item.key())) continue;
    const std::string key_field = JsonField(field, item.key());
    const std::optional<long> line = source.line_of ? source.line_of(key_field) : std::nullopt;
    warnings->Add("unknown key",
                  FormatError(source.path, line, "unknown key \"" + key_field + "\" ignored").what());
  }
}

}  // namespace waymark
