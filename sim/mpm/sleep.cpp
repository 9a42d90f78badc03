#include "sim/mpm/sleep.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <iterator>

#include "sim/mpm/domain.h"
#include "sim/mpm/halo.h"
#include "sim/mpm/particles.h"

namespace triad {

namespace {

// Index of key in sorted keys, or -1.
int64_t indexOf(const std::vector<uint64_t>& keys, uint64_t key) {
  const auto it = std::lower_bound(keys.begin(), keys.end(), key);
  return it != keys.end() && *it == key ? int64_t(it - keys.begin()) : -1;
}

bool contains(const std::vector<uint64_t>& sorted, uint64_t key) {
  return std::binary_search(sorted.begin(), sorted.end(), key);
}

// Block coordinate of world coordinate x along one axis (as the binner files
// a particle at x).
int blockCoord(double x, float origin, float inv_dx) {
  const double node = std::floor((x - double(origin)) * double(inv_dx));
  return blockOf(int(std::clamp(node, -1e9, 1e9)));
}

Vec3i blockOfPoint(const Vec3d& x, const Vec3f& origin, float inv_dx) {
  return {blockCoord(x.x(), origin.x(), inv_dx), blockCoord(x.y(), origin.y(), inv_dx),
          blockCoord(x.z(), origin.z(), inv_dx)};
}

}  // namespace

bool SleepTracker::calmWithin(const WakeBox& box, const Vec3f& origin, float inv_dx) const {
  const Vec3i lo = blockOfPoint(box.lo, origin, inv_dx), hi = blockOfPoint(box.hi, origin, inv_dx);
  for (size_t b = 0; b < state_.keys.size(); ++b) {
    const Vec3i c = unpackBlock(state_.keys[b]);
    if ((c.array() >= lo.array()).all() && (c.array() <= hi.array()).all() &&
        state_.still[b] < desc_.delay)
      return false;
  }
  return true;
}

size_t SleepTracker::classify(GridLayout& layout, const std::vector<WakeBox>& wake,
                              const Vec3f& origin, float inv_dx, DomainExchange* split) {
  const size_t nblocks = layout.particleBlocks();
  const double delay = desc_.delay;

  // Carry each block's still time over. A block whose particle count
  // changed (material came in or left, a source filled it, a sink emptied
  // it) starts again; so do new blocks.
  counts_.assign(nblocks, 0);
  for (const std::vector<uint32_t>& off : layout.offsets)
    for (size_t b = 0; b < nblocks; ++b) counts_[b] += off[b + 1] - off[b];
  still_.assign(nblocks, 0.0);
  for (size_t b = 0, j = 0; b < nblocks; ++b) {
    const uint64_t key = layout.particle_keys[b];
    while (j < state_.keys.size() && state_.keys[j] < key) ++j;
    if (j < state_.keys.size() && state_.keys[j] == key && state_.counts[j] == counts_[b])
      still_[b] = state_.still[j];
  }

  // Every block that holds particles now, and its still time: split over
  // processes, every process's (each holds a run of keys, in process order).
  struct Block {
    uint64_t key;
    double still;
  };
  std::vector<Block> now(nblocks);
  for (size_t b = 0; b < nblocks; ++b) now[b] = {layout.particle_keys[b], still_[b]};
  if (split) now = allGatherValues(*split, now);
  std::vector<uint64_t> keys(now.size());
  for (size_t b = 0; b < now.size(); ++b) keys[b] = now[b].key;
  // Blocks that held particles and hold none now.
  std::vector<uint64_t> gone;
  std::set_difference(state_.keys.begin(), state_.keys.end(), keys.begin(), keys.end(),
                      std::back_inserter(gone));

  // Blocks near a moving solid stay awake.
  std::vector<uint8_t> woken(now.size(), 0);
  for (const WakeBox& w : wake) {
    const Vec3i lo = blockOfPoint(w.lo, origin, inv_dx), hi = blockOfPoint(w.hi, origin, inv_dx);
    for (size_t b = 0; b < now.size(); ++b) {
      const Vec3i c = unpackBlock(now[b].key);
      if ((c.array() >= lo.array()).all() && (c.array() <= hi.array()).all()) woken[b] = 1;
    }
  }

  // Asleep: still long enough, and so is every neighbour; none emptied.
  asleep_keys_.clear();
  for (size_t b = 0; b < now.size(); ++b) {
    if (woken[b] || now[b].still < delay) continue;
    const Vec3i c = unpackBlock(now[b].key);
    bool calm = true;
    for (int dx = -1; dx <= 1 && calm; ++dx)
      for (int dy = -1; dy <= 1 && calm; ++dy)
        for (int dz = -1; dz <= 1 && calm; ++dz) {
          if (dx == 0 && dy == 0 && dz == 0) continue;
          const uint64_t key = packBlock(c + Vec3i(dx, dy, dz));
          const int64_t n = indexOf(keys, key);
          if (n >= 0 ? now[size_t(n)].still < delay : contains(gone, key)) calm = false;
        }
    if (calm) asleep_keys_.push_back(now[b].key);
  }
  layout.asleep.assign(nblocks, 0);
  size_t sleeping = 0;
  for (size_t b = 0; b < nblocks; ++b) {
    if (!contains(asleep_keys_, layout.particle_keys[b])) continue;
    layout.asleep[b] = 1;
    sleeping += counts_[b];
  }
  return sleeping;
}

void SleepTracker::update(const GridLayout& layout, const std::vector<float>& speed2, double dt,
                          DomainExchange* split) {
  const size_t nblocks = layout.particleBlocks();
  const float limit2 = float(desc_.speed * desc_.speed);
  for (size_t b = 0; b < nblocks; ++b) {
    // A sleeping block is still by construction.
    if (layout.sleeping(b) || speed2[b] < limit2)
      still_[b] = std::min(still_[b] + dt, 1e30);
    else
      still_[b] = 0.0;
  }
  if (!split) {
    state_.keys = layout.particle_keys;
    state_.counts = counts_;
    state_.still = still_;
    return;
  }
  struct Block {
    uint64_t key;
    uint64_t count;
    double still;
  };
  std::vector<Block> mine(nblocks);
  for (size_t b = 0; b < nblocks; ++b) mine[b] = {layout.particle_keys[b], counts_[b], still_[b]};
  const std::vector<Block> all = allGatherValues(*split, mine);
  state_.keys.resize(all.size());
  state_.counts.resize(all.size());
  state_.still.resize(all.size());
  for (size_t b = 0; b < all.size(); ++b) {
    state_.keys[b] = all[b].key;
    state_.counts[b] = uint32_t(all[b].count);
    state_.still[b] = all[b].still;
  }
}

void freezeSleepingNodes(const GridLayout& layout, std::vector<GridNode>& grid,
                         std::vector<GridNode>* flip, const std::vector<uint64_t>* asleep) {
  auto freeze = [&](size_t node) {
    grid[node].v[0] = grid[node].v[1] = grid[node].v[2] = 0.0f;
    if (flip) (*flip)[node].v[0] = (*flip)[node].v[1] = (*flip)[node].v[2] = 0.0f;
  };
  if (asleep) {
    // Every process's sleeping blocks: the halo nodes that lie here.
    for (const uint64_t key : *asleep) {
      const Vec3i c = unpackBlock(key);
      std::array<int64_t, 8> gb;
      for (int d = 0; d < 8; ++d)
        gb[size_t(d)] =
            indexOf(layout.grid_keys, packBlock(c + Vec3i((d >> 2) & 1, (d >> 1) & 1, d & 1)));
      for (int x = 0; x < kHalo; ++x)
        for (int y = 0; y < kHalo; ++y)
          for (int z = 0; z < kHalo; ++z) {
            const int d = ((x >> kBlockBits) << 2) | ((y >> kBlockBits) << 1) | (z >> kBlockBits);
            if (gb[size_t(d)] < 0) continue;
            const int k =
                ((x & (kBlockSize - 1)) * kBlockSize + (y & (kBlockSize - 1))) * kBlockSize +
                (z & (kBlockSize - 1));
            freeze(size_t(gb[size_t(d)]) * kBlockNodes + size_t(k));
          }
    }
    return;
  }
  if (layout.asleep.empty()) return;
  for (size_t pb = 0; pb < layout.particleBlocks(); ++pb) {
    if (!layout.asleep[pb]) continue;
    forHalo(layout, pb, [&](int, size_t node) { freeze(node); });
  }
}

void stillSleepingParticles(const GridLayout& layout, std::vector<ParticleSet>& sets) {
  if (layout.asleep.empty()) return;
  for (size_t s = 0; s < sets.size(); ++s) {
    ParticleSet& set = sets[s];
    const std::vector<uint32_t>& off = layout.offsets[s];
    for (size_t pb = 0; pb < layout.particleBlocks(); ++pb) {
      if (!layout.asleep[pb]) continue;
      for (uint32_t i = off[pb]; i < off[pb + 1]; ++i) {
        set.v[i].setZero();
        set.C[i].setZero();
      }
    }
  }
}

}  // namespace triad
