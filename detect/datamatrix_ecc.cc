#include "detect/datamatrix_ecc.h"

#include <array>
#include <cstddef>

namespace waymark {
namespace {

// GF(256) with the field polynomial 0x12D: exponentials and logarithms of alpha = 2.
struct GaloisField {
  std::array<std::uint8_t, 512> exp{};
  std::array<int, 256> log{};
  GaloisField() {
    int x = 1;
    for (int i = 0; i < 255; ++i) {
      exp[static_cast<size_t>(i)] = static_cast<std::uint8_t>(x);
      log[static_cast<size_t>(x)] = i;
      x <<= 1;
      if (x & 0x100) x ^= 0x12D;
    }
    for (int i = 255; i < 512; ++i) exp[static_cast<size_t>(i)] = exp[static_cast<size_t>(i - 255)];
  }
  std::uint8_t Multiply(std::uint8_t a, std::uint8_t b) const {
    if (a == 0 || b == 0) return 0;
    return exp[static_cast<size_t>(log[a] + log[b])];
  }
};

const GaloisField& Field() {
  static const GaloisField field;
  return field;
}

}  // namespace

bool DataMatrixCodewordsValid(const std::vector<std::uint8_t>& codewords, int data_words, int blocks,
                              int error_words_per_block) {
  if (blocks < 1 || error_words_per_block < 1 || data_words <= 0 ||
      static_cast<size_t>(data_words) >= codewords.size())
    return false;
  const GaloisField& field = Field();
  const size_t stride = static_cast<size_t>(blocks), data = static_cast<size_t>(data_words);
  for (size_t block = 0; block < stride; ++block) {
    // The block's words in order: its data words, then its error-correction words.
    std::vector<std::uint8_t> words;
    for (size_t i = block; i < data; i += stride) words.push_back(codewords[i]);
    size_t error_words = 0;
    for (size_t i = data + block; i < codewords.size(); i += stride, ++error_words)
      words.push_back(codewords[i]);
    if (words.size() <= error_words || error_words != static_cast<size_t>(error_words_per_block))
      return false;
    for (int root = 1; root <= error_words_per_block; ++root) {
      // Horner's rule at alpha^root, the block's first word the highest power.
      const std::uint8_t point = field.exp[static_cast<size_t>(root)];
      std::uint8_t value = 0;
      for (const std::uint8_t word : words) value = field.Multiply(value, point) ^ word;
      if (value != 0) return false;
    }
  }
  return true;
}

}  // namespace waymark
