// Small file helpers shared by every reader and writer of Waymark's formats (DESIGN.md
// "Contracts"): one error type that names the file and the line, atomic writes, and
// whole-file reads with a clear message.
#pragma once

#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>

namespace waymark {

// A malformed or unreadable input. what() is one line:
//   "path:line: message"   when the line is known (lines count from 1),
//   "path: message"        otherwise.
class FormatError : public std::runtime_error {
 public:
  FormatError(const std::filesystem::path& file, std::optional<long> line, const std::string& message);
  FormatError(const std::filesystem::path& file, const std::string& message)
      : FormatError(file, std::nullopt, message) {}

  const std::filesystem::path& file() const { return file_; }
  const std::optional<long>& line() const { return line_; }
  // The message without the "path:line: " prefix.
  const std::string& message() const { return message_; }

 private:
  std::filesystem::path file_;
  std::optional<long> line_;
  std::string message_;
};

// Writes `contents` to `path` atomically: the bytes go to a temporary file in the same
// directory, are flushed with fsync, and the file is renamed over `path`. Parent
// directories are created. On any failure the temporary file is removed, `path` is left
// as it was, and std::runtime_error is thrown naming the path.
void AtomicWriteFile(const std::filesystem::path& path, const std::string& contents);

// The whole file as a string. Throws FormatError ("path: cannot open: <reason>") if the
// file is missing, is a directory or cannot be read.
std::string ReadTextFile(const std::filesystem::path& path);

}  // namespace waymark
