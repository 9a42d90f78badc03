#pragma once
// The nodes a particle block's quadratic stencils reach: the block's own
// 4x4x4 and the first two layers of its + neighbours, a 6x6x6 halo.
#include <cstddef>

#include "sim/mpm/sparse_grid.h"

namespace triad {

// Calls f(halo_index, grid_node_index) for every node of particle block pb's
// halo (halo_index = (x * kHalo + y) * kHalo + z), mapping it into the eight
// grid blocks it straddles.
template <class F>
void forHalo(const GridLayout& layout, size_t pb, F&& f) {
  const auto& nb = layout.neighbours[pb];
  for (int x = 0; x < kHalo; ++x)
    for (int y = 0; y < kHalo; ++y)
      for (int z = 0; z < kHalo; ++z) {
        const int d = ((x >> kBlockBits) << 2) | ((y >> kBlockBits) << 1) | (z >> kBlockBits);
        const int k = ((x & (kBlockSize - 1)) * kBlockSize + (y & (kBlockSize - 1))) * kBlockSize +
                      (z & (kBlockSize - 1));
        f((x * kHalo + y) * kHalo + z, size_t{nb[d]} * kBlockNodes + size_t(k));
      }
}

}  // namespace triad
