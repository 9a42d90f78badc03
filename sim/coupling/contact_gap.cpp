// The clearance between MPM material and the solids at each shared node.
// A node up to a stencil's reach outside a solid holds a sliver of it; if
// such a node stopped all approaching material, material pushed a cell away
// (by an impact, a growing collider) could never close the gap again and
// would rest a cell off the surface. Each node's collision therefore lets
// the material approach by its gap in the step (a speculative contact), the
// gap being that of the closest particle whose stencil reaches the node.
// Nodes that moving or driven solids reach take a gap, and with
// solver.contact_gap_fixed (the default) those of fixed solids too:
// without it, sand or
// water falling onto a fixed floor comes to rest 0.65-1.08 dx above its
// face (where the face lies in its cell decides how far), against half a
// particle spacing with it.
// The same pass sums, for the two fields of sim/coupling/front_fields.cpp,
// each node's material in front of its face and all of it.
#include <omp.h>
#include <algorithm>
#include <cmath>
#include <cstring>

#include "sim/coupling/coupling.h"
#include "sim/coupling/node_index.h"
#include "sim/mpm/particles.h"

namespace triad {

namespace {

// A node no particle near a solid reaches: no contact however it moves.
constexpr float kFar = 1e30f;
// Nodes with no solid sample keep the empty node's distance.
constexpr float kNoDistance = -1e29f;

// Along one axis, the least of cell(c) over the base cells whose stencils
// reach node i: cells i - 2 to i of the block's four.
template <class Cell>
float leastBelow(int i, Cell cell) {
  float m = kFar;
  for (int c = std::max(0, i - 2); c <= std::min(kBlockSize - 1, i); ++c) m = std::min(m, cell(c));
  return m;
}

// The nodes a block's particles' stencils reach: the block's and the
// first two layers of its + neighbours.
constexpr int kReach = kBlockSize + 2;

// The block's base cells (a mask of its 64) whose 3^3 stencil reaches a
// node that `has` a distance: particles elsewhere lie farther from the
// solids than any node's distance reaches.
uint64_t nearCells(const bool (&has)[kReach][kReach][kReach]) {
  uint64_t near = 0;
  for (int x = 0; x < kBlockSize; ++x)
    for (int y = 0; y < kBlockSize; ++y)
      for (int z = 0; z < kBlockSize; ++z) {
        bool reach = false;
        for (int a = 0; a < 3 && !reach; ++a)
          for (int b = 0; b < 3 && !reach; ++b)
            for (int c = 0; c < 3 && !reach; ++c) reach = has[x + a][y + b][z + c];
        if (reach) near |= uint64_t(1) << localNode(x, y, z);
      }
  return near;
}

}  // namespace

void GridCoupling::measureNearSolids(const std::vector<ParticleSet>& sets, const GridLayout& layout,
                                     const TransferParams& p, bool gaps, bool fronts) {
  // Nodes of solids that take a gap, and those of solids that move (two
  // fields): nothing to measure without them (a fixed floor under a whole
  // scene costs nothing here unless it takes the gap). Split over
  // processes, each takes part in the exchange below anyway.
  const bool moving =
      std::find(slot_moving_.begin(), slot_moving_.end(), uint8_t(1)) != slot_moving_.end();
  const bool solids = moving || (solver_.contact_gap_fixed && !slot_moving_.empty());
  gap_.clear();
  front_.clear();
  for (auto& list : front_lists_) list.clear();
  if (gaps && (solids || domain_)) gap_.assign(nodes_.size(), kFar);
  // Split over processes, every process takes part in the fields'
  // exchange, with or without moving solids of its own.
  const bool exchange_fronts = fronts && domain_;
  if (exchange_fronts) {
    front_layers_[0].assign(layout.layered_blocks * 8 * kBlockNodes, GridNode{0, {0, 0, 0}});
    front_layers_[1].assign(front_layers_[0].size(), GridNode{0, {0, 0, 0}});
  }
  if (fronts && moving) front_.assign(nodes_.size(), FrontSums{});
  fronts = fronts && moving;
  if ((gaps && solids) || fronts) scanNearSolids(sets, layout, p, gaps, fronts);
  if (exchange_fronts) sumFrontsAcrossProcesses(layout);
  if (!gaps || !domain_) return;
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

void GridCoupling::gapsOfBlock(uint32_t pb, const std::vector<ParticleSet>& sets,
                               const GridLayout& layout, const TransferParams& p,
                               float* gap) const {
  std::array<int32_t, 8> slot;
  bool solid = false;
  for (int d = 0; d < 8; ++d) {
    slot[size_t(d)] = block_slot_[layout.neighbours[pb][size_t(d)]];
    solid |= slot[size_t(d)] >= 0 && takesGap(size_t(slot[size_t(d)]));
  }
  if (!solid) return;
  // The planes (distance and its normal) of the 6^3 nodes the block's
  // stencils reach, copied together as rows along z of eight lanes (six
  // used): a particle then reads the three planes of a stencil row in one
  // vector. A node without a distance (or without a slot) has -1e30 and a
  // zero normal, so its plane is -1e30 at any particle.
  alignas(32) float phi_row[kReach][kReach][8], nx_row[kReach][kReach][8],
      ny_row[kReach][kReach][8], nz_row[kReach][kReach][8];
  bool has[kReach][kReach][kReach];
  bool any = false;
  for (int x = 0; x < kReach; ++x)
    for (int y = 0; y < kReach; ++y) {
      for (int z = 0; z < 8; ++z) {
        const int32_t sl = z < kReach ? slot[size_t(neighbourOf(Vec3i::Zero(), x, y, z))] : -1;
        float ph = -kFar, n0 = 0.0f, n1 = 0.0f, n2 = 0.0f;
        if (sl >= 0) {
          const SolidNode& g = nodes_[uint32_t(sl) * kBlockNodes + localNode(x, y, z)];
          ph = g.phi;
          n0 = g.dn[0];
          n1 = g.dn[1];
          n2 = g.dn[2];
        }
        phi_row[x][y][z] = ph;
        nx_row[x][y][z] = n0;
        ny_row[x][y][z] = n1;
        nz_row[x][y][z] = n2;
        if (z < kReach) {
          has[x][y][z] = ph >= kNoDistance;
          any = any || has[x][y][z];
        }
      }
    }
  if (!any) return;
  // Most particles here lie farther from the solids than any node's
  // distance reaches: a base cell is near when a node of its 3^3 stencil
  // has a distance, and the others are skipped.
  const uint64_t near = nearCells(has);
  if (near == 0) return;
  // The least clearance of each base cell's particles; a node's is then
  // the least of the cells whose stencils reach it (a min is exact in any
  // order: the same as each particle's clearance taken at its 27 nodes).
  float cell_least[kBlockSize][kBlockSize][kBlockSize];
  std::fill(&cell_least[0][0][0], &cell_least[0][0][0] + kBlockNodes, kFar);
  typedef float Row4 __attribute__((vector_size(16)));
  typedef int32_t Mask4 __attribute__((vector_size(16)));
  const Mask4 three = {-1, -1, -1, 0};  // a row's fourth lane is beyond the stencil
  const Row4 far = {-kFar, -kFar, -kFar, -kFar};
  for (size_t s = 0; s < sets.size(); ++s) {
    const ParticleSet& set = sets[s];
    const float radius = 0.5f * std::cbrt(set.volume);
    for (uint32_t q = layout.offsets[s][pb]; q < layout.offsets[s][pb + 1]; ++q) {
      // The stencil's base node and the particle's place in it (its weights
      // are not needed).
      int l[3];
      float fx[3];
      for (int d = 0; d < 3; ++d) {
        const float t = shiftedCoord(set.x[q][d], p.shifted_origin[d], p.inv_dx);
        const float base = std::floor(t);
        fx[d] = t - base + 0.5f;
        l[d] = static_cast<int>(base) & (kBlockSize - 1);
      }
      if (!(near >> localNode(l[0], l[1], l[2]) & 1)) continue;
      // The particle's distance: the envelope of the planes its nodes'
      // distances came from (phi_i + n_i . (x_p - x_i), the largest),
      // exact beside a face, never more than the true distance.
      const Row4 r2 = {fx[2], fx[2] - 1.0f, fx[2] - 2.0f, fx[2] - 3.0f};
      Row4 best = far;
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) {
          const float r0 = fx[0] - float(a), r1 = fx[1] - float(b);
          Row4 ph, n0, n1, n2;
          std::memcpy(&ph, &phi_row[l[0] + a][l[1] + b][l[2]], sizeof(Row4));
          std::memcpy(&n0, &nx_row[l[0] + a][l[1] + b][l[2]], sizeof(Row4));
          std::memcpy(&n1, &ny_row[l[0] + a][l[1] + b][l[2]], sizeof(Row4));
          std::memcpy(&n2, &nz_row[l[0] + a][l[1] + b][l[2]], sizeof(Row4));
          const Row4 d = ph + p.dx * (n0 * r0 + n1 * r1 + n2 * r2);
          best = (three & (d > best)) ? d : best;
        }
      const float phi = std::max(std::max(best[0], best[1]), best[2]);
      if (!(phi > kNoDistance)) continue;
      float& least = cell_least[l[0]][l[1]][l[2]];
      least = std::min(least, std::max(0.0f, phi - radius));
    }
  }
  // Each node the least of the cells up to two below it along each axis:
  // along z, then y, then x.
  float least_z[kBlockSize][kBlockSize][kReach], least_y[kBlockSize][kReach][kReach];
  float least[kReach][kReach][kReach];
  for (int x = 0; x < kBlockSize; ++x)
    for (int y = 0; y < kBlockSize; ++y)
      for (int z = 0; z < kReach; ++z)
        least_z[x][y][z] = leastBelow(z, [&](int c) { return cell_least[x][y][c]; });
  for (int x = 0; x < kBlockSize; ++x)
    for (int y = 0; y < kReach; ++y)
      for (int z = 0; z < kReach; ++z)
        least_y[x][y][z] = leastBelow(y, [&](int c) { return least_z[x][c][z]; });
  for (int x = 0; x < kReach; ++x)
    for (int y = 0; y < kReach; ++y)
      for (int z = 0; z < kReach; ++z)
        least[x][y][z] = leastBelow(x, [&](int c) { return least_y[c][y][z]; });
  // Into the solids' nodes: the least is the same in any order.
  for (int x = 0; x < kReach; ++x)
    for (int y = 0; y < kReach; ++y)
      for (int z = 0; z < kReach; ++z) {
        const int32_t sl = slot[size_t(neighbourOf(Vec3i::Zero(), x, y, z))];
        if (sl < 0 || !takesGap(size_t(sl)) || least[x][y][z] >= kFar) continue;
        float& g = gap[uint32_t(sl) * kBlockNodes + localNode(x, y, z)];
        g = std::min(g, least[x][y][z]);
      }
}

void GridCoupling::scanNearSolids(const std::vector<ParticleSet>& sets, const GridLayout& layout,
                                  const TransferParams& p, bool gaps, bool fronts) {
  const float cos_front = float(std::cos(solver_.front_angle_deg * M_PI / 180.0));
  if (fronts) front_lists_.resize(size_t(omp_get_max_threads()));
  // The gaps and sums that one particle block's particles give their nodes.
  // The fields' sums go first to the block's own halo (`halo`, 6^3 nodes,
  // zero), then to the nodes (addFrontHalo), so that each node adds one
  // block's sums per colour: the order in which a split run's owners add
  // the layers that cross the cut.
  auto scanBlock = [&](uint32_t pb, int colour, float* gap, std::vector<FrontParticle>* list,
                       FrontSums* halo) {
    std::array<int32_t, 8> slot;
    bool any = false;
    for (int d = 0; d < 8; ++d) {
      const uint32_t gb = layout.neighbours[pb][size_t(d)];
      slot[size_t(d)] = block_slot_[gb];
      // Nodes that take a gap, or (a moving solid's) split.
      any |= slot[size_t(d)] >= 0 && takesGap(size_t(slot[size_t(d)]));
    }
    if (!any) return;
    // A particle none of whose nodes holds a solid (has a distance) gives
    // no gap and no field: most of a block beside a body's blocks. Its
    // base cell tells, as in gapsOfBlock.
    bool has[kReach][kReach][kReach];
    for (int x = 0; x < kReach; ++x)
      for (int y = 0; y < kReach; ++y)
        for (int z = 0; z < kReach; ++z) {
          const int32_t sl = slot[size_t(neighbourOf(Vec3i::Zero(), x, y, z))];
          has[x][y][z] =
              sl >= 0 && nodes_[uint32_t(sl) * kBlockNodes + localNode(x, y, z)].phi > kNoDistance;
        }
    const uint64_t near = nearCells(has);
    if (near == 0) return;
    bool summed = false;
    for (size_t s = 0; s < sets.size(); ++s) {
      const ParticleSet& set = sets[s];
      const float radius = 0.5f * std::cbrt(set.volume);
      for (uint32_t q = layout.offsets[s][pb]; q < layout.offsets[s][pb + 1]; ++q) {
        const Stencil st = stencilAt(set.x[q], p.shifted_origin, p.inv_dx);
        const Vec3i l(st.base.x() & (kBlockSize - 1), st.base.y() & (kBlockSize - 1),
                      st.base.z() & (kBlockSize - 1));
        if (!(near >> localNode(l.x(), l.y(), l.z()) & 1)) continue;
        // The particle's distance: the envelope of the planes its nodes'
        // distances came from (phi_i + n_i . (x_p - x_i), the largest),
        // exact beside a face, never more than the true distance.
        int32_t node[27];  // slot node of a solid, or -1
        float plane[27];   // each node's plane distance at the particle
        float phi = -kFar;
        int nearest = -1;  // the node whose plane gave phi
        int k27 = 0;
        // Without branches on the nodes' distances: a node without one
        // (phi -1e30, normal zero) gives a plane of -1e30, which neither
        // beats phi nor counts as a distance.
        for (int a = 0; a < 3; ++a)
          for (int b = 0; b < 3; ++b)
            for (int c = 0; c < 3; ++c, ++k27) {
              node[k27] = -1;
              plane[k27] = kNoDistance;
              const int32_t sl = slot[size_t(neighbourOf(l, a, b, c))];
              if (sl < 0) continue;
              const uint32_t i =
                  uint32_t(sl) * kBlockNodes + localNode(l.x() + a, l.y() + b, l.z() + c);
              const SolidNode& g = nodes_[i];
              node[k27] = int32_t(i);
              const Vec3f r(st.fx[0] - float(a), st.fx[1] - float(b), st.fx[2] - float(c));
              plane[k27] = g.phi + p.dx * (g.dn[0] * r[0] + g.dn[1] * r[1] + g.dn[2] * r[2]);
              const bool nearer = plane[k27] > phi;
              phi = nearer ? plane[k27] : phi;
              nearest = nearer ? int(i) : nearest;
            }
        if (gaps && phi > kNoDistance) {
          const float clearance = std::max(0.0f, phi - radius);
          for (int m = 0; m < 27; ++m)
            if (node[m] >= 0 && takesGap(size_t(node[m]) / kBlockNodes))
              gap[node[m]] = std::min(gap[node[m]], clearance);
        }
        // Sleeping material keeps its sums at rest and gathers nothing:
        // it stays one field.
        if (!fronts || layout.sleeping(pb)) continue;
        // Its momentum as P2G gave it to each node, w m (v + C (x_i -
        // x_p)), to the node's whole sums and, where the node's face
        // faces the way the particle's nearest does, to its front's.
        // With o the node's offset in the stencil, w m (v + C dx (o -
        // fx)) = w (mv0 + D o): three columns added per node.
        uint32_t mask = 0;
        bool touches = false;
        const float m = set.mass;
        const float* dn = nodes_[size_t(nearest >= 0 ? nearest : 0)].dn;
        const Mat3f D = (m * p.dx) * set.C[q];
        const Vec3f mv0 = m * set.v[q] - D * Vec3f(st.fx[0], st.fx[1], st.fx[2]);
        k27 = 0;
        for (int a = 0; a < 3; ++a)
          for (int b = 0; b < 3; ++b)
            for (int c = 0; c < 3; ++c, ++k27) {
              // Nodes that hold no solid (no distance) are never split:
              // their sums would go unread.
              if (node[k27] < 0 || plane[k27] <= kNoDistance ||
                  !slot_moving_[size_t(node[k27]) / kBlockNodes])
                continue;
              touches = true;
              const float w = st.w[0][a] * st.w[1][b] * st.w[2][c];
              const Vec3f mom =
                  w * (mv0 + float(a) * D.col(0) + float(b) * D.col(1) + float(c) * D.col(2));
              FrontSums& f = halo[haloNode(l.x() + a, l.y() + b, l.z() + c)];
              f.ma += w * m;
              for (int e = 0; e < 3; ++e) f.pa[e] += mom[e];
              // In front where the node's face faces the way the
              // particle's nearest face does.
              if (nearest >= 0) {
                const float* dk = nodes_[size_t(node[k27])].dn;
                if (dk[0] * dn[0] + dk[1] * dn[1] + dk[2] * dn[2] < cos_front) continue;
              }
              mask |= 1u << k27;
              f.mf += w * m;
              for (int e = 0; e < 3; ++e) f.pf[e] += mom[e];
            }
        if (touches) list->push_back({uint32_t(s), q, pb, mask, set.x[q]});
        summed = summed || touches;
      }
    }
    if (summed) addFrontHalo(pb, colour, layout, halo);
  };
  if (!fronts) {
    // Gaps alone: a node's gap is the least clearance of its particles, the
    // same in any order. Blocks go to threads as they come free, each
    // thread keeps its own gaps, and each node takes the least of them.
    gap_threads_.resize(size_t(omp_get_max_threads()));
#pragma omp parallel if (layout.particleBlocks() > 1)
    {
      const size_t team = size_t(omp_get_num_threads());
      std::vector<float>& mine = gap_threads_[size_t(omp_get_thread_num())];
      mine.assign(gap_.size(), kFar);
#pragma omp for schedule(dynamic, 1)
      for (int64_t pb = 0; pb < int64_t(layout.particleBlocks()); ++pb)
        gapsOfBlock(uint32_t(pb), sets, layout, p, mine.data());
#pragma omp for schedule(static)
      for (int64_t i = 0; i < int64_t(gap_.size()); ++i)
        for (size_t t = 0; t < team; ++t)
          gap_[size_t(i)] = std::min(gap_[size_t(i)], gap_threads_[t][size_t(i)]);
    }
    return;
  }
  // Two fields: one parallel region for the eight colours (a barrier
  // between them; a region per colour cost a wake-up of the sleeping
  // threads each).
  size_t widest = 0;
  for (const auto& c : layout.colour_blocks) widest = std::max(widest, c.size());
#pragma omp parallel if (widest > 1)
  {
    std::vector<FrontSums> halo(kHaloNodes);
    for (int colour = 0; colour < 8; ++colour) {
      const std::vector<uint32_t>& blocks = layout.colour_blocks[size_t(colour)];
      std::vector<FrontParticle>* list = &front_lists_[size_t(omp_get_thread_num())];
      // Blocks of one colour share no node: the mins and sums need no
      // atomics, and each node's sums are added in colour order, block by
      // block, the same for any thread count.
#pragma omp for schedule(dynamic, 1)
      for (int64_t k = 0; k < int64_t(blocks.size()); ++k)
        scanBlock(blocks[size_t(k)], colour, gap_.data(), list, halo.data());
    }
  }
}

void GridCoupling::addFrontHalo(uint32_t pb, int colour, const GridLayout& layout,
                                FrontSums* halo) {
  // Each halo node of a moving solid's slot: to its node, or, on a grid
  // block whose sums cross processes, to that block's layer of this colour.
  for (int x = 0; x < kHaloSize; ++x)
    for (int y = 0; y < kHaloSize; ++y)
      for (int z = 0; z < kHaloSize; ++z) {
        FrontSums& h = halo[haloNode(x, y, z)];
        const uint32_t gb = layout.neighbours[pb][size_t(neighbourOf(Vec3i::Zero(), x, y, z))];
        const int32_t sl = block_slot_[gb];
        if (sl >= 0 && slot_moving_[size_t(sl)]) {
          const int local = localNode(x, y, z);
          const int32_t layer = domain_ ? layout.layered[gb] : -1;
          if (layer < 0) {
            FrontSums& f = front_[size_t(sl) * kBlockNodes + size_t(local)];
            f.mf += h.mf;
            f.ma += h.ma;
            for (int e = 0; e < 3; ++e) f.pf[e] += h.pf[e], f.pa[e] += h.pa[e];
          } else {
            const size_t at = (size_t(layer) * 8 + size_t(colour)) * kBlockNodes + size_t(local);
            front_layers_[0][at] = GridNode{h.mf, {h.pf[0], h.pf[1], h.pf[2]}};
            front_layers_[1][at] = GridNode{h.ma, {h.pa[0], h.pa[1], h.pa[2]}};
          }
        }
        h = FrontSums{};
      }
}

void GridCoupling::sumFrontsAcrossProcesses(const GridLayout& layout) {
  // The layers of the grid blocks on the cut go to each block's owner,
  // which adds them in colour order (as P2G's sums), and come back whole to
  // every process that holds the block: the field of the material in front
  // and of all of it, as two grids.
  std::array<std::vector<GridNode>, 2> sums;
  for (int f = 0; f < 2; ++f) {
    sums[size_t(f)].assign(layout.gridBlocks() * size_t(kBlockNodes), GridNode{0, {0, 0, 0}});
    domain_->sumGhosts(layout, sums[size_t(f)], front_layers_[size_t(f)]);
    domain_->returnHalo(layout, sums[size_t(f)]);
  }
  if (front_.empty()) return;
  for (size_t s = 0; s < slot_block_.size(); ++s) {
    const uint32_t gb = slot_block_[s];
    if (!slot_moving_[s] || layout.layered[gb] < 0) continue;
    for (int k = 0; k < kBlockNodes; ++k) {
      const GridNode& a = sums[0][size_t(gb) * kBlockNodes + size_t(k)];
      const GridNode& b = sums[1][size_t(gb) * kBlockNodes + size_t(k)];
      front_[s * kBlockNodes + size_t(k)] =
          FrontSums{a.m, {a.v[0], a.v[1], a.v[2]}, b.m, {b.v[0], b.v[1], b.v[2]}};
    }
  }
}

}  // namespace triad
