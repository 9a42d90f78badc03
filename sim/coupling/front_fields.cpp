// Two velocity fields on the nodes that moving solids reach: the material
// in front of the node's own face, and the rest. A node a cell outside a
// face's edge holds both the water over the face and the water beside the
// body; with one velocity per node the collision that stops the first
// drags the second along every step, a drag as large as the node's mass
// over the step (bench/RESULTS.md, "Why moving bodies stall"). Here the
// collision acts on the front field alone, and each particle gathers its
// own field's velocity, so the water beside a body slips past it.
#include <array>
#include <cmath>

#include "sim/coupling/coupling.h"
#include "sim/coupling/node_index.h"
#include "sim/mpm/particles.h"

namespace triad {

void GridCoupling::finishFronts(const std::vector<GridNode>& grid) {
  // Each field's velocity less the grid's after the collision, per node.
  front_dv_.clear();
  rest_dv_.clear();
  if (front_.empty()) return;
  front_dv_.assign(nodes_.size(), Vec3f::Zero());
  rest_dv_.assign(nodes_.size(), Vec3f::Zero());
  split_.assign(slot_block_.size(), 0);
  std::vector<Vec3f> impulse(nodes_.size(), Vec3f::Zero());
  for (const Shared& c : shared_)
    if (c.i != kNotHere && c.lambda > 0.0f) impulse[c.i] = c.P;
  for (size_t s = 0; s < slot_block_.size(); ++s) {
    if (!slot_moving_[s]) continue;
    for (int k = 0; k < kBlockNodes; ++k) {
      const size_t i = s * kBlockNodes + size_t(k);
      const FrontSums& f = front_[i];
      const float mr = f.ma - f.mf;
      if (f.mf <= 0.0f || mr <= 1e-6f * f.ma) continue;  // one field only: the grid's
      const GridNode& g = grid[size_t(slot_block_[s]) * kBlockNodes + size_t(k)];
      const Vec3f pa(f.pa[0], f.pa[1], f.pa[2]), pf(f.pf[0], f.pf[1], f.pf[2]);
      const Vec3f va = pa / f.ma, P = impulse[i];
      front_dv_[i] = pf / f.mf - va + P / f.mf - P / g.m;
      rest_dv_[i] = (pa - pf) / mr - va - P / g.m;
      split_[s] |= uint64_t(1) << k;
    }
  }
}

void GridCoupling::correctFronts(std::vector<ParticleSet>& sets, const GridLayout& layout,
                                 const TransferParams& p) const {
  if (front_.empty()) return;
  const float c_scale = 4.0f * p.inv_dx;
  // Each thread's list from the scan; every particle is corrected alone.
#pragma omp parallel for schedule(dynamic, 1)
  for (int64_t t = 0; t < int64_t(front_lists_.size()); ++t)
    for (const FrontParticle& fp : front_lists_[size_t(t)])
      correctFront(sets, layout, p, c_scale, fp);
}

void GridCoupling::correctFront(std::vector<ParticleSet>& sets, const GridLayout& layout,
                                const TransferParams& p, float c_scale,
                                const FrontParticle& fp) const {
  ParticleSet& set = sets[fp.set];
  const size_t q = fp.index;
  const Stencil st = stencilAt(fp.x, p.shifted_origin, p.inv_dx);
  const Vec3i l(st.base.x() & (kBlockSize - 1), st.base.y() & (kBlockSize - 1),
                st.base.z() & (kBlockSize - 1));
  const size_t pb = fp.block;
  // Only nodes with two fields change anything: most particles have none.
  std::array<int32_t, 8> slot;
  uint64_t any = 0;
  for (int d = 0; d < 8; ++d) {
    slot[size_t(d)] = block_slot_[layout.neighbours[pb][size_t(d)]];
    if (slot[size_t(d)] >= 0) any |= split_[size_t(slot[size_t(d)])];
  }
  if (any == 0) return;
  Vec3f dv = Vec3f::Zero();
  Mat3f dB = Mat3f::Zero(), dB_front = Mat3f::Zero();
  int k = 0;
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b)
      for (int c = 0; c < 3; ++c, ++k) {
        const int32_t sl = slot[size_t(neighbourOf(l, a, b, c))];
        if (sl < 0) continue;
        const int local = localNode(l.x() + a, l.y() + b, l.z() + c);
        if (((split_[size_t(sl)] >> local) & 1u) == 0) continue;
        const size_t i = size_t(sl) * kBlockNodes + size_t(local);
        const Vec3f& delta = (fp.mask >> k) & 1u ? front_dv_[i] : rest_dv_[i];
        const float w = st.w[0][a] * st.w[1][b] * st.w[2][c];
        const Vec3f r(float(a) - st.fx[0], float(b) - st.fx[1], float(c) - st.fx[2]);
        const Mat3f dBk = w * delta * r.transpose();
        dv += w * delta;
        dB += dBk;
        if ((fp.mask >> k) & 1u) dB_front += dBk;
      }
  const Mat3f dC = c_scale * dB;
  set.v[q] += dv;
  set.C[q] += dC;
  set.x[q] = (set.x[q] + p.dt * dv).cwiseMax(p.domain_lo).cwiseMin(p.domain_hi);
  if (set.usesF())
    set.F[q] = (Mat3f::Identity() + p.dt * dC) * set.F[q];
  else if (set.usesJ()) {  // water: J alone
    // Its volume changes by the correction at the nodes where it is in
    // front of a face (the collision compressed that water), not where it
    // is in the rest: the rest field is the water sliding past the body,
    // apart from the node's mixture, and sliding changes no volume. With
    // both, a particle at a face's edge took the divergence of the two
    // fields at once: the water over the edges expanded and drew the body
    // up, so that a cube as dense as water, or 1.5 times as dense, rose to
    // the surface (bench/RESULTS.md, "Two fields: the water's volume").
    set.J[q] *= 1.0f + p.dt * c_scale * dB_front.trace();
  }
}

}  // namespace triad
