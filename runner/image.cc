#include "runner/image.h"

#include <fcntl.h>
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <fstream>
#include <mutex>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <system_error>

namespace waymark {
namespace {

std::string SizeText(long width, long height) { return std::to_string(width) + "x" + std::to_string(height); }

// "" when width x height is within the limits, else why not.
std::string CheckSize(long width, long height) {
  if (width < 1 || height < 1) return "empty image (" + SizeText(width, height) + ")";
  if (width > kMaxImageSidePx || height > kMaxImageSidePx || width * height > kMaxImagePixels) {
    return "image of " + SizeText(width, height) + " is larger than the limit (sides up to " +
           std::to_string(kMaxImageSidePx) + " px, " + std::to_string(kMaxImagePixels) + " pixels in all)";
  }
  return "";
}

// The size a PNG's header (its IHDR chunk) declares, when `bytes` start like a PNG.
bool PngHeaderSize(const std::string& bytes, long* width, long* height) {
  static const char kSignature[] = "\x89PNG\r\n\x1a\n";
  if (bytes.size() < 24 || bytes.compare(0, 8, kSignature, 8) != 0 || bytes.compare(12, 4, "IHDR") != 0) {
    return false;
  }
  const auto be32 = [&](size_t at) {
    uint32_t v = 0;
    for (size_t i = 0; i < 4; ++i) v = (v << 8) | static_cast<unsigned char>(bytes[at + i]);
    return static_cast<long>(v);
  };
  *width = be32(16);
  *height = be32(20);
  return true;
}

// Points stderr at /dev/null for its lifetime (one at a time: the mutex), so a decoder
// library's warnings do not land beside Waymark's one-line error.
class QuietStderr {
 public:
  QuietStderr() : lock_(Mutex()) {
    std::fflush(stderr);
    saved_ = ::dup(STDERR_FILENO);
    const int null_fd = ::open("/dev/null", O_WRONLY | O_CLOEXEC);
    if (saved_ >= 0 && null_fd >= 0) ::dup2(null_fd, STDERR_FILENO);
    if (null_fd >= 0) ::close(null_fd);
  }
  ~QuietStderr() {
    std::fflush(stderr);
    if (saved_ >= 0) {
      ::dup2(saved_, STDERR_FILENO);
      ::close(saved_);
    }
  }
  QuietStderr(const QuietStderr&) = delete;
  QuietStderr& operator=(const QuietStderr&) = delete;

 private:
  static std::mutex& Mutex() {
    static std::mutex mutex;
    return mutex;
  }
  std::lock_guard<std::mutex> lock_;
  int saved_ = -1;
};

}  // namespace

cv::Mat DecodeImage(const std::string& bytes, std::string* why) {
  const auto fail = [why](const std::string& reason) {
    if (why) *why = reason;
    return cv::Mat();
  };
  if (bytes.empty()) return fail("empty file");
  long width = 0, height = 0;
  if (PngHeaderSize(bytes, &width, &height)) {
    const std::string size_problem = CheckSize(width, height);
    if (!size_problem.empty()) return fail(size_problem);
  }
  const cv::Mat buffer(1, static_cast<int>(bytes.size()), CV_8U, const_cast<char*>(bytes.data()));
  cv::Mat image;
  try {
    QuietStderr quiet;
    image = cv::imdecode(buffer, cv::IMREAD_UNCHANGED);
    const int type = image.empty() ? -1 : image.type();
    if (!image.empty() && type != CV_8UC1 && type != CV_8UC3 && type != CV_8UC4 && type != CV_16UC1) {
      image = cv::imdecode(buffer, cv::IMREAD_GRAYSCALE);
    }
  } catch (const cv::Exception& e) {
    return fail("corrupt or not an image (" + e.err + ")");
  }
  if (image.empty()) return fail("corrupt or not an image");
  const std::string size_problem = CheckSize(image.cols, image.rows);
  if (!size_problem.empty()) return fail(size_problem);
  return image;
}

cv::Mat ReadImageFile(const std::filesystem::path& file, std::string* why) {
  const auto fail = [&](const std::string& reason) {
    if (why) *why = file.string() + ": cannot read image: " + reason;
    return cv::Mat();
  };
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec)) {
    return fail(std::filesystem::exists(file, ec) ? "not a regular file" : "no such file");
  }
  const auto size = std::filesystem::file_size(file, ec);
  if (ec) return fail(ec.message());
  if (size > static_cast<uintmax_t>(kMaxImageFileBytes)) {
    return fail("file of " + std::to_string(size) + " bytes is larger than the limit (" +
                std::to_string(kMaxImageFileBytes) + ")");
  }
  std::ifstream in(file, std::ios::binary);
  std::ostringstream bytes;
  bytes << in.rdbuf();
  if (!in) return fail("read error");
  std::string reason;
  cv::Mat image = DecodeImage(bytes.str(), &reason);
  if (image.empty()) return fail(reason);
  return image;
}

}  // namespace waymark
