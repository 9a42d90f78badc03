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

// Position of a stencil's base node inside particle block pb's halo.
inline Vec3i haloOffset(const Stencil& s, const GridLayout& layout, size_t pb) {
  const Vec3i b = unpackBlock(layout.particle_keys[pb]) * kBlockSize;
  return Vec3i(s.base[0] - b.x(), s.base[1] - b.y(), s.base[2] - b.z());
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
    // Between G2P and this pass C holds the velocity gradient, which mu(I) reads.
    if (model.rateDependent())
      projectAndKirchhoffBatch(model, n, &set.F[b], &set.C[b], tau);
    else
      projectAndKirchhoffBatch(model, n, &set.F[b], tau);
  } else if constexpr (std::is_same_v<M, Water<float>>) {
    for (int i = 0; i < n; ++i) tau[i] = model.kirchhoff(set.J[b + i], set.C[b + i]);
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

template <bool kFlip>
void scatterSet(const ParticleSet& set, const std::vector<uint32_t>& off, size_t pb,
                const TransferParams& p, const GridLayout& layout, HaloBuffer<4>& buf,
                HaloBuffer<4>* fbuf) {
  const float m = set.mass;
  for (uint32_t i = off[pb]; i < off[pb + 1]; ++i) {
    const Stencil s = stencilAt(set.x[i], p.shifted_origin, p.inv_dx);
    const Vec3i h = haloOffset(s, layout, pb);
    const Mat3f& A = set.C[i];  // affine momentum times dx (computeAffine)
    const Vec3f fx(s.fx[0], s.fx[1], s.fx[2]);
    // Node momentum is w (m v + A (o - fx)) for stencil offset o.
    const Vec3f mv0 = m * set.v[i] - A * fx;
    for (int a = 0; a < 3; ++a) {
      const Vec3f ma = mv0 + float(a) * A.col(0);
      for (int b = 0; b < 3; ++b) {
        const Vec3f mab = ma + float(b) * A.col(1);
        const float wab = s.w[0][a] * s.w[1][b];
        float* row = buf.d[HaloBuffer<4>::index(h.x() + a, h.y() + b, h.z())];
        for (int c = 0; c < 3; ++c) {
          const float w = wab * s.w[2][c];
          const Vec3f mom = mab + float(c) * A.col(2);
          row[c * 4 + 0] += w * m;
          row[c * 4 + 1] += w * mom.x();
          row[c * 4 + 2] += w * mom.y();
          row[c * 4 + 3] += w * mom.z();
          if constexpr (kFlip) {
            float* frow = fbuf->d[HaloBuffer<4>::index(h.x() + a, h.y() + b, h.z() + c)];
            frow[1] += w * m * set.v[i].x();
            frow[2] += w * m * set.v[i].y();
            frow[3] += w * m * set.v[i].z();
          }
        }
      }
    }
  }
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
void scatterAll(const std::vector<ParticleSet>& sets, const GridLayout& layout,
                const TransferParams& p, std::vector<GridNode>& grid, std::vector<GridNode>* flip,
                std::vector<GridNode>* layers, std::vector<GridNode>* flip_layers) {
  // Colours run one after another; blocks of one colour touch disjoint nodes,
  // so each node's sum has the same order for any thread count. One
  // parallel region for all eight (a barrier between colours): a region
  // per colour cost a wake-up of the sleeping threads each.
  const bool layered = layout.layered_blocks > 0 && layers != nullptr;
#pragma omp parallel
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
        for (size_t s = 0; s < sets.size(); ++s)
          scatterSet<kFlip>(sets[s], layout.offsets[s], pb, p, layout, buf, &fbuf);
        if (layered && touchesLayer(layout, pb)) {
          addToLayers<kFlip>(layout, pb, colour, buf, fbuf, grid, flip, *layers, flip_layers);
          continue;
        }
        forHalo(layout, pb, [&](int h, size_t node) {
          GridNode& g = grid[node];
          g.m += buf.d[h][0];
          g.v[0] += buf.d[h][1];
          g.v[1] += buf.d[h][2];
          g.v[2] += buf.d[h][3];
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
#pragma omp parallel reduction(max : max_speed2) reduction(min : all_finite)
  {
    HaloBuffer<4> buf;
    HaloBuffer<4> fbuf;
#pragma omp for schedule(dynamic, 1)
    for (int64_t pb = 0; pb < static_cast<int64_t>(layout.particleBlocks()); ++pb) {
      if (off[pb] == off[pb + 1] || layout.sleeping(size_t(pb))) continue;
      float block_max2 = 0.0f;
      forHalo(layout, pb, [&](int h, size_t node) {
        std::memcpy(buf.d[h], &grid[node], sizeof(GridNode));
        if constexpr (kFlip) std::memcpy(fbuf.d[h], &(*flip)[node], sizeof(GridNode));
      });
      for (uint32_t i = off[pb]; i < off[pb + 1]; ++i) {
        const Stencil st = stencilAt(set.x[i], p.shifted_origin, p.inv_dx);
        const Vec3i h = haloOffset(st, layout, pb);
        Vec3f v = Vec3f::Zero();
        Vec3f dv = Vec3f::Zero();
        Mat3f B = Mat3f::Zero();
        for (int a = 0; a < 3; ++a)
          for (int b = 0; b < 3; ++b)
            for (int c = 0; c < 3; ++c) {
              const float w = st.w[0][a] * st.w[1][b] * st.w[2][c];
              const int hi = HaloBuffer<4>::index(h.x() + a, h.y() + b, h.z() + c);
              const Vec3f vi(buf.d[hi][1], buf.d[hi][2], buf.d[hi][3]);
              const Vec3f o(float(a) - st.fx[0], float(b) - st.fx[1], float(c) - st.fx[2]);
              v += w * vi;
              B += (w * vi) * o.transpose();
              if constexpr (kFlip) dv += w * Vec3f(fbuf.d[hi][1], fbuf.d[hi][2], fbuf.d[hi][3]);
            }
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

namespace {

// Chunks of at most kStressChunk particles covering the awake blocks' runs
// of a set (start, count).
void awakeChunks(const GridLayout& layout, size_t s, std::vector<std::pair<size_t, int>>& out) {
  out.clear();
  const std::vector<uint32_t>& off = layout.offsets[s];
  size_t pb = 0;
  const size_t nblocks = layout.particleBlocks();
  while (pb < nblocks) {
    if (layout.sleeping(pb)) {
      ++pb;
      continue;
    }
    size_t end = pb;
    while (end < nblocks && !layout.sleeping(end)) ++end;
    for (size_t b = off[pb]; b < off[end]; b += kStressChunk)
      out.emplace_back(b, int(std::min<size_t>(kStressChunk, off[end] - b)));
    pb = end;
  }
}

}  // namespace

float computeAffine(std::vector<ParticleSet>& sets, const TransferParams& p,
                    const GridLayout* layout) {
  const bool apic = p.scheme == TransferScheme::Apic;
  const bool some_asleep = layout && !layout->asleep.empty();
  float max_scale = 1.0f;
  std::vector<std::pair<size_t, int>> awake;
  for (size_t si = 0; si < sets.size(); ++si) {
    ParticleSet& set = sets[si];
    const float stress_scale = p.dt * set.volume * 4.0f * p.inv_dx * p.inv_dx * p.dx;
    const float momentum_scale = apic ? set.mass * p.dx : 0.0f;
    if (some_asleep) awakeChunks(*layout, si, awake);
    const int64_t chunks = some_asleep
                               ? static_cast<int64_t>(awake.size())
                               : (static_cast<int64_t>(set.size()) + kStressChunk - 1) / kStressChunk;
    std::visit(
        [&](const auto& model) {
          using M = std::decay_t<decltype(model)>;
#pragma omp parallel for schedule(static) reduction(max : max_scale)
          for (int64_t c = 0; c < chunks; ++c) {
            const size_t b = some_asleep ? awake[size_t(c)].first : size_t(c) * kStressChunk;
            const int n = some_asleep ? awake[size_t(c)].second
                                      : int(std::min<size_t>(kStressChunk, set.size() - b));
            Mat3f tau[kStressChunk];
            stressChunk(model, set, b, n, tau);
            for (int i = 0; i < n; ++i)
              set.C[b + i] = momentum_scale * set.C[b + i] - stress_scale * tau[i];
            if constexpr (std::is_same_v<M, Snow<float>>) {
              for (int i = 0; i < n; ++i)
                max_scale = std::max(max_scale, model.stiffnessScale(set.J[b + i]));
            }
          }
        },
        set.model);
  }
  return max_scale;
}

void particlesToGrid(const std::vector<ParticleSet>& sets, const GridLayout& layout,
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
    scatterAll<true>(sets, layout, p, grid, flip, layers, flip_layers);
  } else {
    scatterAll<false>(sets, layout, p, grid, nullptr, layers, nullptr);
  }
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
