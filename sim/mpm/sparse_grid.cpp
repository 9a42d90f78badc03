#include "sim/mpm/sparse_grid.h"

#include <algorithm>
#include <iterator>

#include "sim/mpm/domain.h"
#include "sim/mpm/particles.h"

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
  size_t runs = 0;
  for (const auto& r : chunk_runs_) runs += r.capacity();
  size_t colours = 0;
  for (const auto& c : colour_blocks_) colours += c.capacity() * 4;
  return src_.capacity() * 4 + scratch_.capacity() * sizeof(GridNode) + run_keys_.capacity() * 8 +
         runs * sizeof(Run) + (grid_for_.capacity() + grid_keys_.capacity()) * 8 +
         neighbours_.capacity() * sizeof(neighbours_[0]) + colours;
}

void Binner::bin(std::vector<ParticleSet>& sets, const Vec3f& shifted_origin, float inv_dx,
                 GridLayout& layout, std::vector<GridNode>* spare, const BinOrder* order) {
  auto keyOf = [&](const Vec3f& x) {
    const Vec3i base = baseNode(x, shifted_origin, inv_dx);
    return packBlock(Vec3i(blockOf(base.x()), blockOf(base.y()), blockOf(base.z())));
  };

  // Find the runs of particles that share a block. Particles stay sorted from
  // the previous step, so runs are long and few, and everything after this
  // pass costs per run rather than per particle. Chunks have a fixed size, so
  // the runs found do not depend on the thread count. With an order, the
  // ranges are visited in the order given, and a run never crosses one.
  constexpr size_t kChunk = 16384;
  set_chunks_.assign(sets.size() + 1, 0);
  for (size_t s = 0; s < sets.size(); ++s) {
    const std::vector<Vec3f>& x = sets[s].x;
    std::vector<std::pair<size_t, size_t>> chunks;
    auto addRange = [&](size_t begin, size_t end) {
      for (size_t c = begin; c < end; c += kChunk)
        chunks.emplace_back(c, std::min(end, c + kChunk));
    };
    if (order && s < order->size() && !(*order)[s].empty()) {
      for (const auto& [begin, end] : (*order)[s])
        addRange(std::min<size_t>(begin, x.size()), std::min<size_t>(end, x.size()));
    } else {
      addRange(0, x.size());
    }
    const size_t first = set_chunks_[s];
    set_chunks_[s + 1] = first + chunks.size();
    if (chunk_runs_.size() < set_chunks_[s + 1]) chunk_runs_.resize(set_chunks_[s + 1]);
#pragma omp parallel for schedule(static) if (chunks.size() > 1)
    for (int64_t c = 0; c < static_cast<int64_t>(chunks.size()); ++c) {
      std::vector<Run>& out = chunk_runs_[first + size_t(c)];
      out.clear();
      // A particle in the run's block extends the run: for an integer lo,
      // floor(s) >= lo iff s >= lo, so comparing the shifted coordinates with
      // the block's bounds gives the key's answer without the floors.
      Vec3f lo = Vec3f::Constant(1.0f), hi = Vec3f::Constant(0.0f);  // empty
      for (size_t i = chunks[c].first; i < chunks[c].second; ++i) {
        Vec3f sx;
        for (int d = 0; d < 3; ++d) sx[d] = shiftedCoord(x[i][d], shifted_origin[d], inv_dx);
        if ((sx.array() >= lo.array()).all() && (sx.array() < hi.array()).all()) {
          out.back().end = uint32_t(i + 1);
          continue;
        }
        const uint64_t k = keyOf(x[i]);
        const Vec3i b = unpackBlock(k);
        lo = (b * kBlockSize).cast<float>();
        hi = lo.array() + float(kBlockSize);
        if (out.empty() || out.back().block != k) out.push_back({k, uint32_t(i), uint32_t(i)});
        out.back().end = uint32_t(i + 1);
      }
    }
  }
  // Unsorted input (the first step) has many short runs: do not keep the
  // memory once the particles are sorted, nor chunks no set uses now.
  chunk_runs_.resize(set_chunks_.back());
  for (std::vector<Run>& runs : chunk_runs_)
    if (runs.capacity() > 2 * runs.size() + 256) runs.shrink_to_fit();

  // The blocks that hold particles, sorted.
  run_keys_.clear();
  for (const std::vector<Run>& runs : chunk_runs_)
    for (const Run& r : runs) run_keys_.push_back(r.block);
  sortUnique(run_keys_);
  layout.particle_keys = run_keys_;
  layout.asleep.clear();  // all awake until a sleep tracker says otherwise
  layout.layered.clear();  // a split run's exchange marks them anew
  layout.layered_blocks = 0;
  const size_t nblocks = layout.particle_keys.size();

  // Sort each set's particles by block with a stable counting sort over runs.
  layout.offsets.resize(sets.size());
  for (size_t s = 0; s < sets.size(); ++s) {
    ParticleSet& set = sets[s];
    std::vector<uint32_t>& off = layout.offsets[s];
    off.assign(nblocks + 1, 0);
    bool sorted = true;
    const Run* prev = nullptr;
    for (size_t c = set_chunks_[s]; c < set_chunks_[s + 1]; ++c)
      for (Run& r : chunk_runs_[c]) {
        r.block = findKey(layout.particle_keys, r.block);
        off[r.block + 1] += r.end - r.start;
        sorted = sorted && (!prev || (prev->block <= r.block && prev->end == r.start));
        prev = &r;
      }
    for (size_t b = 0; b < nblocks; ++b) off[b + 1] += off[b];
    if (sorted) continue;
    src_.resize(set.size());
    std::vector<uint32_t> cursor(off.begin(), off.end() - 1);
    for (size_t c = set_chunks_[s]; c < set_chunks_[s + 1]; ++c)
      for (const Run& r : chunk_runs_[c])
        for (uint32_t i = r.start; i < r.end; ++i) src_[cursor[r.block]++] = i;
    std::vector<GridNode>& buffer = spare ? *spare : scratch_;
    const size_t need = set.size() * ParticleSet::kPermuteScratch;
    if (buffer.size() * sizeof(GridNode) < need)
      buffer.resize((need + sizeof(GridNode) - 1) / sizeof(GridNode));
    set.permute(src_, reinterpret_cast<unsigned char*>(buffer.data()));
  }

  // Grid blocks: every particle block and its neighbours on the + side.
  // Particles seldom change block; while the set of particle blocks stays
  // the same, so does all that follows from it.
  if (layout.particle_keys == grid_for_) {
    layout.grid_keys = grid_keys_;
    layout.neighbours = neighbours_;
    layout.colour_blocks = colour_blocks_;
    return;
  }
  run_keys_.clear();
  run_keys_.reserve(nblocks * 8);
  for (uint64_t key : layout.particle_keys) {
    const Vec3i b = unpackBlock(key);
    for (int d = 0; d < 8; ++d)
      run_keys_.push_back(packBlock(b + Vec3i((d >> 2) & 1, (d >> 1) & 1, d & 1)));
  }
  sortUnique(run_keys_);
  layout.grid_keys = run_keys_;
  // The first step's unsorted input had a key per short run: let it go.
  if (run_keys_.capacity() > 2 * run_keys_.size() + 4096) run_keys_.shrink_to_fit();

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
  grid_for_ = layout.particle_keys;
  grid_keys_ = layout.grid_keys;
  neighbours_ = layout.neighbours;
  colour_blocks_ = layout.colour_blocks;
}

void addGridBlocks(GridLayout& layout, std::vector<uint64_t> keys) {
  sortUnique(keys);
  std::vector<uint64_t> merged;
  merged.reserve(layout.grid_keys.size() + keys.size());
  std::set_union(layout.grid_keys.begin(), layout.grid_keys.end(), keys.begin(), keys.end(),
                 std::back_inserter(merged));
  if (merged.size() == layout.grid_keys.size()) return;
  // Old block index -> new one: both lists are sorted, so one merge walk.
  std::vector<uint32_t> moved(layout.grid_keys.size());
  for (size_t i = 0, j = 0; i < layout.grid_keys.size(); ++i) {
    while (merged[j] != layout.grid_keys[i]) ++j;
    moved[i] = static_cast<uint32_t>(j);
  }
  for (auto& n : layout.neighbours)
    for (uint32_t& g : n) g = moved[g];
  if (!layout.layered.empty()) {
    std::vector<int32_t> layered(merged.size(), -1);
    for (size_t i = 0; i < moved.size(); ++i) layered[moved[i]] = layout.layered[i];
    layout.layered = std::move(layered);
  }
  layout.grid_keys = std::move(merged);
}

std::vector<uint32_t> equalShareRuns(const std::vector<uint64_t>& before, int team) {
  const size_t items = before.size() - 1;
  const uint64_t total = before.back();
  std::vector<uint32_t> runs(size_t(team) + 1, uint32_t(items));
  for (int t = 0; t < team; ++t)
    runs[size_t(t)] = uint32_t(std::lower_bound(before.begin(), before.end() - 1, uint64_t(t),
                                                [&](uint64_t sum, uint64_t k) {
                                                  return sum * uint64_t(team) < total * k;
                                                }) -
                               before.begin());
  return runs;
}

}  // namespace triad
