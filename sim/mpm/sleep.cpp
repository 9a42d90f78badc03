#include "sim/mpm/sleep.h"

#include <algorithm>
#include <cmath>

#include "sim/mpm/domain.h"
#include "sim/mpm/halo.h"
#include "sim/mpm/particles.h"

namespace triad {

namespace {

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

  // Split over processes and cut anew since the state was kept: blocks
  // this process kept and another owns now go to their owner.
  if (split && own_only_ && split->cuts() != cuts_) handOver(*split);

  // Carry each block's still time over. A block whose particle count
  // changed (material came in or left, a source filled it, a sink emptied
  // it) starts again; so do new blocks.
  counts_.assign(nblocks, 0);
  for (const std::vector<uint32_t>& off : layout.offsets)
    for (size_t b = 0; b < nblocks; ++b) counts_[b] += off[b + 1] - off[b];
  still_.assign(nblocks, 0.0);
  woken_.assign(nblocks, 0);
  for (size_t b = 0, j = 0; b < nblocks; ++b) {
    const uint64_t key = layout.particle_keys[b];
    while (j < state_.keys.size() && state_.keys[j] < key) ++j;
    if (j < state_.keys.size() && state_.keys[j] == key && state_.counts[j] == counts_[b])
      still_[b] = state_.still[j];
  }

  // Every block that holds particles now, and its still time: this
  // process's, and split over processes the other processes' blocks beside
  // its own.
  struct Block {
    uint64_t key;
    double still;
  };
  std::vector<Block> now(nblocks);
  for (size_t b = 0; b < nblocks; ++b) now[b] = {layout.particle_keys[b], still_[b]};
  if (split) {
    std::vector<std::vector<Block>> out;
    std::vector<int> to;
    for (size_t b = 0; b < nblocks; ++b) {
      // Only blocks whose neighbourhood's keys leave this process's run.
      const Vec3i c = unpackBlock(layout.particle_keys[b]);
      if (split->owns(packBlock(c - Vec3i::Ones())) && split->owns(packBlock(c + Vec3i::Ones())))
        continue;
      to.clear();
      for (int dx = -1; dx <= 1; ++dx)
        for (int dy = -1; dy <= 1; ++dy)
          for (int dz = -1; dz <= 1; ++dz) {
            const int p = split->ownerOf(packBlock(c + Vec3i(dx, dy, dz)));
            if (p != split->process() && std::find(to.begin(), to.end(), p) == to.end())
              to.push_back(p);
          }
      for (const int p : to) {
        if (out.size() <= size_t(p)) out.resize(size_t(p) + 1);
        out[size_t(p)].push_back(now[b]);
      }
    }
    const std::vector<Block> beside = exchangeValues(*split, out);
    now.insert(now.end(), beside.begin(), beside.end());
    std::sort(now.begin(), now.end(), [](const Block& a, const Block& b) { return a.key < b.key; });
  }
  std::vector<uint64_t> keys(now.size());
  for (size_t b = 0; b < now.size(); ++b) keys[b] = now[b].key;
  auto stillAt = [&](const Vec3i& c) {
    const auto it = std::lower_bound(keys.begin(), keys.end(), packBlock(c));
    return it == keys.end() || *it != packBlock(c) ||
           now[size_t(it - keys.begin())].still >= desc_.delay;
  };

  // Asleep: still for the delay, and so is every block around it (material
  // creeping next to a sleeping block would be held back by its rest), and
  // no moving solid near.
  layout.asleep.assign(nblocks, 0);
  for (size_t b = 0; b < nblocks; ++b) {
    if (still_[b] < desc_.delay) continue;
    const Vec3i c = unpackBlock(layout.particle_keys[b]);
    bool calm = true;
    for (int dx = -1; dx <= 1 && calm && desc_.neighbours; ++dx)
      for (int dy = -1; dy <= 1 && calm; ++dy)
        for (int dz = -1; dz <= 1 && calm; ++dz) calm = stillAt(c + Vec3i(dx, dy, dz));
    layout.asleep[b] = calm;
  }
  for (const WakeBox& w : wake) {
    const Vec3i lo = blockOfPoint(w.lo, origin, inv_dx), hi = blockOfPoint(w.hi, origin, inv_dx);
    for (size_t b = 0; b < nblocks; ++b) {
      const Vec3i c = unpackBlock(layout.particle_keys[b]);
      if ((c.array() >= lo.array()).all() && (c.array() <= hi.array()).all()) layout.asleep[b] = 0;
    }
  }
  size_t sleeping = 0;
  for (size_t b = 0; b < nblocks; ++b) sleeping += layout.asleep[b] ? counts_[b] : 0;
  return sleeping;
}

size_t SleepTracker::wakeMoving(GridLayout& layout, const std::vector<uint8_t>& moving,
                                SleepHalos& halos) {
  size_t woken = 0;
  for (size_t pb = 0; pb < layout.particleBlocks(); ++pb) {
    if (!layout.sleeping(pb) || !moving[pb]) continue;
    layout.asleep[pb] = 0;
    woken_[pb] = 1;
    woken += counts_[pb];
    if (halos.slot[pb] >= 0) halos.filled[size_t(halos.slot[pb])] = 0;
  }
  return woken;
}

void SleepHalos::prepare(const GridLayout& layout) {
  const size_t nblocks = layout.particleBlocks();
  std::vector<uint64_t> now;
  for (size_t b = 0; b < nblocks; ++b)
    if (layout.sleeping(b)) now.push_back(layout.particle_keys[b]);
  if (now != keys) {
    // Carry over the sums of blocks that slept before and still do.
    std::vector<float> s(now.size() * kFloats);
    std::vector<uint8_t> f(now.size(), 0);
    for (size_t i = 0, j = 0; i < now.size(); ++i) {
      while (j < keys.size() && keys[j] < now[i]) ++j;
      if (j == keys.size() || keys[j] != now[i] || !filled[j]) continue;
      std::copy_n(sums.begin() + std::ptrdiff_t(j * kFloats), kFloats,
                  s.begin() + std::ptrdiff_t(i * kFloats));
      f[i] = 1;
    }
    keys = std::move(now);
    sums = std::move(s);
    filled = std::move(f);
  }
  slot.assign(nblocks, -1);
  for (size_t b = 0, i = 0; b < nblocks; ++b)
    if (layout.sleeping(b)) slot[b] = int32_t(i++);
}

size_t SleepHalos::bytes() const {
  return keys.capacity() * 8 + sums.capacity() * sizeof(float) + filled.capacity() +
         slot.capacity() * 4;
}

void SleepTracker::update(const GridLayout& layout, const std::vector<float>& speed2, double dt,
                          DomainExchange* split) {
  const size_t nblocks = layout.particleBlocks();
  const float limit2 = float(desc_.speed * desc_.speed);
  for (size_t b = 0; b < nblocks; ++b) {
    // A sleeping block is still by construction; a woken one starts again.
    if (b < woken_.size() && woken_[b])
      still_[b] = 0.0;
    else if (layout.sleeping(b) || speed2[b] < limit2)
      still_[b] = std::min(still_[b] + dt, 1e30);
    else
      still_[b] = 0.0;
  }
  // Each process keeps its own blocks' state (the whole world's is
  // gathered only for a checkpoint).
  state_.keys = layout.particle_keys;
  state_.counts = counts_;
  state_.still = still_;
  own_only_ = split != nullptr;
  cuts_ = split ? split->cuts() : 0;
}

namespace {

// A block's state as processes send it.
struct Entry {
  uint64_t key;
  uint64_t count;
  double still;
};

void setState(SleepState& state, const std::vector<Entry>& entries) {
  state.keys.resize(entries.size());
  state.counts.resize(entries.size());
  state.still.resize(entries.size());
  for (size_t b = 0; b < entries.size(); ++b) {
    state.keys[b] = entries[b].key;
    state.counts[b] = uint32_t(entries[b].count);
    state.still[b] = entries[b].still;
  }
}

}  // namespace

void SleepTracker::handOver(DomainExchange& split) {
  std::vector<std::vector<Entry>> out;
  std::vector<Entry> kept;
  for (size_t b = 0; b < state_.keys.size(); ++b) {
    const Entry e{state_.keys[b], state_.counts[b], state_.still[b]};
    const int p = split.ownerOf(e.key);
    if (p == split.process()) {
      kept.push_back(e);
      continue;
    }
    if (out.size() <= size_t(p)) out.resize(size_t(p) + 1);
    out[size_t(p)].push_back(e);
  }
  const std::vector<Entry> arrived = exchangeValues(split, out);
  kept.insert(kept.end(), arrived.begin(), arrived.end());
  std::sort(kept.begin(), kept.end(), [](const Entry& a, const Entry& b) { return a.key < b.key; });
  setState(state_, kept);
  cuts_ = split.cuts();
}

void SleepTracker::gatherState(DomainExchange& split) {
  if (!own_only_) return;
  std::vector<Entry> mine(state_.keys.size());
  for (size_t b = 0; b < mine.size(); ++b)
    mine[b] = {state_.keys[b], state_.counts[b], state_.still[b]};
  // Each process's blocks lie in its run of keys, in process order.
  setState(state_, allGatherValues(split, mine));
  own_only_ = false;
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
