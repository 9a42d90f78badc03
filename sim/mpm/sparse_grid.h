#pragma once
// A sparse grid of 4x4x4-node blocks that exist only near particles, so that
// memory follows the material rather than the domain. Each step the particles
// are binned into the blocks that hold their stencil's base node; a block of
// particles scatters into itself and its seven neighbours on the + side.
// Blocks are coloured by coordinate parity: blocks of one colour never share
// nodes, which makes parallel P2G free of races and its sums independent of
// the thread count.
#include <array>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

#include "sim/math.h"

namespace triad {

struct ParticleSet;

constexpr int kBlockBits = 2;
constexpr int kBlockSize = 1 << kBlockBits;                        // nodes per block side
constexpr int kBlockNodes = kBlockSize * kBlockSize * kBlockSize;  // 64
constexpr int kHalo = kBlockSize + 2;  // nodes a particle block touches per side (quadratic)
constexpr int kHaloNodes = kHalo * kHalo * kHalo;

// Grid node of the MPM grid: mass and momentum during P2G, velocity after the
// grid update. 16 bytes so that a node is one vector register.
struct alignas(16) GridNode {
  float m;
  float v[3];
};

// Packs block coordinates (21 bits each, offset to stay non-negative) into a
// key whose order is x-major: sorting keys sorts blocks in memory order.
uint64_t packBlock(const Vec3i& b);
Vec3i unpackBlock(uint64_t key);

// Floor division of node indices into block coordinates.
inline int blockOf(int node) {
  return node >> kBlockBits;
}

// Which particles of which set fall in which block, and the grid blocks their
// stencils reach. Rebuilt every step by bin().
struct GridLayout {
  // Grid blocks (sorted keys) and their node storage offsets (block * 64).
  std::vector<uint64_t> grid_keys;
  // Blocks that hold particles, sorted by key.
  std::vector<uint64_t> particle_keys;
  // For each particle block, the grid block indices of b + {0,1}^3 in the
  // order dx*4 + dy*2 + dz.
  std::vector<std::array<uint32_t, 8>> neighbours;
  // For each colour (parity of bx, by, bz), the particle blocks of that colour.
  std::array<std::vector<uint32_t>, 8> colour_blocks;
  // Per set: offsets into the set's (sorted) particle arrays; block b holds
  // particles [offsets[s][b], offsets[s][b+1]).
  std::vector<std::vector<uint32_t>> offsets;
  // Per particle block, whether its material sleeps (sim/mpm/sleep.h); empty
  // when the scene does not let material sleep.
  std::vector<uint8_t> asleep;
  // Split over processes (sim/mpm/domain.h): per grid block, its slot among
  // the blocks whose P2G sums cross processes, or -1 (empty when the run is
  // not split). P2G keeps such a block's sums one layer per colour, so that
  // its owner can add them in colour order, the order a single process
  // adds them in: the split then changes no sum.
  std::vector<int32_t> layered;
  size_t layered_blocks = 0;

  bool sleeping(size_t pb) const { return !asleep.empty() && asleep[pb] != 0; }

  size_t gridBlocks() const { return grid_keys.size(); }
  size_t particleBlocks() const { return particle_keys.size(); }
  size_t bytes() const;
};

// Per set, ranges [begin, end) of its particle arrays in the order binning
// visits them (end may pass the set's size: up to its end); an empty list
// visits the set in array order.
using BinOrder = std::vector<std::vector<std::pair<uint32_t, uint32_t>>>;

// Bins every set's particles into blocks, reorders each set's attribute arrays
// by block (stable, so the order is the same for any thread count) and builds
// the layout. `shifted_origin` is node 0 plus dx/2 (see shiftedCoord).
class Binner {
 public:
  // The reorder goes through `spare`, a buffer whose contents are dead
  // until the next scatter (the solver passes its grid, which P2G fills
  // afresh): grown if it is smaller than the largest set needs, so that
  // the step holds the larger of grid and scratch, not both. Without it,
  // the binner keeps a scratch of its own.
  // With `order`, particles of one block keep the order in which its
  // ranges visit them rather than their array order.
  void bin(std::vector<ParticleSet>& sets, const Vec3f& shifted_origin, float inv_dx,
           GridLayout& layout, std::vector<GridNode>* spare = nullptr,
           const BinOrder* order = nullptr);
  size_t bytes() const;

 private:
  // Consecutive particles of one set in one block: [start, end).
  struct Run {
    // The block's key, until the blocks are known; then its index into
    // GridLayout::particle_keys (16 bytes a run: the first step's unsorted
    // particles make a run of nearly every one).
    uint64_t block;
    uint32_t start, end;
  };
  // Per chunk of particles, the chunks of all sets in turn (set s has
  // chunks [set_chunks_[s], set_chunks_[s + 1])): reused between steps, and
  // never copied into one list per set, which held them twice.
  std::vector<std::vector<Run>> chunk_runs_;
  std::vector<size_t> set_chunks_;
  std::vector<uint32_t> src_;                 // per particle: source index of the sorted order
  std::vector<GridNode> scratch_;             // without a spare buffer
  std::vector<uint64_t> run_keys_;
  // The grid blocks, neighbours and colours last built, and the particle
  // blocks they were built for.
  std::vector<uint64_t> grid_for_, grid_keys_;
  std::vector<std::array<uint32_t, 8>> neighbours_;
  std::array<std::vector<uint32_t>, 8> colour_blocks_;
};

// Node coordinate of x shifted down by half a cell, whose floor is the base
// (lowest) node of the particle's quadratic stencil. `shifted_origin` is the
// world position of node 0 plus dx/2. Written as (x - o) * s, with no add
// after the multiply, so that no fused multiply-add can move floor() between
// the binning and the transfers.
inline float shiftedCoord(float x, float shifted_origin, float inv_dx) {
  return (x - shifted_origin) * inv_dx;
}

// Where each of `team` threads' run of consecutive items starts (team + 1
// entries, the last the item count), for items weighing before[i + 1] -
// before[i] (`before`: running sums from 0, one entry more than items):
// thread t starts at the first item with at least its share of the whole
// weight before it. Runs of equal weight rather than of equal count: a
// material filling one side of the domain would sit on one thread.
std::vector<uint32_t> equalShareRuns(const std::vector<uint64_t>& before, int team);

inline Vec3i baseNode(const Vec3f& x, const Vec3f& shifted_origin, float inv_dx) {
  Vec3i b;
  for (int d = 0; d < 3; ++d)
    b[d] = static_cast<int>(std::floor(shiftedCoord(x[d], shifted_origin[d], inv_dx)));
  return b;
}

}  // namespace triad
