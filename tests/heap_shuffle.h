// Shared by the determinism tests: a heap left in a shuffled state, and bitwise comparison of
// poses. Ceres orders parameter blocks by address in places (an elimination group is a
// std::set<double*>), so a build whose blocks the allocator places can round differently from
// run to run; these tests build twice with the heap in different states and compare bits.
#pragma once

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <random>
#include <vector>

#include "geometry/pose.h"

namespace waymark::testing {

// Leaves the heap's free lists in a shuffled order: blocks of the sizes of small containers'
// nodes, allocated, then freed in a random order, so that what is allocated next lands at
// addresses in no particular order.
inline void ShuffleTheHeap(std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<void*> blocks(4000);
  for (void*& b : blocks) b = std::malloc(16 + rng() % 512);
  std::shuffle(blocks.begin(), blocks.end(), rng);
  for (void* b : blocks) std::free(b);
}

inline bool BitIdentical(const SE3d& a, const SE3d& b) {
  return std::memcmp(a.rotation().coeffs().data(), b.rotation().coeffs().data(), 4 * sizeof(double)) == 0 &&
         std::memcmp(a.translation().data(), b.translation().data(), 3 * sizeof(double)) == 0;
}

}  // namespace waymark::testing
