#pragma once
// Indexing of the nodes of a quadratic stencil in the sparse grid's blocks,
// shared by the coupling's scatter, gather and gap measurement.
#include "sim/math.h"
#include "sim/mpm/sparse_grid.h"

namespace triad {

// Node offset inside a grid block.
inline int localNode(int x, int y, int z) {
  return ((x & (kBlockSize - 1)) * kBlockSize + (y & (kBlockSize - 1))) * kBlockSize +
         (z & (kBlockSize - 1));
}

// Which of a base block's eight neighbours (dx*4 + dy*2 + dz) holds the
// node at offset (a, b, c) from a base node at local position l (0..3) in it.
inline int neighbourOf(const Vec3i& l, int a, int b, int c) {
  return (((l.x() + a) >> kBlockBits) << 2) | (((l.y() + b) >> kBlockBits) << 1) |
         ((l.z() + c) >> kBlockBits);
}

}  // namespace triad
