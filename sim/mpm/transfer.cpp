#include "sim/mpm/transfer.h"

#include <omp.h>

#include <algorithm>
#include <cstring>

#include "sim/mpm/halo.h"
#include "sim/mpm/particles.h"
#include "sim/mpm/sleep.h"

namespace triad {

namespace {

// A particle block's stencil region, gathered into a dense 6x6x6 buffer so
// that the per-particle loops touch only L1-resident memory.
template <int kChannels>
struct HaloBuffer {
  // One node more than the halo: a row's four-node vectors end past the last one.
  alignas(64) float d[kHaloNodes + 1][kChannels];
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
// others and meeting them at the scatter's eight colour barriers takes
// longer than the work. Measured with threads that spin briefly before they
// sleep (the program's default): 4096 neither slows a 3,375-particle cube
// nor leaves the draft default scene's sets (a few thousand particles each,
// beside solids phases that run in parallel) on one thread, whose data the
// other thread then had in its cache (G2P 0.27 s on one thread, 0.41 on two).
constexpr size_t kParallelTransfer = 4096;

// Particles of every set of a layout, asleep or not.
size_t layoutParticles(const GridLayout& layout) {
  size_t n = 0;
  for (const std::vector<uint32_t>& off : layout.offsets) n += off.empty() ? 0 : off.back();
  return n;
}

// Where each of `team` threads' run of particle blocks starts in the
// transfers (team + 1 entries, the last the block count): contiguous runs
// holding equal shares of the awake particles. The scatter and the gather
// both hand out blocks by these runs, so a block's particles meet the same
// core in both passes, whose caches still hold them; handed out as they came
// free, a block met a different core in each pass, and at 2 threads the
// jelly's gather took 0.90 s where it took 1.08 s at one (0.57 s in runs).
std::vector<uint32_t> blockRuns(const GridLayout& layout, int team) {
  const size_t nb = layout.particleBlocks();
  std::vector<uint64_t> before(nb + 1, 0);  // awake particles in blocks [0, pb)
  for (size_t pb = 0; pb < nb; ++pb) {
    before[pb + 1] = before[pb];
    if (!layout.sleeping(pb))
      for (const std::vector<uint32_t>& off : layout.offsets)
        before[pb + 1] += off[pb + 1] - off[pb];
  }
  return equalShareRuns(before, team);
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

// Four floats in one SSE register (GCC's and clang's vector extension); the
// halo buffer's rows are 16-byte aligned; may_alias as for SSE's __m128.
typedef float Lanes4 __attribute__((vector_size(16), may_alias));
// Sixteen floats: the four channels (m, m v) of four nodes next to each
// other along z, the stencil's three and the one after them. One AVX-512
// register, or two AVX2 ones.
typedef float Lanes16 __attribute__((vector_size(64)));

// A halo row's four nodes from node p on (the buffer holds one node past
// its last row for this read). Through a reference: a 64-byte vector
// returned by value changes the ABI where AVX-512 is off (-Wpsabi).
[[gnu::always_inline]] inline void loadRow(const float* p, Lanes16& r) {
  std::memcpy(&r, p, sizeof(r));
}

// Node c's four channels of a row's sum.
template <int c>
[[gnu::always_inline]] inline Lanes4 group(const Lanes16& g) {
  return __builtin_shufflevector(g, g, 4 * c, 4 * c + 1, 4 * c + 2, 4 * c + 3);
}

// The velocity v = sum w_i v_i at a particle and its affine part
// B = sum w_i v_i (o_i - fx)^T over the 27 nodes of its stencil (o_i the
// node's offset from the base node); fv receives sum w_i f_i of a second
// buffer (FLIP's change) with kFlip. The weights are products of one
// weight per axis, so the z weights factor out of every sum: each row of
// four nodes along z is one vector, summed with its x and y weights, and
// the z weights (and z's offsets, for B's third column) are applied once
// at the end to the three node groups; the fourth node is never used.
// A third of the vector operations of summing node by node.
template <bool kFlip>
[[gnu::always_inline]] inline void gatherAffine(const HaloBuffer<4>& buf, const HaloBuffer<4>* fbuf,
                                                const Vec3i& h, const Stencil& st, Vec3f& v,
                                                Mat3f& B, Vec3f& fv) {
  Lanes16 G = {}, GX = {}, GY = {}, FG = {};
  // Unrolled, so that the sums stay in registers.
#pragma GCC unroll 3
  for (int a = 0; a < 3; ++a) {
    Lanes16 Ga = {}, GYa = {}, FGa = {};
#pragma GCC unroll 3
    for (int b = 0; b < 3; ++b) {
      const int row = HaloBuffer<4>::index(h.x() + a, h.y() + b, h.z());
      Lanes16 n;
      loadRow(buf.d[row], n);
      const float wb = st.w[1][b];
      Ga += wb * n;
      GYa += (wb * (float(b) - st.fx[1])) * n;
      if constexpr (kFlip) {
        Lanes16 f;
        loadRow(fbuf->d[row], f);
        FGa += wb * f;
      }
    }
    const float wa = st.w[0][a];
    G += wa * Ga;
    GX += (wa * (float(a) - st.fx[0])) * Ga;
    GY += wa * GYa;
    if constexpr (kFlip) FG += wa * FGa;
  }
  const float* w = st.w[2];
  const Lanes4 sv = w[0] * group<0>(G) + w[1] * group<1>(G) + w[2] * group<2>(G);
  const Lanes4 bx = w[0] * group<0>(GX) + w[1] * group<1>(GX) + w[2] * group<2>(GX);
  const Lanes4 by = w[0] * group<0>(GY) + w[1] * group<1>(GY) + w[2] * group<2>(GY);
  const Lanes4 bz = (w[0] * -st.fx[2]) * group<0>(G) + (w[1] * (1.0f - st.fx[2])) * group<1>(G) +
                    (w[2] * (2.0f - st.fx[2])) * group<2>(G);
  v = Vec3f(sv[1], sv[2], sv[3]);
  B << bx[1], by[1], bz[1], bx[2], by[2], bz[2], bx[3], by[3], bz[3];
  if constexpr (kFlip) {
    const Lanes4 f = w[0] * group<0>(FG) + w[1] * group<1>(FG) + w[2] * group<2>(FG);
    fv = Vec3f(f[1], f[2], f[3]);
  }
}

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
    // momentum go as one vector of four channels, as the buffer holds them,
    // and a row's four nodes along z as one vector of sixteen (lanes 4c to
    // 4c + 3 node c's). The fourth node's lanes are zero in every term, so
    // it gains exactly nothing. GCC's vectors, built from registers:
    // Eigen's Vector4f(a, b, c, d) went through four narrow stores and one
    // wide load, which cannot be forwarded and stalled the scatter a fifth
    // of its time.
    const Vec3f mv0 = m * set.v[i] - A * fx;
    const Lanes16 p0 = {m, mv0.x(), mv0.y(), mv0.z(), m, mv0.x(), mv0.y(), mv0.z(),
                        m, mv0.x(), mv0.y(), mv0.z(), 0, 0,       0,       0};
    const Lanes16 da = {0, A(0, 0), A(1, 0), A(2, 0), 0, A(0, 0), A(1, 0), A(2, 0),
                        0, A(0, 0), A(1, 0), A(2, 0), 0, 0,       0,       0};
    const Lanes16 db = {0, A(0, 1), A(1, 1), A(2, 1), 0, A(0, 1), A(1, 1), A(2, 1),
                        0, A(0, 1), A(1, 1), A(2, 1), 0, 0,       0,       0};
    const Lanes16 dc = {
        0, 0, 0, 0, 0, A(0, 2), A(1, 2), A(2, 2), 0, 2.0f * A(0, 2), 2.0f * A(1, 2), 2.0f * A(2, 2),
        0, 0, 0, 0};
    const Lanes16 wz = {s.w[2][0], s.w[2][0], s.w[2][0], s.w[2][0], s.w[2][1], s.w[2][1],
                        s.w[2][1], s.w[2][1], s.w[2][2], s.w[2][2], s.w[2][2], s.w[2][2],
                        0,         0,         0,         0};
    const Lanes16 p0c = p0 + dc;
    for (int a = 0; a < 3; ++a) {
      const Lanes16 pa = p0c + float(a) * da;
      for (int bb = 0; bb < 3; ++bb) {
        const Lanes16 pab = pa + float(bb) * db;
        const float wab = s.w[0][a] * s.w[1][bb];
        float* row = buf.d[HaloBuffer<4>::index(h.x() + a, h.y() + bb, h.z())];
        Lanes16 r;
        std::memcpy(&r, row, sizeof(r));
        r += (wab * wz) * pab;
        std::memcpy(row, &r, sizeof(r));
        if constexpr (kFlip) {
          for (int c = 0; c < 3; ++c) {
            const float w = wab * s.w[2][c];
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

// Sleeping block pb's halo sums into buf: its kept sums, or, where it has
// none, those its particles give at rest with a unit time step, from
// copies of F and J (the stress's return mapping writes them, and the
// state must stay as it is for a resumed run to compute the same sums);
// then the momentum scaled to the step. Its particles are at rest, so the
// momentum is all stress, linear in the step.
template <bool kFlip>
void sleepingHalo(std::vector<ParticleSet>& sets, const GridLayout& layout, size_t pb,
                  const TransferParams& p, SleepHalos& halos, HaloBuffer<4>& buf,
                  HaloBuffer<4>& fbuf, std::vector<Mat3f>& keep_F, std::vector<float>& keep_J) {
  const size_t slot = size_t(halos.slot[pb]);
  float* sums = halos.sums.data() + slot * SleepHalos::kFloats;
  if (!halos.filled[slot]) {
    std::memset(buf.d, 0, sizeof(buf.d));
    TransferParams unit = p;
    unit.dt = 1.0f;
    for (size_t s = 0; s < sets.size(); ++s) {
      ParticleSet& set = sets[s];
      const std::vector<uint32_t>& off = layout.offsets[s];
      const size_t b = off[pb], e = off[pb + 1];
      if (b == e) continue;
      if (!set.F.empty())
        keep_F.assign(set.F.begin() + std::ptrdiff_t(b), set.F.begin() + std::ptrdiff_t(e));
      if (!set.J.empty())
        keep_J.assign(set.J.begin() + std::ptrdiff_t(b), set.J.begin() + std::ptrdiff_t(e));
      const SetScales k = setScales(set, unit);
      std::visit(
          [&](const auto& model) {
            stressAndScatter<std::decay_t<decltype(model)>, kFlip>(model, set, k, off, pb, unit,
                                                                   layout, buf, &fbuf);
          },
          set.model);
      if (!set.F.empty())
        std::copy(keep_F.begin(), keep_F.end(), set.F.begin() + std::ptrdiff_t(b));
      if (!set.J.empty())
        std::copy(keep_J.begin(), keep_J.end(), set.J.begin() + std::ptrdiff_t(b));
    }
    std::memcpy(sums, buf.d, SleepHalos::kFloats * sizeof(float));
    halos.filled[slot] = 1;
  } else {
    std::memcpy(buf.d, sums, SleepHalos::kFloats * sizeof(float));
  }
  for (int h = 0; h < kHaloNodes; ++h)
    for (int c = 1; c < 4; ++c) buf.d[h][c] *= p.dt;
  // At rest: no momentum before the stress, for FLIP's change.
  if constexpr (kFlip) std::memset(fbuf.d, 0, sizeof(fbuf.d));
}

template <bool kFlip>
float scatterAll(std::vector<ParticleSet>& sets, const GridLayout& layout, const TransferParams& p,
                 std::vector<GridNode>& grid, std::vector<GridNode>* flip,
                 std::vector<GridNode>* layers, std::vector<GridNode>* flip_layers,
                 SleepHalos* halos) {
  // Colours run one after another; blocks of one colour touch disjoint nodes,
  // so each node's sum has the same order for any thread count. One
  // parallel region for all eight (a barrier between colours): a region
  // per colour cost a wake-up of the sleeping threads each. Each thread
  // takes the blocks of its run (blockRuns) in every colour.
  const bool layered = layout.layered_blocks > 0 && layers != nullptr;
  std::vector<SetScales> scales;
  for (const ParticleSet& set : sets) scales.push_back(setScales(set, p));
  float max_scale = 1.0f;
  std::vector<uint32_t> runs;
#pragma omp parallel reduction(max : max_scale) if (layoutParticles(layout) > kParallelTransfer)
  {
    HaloBuffer<4> buf;
    HaloBuffer<4> fbuf;
    std::vector<Mat3f> keep_F;
    std::vector<float> keep_J;
#pragma omp single
    runs = blockRuns(layout, omp_get_num_threads());
    const uint32_t first = runs[size_t(omp_get_thread_num())];
    const uint32_t last = runs[size_t(omp_get_thread_num()) + 1];
    for (int colour = 0; colour < 8; ++colour) {
      // This colour's blocks in the run (the lists are in block order).
      const std::vector<uint32_t>& blocks = layout.colour_blocks[colour];
      const auto from = std::lower_bound(blocks.begin(), blocks.end(), first);
      const auto to = std::lower_bound(from, blocks.end(), last);
      if (colour > 0) {
#pragma omp barrier
      }
      for (auto it = from; it != to; ++it) {
        const size_t pb = *it;
        if (layout.sleeping(pb)) {
          if (!halos) continue;
          sleepingHalo<kFlip>(sets, layout, pb, p, *halos, buf, fbuf, keep_F, keep_J);
        } else {
          std::memset(buf.d, 0, sizeof(buf.d));
          if constexpr (kFlip) std::memset(fbuf.d, 0, sizeof(fbuf.d));
        }
        for (size_t s = 0; s < sets.size() && !layout.sleeping(pb); ++s) {
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

// Gathers block pb's particles of `set` from the block's halo of nodes in
// buf (and fbuf with FLIP), and raises block_max2 to their largest speed².
template <class M, bool kFlip>
void gatherBlock(ParticleSet& set, const std::vector<uint32_t>& off, size_t pb, const Vec3i& origin,
                 const TransferParams& p, const HaloBuffer<4>& buf, const HaloBuffer<4>& fbuf,
                 float& block_max2, int& all_finite) {
  const float dt = p.dt;
  const float c_scale = 4.0f * p.inv_dx;
  const float flip_ratio = p.flip_ratio;
  for (uint32_t i = off[pb]; i < off[pb + 1]; ++i) {
    const Stencil st = stencilAt(set.x[i], p.shifted_origin, p.inv_dx);
    const Vec3i h = haloOffset(st, origin);
    Vec3f v, dv;
    Mat3f B;
    gatherAffine<kFlip>(buf, &fbuf, h, st, v, B, dv);
    // Everything read again below comes from registers, not from the
    // particle just stored: a wide load of C or x waited on its stores
    // (they cannot be forwarded to it), and with two threads that wait
    // was a third of the jelly's gather (8.3 -> 9.9 M particle-substeps/s)
    // and a fifth of water's (G2P 0.90 -> 0.72 s over the dam break's
    // first 0.05 s, while its column is packed).
    const Mat3f C = c_scale * B;
    const Vec3f x = (set.x[i] + dt * v).cwiseMax(p.domain_lo).cwiseMin(p.domain_hi);
    if constexpr (kFlip) v = flip_ratio * (set.v[i] + dv) + (1.0f - flip_ratio) * v;
    set.C[i] = C;
    set.x[i] = x;
    set.v[i] = v;
    updateDeformation<M>(set, i, dt, C);
    block_max2 = std::max(block_max2, v.squaredNorm());
    if (!std::isfinite(block_max2 + x.sum() + C.sum())) all_finite = 0;
  }
}

template <bool kFlip>
G2PStats gatherAll(std::vector<ParticleSet>& sets, const GridLayout& layout,
                   const TransferParams& p, const std::vector<GridNode>& grid,
                   const std::vector<GridNode>* flip, float* block_speed2) {
  float max_speed2 = 0.0f;
  int all_finite = 1;
  // One pass over the blocks, every set's particles of a block in turn: the
  // block's halo is read once, and each thread takes the run of blocks it
  // scattered (blockRuns).
  std::vector<uint32_t> runs;
  // clang-format off
#pragma omp parallel reduction(max : max_speed2) reduction(min : all_finite) if (layoutParticles(layout) > kParallelTransfer)
  // clang-format on
  {
    HaloBuffer<4> buf;
    HaloBuffer<4> fbuf;
    // The node past the halo, which rows' reads reach: zero, never filled.
    std::memset(buf.d[kHaloNodes], 0, sizeof(buf.d[kHaloNodes]));
    std::memset(fbuf.d[kHaloNodes], 0, sizeof(fbuf.d[kHaloNodes]));
#pragma omp single
    runs = blockRuns(layout, omp_get_num_threads());
    const uint32_t last = runs[size_t(omp_get_thread_num()) + 1];
    for (size_t pb = runs[size_t(omp_get_thread_num())]; pb < last; ++pb) {
      if (layout.sleeping(pb)) continue;
      bool any = false;
      for (size_t s = 0; s < sets.size() && !any; ++s)
        any = layout.offsets[s][pb] != layout.offsets[s][pb + 1];
      if (!any) continue;
      forHalo(layout, pb, [&](int h, size_t node) {
        std::memcpy(buf.d[h], &grid[node], sizeof(GridNode));
        if constexpr (kFlip) std::memcpy(fbuf.d[h], &(*flip)[node], sizeof(GridNode));
      });
      const Vec3i origin = haloOrigin(layout, pb);
      float block_max2 = 0.0f;
      for (size_t s = 0; s < sets.size(); ++s) {
        const std::vector<uint32_t>& off = layout.offsets[s];
        if (off[pb] == off[pb + 1]) continue;
        // The material variant is visited once per block and set.
        std::visit(
            [&](const auto& model) {
              gatherBlock<std::decay_t<decltype(model)>, kFlip>(sets[s], off, pb, origin, p, buf,
                                                                fbuf, block_max2, all_finite);
            },
            sets[s].model);
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
                      std::vector<GridNode>* flip_layers, SleepHalos* sleeping) {
  const size_t nodes = layout.gridBlocks() * kBlockNodes;
  const size_t layer_nodes = layout.layered_blocks * 8 * kBlockNodes;
  grid.assign(nodes, GridNode{0, {0, 0, 0}});
  if (layers) layers->assign(layer_nodes, GridNode{0, {0, 0, 0}});
  if (flip) {
    flip->assign(nodes, GridNode{0, {0, 0, 0}});
    if (flip_layers) flip_layers->assign(layer_nodes, GridNode{0, {0, 0, 0}});
    return scatterAll<true>(sets, layout, p, grid, flip, layers, flip_layers, sleeping);
  }
  return scatterAll<false>(sets, layout, p, grid, nullptr, layers, nullptr, sleeping);
}

void sleepersThatWouldMove(const std::vector<ParticleSet>& sets, const GridLayout& layout,
                           const TransferParams& p, const std::vector<GridNode>& grid, float speed,
                           std::vector<uint8_t>& moving) {
  const size_t nblocks = layout.particleBlocks();
  moving.assign(nblocks, 0);
  if (layout.asleep.empty()) return;
  const float limit2 = speed * speed;
  // Velocities only: a sleeping block costs this sum of 27 node velocities
  // per particle, none of the stress, scatter or stores.
#pragma omp parallel for schedule(dynamic, 1) if (layoutParticles(layout) > kParallelTransfer)
  for (int64_t b = 0; b < static_cast<int64_t>(nblocks); ++b) {
    const size_t pb = size_t(b);
    if (!layout.sleeping(pb)) continue;
    HaloBuffer<4> buf;
    std::memset(buf.d[kHaloNodes], 0, sizeof(buf.d[kHaloNodes]));  // past the last row
    float fastest = 0.0f;
    forHalo(layout, pb, [&](int h, size_t node) {
      const GridNode& g = grid[node];
      std::memcpy(buf.d[h], &g, sizeof(GridNode));
      fastest = std::max(fastest, g.v[0] * g.v[0] + g.v[1] * g.v[1] + g.v[2] * g.v[2]);
    });
    // A particle's velocity is a weighted mean of its nodes': none is faster
    // than the fastest node (a NaN fails the test and goes on).
    if (fastest <= limit2) continue;
    const Vec3i origin = haloOrigin(layout, pb);
    for (size_t s = 0; s < sets.size() && !moving[pb]; ++s) {
      const ParticleSet& set = sets[s];
      const std::vector<uint32_t>& off = layout.offsets[s];
      for (uint32_t i = off[pb]; i < off[pb + 1]; ++i) {
        const Stencil st = stencilAt(set.x[i], p.shifted_origin, p.inv_dx);
        const Vec3i h = haloOffset(st, origin);
        // Rows of four nodes along z, their z weights applied at the end.
        Lanes16 rows = {};
        for (int x = 0; x < 3; ++x)
          for (int y = 0; y < 3; ++y) {
            Lanes16 r;
            loadRow(buf.d[HaloBuffer<4>::index(h.x() + x, h.y() + y, h.z())], r);
            rows += (st.w[0][x] * st.w[1][y]) * r;
          }
        const Lanes4 v =
            st.w[2][0] * group<0>(rows) + st.w[2][1] * group<1>(rows) + st.w[2][2] * group<2>(rows);
        // A NaN wakes the block too: its gather then reports it.
        if (!(v[1] * v[1] + v[2] * v[2] + v[3] * v[3] <= limit2)) {
          moving[pb] = 1;
          break;
        }
      }
    }
  }
}

G2PStats gridToParticles(std::vector<ParticleSet>& sets, const GridLayout& layout,
                         const TransferParams& p, const std::vector<GridNode>& grid,
                         const std::vector<GridNode>* flip, std::vector<float>* block_speed2) {
  if (block_speed2) block_speed2->assign(layout.particleBlocks(), 0.0f);
  float* bs = block_speed2 ? block_speed2->data() : nullptr;
  return flip ? gatherAll<true>(sets, layout, p, grid, flip, bs)
              : gatherAll<false>(sets, layout, p, grid, nullptr, bs);
}

}  // namespace triad
