#include "sim/sparse_grid.h"

#include <algorithm>

#include "sim/particles.h"

namespace triad {

namespace {

constexpr int kKeyBits = 21;
constexpr int64_t kKeyOffset = int64_t{1} << (kKeyBits - 1);
constexpr uint64_t kKeyMask = (uint64_t{1} << kKeyBits) - 1;

uint32_t findKey(const std::vector<uint64_t>& keys, uint64_t key) {
  return static_cast<uint32_t>(std::lower_bound(keys.begin(), keys.end(), key) - keys.begin());
}

void sortUnique(std::vector<uint64_t>& keys) {
  std::sort(keys.begin(), keys.end());
  keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
}

}  // namespace

uint64_t packBlock(const Vec3i& b) {
  return (static_cast<uint64_t>(b.x() + kKeyOffset) << (2 * kKeyBits)) |
         (static_cast<uint64_t>(b.y() + kKeyOffset) << kKeyBits) |
         static_cast<uint64_t>(b.z() + kKeyOffset);
}

Vec3i unpackBlock(uint64_t key) {
  return Vec3i(static_cast<int>(static_cast<int64_t>((key >> (2 * kKeyBits)) & kKeyMask) - kKeyOffset),
               static_cast<int>(static_cast<int64_t>((key >> kKeyBits) & kKeyMask) - kKeyOffset),
               static_cast<int>(static_cast<int64_t>(key & kKeyMask) - kKeyOffset));
}

size_t GridLayout::bytes() const {
  size_t b = grid_keys.capacity() * 8 + particle_keys.capacity() * 8 +
             neighbours.capacity() * sizeof(neighbours[0]);
  for (const auto& c : colour_blocks) b += c.capacity() * 4;
  for (const auto& o : offsets) b += o.capacity() * 4;
  return b;
}

size_t Binner::bytes() const {
  return block_of_.capacity() * 4 + src_.capacity() * 4 + scratch_.capacity() +
         run_keys_.capacity() * 8;
}

void Binner::bin(std::vector<ParticleSet>& sets, const Vec3f& shifted_origin, float inv_dx,
                 GridLayout& layout) {
  auto keyOf = [&](const Vec3f& x) {
    const Vec3i base = baseNode(x, shifted_origin, inv_dx);
    return packBlock(Vec3i(blockOf(base.x()), blockOf(base.y()), blockOf(base.z())));
  };

  // Collect the blocks that hold particles. Particles stay sorted from the
  // previous step, so consecutive runs of one key are long and few.
  run_keys_.clear();
  for (const ParticleSet& set : sets) {
    uint64_t prev = ~uint64_t{0};
    for (const Vec3f& x : set.x) {
      const uint64_t k = keyOf(x);
      if (k != prev) run_keys_.push_back(k);
      prev = k;
    }
  }
  sortUnique(run_keys_);
  layout.particle_keys = run_keys_;
  const size_t nblocks = layout.particle_keys.size();

  // Sort each set's particles by block with a stable counting sort.
  layout.offsets.resize(sets.size());
  for (size_t s = 0; s < sets.size(); ++s) {
    ParticleSet& set = sets[s];
    const size_t n = set.size();
    block_of_.resize(n);
#pragma omp parallel for schedule(static)
    for (int64_t i = 0; i < static_cast<int64_t>(n); ++i)
      block_of_[i] = findKey(layout.particle_keys, keyOf(set.x[i]));

    std::vector<uint32_t>& off = layout.offsets[s];
    off.assign(nblocks + 1, 0);
    for (size_t i = 0; i < n; ++i) ++off[block_of_[i] + 1];
    for (size_t b = 0; b < nblocks; ++b) off[b + 1] += off[b];

    bool sorted = true;
    for (size_t i = 1; i < n && sorted; ++i) sorted = block_of_[i - 1] <= block_of_[i];
    if (sorted) continue;
    src_.resize(n);
    std::vector<uint32_t> cursor(off.begin(), off.end() - 1);
    for (size_t i = 0; i < n; ++i) src_[cursor[block_of_[i]]++] = static_cast<uint32_t>(i);
    set.permute(src_, scratch_);
  }

  // Grid blocks: every particle block and its neighbours on the + side.
  run_keys_.clear();
  run_keys_.reserve(nblocks * 8);
  for (uint64_t key : layout.particle_keys) {
    const Vec3i b = unpackBlock(key);
    for (int d = 0; d < 8; ++d)
      run_keys_.push_back(packBlock(b + Vec3i((d >> 2) & 1, (d >> 1) & 1, d & 1)));
  }
  sortUnique(run_keys_);
  layout.grid_keys = run_keys_;

  layout.neighbours.resize(nblocks);
  for (auto& c : layout.colour_blocks) c.clear();
  for (size_t pb = 0; pb < nblocks; ++pb) {
    const Vec3i b = unpackBlock(layout.particle_keys[pb]);
    for (int d = 0; d < 8; ++d)
      layout.neighbours[pb][d] =
          findKey(layout.grid_keys, packBlock(b + Vec3i((d >> 2) & 1, (d >> 1) & 1, d & 1)));
    const int colour = ((b.x() & 1) << 2) | ((b.y() & 1) << 1) | (b.z() & 1);
    layout.colour_blocks[colour].push_back(static_cast<uint32_t>(pb));
  }
}

}  // namespace triad
