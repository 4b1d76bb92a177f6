// detect/datamatrix_ecc.h: the Reed-Solomon check of a DataMatrix read against libdmtx's encoder.
#include "detect/datamatrix_ecc.h"

#include <dmtx.h>
#include <gtest/gtest.h>

#include <memory>
#include <string>
#include <vector>

namespace waymark {
namespace {

struct EncodeDeleter {
  void operator()(DmtxEncode* enc) const { dmtxEncodeDestroy(&enc); }
};

// libdmtx's codewords of `text` at symbol size `size_idx` (data and error-correction words).
std::vector<std::uint8_t> Encode(const std::string& text, int size_idx) {
  std::unique_ptr<DmtxEncode, EncodeDeleter> enc(dmtxEncodeCreate());
  dmtxEncodeSetProp(enc.get(), DmtxPropSizeRequest, size_idx);
  std::vector<unsigned char> bytes(text.begin(), text.end());
  if (dmtxEncodeDataMatrix(enc.get(), static_cast<int>(bytes.size()), bytes.data()) != DmtxPass) return {};
  return {enc->message->code, enc->message->code + enc->message->codeSize};
}

int DataWords(int size_idx) { return dmtxGetSymbolAttribute(DmtxSymAttribSymbolDataWords, size_idx); }
int Blocks(int size_idx) { return dmtxGetSymbolAttribute(DmtxSymAttribInterleavedBlocks, size_idx); }
int ErrorWords(int size_idx) { return dmtxGetSymbolAttribute(DmtxSymAttribBlockErrorWords, size_idx); }

// Every size libdmtx encodes (square 10 x 10 to 144 x 144 with up to 10 interleaved blocks, the
// last with blocks of unequal length, and the rectangles): its codewords pass; any one codeword changed
// (every position of three sizes, one block and several) fails.
TEST(DataMatrixCodewordsValid, AcceptsEveryEncodingAndRejectsAnyChangedCodeword) {
  for (int size_idx = 0; size_idx < 30; ++size_idx) {
    const std::vector<std::uint8_t> code = Encode("W" + std::to_string(size_idx), size_idx);
    ASSERT_FALSE(code.empty()) << size_idx;
    EXPECT_TRUE(DataMatrixCodewordsValid(code, DataWords(size_idx), Blocks(size_idx), ErrorWords(size_idx)))
        << size_idx;
  }
  for (const int size_idx : {0, 3, 16}) {  // 10 x 10, 16 x 16, 64 x 64 (4 blocks)
    const std::vector<std::uint8_t> code = Encode("D" + std::to_string(227 + size_idx), size_idx);
    for (size_t i = 0; i < code.size(); ++i) {
      for (const std::uint8_t flip : {0x01, 0x80, 0xff}) {
        std::vector<std::uint8_t> changed = code;
        changed[i] ^= flip;
        EXPECT_FALSE(
            DataMatrixCodewordsValid(changed, DataWords(size_idx), Blocks(size_idx), ErrorWords(size_idx)))
            << "size " << size_idx << " codeword " << i;
      }
    }
  }
}

// The read that libdmtx 0.7.7 returned as "F867" from a motion-blurred "D227" (recall bench,
// DataMatrix-only hard renders, seed 1, frame 37): F867's data words with error-correction words
// that are not F867's. It fails; F867's own and D227's own codewords pass.
TEST(DataMatrixCodewordsValid, RejectsLibdmtxsMisreadOfABlurredSymbol) {
  const std::vector<std::uint8_t> misread = {71, 216, 56, 15, 202, 36, 118, 253};
  EXPECT_FALSE(DataMatrixCodewordsValid(misread, 3, 1, 5));
  EXPECT_EQ(Encode("F867", 0), (std::vector<std::uint8_t>{71, 216, 56, 207, 56, 26, 34, 144}));
  EXPECT_TRUE(DataMatrixCodewordsValid(Encode("F867", 0), 3, 1, 5));
  EXPECT_TRUE(DataMatrixCodewordsValid(Encode("D227", 0), 3, 1, 5));
  // Arguments that describe no code.
  EXPECT_FALSE(DataMatrixCodewordsValid(misread, 3, 0, 5));
  EXPECT_FALSE(DataMatrixCodewordsValid(misread, 3, 1, 0));
  EXPECT_FALSE(DataMatrixCodewordsValid(misread, 8, 1, 5));
  EXPECT_FALSE(DataMatrixCodewordsValid(misread, 4, 1, 5));
}

}  // namespace
}  // namespace waymark
