// The collision of MPM material with elastic solids, made to hold for what
// the solids' points read back. The contract's step 6 gives a shared node
// the common velocity of its material and of the solid mass there, m_i =
// sum_q w_iq m_q; the points then read the change as sum_i w_iq delta_i,
// delta_i = -P_i / m_i. That keeps momentum, but the node's solid velocity,
// scattered again from its points, changes by sum_j A_ij P_j only, with
//   A_ij = sum_q w_iq w_jq m_q / (m_i m_j),
// since a point at the face also reaches nodes inside the body that took no
// impulse. So after every collision the face still approaches the material
// by part of the g dt it gained, and a stiff solid creeps into sand at a
// speed that grows with the step (bench/RESULTS.md, "Why a stiff elastic
// solid creeps into sand"). A rigid body has no such shortfall: its Newton
// solve moves the whole body.
//
// Here, after the contract's pass, Jacobi passes relax each elastic node
// against its solid velocity plus the change its points really make, each
// node's step taking the row sum of A (and the material's own mass) as its
// inverse mass. A has non-negative entries and is positive semi-definite,
// so with D its row sums D^-1 A has its eigenvalues in [0, 1]: the passes
// cannot overshoot, and an approach that is the same over a flat face goes
// in one pass. Only nodes whose material is within a quarter cell of the
// solid (the contact gap's clearance) take part: a node a cell or more from
// the surface holds a sliver of the solid, and stopping the solid there in
// full would hold it that far above the material. Sums run in a fixed
// order over lists built from the points, so that results do not depend on
// the thread count, and every process, holding every solid's points and
// every shared node, solves alike.
#include <algorithm>

#include "sim/coupling/coupling.h"
#include "sim/coupling/node_index.h"

namespace triad {

namespace {

// How close the material must be for a node to take part, in cells.
constexpr float kElasticReach = 0.25f;

// Node coordinates to the index of a selected node: a dense table over the
// box of the nodes' 4^3 blocks, each present block holding 64 indices. It
// fills the two arrays it is given, kept by the caller from step to step.
class NodeTable {
 public:
  NodeTable(const std::vector<Vec3i>& nodes, std::vector<int32_t>& block,
            std::vector<int32_t>& index)
      : block_(block), index_(index) {
    lo_ = hi_ = blockOf3(nodes[0]);
    for (const Vec3i& n : nodes) {
      lo_ = lo_.cwiseMin(blockOf3(n));
      hi_ = hi_.cwiseMax(blockOf3(n));
    }
    ext_ = hi_ - lo_ + Vec3i::Ones();
    block_.assign(size_t(ext_.x()) * size_t(ext_.y()) * size_t(ext_.z()), -1);
    index_.clear();
    for (size_t k = 0; k < nodes.size(); ++k) {
      int32_t& b = block_[blockIndex(blockOf3(nodes[k]))];
      if (b < 0) {
        b = int32_t(index_.size() / kBlockNodes);
        index_.resize(index_.size() + kBlockNodes, -1);
      }
      index_[size_t(b) * kBlockNodes + localNode(nodes[k].x(), nodes[k].y(), nodes[k].z())] =
          int32_t(k);
    }
  }
  // The selected node at n, or -1.
  int32_t find(const Vec3i& n) const {
    const Vec3i b = blockOf3(n);
    if ((b.array() < lo_.array()).any() || (b.array() > hi_.array()).any()) return -1;
    const int32_t s = block_[blockIndex(b)];
    return s < 0 ? -1 : index_[size_t(s) * kBlockNodes + localNode(n.x(), n.y(), n.z())];
  }
  // Whether a stencil from base node `base` may reach a selected node.
  bool mayReach(const Vec3i& base) const {
    const Vec3i b0 = blockOf3(base), b1 = blockOf3(base + Vec3i::Constant(2));
    return !((b1.array() < lo_.array()).any() || (b0.array() > hi_.array()).any());
  }

 private:
  static Vec3i blockOf3(const Vec3i& n) {
    return Vec3i(blockOf(n.x()), blockOf(n.y()), blockOf(n.z()));
  }
  size_t blockIndex(const Vec3i& b) const {
    const Vec3i r = b - lo_;
    return (size_t(r.x()) * size_t(ext_.y()) + size_t(r.y())) * size_t(ext_.z()) + size_t(r.z());
  }
  Vec3i lo_, hi_, ext_;
  std::vector<int32_t>& block_;
  std::vector<int32_t>& index_;
};

}  // namespace

size_t GridCoupling::ElasticScratch::bytes() const {
  return (sel.capacity() + cand.capacity() + first.capacity() + node_first.capacity() +
          next.capacity() + s_q.capacity() + row.capacity() + inv_m.capacity() +
          table_block.capacity() + table_index.capacity()) *
             4 +
         at.capacity() * sizeof(Vec3i) +
         (slots.capacity() + entries.capacity() + back.capacity()) * sizeof(Link) +
         (dv.capacity() + change.capacity() + per_mass.capacity()) * sizeof(Vec3f);
}

void GridCoupling::settleElasticNodes(const SolidPoints& pts, const TransferParams& p) {
  const int passes = solver_.elastic_contact_passes;
  if (passes <= 0) return;
  ElasticScratch& z = elastic_scratch_;
  using Link = ElasticScratch::Link;
  // The nodes that take part, and where they lie.
  const float reach = kElasticReach * p.dx;
  const Vec3f node0 = p.shifted_origin - Vec3f::Constant(0.5f * p.dx);
  std::vector<uint32_t>& sel = z.sel;
  sel.clear();
  z.at.clear();
  for (size_t k = 0; k < shared_.size(); ++k) {
    const Shared& c = shared_[k];
    if (!c.elastic || c.fixed || c.m_mpm <= 0.0f || c.n.isZero() || !(c.gap <= reach)) continue;
    sel.push_back(uint32_t(k));
    z.at.push_back(((c.x - node0) * p.inv_dx).array().round().cast<int>().matrix());
  }
  if (sel.empty()) return;
  const NodeTable table(z.at, z.table_block, z.table_index);
  const size_t nodes = sel.size();

  // Each elastic point's stencil entries on the selected nodes, point by
  // point (counted, then filled, in parallel).
  std::vector<uint32_t>& cand = z.cand;
  cand.clear();
  for (size_t s = 0; s < pts.solids(); ++s) {
    if (pts.kind[s] != SolidKind::Moving || pts.body_mass[s] != 0.0) continue;
    const size_t e = s + 1 < pts.begin.size() ? pts.begin[s + 1] : pts.size();
    for (size_t q = pts.begin[s]; q < e; ++q)
      if (table.mayReach(baseNode(pts.x[q], p.shifted_origin, p.inv_dx)))
        cand.push_back(uint32_t(q));
  }
  const int64_t npts = int64_t(cand.size());
  // Each point's entries into 27 slots of its own, then packed.
  std::vector<Link>& slots = z.slots;
  std::vector<uint32_t>& first = z.first;
  slots.resize(cand.size() * 27);
  first.assign(cand.size() + 1, 0);
#pragma omp parallel for schedule(static) if (npts > 2048)
  for (int64_t j = 0; j < npts; ++j) {
    const Stencil st = stencilAt(pts.x[cand[size_t(j)]], p.shifted_origin, p.inv_dx);
    Link* out = &slots[size_t(j) * 27];
    uint32_t n = 0;
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b)
        for (int c = 0; c < 3; ++c) {
          const int32_t k = table.find(st.base + Vec3i(a, b, c));
          if (k >= 0) out[n++] = {uint32_t(k), st.w[0][a] * st.w[1][b] * st.w[2][c]};
        }
    first[size_t(j) + 1] = n;
  }
  for (size_t j = 0; j < cand.size(); ++j) first[j + 1] += first[j];
  std::vector<Link>& entries = z.entries;
  entries.resize(first.back());
  for (size_t j = 0; j < cand.size(); ++j)
    std::copy_n(&slots[j * 27], first[j + 1] - first[j], &entries[first[j]]);
  // The same entries node by node, in point order within each node.
  std::vector<uint32_t>& node_first = z.node_first;
  std::vector<Link>& back = z.back;
  node_first.assign(nodes + 1, 0);
  back.resize(entries.size());
  for (const Link& en : entries) ++node_first[en.to + 1];
  for (size_t k = 0; k < nodes; ++k) node_first[k + 1] += node_first[k];
  {
    std::vector<uint32_t>& next = z.next;
    next.assign(node_first.begin(), node_first.end() - 1);
    for (size_t j = 0; j < cand.size(); ++j)
      for (uint32_t e = first[j]; e < first[j + 1]; ++e)
        back[next[entries[e].to]++] = {uint32_t(j), entries[e].w};
  }
  const int64_t nn = int64_t(nodes);

  // Each selected node's inverse solid mass, in a compact array: the passes
  // read it (and the impulse below) once per entry.
  std::vector<float>& inv_m = z.inv_m;
  inv_m.resize(nodes);
  for (size_t k = 0; k < nodes; ++k) inv_m[k] = 1.0f / shared_[sel[k]].m_vol;

  // Row sums of A: sum_j A_kj = sum_q w_kq m_q (sum_j w_jq / m_j) / m_k.
  std::vector<float>&s_q = z.s_q, &row = z.row;
  s_q.resize(cand.size());
  row.resize(nodes);
#pragma omp parallel for schedule(static) if (npts > 2048)
  for (int64_t j = 0; j < npts; ++j) {
    float s = 0.0f;
    for (uint32_t e = first[size_t(j)]; e < first[size_t(j) + 1]; ++e)
      s += entries[e].w * inv_m[entries[e].to];
    s_q[size_t(j)] = s * pts.point_mass[cand[size_t(j)]];
  }
#pragma omp parallel for schedule(static) if (nn > 1024)
  for (int64_t k = 0; k < nn; ++k) {
    float sum = 0.0f;
    for (uint32_t e = node_first[size_t(k)]; e < node_first[size_t(k) + 1]; ++e)
      sum += back[e].w * s_q[back[e].to];
    row[size_t(k)] = sum * inv_m[size_t(k)];
  }

  // The passes: each point's change from the nodes' impulses, each node's
  // solid velocity change from its points', and each node relaxed again.
  // The impulses per unit of solid mass are copied into a compact array
  // once per pass.
  std::vector<Vec3f>&dv = z.dv, &change = z.change, &per_mass = z.per_mass;
  dv.resize(cand.size());
  change.resize(nodes);
  per_mass.resize(nodes);
  for (size_t k = 0; k < nodes; ++k) per_mass[k] = inv_m[k] * shared_[sel[k]].P;
  for (int pass = 0; pass < passes; ++pass) {
#pragma omp parallel for schedule(static) if (npts > 2048)
    for (int64_t j = 0; j < npts; ++j) {
      Vec3f d = Vec3f::Zero();
      for (uint32_t e = first[size_t(j)]; e < first[size_t(j) + 1]; ++e)
        d -= entries[e].w * per_mass[entries[e].to];
      dv[size_t(j)] = pts.point_mass[cand[size_t(j)]] * d;  // momentum
    }
#pragma omp parallel for schedule(static) if (nn > 1024)
    for (int64_t k = 0; k < nn; ++k) {
      Vec3f sum = Vec3f::Zero();
      for (uint32_t e = node_first[size_t(k)]; e < node_first[size_t(k) + 1]; ++e)
        sum += back[e].w * dv[back[e].to];
      change[size_t(k)] = inv_m[size_t(k)] * sum;
    }
#pragma omp parallel for schedule(static) if (nn > 1024)
    for (int64_t k = 0; k < nn; ++k) {
      Shared& c = shared_[sel[size_t(k)]];
      const Vec3f u = c.v_cmp + c.P / c.m_mpm - (c.v_vol + change[size_t(k)]);
      const float un = u.dot(c.n);
      if (un >= 0.0f && c.lambda <= 0.0f) continue;  // separating: material leaves freely
      c.relaxWith(u, un, 1.0f / (1.0f / c.m_mpm + row[size_t(k)]));
      per_mass[size_t(k)] = inv_m[size_t(k)] * c.P;
    }
  }
}

}  // namespace triad
