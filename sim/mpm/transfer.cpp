#include "sim/mpm/transfer.h"

#include <cstring>

#include "sim/mpm/halo.h"
#include "sim/mpm/particles.h"

namespace triad {

namespace {

// A particle block's stencil region, gathered into a dense 6x6x6 buffer so
// that the per-particle loops touch only L1-resident memory.
template <int kChannels>
struct HaloBuffer {
  alignas(64) float d[kHaloNodes][kChannels];
  static int index(int x, int y, int z) { return (x * kHalo + y) * kHalo + z; }
};

// The first node of particle block pb: its halo's origin.
inline Vec3i haloOrigin(const GridLayout& layout, size_t pb) {
  return unpackBlock(layout.particle_keys[pb]) * kBlockSize;
}

// Position of a stencil's base node inside the halo that starts at node o.
[[gnu::always_inline]] inline Vec3i haloOffset(const Stencil& s, const Vec3i& o) {
  return Vec3i(s.base[0] - o.x(), s.base[1] - o.y(), s.base[2] - o.z());
}

// Below this many particles in a transfer, one thread does it: waking the
// others and meeting them at the scatter's eight colour barriers took longer
// than the work (a draft-size scene ran faster on one thread than on two).
constexpr size_t kParallelTransfer = 16384;

// Particles of every set of a layout, asleep or not.
size_t layoutParticles(const GridLayout& layout) {
  size_t n = 0;
  for (const std::vector<uint32_t>& off : layout.offsets) n += off.empty() ? 0 : off.back();
  return n;
}

// Particles per stress chunk: the batched SVD fills the vector lanes, and a
// chunk's stresses stay in L1 until they are folded into C.
constexpr int kStressChunk = 128;

// Kirchhoff stresses of particles [b, b+n) of a set. Plastic models project
// the trial elastic F onto their yield surface first, sharing one SVD with
// the stress (so F is stored unprojected between G2P and the next step).
template <class M>
void stressChunk(const M& model, ParticleSet& set, size_t b, int n, Mat3f* tau) {
  if constexpr (std::is_same_v<M, FixedCorotated<float>>) {
    kirchhoffBatch(model, n, &set.F[b], tau);
  } else if constexpr (std::is_same_v<M, Snow<float>>) {
    projectAndKirchhoffBatch(model, n, &set.F[b], &set.J[b], tau);
  } else if constexpr (std::is_same_v<M, DruckerPrager<float>>) {
    projectAndKirchhoffBatch(model, n, &set.F[b], tau);
  } else if constexpr (std::is_same_v<M, MohrCoulomb<float>>) {
    // C holds the velocity gradient of the last G2P, which mu(I) reads.
    if (model.rateDependent())
      projectAndKirchhoffBatch(model, n, &set.F[b], &set.C[b], tau);
    else
      projectAndKirchhoffBatch(model, n, &set.F[b], tau);
  } else if constexpr (std::is_same_v<M, Water<float>>) {
    kirchhoffBatch(model, n, &set.J[b], &set.C[b], tau);
  } else {
    for (int i = 0; i < n; ++i) tau[i] = model.kirchhoff(set.F[b + i]);
  }
}

// Deformation update of particle i after G2P: F <- (I + dt C) F, or for
// water J <- J (1 + dt tr C).
template <class M>
void updateDeformation(ParticleSet& set, size_t i, float dt, const Mat3f& C) {
  if constexpr (M::kUsesF) {
    set.F[i] = (Mat3f::Identity() + dt * C) * set.F[i];
  } else {
    set.J[i] *= 1.0f + dt * C.trace();
  }
}

// The velocity v = sum w_i v_i at a particle and its affine part
// B = sum w_i v_i (o_i - fx)^T over the 27 nodes of its stencil (o_i the
// node's offset from the base node). The weights are products of one
// weight per axis, so the sums contract one axis at a time (z, then y,
// then x), each node's four channels (m, v) one vector: two thirds of the
// multiplications of the sum node by node, each on a whole vector instead
// of shuffled 3-vectors.
// fv receives sum w_i f_i of a second buffer (FLIP's change) with kFlip.
// a x + b y + c z. Written as one Eigen expression, GCC 12 called its
// assignment loop out of line, four times per particle (5% of the step).
[[gnu::always_inline]] inline Eigen::Vector4f sum3(float a, const Eigen::Vector4f& x, float b,
                                                   const Eigen::Vector4f& y, float c,
                                                   const Eigen::Vector4f& z) {
  Eigen::Vector4f r = a * x;
  r += b * y;
  r += c * z;
  return r;
}

template <bool kFlip>
[[gnu::always_inline]] inline void gatherAffine(const HaloBuffer<4>& buf, const HaloBuffer<4>* fbuf,
                                                const Vec3i& h, const Stencil& st, Vec3f& v,
                                                Mat3f& B, Vec3f& fv) {
  using V4 = Eigen::Vector4f;
  using Node = Eigen::Map<const V4, Eigen::Aligned16>;
  V4 U[3], Y[3], Z[3], F[3];
  // Unrolled, so that the sums stay in registers (a loop over a kept them in
  // memory, stored and loaded again per particle).
#pragma GCC unroll 3
  for (int a = 0; a < 3; ++a) {
    U[a] = Y[a] = Z[a] = F[a] = V4::Zero();
    for (int b = 0; b < 3; ++b) {
      // The three nodes along z lie next to each other in the buffer.
      const int row = HaloBuffer<4>::index(h.x() + a, h.y() + b, h.z());
      const Node n0(buf.d[row]), n1(buf.d[row + 1]), n2(buf.d[row + 2]);
      const V4 S = st.w[2][0] * n0 + st.w[2][1] * n1 + st.w[2][2] * n2;
      const V4 T = st.w[2][1] * n1 + (2.0f * st.w[2][2]) * n2;
      const float wb = st.w[1][b];
      U[a] += wb * S;
      Y[a] += (wb * (float(b) - st.fx[1])) * S;
      Z[a] += wb * (T - st.fx[2] * S);
      if constexpr (kFlip) {
        const Node f0(fbuf->d[row]), f1(fbuf->d[row + 1]), f2(fbuf->d[row + 2]);
        F[a] += wb * (st.w[2][0] * f0 + st.w[2][1] * f1 + st.w[2][2] * f2);
      }
    }
  }
  const float* w = st.w[0];
  const V4 sv = sum3(w[0], U[0], w[1], U[1], w[2], U[2]);
  const V4 bx =
      sum3(w[0] * -st.fx[0], U[0], w[1] * (1.0f - st.fx[0]), U[1], w[2] * (2.0f - st.fx[0]), U[2]);
  const V4 by = sum3(w[0], Y[0], w[1], Y[1], w[2], Y[2]);
  const V4 bz = sum3(w[0], Z[0], w[1], Z[1], w[2], Z[2]);
  v = sv.tail<3>();
  B.col(0) = bx.tail<3>();
  B.col(1) = by.tail<3>();
  B.col(2) = bz.tail<3>();
  if constexpr (kFlip) fv = sum3(w[0], F[0], w[1], F[1], w[2], F[2]).tail<3>();
}

// Four floats in one SSE register (GCC's and clang's vector extension); the
// halo buffer's rows are 16-byte aligned; may_alias as for SSE's __m128.
typedef float Lanes4 __attribute__((vector_size(16), may_alias));

// Scatters particles [b, b + n) of a set, A[k] the affine momentum (times
// dx) of particle b + k.
template <bool kFlip>
void scatterRun(const ParticleSet& set, size_t b, int n, const Mat3f* A_run, const Vec3i& origin,
                const TransferParams& p, HaloBuffer<4>& buf, HaloBuffer<4>* fbuf) {
  const float m = set.mass;
  for (int k = 0; k < n; ++k) {
    const size_t i = b + size_t(k);
    const Stencil s = stencilAlwaysInline(set.x[i], p.shifted_origin, p.inv_dx);
    const Vec3i h = haloOffset(s, origin);
    const Mat3f& A = A_run[k];
    const Vec3f fx(s.fx[0], s.fx[1], s.fx[2]);
    // Node momentum is w (m v + A (o - fx)) for stencil offset o; mass and
    // momentum go as one vector of four channels, as the buffer holds them.
    // GCC's vectors, built from registers: Eigen's Vector4f(a, b, c, d)
    // went through four narrow stores and one wide load, which cannot be
    // forwarded and stalled the scatter a fifth of its time.
    const Vec3f mv0 = m * set.v[i] - A * fx;
    const Lanes4 p0 = {m, mv0.x(), mv0.y(), mv0.z()};
    const Lanes4 da = {0.0f, A(0, 0), A(1, 0), A(2, 0)}, db = {0.0f, A(0, 1), A(1, 1), A(2, 1)},
                 dc = {0.0f, A(0, 2), A(1, 2), A(2, 2)};
    for (int a = 0; a < 3; ++a) {
      const Lanes4 pa = p0 + float(a) * da;
      for (int bb = 0; bb < 3; ++bb) {
        const Lanes4 pab = pa + float(bb) * db;
        const float wab = s.w[0][a] * s.w[1][bb];
        float* row = buf.d[HaloBuffer<4>::index(h.x() + a, h.y() + bb, h.z())];
        for (int c = 0; c < 3; ++c) {
          const float w = wab * s.w[2][c];
          Lanes4* node = reinterpret_cast<Lanes4*>(row + 4 * c);
          *node += w * (pab + float(c) * dc);
          if constexpr (kFlip) {
            float* frow = fbuf->d[HaloBuffer<4>::index(h.x() + a, h.y() + bb, h.z() + c)];
            frow[1] += w * m * set.v[i].x();
            frow[2] += w * m * set.v[i].y();
            frow[3] += w * m * set.v[i].z();
          }
        }
      }
    }
  }
}

// The factors that turn a set's (C, tau) into its affine momentum.
struct SetScales {
  float stress = 0.0f;    // dt V0 (4/dx^2) dx
  float momentum = 0.0f;  // m dx for APIC, 0 otherwise
};

SetScales setScales(const ParticleSet& set, const TransferParams& p) {
  const bool apic = p.scheme == TransferScheme::Apic;
  return {p.dt * set.volume * 4.0f * p.inv_dx * p.inv_dx * p.dx, apic ? set.mass * p.dx : 0.0f};
}

// Particle block pb's particles of one set: their stresses (plastic models
// project F onto their yield surface first), folded with the APIC affine
// velocity into the affine momentum m C dx - dt V0 (4/dx^2) tau dx (MLS-MPM),
// then scattered. In chunks, so that a chunk's stresses are still in L1 when
// the scatter reads them, and C, F and x are read once per step here instead
// of once more in a pass of their own. Returns the largest stiffness scale
// (snow's hardening; 1 for the others).
template <class M, bool kFlip>
float stressAndScatter(const M& model, ParticleSet& set, const SetScales& k,
                       const std::vector<uint32_t>& off, size_t pb, const TransferParams& p,
                       const GridLayout& layout, HaloBuffer<4>& buf, HaloBuffer<4>* fbuf) {
  float max_scale = 1.0f;
  const Vec3i origin = haloOrigin(layout, pb);
  for (size_t b = off[pb]; b < off[pb + 1]; b += kStressChunk) {
    const int n = int(std::min<size_t>(kStressChunk, off[pb + 1] - b));
    Mat3f A[kStressChunk];
    stressChunk(model, set, b, n, A);
    for (int i = 0; i < n; ++i) A[i] = k.momentum * set.C[b + size_t(i)] - k.stress * A[i];
    if constexpr (std::is_same_v<M, Snow<float>>) {
      for (int i = 0; i < n; ++i)
        max_scale = std::max(max_scale, model.stiffnessScale(set.J[b + size_t(i)]));
    }
    scatterRun<kFlip>(set, b, n, A, origin, p, buf, fbuf);
  }
  return max_scale;
}

// Whether particle block pb scatters into a layered grid block (a split run).
bool touchesLayer(const GridLayout& layout, size_t pb) {
  for (uint32_t gb : layout.neighbours[pb])
    if (layout.layered[gb] >= 0) return true;
  return false;
}

// Adds particle block pb's halo sums to the grid, those on layered blocks
// to their colour's layer. Kept out of line: inlined into the scatter it
// changed how the compiler laid out the gather in this file (jelly G2P
// 2.1 -> 2.8 s).
template <bool kFlip>
[[gnu::noinline]] void addToLayers(const GridLayout& layout, size_t pb, int colour,
                                   const HaloBuffer<4>& buf, const HaloBuffer<4>& fbuf,
                                   std::vector<GridNode>& grid, std::vector<GridNode>* flip,
                                   std::vector<GridNode>& layers,
                                   std::vector<GridNode>* flip_layers) {
  forHalo(layout, pb, [&](int h, size_t node) {
    const int32_t slot = layout.layered[node / kBlockNodes];
    const size_t at = (size_t(slot) * 8 + size_t(colour)) * kBlockNodes + node % kBlockNodes;
    GridNode& g = slot < 0 ? grid[node] : layers[at];
    g.m += buf.d[h][0];
    g.v[0] += buf.d[h][1];
    g.v[1] += buf.d[h][2];
    g.v[2] += buf.d[h][3];
    if constexpr (kFlip) {
      GridNode& f = slot < 0 ? (*flip)[node] : (*flip_layers)[at];
      f.v[0] += fbuf.d[h][1];
      f.v[1] += fbuf.d[h][2];
      f.v[2] += fbuf.d[h][3];
    }
  });
}

template <bool kFlip>
float scatterAll(std::vector<ParticleSet>& sets, const GridLayout& layout, const TransferParams& p,
                 std::vector<GridNode>& grid, std::vector<GridNode>* flip,
                 std::vector<GridNode>* layers, std::vector<GridNode>* flip_layers) {
  // Colours run one after another; blocks of one colour touch disjoint nodes,
  // so each node's sum has the same order for any thread count. One
  // parallel region for all eight (a barrier between colours): a region
  // per colour cost a wake-up of the sleeping threads each.
  const bool layered = layout.layered_blocks > 0 && layers != nullptr;
  std::vector<SetScales> scales;
  for (const ParticleSet& set : sets) scales.push_back(setScales(set, p));
  float max_scale = 1.0f;
#pragma omp parallel reduction(max : max_scale) if (layoutParticles(layout) > kParallelTransfer)
  {
    HaloBuffer<4> buf;
    HaloBuffer<4> fbuf;
    for (int colour = 0; colour < 8; ++colour) {
      const std::vector<uint32_t>& blocks = layout.colour_blocks[colour];
#pragma omp for schedule(dynamic, 1)
      for (int64_t k = 0; k < static_cast<int64_t>(blocks.size()); ++k) {
        const size_t pb = blocks[k];
        if (layout.sleeping(pb)) continue;
        std::memset(buf.d, 0, sizeof(buf.d));
        if constexpr (kFlip) std::memset(fbuf.d, 0, sizeof(fbuf.d));
        for (size_t s = 0; s < sets.size(); ++s) {
          const std::vector<uint32_t>& off = layout.offsets[s];
          if (off[pb] == off[pb + 1]) continue;
          // The material variant is visited once per block and set.
          const float scale = std::visit(
              [&](const auto& model) {
                return stressAndScatter<std::decay_t<decltype(model)>, kFlip>(
                    model, sets[s], scales[s], off, pb, p, layout, buf, &fbuf);
              },
              sets[s].model);
          max_scale = std::max(max_scale, scale);
        }
        if (layered && touchesLayer(layout, pb)) {
          addToLayers<kFlip>(layout, pb, colour, buf, fbuf, grid, flip, *layers, flip_layers);
          continue;
        }
        forHalo(layout, pb, [&](int h, size_t node) {
          // A node's four channels (m, v) in one add, as the buffer holds them.
          static_assert(sizeof(GridNode) == sizeof(Lanes4) && alignof(GridNode) == 16);
          *reinterpret_cast<Lanes4*>(&grid[node]) += *reinterpret_cast<const Lanes4*>(buf.d[h]);
          if constexpr (kFlip) {
            GridNode& f = (*flip)[node];
            f.v[0] += fbuf.d[h][1];
            f.v[1] += fbuf.d[h][2];
            f.v[2] += fbuf.d[h][3];
          }
        });
      }
    }
  }
  return max_scale;
}

template <class M, bool kFlip>
G2PStats gatherSet(ParticleSet& set, size_t s, const GridLayout& layout,
                   const TransferParams& p, const std::vector<GridNode>& grid,
                   const std::vector<GridNode>* flip, float* block_speed2) {
  const std::vector<uint32_t>& off = layout.offsets[s];
  const float dt = p.dt;
  const float c_scale = 4.0f * p.inv_dx;
  const float flip_ratio = p.flip_ratio;
  float max_speed2 = 0.0f;
  int all_finite = 1;
  const bool parallel = off.back() > kParallelTransfer;
  // clang-format off
#pragma omp parallel reduction(max : max_speed2) reduction(min : all_finite) if (parallel)
  // clang-format on
  {
    HaloBuffer<4> buf;
    HaloBuffer<4> fbuf;
#pragma omp for schedule(dynamic, 1)
    for (int64_t pb = 0; pb < static_cast<int64_t>(layout.particleBlocks()); ++pb) {
      if (off[pb] == off[pb + 1] || layout.sleeping(size_t(pb))) continue;
      float block_max2 = 0.0f;
      const Vec3i origin = haloOrigin(layout, size_t(pb));
      forHalo(layout, pb, [&](int h, size_t node) {
        std::memcpy(buf.d[h], &grid[node], sizeof(GridNode));
        if constexpr (kFlip) std::memcpy(fbuf.d[h], &(*flip)[node], sizeof(GridNode));
      });
      for (uint32_t i = off[pb]; i < off[pb + 1]; ++i) {
        const Stencil st = stencilAt(set.x[i], p.shifted_origin, p.inv_dx);
        const Vec3i h = haloOffset(st, origin);
        Vec3f v, dv;
        Mat3f B;
        gatherAffine<kFlip>(buf, &fbuf, h, st, v, B, dv);
        if constexpr (M::kUsesF) {
          // Everything read again below comes from registers, not from the
          // particle just stored: a wide load of C or x waited on its
          // stores (they cannot be forwarded to it), and with two threads
          // that wait was a third of the gather (jelly 8.3 -> 9.9 M
          // particle-substeps/s). Water's J update reads three floats,
          // which are forwarded, and its loop is faster as written below.
          const Mat3f C = c_scale * B;
          const Vec3f x = (set.x[i] + dt * v).cwiseMax(p.domain_lo).cwiseMin(p.domain_hi);
          if constexpr (kFlip) v = flip_ratio * (set.v[i] + dv) + (1.0f - flip_ratio) * v;
          set.C[i] = C;
          set.x[i] = x;
          set.v[i] = v;
          updateDeformation<M>(set, i, dt, C);
          block_max2 = std::max(block_max2, v.squaredNorm());
          if (!std::isfinite(block_max2 + x.sum() + C.sum())) all_finite = 0;
        } else {
          set.C[i] = c_scale * B;
          set.x[i] = (set.x[i] + dt * v).cwiseMax(p.domain_lo).cwiseMin(p.domain_hi);
          if constexpr (kFlip) {
            set.v[i] = flip_ratio * (set.v[i] + dv) + (1.0f - flip_ratio) * v;
          } else {
            set.v[i] = v;
          }
          updateDeformation<M>(set, i, dt, set.C[i]);
          block_max2 = std::max(block_max2, set.v[i].squaredNorm());
          if (!std::isfinite(block_max2 + set.x[i].sum() + set.C[i].sum())) all_finite = 0;
        }
      }
      max_speed2 = std::max(max_speed2, block_max2);
      if (block_speed2) block_speed2[pb] = std::max(block_speed2[pb], block_max2);
    }
  }
  // A NaN never wins a max reduction, so report non-finite separately.
  return {std::sqrt(max_speed2), all_finite != 0};
}

}  // namespace

float particlesToGrid(std::vector<ParticleSet>& sets, const GridLayout& layout,
                      const TransferParams& p, std::vector<GridNode>& grid,
                      std::vector<GridNode>* flip, std::vector<GridNode>* layers,
                      std::vector<GridNode>* flip_layers) {
  const size_t nodes = layout.gridBlocks() * kBlockNodes;
  const size_t layer_nodes = layout.layered_blocks * 8 * kBlockNodes;
  grid.assign(nodes, GridNode{0, {0, 0, 0}});
  if (layers) layers->assign(layer_nodes, GridNode{0, {0, 0, 0}});
  if (flip) {
    flip->assign(nodes, GridNode{0, {0, 0, 0}});
    if (flip_layers) flip_layers->assign(layer_nodes, GridNode{0, {0, 0, 0}});
    return scatterAll<true>(sets, layout, p, grid, flip, layers, flip_layers);
  }
  return scatterAll<false>(sets, layout, p, grid, nullptr, layers, nullptr);
}

G2PStats gridToParticles(std::vector<ParticleSet>& sets, const GridLayout& layout,
                         const TransferParams& p, const std::vector<GridNode>& grid,
                         const std::vector<GridNode>* flip, std::vector<float>* block_speed2) {
  G2PStats total;
  if (block_speed2) block_speed2->assign(layout.particleBlocks(), 0.0f);
  float* bs = block_speed2 ? block_speed2->data() : nullptr;
  for (size_t s = 0; s < sets.size(); ++s) {
    ParticleSet& set = sets[s];
    const G2PStats st = std::visit(
        [&](const auto& model) {
          using M = std::decay_t<decltype(model)>;
          return flip ? gatherSet<M, true>(set, s, layout, p, grid, flip, bs)
                      : gatherSet<M, false>(set, s, layout, p, grid, nullptr, bs);
        },
        set.model);
    total.max_speed = std::max(total.max_speed, st.max_speed);
    total.finite = total.finite && st.finite;
  }
  return total;
}

}  // namespace triad
