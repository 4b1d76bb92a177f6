// Reading an image file for detection with bounded work and one-line errors: every command
// that detects on image files (detect, map build/localize --detect-images, live image lines,
// demo) reads through ReadImageFile.
#pragma once

#include <filesystem>
#include <opencv2/core.hpp>
#include <string>

namespace waymark {

// The largest image a detector accepts: each side at most kMaxImageSidePx and at most
// kMaxImagePixels in all (a 64-megapixel photo fits; a decompression bomb does not).
inline constexpr int kMaxImageSidePx = 32768;
inline constexpr long kMaxImagePixels = 64L * 1024 * 1024;
// Files larger than this are refused before they are read.
inline constexpr long kMaxImageFileBytes = 512L * 1024 * 1024;

// Decodes the encoded bytes of an image file (PNG, JPEG, ... as OpenCV reads them) into an
// 8-bit gray, BGR or BGRA or a 16-bit gray image (the types MarkerDetector::Detect takes;
// other types are converted to 8-bit gray). Returns an empty image and sets *why (one line,
// without the file name) when the bytes are not an image or the image is empty or larger
// than the limits above; the size of a PNG is checked before it is decoded. The decoder's
// own warnings (libpng's "libpng warning: ...") are not printed: stderr is pointed at
// /dev/null while OpenCV decodes.
cv::Mat DecodeImage(const std::string& bytes, std::string* why);

// The image in `file` (DecodeImage); *why is "FILE: cannot read image: REASON" on failure.
cv::Mat ReadImageFile(const std::filesystem::path& file, std::string* why);

}  // namespace waymark
