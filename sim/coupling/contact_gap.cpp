// The clearance between MPM material and the solids at each shared node.
// A node up to a stencil's reach outside a solid holds a sliver of it; if
// such a node stopped all approaching material, material pushed a cell away
// (by an impact, a growing collider) could never close the gap again and
// would rest a cell off the surface. Each node's collision therefore lets
// the material approach by its gap in the step (a speculative contact), the
// gap being that of the closest particle whose stencil reaches the node.
// Only nodes that moving or driven solids reach take a gap.
#include <algorithm>
#include <cmath>

#include "sim/coupling/coupling.h"
#include "sim/coupling/node_index.h"
#include "sim/mpm/particles.h"

namespace triad {

namespace {

// A node no particle near a solid reaches: no contact however it moves.
constexpr float kFar = 1e30f;
// Nodes with no solid sample keep the empty node's distance.
constexpr float kNoDistance = -1e29f;

}  // namespace

void GridCoupling::measureGaps(const std::vector<ParticleSet>& sets, const GridLayout& layout,
                               const TransferParams& p) {
  // No solid that moves: nothing to measure (fixed solids take no gap).
  // Split over processes, each takes part in the exchange below anyway.
  const bool moving =
      std::find(slot_moving_.begin(), slot_moving_.end(), uint8_t(1)) != slot_moving_.end();
  if (!moving && !domain_) {
    gap_.clear();
    return;
  }
  gap_.assign(nodes_.size(), kFar);
  if (moving) measureOwnGaps(sets, layout, p);
  if (!domain_) return;
  // The owner of a block takes the closest particle of every process.
  std::vector<float> per_node(layout.gridBlocks() * size_t(kBlockNodes), kFar);
  for (size_t s = 0; s < slot_block_.size(); ++s)
    std::copy_n(&gap_[s * kBlockNodes], kBlockNodes,
                &per_node[size_t(slot_block_[s]) * kBlockNodes]);
  domain_->minGhosts(layout, per_node);
  for (size_t s = 0; s < slot_block_.size(); ++s)
    std::copy_n(&per_node[size_t(slot_block_[s]) * kBlockNodes], kBlockNodes,
                &gap_[s * kBlockNodes]);
}

void GridCoupling::measureOwnGaps(const std::vector<ParticleSet>& sets, const GridLayout& layout,
                                  const TransferParams& p) {
  // One parallel region for the eight colours (a barrier between them): a
  // region per colour cost a wake-up of the sleeping threads each.
  size_t widest = 0;
  for (const auto& c : layout.colour_blocks) widest = std::max(widest, c.size());
#pragma omp parallel if (widest > 1)
  for (int colour = 0; colour < 8; ++colour) {
    const std::vector<uint32_t>& blocks = layout.colour_blocks[size_t(colour)];
    // Blocks of one colour share no node: the mins need no atomics, and
    // being mins they are the same for any thread count.
#pragma omp for schedule(dynamic, 1)
    for (int64_t k = 0; k < int64_t(blocks.size()); ++k) {
      const uint32_t pb = blocks[size_t(k)];
      std::array<int32_t, 8> slot;
      bool any = false;
      for (int d = 0; d < 8; ++d) {
        const uint32_t gb = layout.neighbours[pb][size_t(d)];
        slot[size_t(d)] = block_slot_[gb];
        // Only solids that move can open a gap; a fixed solid's nodes keep
        // the plain approach test (and a floor under a whole scene costs
        // nothing here).
        any |= slot[size_t(d)] >= 0 && slot_moving_[size_t(slot[size_t(d)])];
      }
      if (!any) continue;
      for (size_t s = 0; s < sets.size(); ++s) {
        const ParticleSet& set = sets[s];
        const float radius = 0.5f * std::cbrt(set.volume);
        for (uint32_t q = layout.offsets[s][pb]; q < layout.offsets[s][pb + 1]; ++q) {
          const Stencil st = stencilAt(set.x[q], p.shifted_origin, p.inv_dx);
          const Vec3i l(st.base.x() & (kBlockSize - 1), st.base.y() & (kBlockSize - 1),
                        st.base.z() & (kBlockSize - 1));
          // The particle's distance: the envelope of the planes its nodes'
          // distances came from (phi_i + n_i . (x_p - x_i), the largest),
          // exact beside a face, never more than the true distance.
          uint32_t node[27];
          float phi = -kFar;
          int n = 0;
          for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 3; ++b)
              for (int c = 0; c < 3; ++c) {
                const int32_t sl = slot[size_t(neighbourOf(l, a, b, c))];
                if (sl < 0) continue;
                const uint32_t i =
                    uint32_t(sl) * kBlockNodes + localNode(l.x() + a, l.y() + b, l.z() + c);
                if (slot_moving_[size_t(sl)]) node[n++] = i;
                const SolidNode& g = nodes_[i];
                if (g.phi < kNoDistance) continue;
                const Vec3f r(st.fx[0] - float(a), st.fx[1] - float(b), st.fx[2] - float(c));
                phi = std::max(phi, g.phi + p.dx * (g.dn[0] * r[0] + g.dn[1] * r[1] + g.dn[2] * r[2]));
              }
          const bool known = phi > kNoDistance;
          if (!known) continue;
          const float clearance = std::max(0.0f, phi - radius);
          for (int m = 0; m < n; ++m) gap_[node[m]] = std::min(gap_[node[m]], clearance);
        }
      }
    }
  }
}

}  // namespace triad
