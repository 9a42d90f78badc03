#include "sim/coupling/coupling.h"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include "sim/coupling/node_index.h"

namespace triad {

namespace {

constexpr int32_t kNoSlot = -1;
// Newton's method on a body's six velocity unknowns: a few iterations in
// practice (piecewise quadratic energy); this only bounds a pathological case.
constexpr int kNewtonIterations = 50;
// Below this many slot blocks a pass over their nodes is shorter than
// waking the other threads and moving the nodes to their cores (a few
// hundred slots take tens of microseconds).
constexpr int64_t kParallelSlots = 1024;

// A node no solid reaches: no mass, and as far outside as can be.
const GridCoupling::SolidNode kEmptyNode{0, {0, 0, 0}, {0, 0, 0}, 0, 0, {0, 0, 0}, {0, 0, 0},
                                         0, -1e30f,    {0, 0, 0}, 0, 0, 0,         0};

// A row of a SolidNode's sums.
typedef float Row8 __attribute__((vector_size(32), may_alias));
typedef int32_t Mask8 __attribute__((vector_size(32)));

// Calls f(w, slot node index, node - x in cells) for every node of point x's quadratic stencil
// that lies in one of base block blk's eight grid blocks with a slot.
template <class Block, class F>
void forStencil(const Block& blk, const Stencil& st, F&& f) {
  const Vec3i l(st.base.x() & (kBlockSize - 1), st.base.y() & (kBlockSize - 1),
                st.base.z() & (kBlockSize - 1));
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b)
      for (int c = 0; c < 3; ++c) {
        const int32_t slot = blk.slot[neighbourOf(l, a, b, c)];
        if (slot == kNoSlot) continue;
        f(st.w[0][a] * st.w[1][b] * st.w[2][c],
          size_t(slot) * kBlockNodes + localNode(l.x() + a, l.y() + b, l.z() + c),
          Vec3f(float(a) - st.fx[0], float(b) - st.fx[1], float(c) - st.fx[2]));
      }
}

template <class Block, class F>
void forStencil(const Block& blk, const Vec3f& x, const TransferParams& p, F&& f) {
  forStencil(blk, stencilAt(x, p.shifted_origin, p.inv_dx), f);
}

// Bytes held by per-thread lists (capacity, not size).
template <class T>
size_t listBytes(const std::vector<std::vector<T>>& lists) {
  size_t b = 0;
  for (const auto& list : lists) b += list.capacity() * sizeof(T);
  return b;
}

// What one collision sample adds to the nodes of its stencil, per unit of
// each node's weight w, as the three rows of a SolidNode: the first row
// gains w (m, m v, n, m mu); the second w (m, m v, 0) for solids of
// infinite mass (fixed or driven), 0 for others, and w max(0, distance)
// (0, n, 0); the third takes the sample's distance, normal and tags. The
// constant rows are made once per sample, so that a node costs a
// multiply-add per row.
struct SampleRows {
  Row8 a, b, nb, normal;
  float phi;
  Vec3f n;
  Mask8 tag, keep;
};

// A sample of mass m, velocity v, normal n and distance phi of solid
// `solid` (of friction mu) of the given kind.
inline SampleRows sampleRows(float m, const Vec3f& v, const Vec3f& n, float phi, float mu,
                             SolidKind kind, uint32_t solid) {
  SampleRows s;
  // Solids of infinite mass (fixed ones, and driven ones, which move) are
  // never a moving body's node.
  const bool infinite = kind != SolidKind::Moving;
  const float mb = infinite ? m : 0.0f;
  s.a = Row8{m, m * v[0], m * v[1], m * v[2], n[0], n[1], n[2], m * mu};
  s.b = Row8{mb, mb * v[0], mb * v[1], mb * v[2], 0.0f, 0.0f, 0.0f, 0.0f};
  s.nb = Row8{0.0f, 0.0f, 0.0f, 0.0f, n[0], n[1], n[2], 0.0f};
  s.normal = Row8{0.0f, n[0], n[1], n[2], 0.0f, 0.0f, 0.0f, 0.0f};
  s.phi = phi;
  s.n = n;
  // The third row's lanes: phi, dn, then the tags solid, fixed_solid and
  // owner. A tag lane merges its solid's tag (the tag where it was 0 or the
  // same, -1 for several; merging -1 gives -1), or is kept.
  const int32_t tag = int32_t(solid) + 1;
  s.tag = infinite ? Mask8{0, 0, 0, 0, -1, tag, tag, 0} : Mask8{0, 0, 0, 0, tag, 0, tag, 0};
  s.keep = infinite ? Mask8{-1, -1, -1, -1, 0, 0, 0, -1} : Mask8{-1, -1, -1, -1, 0, -1, 0, -1};
  return s;
}

// A tag lane's join: 0 none, a solid's tag, -1 several.
inline Mask8 joinTags(Mask8 old, Mask8 add) {
  return ((old == 0) | (old == add)) ? add : Mask8{} - 1;
}

// Adds sample s at weight w to node g, r being the node less the sample in
// cells. Each row is read and written whole, as one vector: a row written
// by narrower stores would stall the next sample's wide load of it. The
// distance, carried along the sample's normal to the node (phi_q + n_q .
// (x_i - x_q)), is the node's where it is the largest; as selects rather
// than branches (which sample is nearest, and whether the node lies outside
// its plane, change unpredictably from node to node). Adding w * 0 * n
// where the node lies inside leaves each sum as it was (the sums start at +0
// and never become -0).
inline void addSample(GridCoupling::SolidNode& g, const SampleRows& s, float w, const Vec3f& r,
                      float dx) {
  const Mask8 first1 = {-1, 0, 0, 0, 0, 0, 0, 0}, first4 = {-1, -1, -1, -1, 0, 0, 0, 0};
  const float dist = s.phi + dx * s.n.dot(r);
  Row8& sums_a = *reinterpret_cast<Row8*>(&g.m);
  Row8& sums_b = *reinterpret_cast<Row8*>(&g.fixed_m);
  sums_a += w * s.a;
  sums_b += w * s.b + (w * std::max(dist, 0.0f)) * s.nb;
  Row8& row = *reinterpret_cast<Row8*>(&g.phi);
  const Mask8 old = (Mask8)row;
  const Mask8 tags = s.keep ? old : joinTags(old, s.tag);
  const Mask8 take = dist > row[0] ? first4 : Mask8{};
  row = take ? (first1 ? Row8{} + dist : s.normal) : (Row8)tags;
}

// Adds a halo's node h, the sums of some samples from the empty node, to
// node g: what adding those samples to g one by one gives, up to the sums'
// rounding. The largest distance is taken only where strictly larger, so
// the first of equal distances wins, as sample by sample; a tag lane joins
// (0 none, a solid, -1 several) the same way.
inline void addHaloNode(GridCoupling::SolidNode& g, const GridCoupling::SolidNode& h) {
  const Mask8 first4 = {-1, -1, -1, -1, 0, 0, 0, 0}, keep = {-1, -1, -1, -1, 0, 0, 0, -1};
  Row8& sums_a = *reinterpret_cast<Row8*>(&g.m);
  Row8& sums_b = *reinterpret_cast<Row8*>(&g.fixed_m);
  sums_a += *reinterpret_cast<const Row8*>(&h.m);
  sums_b += *reinterpret_cast<const Row8*>(&h.fixed_m);
  Row8& row = *reinterpret_cast<Row8*>(&g.phi);
  const Row8 hrow = *reinterpret_cast<const Row8*>(&h.phi);
  const Mask8 old = (Mask8)row, add = (Mask8)hrow;
  // (Written as two statements: GCC 12 crashed on the one expression.)
  const Mask8 joined = joinTags(old, add);
  const Mask8 tags = (keep | (add == 0)) ? old : joined;
  const Mask8 take = hrow[0] > row[0] ? first4 : Mask8{};
  row = take ? hrow : (Row8)tags;
}

}  // namespace

void SolidPoints::clear() {
  x.clear();
  v.clear();
  point_mass.clear();
  n.clear();
  phi.clear();
  dv.clear();
  begin.clear();
  mass.clear();
  friction.clear();
  kind.clear();
  body_mass.clear();
  centre.clear();
  inv_mass.clear();
  inv_inertia.clear();
  velocity.clear();
  spin.clear();
}

size_t SolidPoints::addSolid(float uniform_mass, float mu, SolidKind how, double whole_mass) {
  begin.push_back(x.size());
  body_mass.push_back(whole_mass);
  centre.push_back(Vec3f::Zero());
  inv_mass.push_back(0.0f);
  inv_inertia.push_back(Mat3f::Zero());
  velocity.push_back(Vec3f::Zero());
  spin.push_back(Vec3f::Zero());
  mass.push_back(uniform_mass);
  friction.push_back(mu);
  kind.push_back(how);
  return mass.size() - 1;
}

void GridCoupling::scatter(const SolidPoints& pts, const GridLayout& layout,
                           const TransferParams& p) {
  stats_ = {};
  const size_t n = pts.size();
  point_key_.resize(n);
  if (point_key_.capacity() > 2 * n + 4096) point_key_.shrink_to_fit();  // fixed points gone
#pragma omp parallel for schedule(static) if (n > 2048)
  for (int64_t q = 0; q < int64_t(n); ++q) {
    const Vec3i b = baseNode(pts.x[q], p.shifted_origin, p.inv_dx);
    point_key_[q] = packBlock(Vec3i(blockOf(b.x()), blockOf(b.y()), blockOf(b.z())));
  }

  // Runs of consecutive points of one solid in one base block. Samples are
  // stored in lattice order, so runs are long and sorting them is cheap.
  struct Run {
    uint64_t key;
    uint32_t start, end, solid;
  };
  std::vector<Run> runs;
  if (!fixed_built_) buildFixed(pts, p);
  for (size_t s = 0; s < pts.solids(); ++s) {
    if (pts.kind[s] == SolidKind::Static) continue;  // scattered once, in buildFixed
    const size_t e = s + 1 < pts.begin.size() ? pts.begin[s + 1] : n;
    for (size_t q = pts.begin[s]; q < e; ++q) {
      if (runs.empty() || runs.back().solid != s || runs.back().key != point_key_[q] ||
          runs.back().end != q)
        runs.push_back({point_key_[q], uint32_t(q), uint32_t(q), uint32_t(s)});
      runs.back().end = uint32_t(q + 1);
    }
  }
  // By key, runs of one key in point order. Keys order blocks by x, then
  // y, then z, as an index into the box of blocks the runs span does: where
  // that box is small, a counting sort over it (a comparison sort of a
  // thousand runs took 70 us a step, its branches unpredictable).
  Vec3i box_lo = Vec3i::Constant(std::numeric_limits<int>::max()), box_hi = -box_lo;
  for (const Run& r : runs) {
    const Vec3i b = unpackBlock(r.key);
    box_lo = box_lo.cwiseMin(b);
    box_hi = box_hi.cwiseMax(b);
  }
  // (No runs, no box: its extent would overflow.)
  const Vec3i ext = runs.empty() ? Vec3i::Zero() : Vec3i(box_hi - box_lo + Vec3i::Ones());
  if (!runs.empty() && ext.cast<double>().prod() <= 8.0 * double(runs.size()) + 4096.0) {
    auto cell = [&](uint64_t key) {
      const Vec3i b = unpackBlock(key) - box_lo;
      return (size_t(b.x()) * size_t(ext.y()) + size_t(b.y())) * size_t(ext.z()) + size_t(b.z());
    };
    std::vector<uint32_t> start(size_t(ext.prod()) + 1, 0);
    for (const Run& r : runs) ++start[cell(r.key) + 1];
    for (size_t c = 1; c < start.size(); ++c) start[c] += start[c - 1];
    std::vector<Run> sorted(runs.size());
    for (const Run& r : runs) sorted[start[cell(r.key)]++] = r;
    runs.swap(sorted);
  } else {
    std::sort(runs.begin(), runs.end(), [](const Run& a, const Run& b) {
      return a.key != b.key ? a.key < b.key : a.start < b.start;
    });
  }

  // Base blocks whose stencils reach the MPM grid; their neighbours' slots.
  layout_keys_ = &layout.grid_keys;
  blocks_.clear();
  block_points_.assign(1, 0);
  slot_moving_.clear();
  slot_fixed_.clear();
  block_slot_.assign(layout.gridBlocks(), kNoSlot);
  slot_block_.clear();
  order_.clear();
  for (size_t r = 0; r < runs.size();) {
    size_t e = r;
    while (e < runs.size() && runs[e].key == runs[r].key) ++e;
    const Vec3i bc = unpackBlock(runs[r].key);
    PointBlock blk{runs[r].key, uint32_t(order_.size()), 0, {}};
    bool any = false;
    for (int d = 0; d < 8; ++d) {
      const uint64_t k = packBlock(bc + Vec3i((d >> 2) & 1, (d >> 1) & 1, d & 1));
      auto it = std::lower_bound(layout.grid_keys.begin(), layout.grid_keys.end(), k);
      blk.slot[d] = kNoSlot;
      if (it == layout.grid_keys.end() || *it != k) continue;
      const size_t gb = size_t(it - layout.grid_keys.begin());
      if (block_slot_[gb] == kNoSlot) {
        block_slot_[gb] = int32_t(slot_block_.size());
        slot_block_.push_back(uint32_t(gb));
        slot_moving_.push_back(1);  // these runs are of solids that move
        slot_fixed_.push_back(-1);
      }
      blk.slot[d] = block_slot_[gb];
      any = true;
    }
    if (any) {
      // order_ holds run indices as (start, end, solid) triples.
      uint32_t count = 0;
      for (size_t k = r; k < e; ++k) {
        order_.push_back(runs[k].start);
        order_.push_back(runs[k].end);
        order_.push_back(runs[k].solid);
        count += runs[k].end - runs[k].start;
      }
      stats_.active_points += count;
      blk.last = uint32_t(order_.size());
      block_points_.push_back(block_points_.back() + count);
      blocks_.push_back(blk);
    }
    r = e;
  }

  // Fixed solids: their node sums, for the grid blocks that exist now
  // (both key lists are sorted: one merge).
  for (size_t gb = 0, f = 0; gb < layout.grid_keys.size() && f < fixed_keys_.size();) {
    if (layout.grid_keys[gb] < fixed_keys_[f]) {
      ++gb;
    } else if (fixed_keys_[f] < layout.grid_keys[gb]) {
      ++f;
    } else {
      if (block_slot_[gb] == kNoSlot) {
        block_slot_[gb] = int32_t(slot_block_.size());
        slot_block_.push_back(uint32_t(gb));
        slot_moving_.push_back(0);  // fixed solids alone
        slot_fixed_.push_back(-1);
      }
      slot_fixed_[size_t(block_slot_[gb])] = int32_t(f);
      ++gb;
      ++f;
    }
  }
  // Each slot starts from its fixed solids' sums (copied in the parallel
  // pass below, by the thread that then adds to it), or empty.
  nodes_.resize(slot_block_.size() * kBlockNodes);
  // Each slot block gathers what the base blocks that reach it scatter.
  // The eight base blocks that can reach a slot (slot - {0,1}^3) have the
  // eight colours (parities): taken in colour order, every node's sum is
  // added in the order of a serial scatter colour by colour, whatever the
  // thread count. Slots are independent, so threads need no colours nor
  // barriers, and none waits while a colour has fewer blocks than threads.
  slot_sources_.assign(slot_block_.size(), {-1, -1, -1, -1, -1, -1, -1, -1});
  for (size_t k = 0; k < blocks_.size(); ++k) {
    const Vec3i b = unpackBlock(blocks_[k].key);
    const int colour = ((b.x() & 1) << 2) | ((b.y() & 1) << 1) | (b.z() & 1);
    for (int d = 0; d < 8; ++d)
      if (blocks_[k].slot[d] != kNoSlot)
        slot_sources_[size_t(blocks_[k].slot[d])][size_t(colour)] = int32_t(k * 8 + size_t(d));
  }
  // Each base block's points, once each, into a 6x6x6 halo of node records
  // (the block and the first two layers of its + neighbours); then each
  // slot takes its nodes from the halos of the base blocks that reach it,
  // in colour order. A point's 27 nodes lie at fixed strides in its halo,
  // where visiting it once per slot it reaches (3.4 on average) recomputed
  // its rows and clipped its stencil each time. One parallel region (below
  // some hundreds of points, waking the other threads costs more).
  stencils_.resize(n);
  halos_.resize(blocks_.size() * kHaloNodes);
  halo_box_.resize(blocks_.size());
  // Each thread takes a run of consecutive base blocks with an equal share
  // of the points, and then the slots whose first source block is in its
  // run. Blocks are in key order, and a rigid body's points lie in lattice
  // order and were posed by halves (Solver::predictSolids), so a thread
  // mostly reads the points it wrote and the halos it filled: between
  // cores a cache line costs a transfer of some hundred nanoseconds, and
  // with blocks and slots dealt out as threads came free the slots' pass
  // ran slower on two threads than on one.
#pragma omp parallel if (stats_.active_points > 512)
  {
    const int threads = omp_get_num_threads(), me = omp_get_thread_num();
    const std::vector<uint32_t> run = equalShareRuns(block_points_, threads);
    for (size_t k = run[size_t(me)]; k < run[size_t(me) + 1]; ++k) {
      // The stencils first, and the box of halo nodes they reach: only that
      // box is emptied here and read by the slots (a block of a solid's
      // surface reaches a slab of its halo, and emptying all of it cost
      // as much as its points' sums).
      std::array<int8_t, 6> box = {kHalo, kHalo, kHalo, 0, 0, 0};
      for (uint32_t o = blocks_[k].first; o < blocks_[k].last; o += 3)
        for (uint32_t q = order_[o]; q < order_[o + 1]; ++q) {
          const Stencil st = stencilAt(pts.x[q], p.shifted_origin, p.inv_dx);
          stencils_[q] = st;
          for (int e = 0; e < 3; ++e) {
            const int l = st.base[e] & (kBlockSize - 1);
            box[size_t(e)] = int8_t(std::min<int>(box[size_t(e)], l));
            box[size_t(e) + 3] = int8_t(std::max<int>(box[size_t(e) + 3], l + 2));
          }
        }
      halo_box_[k] = box;
      SolidNode* halo = &halos_[k * kHaloNodes];
      for (int x = box[0]; x <= box[3]; ++x)
        for (int y = box[1]; y <= box[4]; ++y)
          std::fill_n(&halo[(x * kHalo + y) * kHalo + box[2]], box[5] - box[2] + 1, kEmptyNode);
      for (uint32_t o = blocks_[k].first; o < blocks_[k].last; o += 3) {
        const uint32_t solid = order_[o + 2];
        for (uint32_t q = order_[o]; q < order_[o + 1]; ++q) {
          const Stencil& st = stencils_[q];
          const SampleRows rows = sampleRows(pts.point_mass[q], pts.v[q], pts.n[q], pts.phi[q],
                                             pts.friction[solid], pts.kind[solid], solid);
          SolidNode* base =
              halo +
              ((st.base[0] & (kBlockSize - 1)) * kHalo + (st.base[1] & (kBlockSize - 1))) * kHalo +
              (st.base[2] & (kBlockSize - 1));
          for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 3; ++b)
              for (int c = 0; c < 3; ++c) {
                const float w = st.w[0][a] * st.w[1][b] * st.w[2][c];
                const Vec3f r(float(a) - st.fx[0], float(b) - st.fx[1], float(c) - st.fx[2]);
                addSample(base[(a * kHalo + b) * kHalo + c], rows, w, r, p.dx);
              }
        }
      }
    }
#pragma omp barrier
    for (int64_t s = 0; s < int64_t(slot_sources_.size()); ++s) {
      // The thread whose run holds the slot's first source block.
      int32_t first = -1;
      for (const int32_t source : slot_sources_[size_t(s)])
        if (source >= 0) {
          first = source >> 3;
          break;
        }
      const size_t owner =
          first < 0
              ? size_t(s) % size_t(threads)
              : size_t(std::upper_bound(run.begin(), run.end(), size_t(first)) - run.begin()) - 1;
      if (owner != size_t(me)) continue;
      SolidNode* slot_nodes = &nodes_[size_t(s) * kBlockNodes];
      if (slot_fixed_[size_t(s)] >= 0)
        std::copy_n(&fixed_nodes_[size_t(slot_fixed_[size_t(s)]) * kBlockNodes], kBlockNodes,
                    slot_nodes);
      else
        std::fill_n(slot_nodes, kBlockNodes, kEmptyNode);
      for (const int32_t source : slot_sources_[size_t(s)]) {
        if (source < 0) continue;
        const SolidNode* halo = &halos_[size_t(source >> 3) * kHaloNodes];
        const std::array<int8_t, 6>& box = halo_box_[size_t(source >> 3)];
        const int d = source & 7;
        // A + neighbour's first two layers lie at halo offset 4 on that
        // axis; the slot's nodes that the block's box holds.
        const int side[3] = {(d >> 2) & 1, (d >> 1) & 1, d & 1};
        int lo[3], hi[3];
        for (int e = 0; e < 3; ++e) {
          lo[e] = std::max(0, box[size_t(e)] - side[e] * kBlockSize);
          hi[e] = std::min(side[e] ? 1 : kBlockSize - 1, box[size_t(e) + 3] - side[e] * kBlockSize);
        }
        for (int x = lo[0]; x <= hi[0]; ++x)
          for (int y = lo[1]; y <= hi[1]; ++y)
            for (int z = lo[2]; z <= hi[2]; ++z)
              addHaloNode(
                  slot_nodes[localNode(x, y, z)],
                  halo[((side[0] * kBlockSize + x) * kHalo + side[1] * kBlockSize + y) * kHalo +
                       side[2] * kBlockSize + z]);
      }
    }
  }
}

void GridCoupling::buildFixed(const SolidPoints& pts, const TransferParams& p) {
  // Fixed solids never move: scatter their points once into node sums per
  // grid block (serially, in point order: deterministic), and copy the
  // blocks the MPM grid has each step.
  fixed_built_ = true;
  std::map<uint64_t, std::vector<SolidNode>> blocks;
  for (size_t s = 0; s < pts.solids(); ++s) {
    if (pts.kind[s] != SolidKind::Static) continue;
    const size_t e = s + 1 < pts.begin.size() ? pts.begin[s + 1] : pts.size();
    for (size_t q = pts.begin[s]; q < e; ++q) {
      // At rest: no momentum.
      const SampleRows rows = sampleRows(pts.mass[s], Vec3f::Zero(), pts.n[q], pts.phi[q],
                                         pts.friction[s], SolidKind::Static, uint32_t(s));
      const Stencil st = stencilAt(pts.x[q], p.shifted_origin, p.inv_dx);
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b)
          for (int c = 0; c < 3; ++c) {
            const Vec3i node = st.base + Vec3i(a, b, c);
            const uint64_t key =
                packBlock(Vec3i(blockOf(node.x()), blockOf(node.y()), blockOf(node.z())));
            std::vector<SolidNode>& blk = blocks[key];
            if (blk.empty()) blk.assign(kBlockNodes, kEmptyNode);
            const Vec3f r(float(a) - st.fx[0], float(b) - st.fx[1], float(c) - st.fx[2]);
            addSample(blk[localNode(node.x(), node.y(), node.z())], rows,
                      st.w[0][a] * st.w[1][b] * st.w[2][c], r, p.dx);
          }
    }
  }
  fixed_keys_.clear();
  fixed_nodes_.clear();
  for (const auto& [key, blk] : blocks) {
    fixed_keys_.push_back(key);
    fixed_nodes_.insert(fixed_nodes_.end(), blk.begin(), blk.end());
  }
}

void GridCoupling::keepPreUpdate(const std::vector<GridNode>& grid) {
  const bool needed = solver_.coupling == CouplingScheme::ThreeGrid &&
                      (solver_.contact_velocity == ContactVelocity::BeforeUpdate ||
                       solver_.solid_readback == SolidReadback::Combined);
  if (!needed) {
    pre_.clear();
    return;
  }
  pre_.assign(nodes_.size(), Vec3f::Zero());
#pragma omp parallel for schedule(static) if (int64_t(slot_block_.size()) > kParallelSlots)
  for (int64_t s = 0; s < int64_t(slot_block_.size()); ++s)
    for (int k = 0; k < kBlockNodes; ++k) {
      const GridNode& g = grid[size_t(slot_block_[s]) * kBlockNodes + k];
      if (g.m > 0.0f) pre_[s * kBlockNodes + k] = Vec3f(g.v[0], g.v[1], g.v[2]) / g.m;
    }
}

void GridCoupling::collide(std::vector<GridNode>& grid, const SolidPoints& pts,
                           const TransferParams& p, std::vector<GridNode>* flip) {
  delta_.assign(nodes_.size(), Vec3f::Zero());
  const bool single = solver_.coupling == CouplingScheme::SingleGrid;
  const bool before = solver_.contact_velocity == ContactVelocity::BeforeUpdate;
  const bool combined = solver_.solid_readback == SolidReadback::Combined;
  const Vec3f node0 = p.shifted_origin - Vec3f::Constant(0.5f * p.dx);
  // A node takes part when both grids have mass there and, with three
  // grids, it lies no further outside its solid than the contact reach
  // (solver.contact_reach). A node of several solids has one distance per
  // solid, not one in all: it always takes part.
  // 1.5 cells is the stencil's reach: every node the samples touch.
  const float reach = single || solver_.contact_reach >= 1.5
                          ? std::numeric_limits<float>::infinity()
                          : float(solver_.contact_reach) * p.dx;
  const bool by_distance = !single && solver_.contact_normal == ContactNormal::Distance;
  const bool body_velocity =
      !single && !combined && solver_.rigid_node_velocity == RigidNodeVelocity::Body;
  auto inContact = [&](const SolidNode& sn, const GridNode& g) {
    return sn.m > 0.0f && g.m > 0.0f && (sn.phi <= reach || sn.owner < 0);
  };

  // The shared nodes in the order of their grid blocks' keys, the order
  // every split of the run gathers them in (the sums over them below then
  // do not depend on the split): counted per block, then filled.
  const int64_t slots = int64_t(slot_block_.size());
  std::vector<uint32_t> by_key(static_cast<size_t>(slots));
  for (size_t s = 0; s < by_key.size(); ++s) by_key[s] = uint32_t(s);
  std::sort(by_key.begin(), by_key.end(),
            [&](uint32_t a, uint32_t b) { return slot_block_[a] < slot_block_[b]; });
  // Each slot's nodes in contact, as a mask of its 64 (kBlockNodes) nodes.
  static_assert(kBlockNodes == 64, "a mask per block");
  std::vector<uint32_t> first(size_t(slots) + 1, 0);
  std::vector<uint64_t> contact_mask(size_t(slots), 0);
#pragma omp parallel for schedule(static) if (slots > kParallelSlots)
  for (int64_t j = 0; j < slots; ++j) {
    const size_t s = by_key[size_t(j)];
    uint64_t mask = 0;
    for (int k = 0; k < kBlockNodes; ++k)
      mask |= uint64_t(inContact(nodes_[s * kBlockNodes + k],
                                 grid[size_t(slot_block_[s]) * kBlockNodes + k]))
              << k;
    contact_mask[size_t(j)] = mask;
    first[size_t(j) + 1] = uint32_t(__builtin_popcountll(mask));
  }
  for (int64_t j = 0; j < slots; ++j) first[size_t(j) + 1] += first[size_t(j)];
  shared_.resize(first.back());
#pragma omp parallel for schedule(static) if (slots > kParallelSlots)
  for (int64_t j = 0; j < slots; ++j) {
    const size_t s = by_key[size_t(j)];
    const size_t gb = slot_block_[s];
    uint32_t out = first[size_t(j)];
    for (uint64_t mask = contact_mask[size_t(j)]; mask != 0; mask &= mask - 1) {
      const int k = __builtin_ctzll(mask);
      const size_t i = size_t(s) * kBlockNodes + k;
      const SolidNode& sn = nodes_[i];
      const GridNode& g = grid[gb * kBlockNodes + k];
      Shared& c = shared_[out++];
      c.P = c.T = c.dP = Vec3f::Zero();
      c.lambda = 0.0f;
      // Elastic solids (moving nodes of their own mass) take no gap: with
      // it a soft jelly let a sand stream slide off its top (17-29 of 384
      // particles stayed, against 210) and a dropped one dug a crater a
      // cell deep into sand (bench/RESULTS.md, "Elastic solids on sand").
      const bool elastic = sn.owner > 0 && pts.kind[size_t(sn.owner - 1)] == SolidKind::Moving &&
                           pts.body_mass[size_t(sn.owner - 1)] == 0.0;
      c.gap = gap_.size() == nodes_.size() && sn.phi > -1e29f ? gap_[i] : 1e30f;
      c.close = c.gap < 1e29f && !elastic ? c.gap / p.dt : 0.0f;
      c.elastic = elastic;
      c.i = uint32_t(i);
      c.g = uint32_t(gb * kBlockNodes + k);
      c.fixed = sn.fixed_m > 0.0f;  // any immovable solid: infinite mass
      c.fixed_solid = sn.fixed_solid > 0 ? sn.fixed_solid - 1 : -1;
      // A node of one moving rigid body: its response feeds back (below).
      c.solid = sn.solid > 0 && !c.fixed && pts.body_mass[size_t(sn.solid - 1)] > 0.0
                    ? sn.solid - 1
                    : -1;
      c.m_mpm = c.m_all = g.m;
      c.m_vol = sn.m;
      // Solids of infinite mass set the node's solid velocity alone: zero
      // for fixed ones, a driven collider's own.
      c.v_vol = c.fixed ? Vec3f(Vec3f(sn.fixed_p[0], sn.fixed_p[1], sn.fixed_p[2]) / sn.fixed_m)
                        : Vec3f(Vec3f(sn.p[0], sn.p[1], sn.p[2]) / sn.m);
      c.v_mpm = Vec3f(g.v[0], g.v[1], g.v[2]);
      c.v_pre = pre_.empty() ? c.v_mpm : pre_[i];
      c.v_cmp = before ? c.v_pre : c.v_mpm;
      // Two fields: the collision acts on the front field's mass and
      // velocity; a node with no front material takes none.
      if (!front_.empty()) {
        const FrontSums& f = front_[i];
        if (f.mf > 0.0f && f.ma > 0.0f) {
          c.m_mpm = f.mf;
          c.v_cmp +=
              Vec3f(f.pf[0], f.pf[1], f.pf[2]) / f.mf - Vec3f(f.pa[0], f.pa[1], f.pa[2]) / f.ma;
        } else if (f.ma > 0.0f) {
          c.m_mpm = 0.0f;
        }
      }
      // The distance's normal where one solid with a distance holds the
      // node: outside it the closest point's direction, inside the normal
      // of the face the node is nearest; otherwise (nodes of several
      // solids) the summed one.
      const Vec3f nsum(sn.n[0], sn.n[1], sn.n[2]), ndist(sn.dn[0], sn.dn[1], sn.dn[2]);
      const Vec3f nout(sn.on[0], sn.on[1], sn.on[2]);
      if (c.m_mpm <= 0.0f)
        c.n = Vec3f::Zero();
      else if (by_distance && sn.owner > 0 && sn.phi > 0.0f && nout.norm() > 0.0f)
        c.n = nout.normalized();
      else if (by_distance && sn.owner > 0 && !ndist.isZero())
        c.n = ndist;
      else
        c.n = nsum.norm() > 0.0f ? Vec3f(nsum.normalized()) : Vec3f(Vec3f::Zero());
      c.mu = sn.mu / sn.m;
      const Vec3i node = unpackBlock((*layout_keys_)[gb]) * kBlockSize +
                         Vec3i(k >> (2 * kBlockBits), (k >> kBlockBits) & (kBlockSize - 1),
                               k & (kBlockSize - 1));
      c.x = node0 + p.dx * node.cast<float>();
      // A moving rigid body's node (rigid_node_velocity body): the body's
      // own velocity at the node, where its impulse acts, not its samples'
      // mean there (their mean position lies inside, off the line from the
      // centre to the node). With the two apart, a turning ball met the
      // water at nodes where its surface moved along the normal, and the
      // impulses there spun it on: a frictionless ball floating in calm
      // water turned at 3 rad/s.
      if (body_velocity && c.solid >= 0)
        c.v_vol = pts.velocity[size_t(c.solid)] +
                  pts.spin[size_t(c.solid)].cross(c.x - pts.centre[size_t(c.solid)]);
    }
  }
  if (domain_) shareAcrossProcesses();
  stats_.shared_nodes = shared_.size();
  // What fixed solids take: the opposite of their nodes' impulses.
  node_impulse_.assign(pts.solids(), Vec3d::Zero());
  node_moment_.assign(pts.solids(), Vec3d::Zero());

  change_keys_.clear();
  change_.clear();
  if (single) {
    // One grid: both sides move with the combined velocity.
    for (size_t k = 0; k < shared_.size(); ++k) {
      const Shared& c = shared_[k];
      const Vec3f vc =
          c.fixed ? c.v_vol : Vec3f((c.m_vol * c.v_vol + c.m_mpm * c.v_mpm) / (c.m_vol + c.m_mpm));
      if (c.fixed) addNodeLoad(c.fixed_solid, c, c.m_mpm * (c.v_mpm - vc));
      // Split over processes, every copy of the node takes its velocity.
      if (c.g != kNotHere)
        for (int d = 0; d < 3; ++d) {
          if (flip) (*flip)[c.g].v[d] += vc[d] - grid[c.g].v[d];
          grid[c.g].v[d] = vc[d];
        }
      if (!c.fixed) setChange(k, vc - c.v_vol);
    }
    return;
  }
  if (combined) {
    // The solids read the combined grid of step 3, from before the collision
    // (each node's as its owner summed it, where the run is split).
    for (size_t k = 0; k < shared_.size(); ++k) {
      const Shared& c = shared_[k];
      if (!c.fixed) setChange(k, c.m_mpm / (c.m_mpm + c.m_vol) * (c.v_pre - c.v_vol));
    }
  }

  // Optionally (rigid_node_mass body_share) a rigid body's mass is shared
  // over its approaching nodes (share = M / sum of their node masses, at
  // least 1) instead of each node's own mass standing for the solid: a node
  // of a rigid body moves with the whole body. Measured against the
  // literal node mass in bench/RESULTS.md ("Coupling").
  const size_t nsolids = pts.solids();
  std::vector<float> share(nsolids, 1.0f);
  if (solver_.rigid_node_mass == RigidNodeMass::BodyShare) {
    std::vector<double> contact(nsolids, 0.0);
    for (const Shared& c : shared_)
      if (c.solid >= 0 && (c.v_cmp - c.v_vol).dot(c.n) < 0.0f) contact[size_t(c.solid)] += c.m_vol;
    for (size_t b = 0; b < nsolids; ++b)
      if (pts.body_mass[b] > 0.0 && contact[b] > 0.0)
        share[b] = float(std::max(1.0, pts.body_mass[b] / contact[b]));
  }

  // The collision, as accumulated impulses P on the MPM side of each node
  // (normal part never pulling, tangential part within the Coulomb cone).
  // Every node sees the solid's velocity as it was predicted, plus the
  // change the impulses of all nodes made to the body so far: one pass is
  // the contract's step 6; further passes (Jacobi) let the body's response
  // feed back, so that material resting on a body does not sink into it by
  // g dt^2 every step. A node whose material is still a gap away from the
  // solid (measureNearSolids) lets it approach by that gap in the step.
  std::vector<Vec3f> dV(nsolids, Vec3f::Zero()), dW(nsolids, Vec3f::Zero());
  // One relaxation of node c against the solid's current velocity.
  auto relax = [&](Shared& c) {
    c.dP.setZero();
    if (c.n.isZero()) return;  // normals cancel (a sliver): no direction to push
    Vec3f v_solid = c.v_vol;
    if (c.solid >= 0) v_solid += dV[c.solid] + dW[c.solid].cross(c.x - pts.centre[c.solid]);
    const Vec3f u = c.v_cmp + c.P / c.m_mpm - v_solid;
    const float un = u.dot(c.n) + c.close;  // the gap may close in the step
    if (un >= 0.0f && c.lambda <= 0.0f) return;  // separating: material leaves freely
    const float m_solid = c.m_vol * (c.solid >= 0 ? share[c.solid] : 1.0f);
    const float reduced = c.fixed ? c.m_mpm : c.m_mpm * m_solid / (c.m_mpm + m_solid);
    c.relaxWith(u, un, reduced);
  };
  // First pass: every shared node. Nodes of fixed solids (or of several)
  // see a solid velocity that no pass changes: they are done after it.
#pragma omp parallel for schedule(static) if (shared_.size() > 8192)
  for (int64_t k = 0; k < int64_t(shared_.size()); ++k) relax(shared_[k]);
  moving_.clear();
  for (uint32_t k = 0; k < shared_.size(); ++k)
    if (shared_[k].solid >= 0) moving_.push_back(k);
  const bool newton = solver_.rigid_collision == RigidCollision::Newton;
  const int passes = moving_.empty() ? 1 : solver_.coupling_iterations;
  int pass = 1;
  // With rigid_collision newton, each moving body's normal impulses are
  // solved exactly first; the passes then only settle friction.
  if (newton && !moving_.empty()) solveBodyNormals(pts, kNewtonIterations, dV, dW);
  pass = relaxMoving(pts, share, pass, passes, dV, dW);

  stats_.passes = std::min(pass, passes);
  if (!combined) settleElasticNodes(pts, p);
  size_t collisions = 0;
  for (size_t k = 0; k < shared_.size(); ++k) {
    const Shared& c = shared_[k];
    if (c.lambda <= 0.0f) continue;
    ++collisions;
    // Split over processes, every copy of the node takes its velocity.
    if (c.g != kNotHere) {
      GridNode& g = grid[c.g];
      const Vec3f v = c.v_mpm + c.P / c.m_all;
      for (int d = 0; d < 3; ++d) g.v[d] = v[d];
      // FLIP particles add the node's change to their own velocity: without
      // the collision's share in it they kept flip_ratio (0.95 by default)
      // of their approach, and
      // the collision took it from the node again every step, a push the
      // water never paid for (a slab at its draft was thrown out of the
      // water at 0.28 m/s while the water was pressed 4% smaller).
      if (flip)
        for (int d = 0; d < 3; ++d) (*flip)[c.g].v[d] += c.P[d] / c.m_all;
    }
    // The opposite impulse goes to the solid: a rigid body's own node to the
    // body, at the node; any other solid's node to its points (gather),
    // from its owner alone where the run is split.
    if (c.fixed)
      addNodeLoad(c.fixed_solid, c, -c.P);
    else if (!combined && c.solid >= 0)
      addNodeLoad(c.solid, c, -c.P);
    else if (!combined)
      setChange(k, -c.P / c.m_vol);
  }
  stats_.collisions = collisions;
}

void GridCoupling::setChange(size_t k, const Vec3f& dv) {
  const Shared& c = shared_[k];
  if (!domain_) {
    delta_[c.i] = dv;
    return;
  }
  // Split over processes: every node's change, block by block in key order
  // (shared_'s), for gatherEverywhere.
  if (change_keys_.empty() || change_keys_.back() != shared_at_[k].first) {
    change_keys_.push_back(shared_at_[k].first);
    change_.resize(change_.size() + kBlockNodes, Vec3f::Zero());
  }
  change_[change_.size() - kBlockNodes + shared_at_[k].second] = dv;
}

void GridCoupling::shareAcrossProcesses() {
  // A node as solved here, with where it lies (block key, node in block).
  struct Record {
    uint64_t key;
    uint32_t k;
    Shared c;
  };
  std::vector<Record> mine;
  for (const Shared& c : shared_) {
    const uint64_t key = (*layout_keys_)[c.g / kBlockNodes];
    if (domain_->owns(key)) mine.push_back({key, c.g % kBlockNodes, c});  // complete sums
  }
  const std::vector<Record> all = allGatherValues(*domain_, mine);
  shared_.clear();
  shared_at_.clear();
  for (const Record& r : all) {
    shared_at_.emplace_back(r.key, r.k);
    Shared c = r.c;
    c.g = c.i = kNotHere;
    const auto it = std::lower_bound(layout_keys_->begin(), layout_keys_->end(), r.key);
    if (it != layout_keys_->end() && *it == r.key) {
      const size_t gb = size_t(it - layout_keys_->begin());
      c.g = uint32_t(gb * kBlockNodes + r.k);
      if (block_slot_[gb] >= 0) c.i = uint32_t(size_t(block_slot_[gb]) * kBlockNodes + r.k);
    }
    shared_.push_back(c);
  }
}

void GridCoupling::addNodeLoad(int32_t solid, const Shared& c, const Vec3f& impulse) {
  // A node that several fixed solids share is counted for none of them.
  if (solid < 0) return;
  const Vec3d j = impulse.cast<double>();
  node_impulse_[size_t(solid)] += j;
  node_moment_[size_t(solid)] += c.x.cast<double>().cross(j);
}

void GridCoupling::gather(SolidPoints& pts, const TransferParams& p) const {
  if (domain_) {
    gatherEverywhere(pts, p);
    return;
  }
  pts.dv.assign(pts.size(), Vec3f::Zero());
  // A solid of a few thousand points lies in a few dozen base blocks.
#pragma omp parallel for schedule(dynamic, 1) if (stats_.active_points > 2048)
  for (int64_t k = 0; k < int64_t(blocks_.size()); ++k) {
    const PointBlock& blk = blocks_[k];
    for (uint32_t o = blk.first; o < blk.last; o += 3) {
      // Driven colliders take nothing back from the grid.
      if (pts.kind[order_[o + 2]] != SolidKind::Moving) continue;
      for (uint32_t q = order_[o]; q < order_[o + 1]; ++q) {
        Vec3f dv = Vec3f::Zero();
        // The stencil the scatter computed: the points have not moved.
        forStencil(blk, stencils_[q],
                   [&](float w, size_t i, const Vec3f&) { dv += w * delta_[i]; });
        pts.dv[q] = dv;
      }
    }
  }
}

void GridCoupling::gatherEverywhere(SolidPoints& pts, const TransferParams& p) const {
  // The same sums as gather(): the stencil's nodes in the same order, the
  // nodes without a change (or without a block here) adding nothing.
  pts.dv.assign(pts.size(), Vec3f::Zero());
  struct Blocks {
    std::array<int32_t, 8> slot;
  };
  for (size_t s = 0; s < pts.solids(); ++s) {
    if (pts.kind[s] != SolidKind::Moving || change_keys_.empty()) continue;
    const int64_t first = int64_t(pts.begin[s]);
    const int64_t last = int64_t(s + 1 < pts.begin.size() ? pts.begin[s + 1] : pts.size());
#pragma omp parallel if (last - first > 4096)
    {
      // Points lie in lattice order: look the eight blocks up once per run
      // of points with one base block.
      Blocks blk;
      uint64_t blk_key = UINT64_MAX;
#pragma omp for schedule(static)
      for (int64_t q = first; q < last; ++q) {
        const Vec3i base = baseNode(pts.x[q], p.shifted_origin, p.inv_dx);
        const Vec3i bc(blockOf(base.x()), blockOf(base.y()), blockOf(base.z()));
        if (packBlock(bc) != blk_key) {
          blk_key = packBlock(bc);
          for (int d = 0; d < 8; ++d) {
            const uint64_t key = packBlock(bc + Vec3i((d >> 2) & 1, (d >> 1) & 1, d & 1));
            const auto it = std::lower_bound(change_keys_.begin(), change_keys_.end(), key);
            blk.slot[d] = it != change_keys_.end() && *it == key
                              ? int32_t(it - change_keys_.begin())
                              : kNoSlot;
          }
        }
        Vec3f dv = Vec3f::Zero();
        forStencil(blk, pts.x[q], p,
                   [&](float w, size_t i, const Vec3f&) { dv += w * change_[i]; });
        pts.dv[q] = dv;
      }
    }
  }
}

const GridCoupling::SolidNode* GridCoupling::solidNode(size_t node) const {
  const size_t block = node / kBlockNodes;
  if (block >= block_slot_.size() || block_slot_[block] == kNoSlot) return nullptr;
  return &nodes_[size_t(block_slot_[block]) * kBlockNodes + node % kBlockNodes];
}

size_t GridCoupling::bytes() const {
  return nodes_.capacity() * sizeof(SolidNode) + delta_.capacity() * sizeof(Vec3f) +
         pre_.capacity() * sizeof(Vec3f) + slot_block_.capacity() * 4 + block_slot_.capacity() * 4 +
         order_.capacity() * 4 + blocks_.capacity() * sizeof(PointBlock) +
         point_key_.capacity() * 8 + front_.capacity() * sizeof(FrontSums) +
         (front_dv_.capacity() + rest_dv_.capacity()) * sizeof(Vec3f) + split_.capacity() * 8 +
         listBytes(front_lists_) + slot_sources_.capacity() * sizeof(slot_sources_[0]) +
         stencils_.capacity() * sizeof(Stencil) + halos_.capacity() * sizeof(SolidNode) +
         slot_fixed_.capacity() * 4 + block_points_.capacity() * 8 + halo_box_.capacity() * 6 +
         listBytes(gap_threads_) + moving_lanes_.capacity() * 4 + moving_start_.capacity() * 4 +
         (front_layers_[0].capacity() + front_layers_[1].capacity()) * sizeof(GridNode) +
         elastic_scratch_.bytes();
}

}  // namespace triad
