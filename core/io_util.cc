#include "core/io_util.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <random>
#include <sstream>
#include <system_error>

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
  static thread_local std::mt19937_64 rng(std::random_device{}() ^
                                          static_cast<unsigned long>(::getpid()));
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

void AtomicWriteFile(const std::filesystem::path& path, const std::string& contents) {
  if (path.empty() || !path.has_filename()) {
    throw std::runtime_error("cannot write '" + path.string() + "': not a file path");
  }
  const std::filesystem::path parent = path.parent_path();
  if (!parent.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(parent, ec);
    if (ec) throw std::runtime_error(path.string() + ": cannot create directory: " + ec.message());
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
  if (::rename(temp.c_str(), path.c_str()) != 0) {
    const std::string reason = ErrnoText();
    ::unlink(temp.c_str());
    throw std::runtime_error(path.string() + ": cannot rename temporary file into place: " + reason);
  }
  SyncDirectory(parent);
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

}  // namespace waymark
