// DataMatrix ECC 200: is a read's codeword sequence a Reed-Solomon codeword? A guard against
// libdmtx's misreads.
//
// libdmtx 0.7.7 (Debian 12) can return a message whose codewords, after its error correction,
// are not a codeword of the symbol's Reed-Solomon code: on the recall bench's motion-blurred
// 25 px symbol "D227" it read "F867" from the codewords 71 216 56 15 202 36 118 253, whose three
// data words are F867's but whose five error-correction words are not (F867's are 207 56 26 34
// 144): its decoder located no error it could repair and let the word through. A corrected read
// must have every syndrome zero, so each interleaved block is checked here: over GF(256) with
// DataMatrix's field polynomial x^8 + x^5 + x^3 + x^2 + 1 (0x12D) and the generator's roots
// alpha^1 .. alpha^e (alpha = 2, e the block's error-correction words), the block's words
// c_0 .. c_{n-1} (its data words, then its error-correction words, interleaved as below) as the
// polynomial c_0 x^{n-1} + ... + c_{n-1} must vanish at every root.
#pragma once

#include <cstdint>
#include <vector>

namespace waymark {

// True when every interleaved block of `codewords` (the symbol's data words, then its
// error-correction words) is a Reed-Solomon codeword with `error_words_per_block`
// error-correction words. Block b holds the data words b, b + blocks, b + 2 blocks, ... below
// `data_words` and the error-correction words data_words + b, data_words + b + blocks, ...
// (ISO/IEC 16022; libdmtx's encoder; they differ from "every blocks-th codeword" only in the
// 144 x 144 symbol, whose blocks hold 156 or 155 data words). False for blocks < 1,
// error_words_per_block < 1 or data_words outside (0, size).
bool DataMatrixCodewordsValid(const std::vector<std::uint8_t>& codewords, int data_words, int blocks,
                              int error_words_per_block);

}  // namespace waymark
