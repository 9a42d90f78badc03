#include "sim/coupling.h"

#include <algorithm>
#include <cmath>

namespace triad {

namespace {

constexpr int32_t kNoSlot = -1;

// Node offset inside a grid block.
inline int localNode(int x, int y, int z) {
  return ((x & (kBlockSize - 1)) * kBlockSize + (y & (kBlockSize - 1))) * kBlockSize +
         (z & (kBlockSize - 1));
}

// Which of a base block's eight neighbours (dx*4 + dy*2 + dz) holds the
// node at offset o from a base node at local position l (0..3) in it.
inline int neighbourOf(const Vec3i& l, int a, int b, int c) {
  return (((l.x() + a) >> kBlockBits) << 2) | (((l.y() + b) >> kBlockBits) << 1) |
         ((l.z() + c) >> kBlockBits);
}

}  // namespace

void SolidPoints::clear() {
  x.clear();
  v.clear();
  n.clear();
  dv.clear();
  begin.clear();
  mass.clear();
  friction.clear();
  fixed.clear();
}

size_t SolidPoints::addSolid(float point_mass, float mu, bool is_fixed) {
  begin.push_back(x.size());
  mass.push_back(point_mass);
  friction.push_back(mu);
  fixed.push_back(is_fixed ? 1 : 0);
  return mass.size() - 1;
}

void GridCoupling::scatter(const SolidPoints& pts, const GridLayout& layout,
                           const TransferParams& p) {
  stats_ = {};
  const size_t n = pts.size();
  point_key_.resize(n);
#pragma omp parallel for schedule(static)
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
  for (size_t s = 0; s < pts.solids(); ++s) {
    const size_t e = s + 1 < pts.begin.size() ? pts.begin[s + 1] : n;
    for (size_t q = pts.begin[s]; q < e; ++q) {
      if (runs.empty() || runs.back().solid != s || runs.back().key != point_key_[q] ||
          runs.back().end != q)
        runs.push_back({point_key_[q], uint32_t(q), uint32_t(q), uint32_t(s)});
      runs.back().end = uint32_t(q + 1);
    }
  }
  std::stable_sort(runs.begin(), runs.end(),
                   [](const Run& a, const Run& b) { return a.key < b.key; });

  // Base blocks whose stencils reach the MPM grid; their neighbours' slots.
  blocks_.clear();
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
      }
      blk.slot[d] = block_slot_[gb];
      any = true;
    }
    if (any) {
      // order_ holds run indices as (start, end, solid) triples.
      for (size_t k = r; k < e; ++k) {
        order_.push_back(runs[k].start);
        order_.push_back(runs[k].end);
        order_.push_back(runs[k].solid);
        stats_.active_points += runs[k].end - runs[k].start;
      }
      blk.last = uint32_t(order_.size());
      blocks_.push_back(blk);
    }
    r = e;
  }

  nodes_.assign(slot_block_.size() * kBlockNodes, SolidNode{});
  for (auto& c : colour_blocks_) c.clear();
  for (size_t k = 0; k < blocks_.size(); ++k) {
    const Vec3i b = unpackBlock(blocks_[k].key);
    colour_blocks_[((b.x() & 1) << 2) | ((b.y() & 1) << 1) | (b.z() & 1)].push_back(uint32_t(k));
  }

  // Scatter colour by colour: base blocks of one colour reach disjoint nodes,
  // so each node's sum has one order for any thread count.
  for (const std::vector<uint32_t>& colour : colour_blocks_) {
#pragma omp parallel for schedule(dynamic, 1)
    for (int64_t k = 0; k < int64_t(colour.size()); ++k) {
      const PointBlock& blk = blocks_[colour[k]];
      for (uint32_t o = blk.first; o < blk.last; o += 3) {
        const uint32_t s = order_[o + 2];
        const float m = pts.mass[s], mu = pts.friction[s];
        const float fixed_m = pts.fixed[s] ? m : 0.0f;
        for (uint32_t q = order_[o]; q < order_[o + 1]; ++q) {
          const Stencil st = stencilAt(pts.x[q], p.shifted_origin, p.inv_dx);
          const Vec3i l(st.base.x() & (kBlockSize - 1), st.base.y() & (kBlockSize - 1),
                        st.base.z() & (kBlockSize - 1));
          const Vec3f& v = pts.v[q];
          const Vec3f& nq = pts.n[q];
          for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 3; ++b)
              for (int c = 0; c < 3; ++c) {
                const int32_t slot = blk.slot[neighbourOf(l, a, b, c)];
                if (slot == kNoSlot) continue;
                const float w = st.w[0][a] * st.w[1][b] * st.w[2][c];
                SolidNode& g =
                    nodes_[size_t(slot) * kBlockNodes + localNode(l.x() + a, l.y() + b, l.z() + c)];
                g.m += w * m;
                for (int d = 0; d < 3; ++d) {
                  g.p[d] += w * m * v[d];
                  g.n[d] += w * nq[d];
                }
                g.mu += w * m * mu;
                g.fixed_m += w * fixed_m;
              }
        }
      }
    }
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
#pragma omp parallel for schedule(static)
  for (int64_t s = 0; s < int64_t(slot_block_.size()); ++s)
    for (int k = 0; k < kBlockNodes; ++k) {
      const GridNode& g = grid[size_t(slot_block_[s]) * kBlockNodes + k];
      if (g.m > 0.0f) pre_[s * kBlockNodes + k] = Vec3f(g.v[0], g.v[1], g.v[2]) / g.m;
    }
}

void GridCoupling::collide(std::vector<GridNode>& grid) {
  const bool single = solver_.coupling == CouplingScheme::SingleGrid;
  const bool before = solver_.contact_velocity == ContactVelocity::BeforeUpdate;
  const bool combined = solver_.solid_readback == SolidReadback::Combined;
  delta_.assign(nodes_.size(), Vec3f::Zero());
  size_t shared = 0, collisions = 0;
#pragma omp parallel for schedule(static) reduction(+ : shared, collisions)
  for (int64_t s = 0; s < int64_t(slot_block_.size()); ++s) {
    for (int k = 0; k < kBlockNodes; ++k) {
      const size_t i = size_t(s) * kBlockNodes + k;
      const SolidNode& sn = nodes_[i];
      GridNode& g = grid[size_t(slot_block_[s]) * kBlockNodes + k];
      if (sn.m <= 0.0f || g.m <= 0.0f) continue;
      ++shared;
      const bool fixed = sn.fixed_m > 0.0f;  // any immovable solid: infinite mass
      const float m_mpm = g.m, m_vol = sn.m;
      const Vec3f v_vol = fixed ? Vec3f(Vec3f::Zero()) : Vec3f(Vec3f(sn.p[0], sn.p[1], sn.p[2]) / m_vol);
      Vec3f v_mpm(g.v[0], g.v[1], g.v[2]);

      if (single) {
        // One grid: both sides move with the combined velocity.
        const Vec3f vc =
            fixed ? Vec3f(Vec3f::Zero()) : Vec3f((m_vol * v_vol + m_mpm * v_mpm) / (m_vol + m_mpm));
        for (int d = 0; d < 3; ++d) g.v[d] = vc[d];
        if (!fixed) delta_[i] = vc - v_vol;
        continue;
      }
      if (combined && !fixed) {
        // The combined grid of step 3, before the collision.
        delta_[i] = m_mpm / (m_mpm + m_vol) * (pre_[i] - v_vol);
      }
      const Vec3f nsum(sn.n[0], sn.n[1], sn.n[2]);
      const float len = nsum.norm();
      if (len <= 0.0f) continue;  // normals cancel (a sliver): no direction to push
      const Vec3f nrm = nsum / len;
      const Vec3f u = (before ? pre_[i] : v_mpm) - v_vol;
      const float un = u.dot(nrm);
      if (un >= 0.0f) continue;  // separating: material leaves freely
      ++collisions;
      // Reduced mass; an immovable solid takes the whole approach.
      const float reduced = fixed ? m_mpm : m_mpm * m_vol / (m_mpm + m_vol);
      const float J = -reduced * un;
      Vec3f dv = (J / m_mpm) * nrm;
      // Coulomb friction: can stop sliding, never reverse it.
      const Vec3f ut = u - un * nrm;
      const float ut_len = ut.norm();
      if (ut_len > 0.0f) {
        const float mu = sn.mu / m_vol;
        dv -= std::min(mu * J / m_mpm, ut_len) / ut_len * ut;
      }
      v_mpm += dv;
      for (int d = 0; d < 3; ++d) g.v[d] = v_mpm[d];
      if (!combined && !fixed) delta_[i] = -(m_mpm / m_vol) * dv;
    }
  }
  stats_.shared_nodes = shared;
  stats_.collisions = collisions;
}

void GridCoupling::gather(SolidPoints& pts, const TransferParams& p) const {
  pts.dv.assign(pts.size(), Vec3f::Zero());
#pragma omp parallel for schedule(dynamic, 4)
  for (int64_t k = 0; k < int64_t(blocks_.size()); ++k) {
    const PointBlock& blk = blocks_[k];
    for (uint32_t o = blk.first; o < blk.last; o += 3) {
      for (uint32_t q = order_[o]; q < order_[o + 1]; ++q) {
        const Stencil st = stencilAt(pts.x[q], p.shifted_origin, p.inv_dx);
        const Vec3i l(st.base.x() & (kBlockSize - 1), st.base.y() & (kBlockSize - 1),
                      st.base.z() & (kBlockSize - 1));
        Vec3f dv = Vec3f::Zero();
        for (int a = 0; a < 3; ++a)
          for (int b = 0; b < 3; ++b)
            for (int c = 0; c < 3; ++c) {
              const int32_t slot = blk.slot[neighbourOf(l, a, b, c)];
              if (slot == kNoSlot) continue;
              const float w = st.w[0][a] * st.w[1][b] * st.w[2][c];
              dv += w * delta_[size_t(slot) * kBlockNodes + localNode(l.x() + a, l.y() + b, l.z() + c)];
            }
        pts.dv[q] = dv;
      }
    }
  }
}

size_t GridCoupling::bytes() const {
  return nodes_.capacity() * sizeof(SolidNode) + delta_.capacity() * sizeof(Vec3f) +
         pre_.capacity() * sizeof(Vec3f) + slot_block_.capacity() * 4 + block_slot_.capacity() * 4 +
         order_.capacity() * 4 + blocks_.capacity() * sizeof(PointBlock) +
         point_key_.capacity() * 8;
}

}  // namespace triad
