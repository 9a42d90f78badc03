#pragma once
// Particle-grid transfers of MLS-MPM (Hu et al. 2018) with APIC, PIC or
// PIC/FLIP blends (Jiang et al. 2015), on the blocked sparse grid.
#include <vector>

#include "sim/math.h"
#include "sim/scene_desc.h"
#include "sim/mpm/sparse_grid.h"

namespace triad {

struct ParticleSet;
struct SleepHalos;

struct TransferParams {
  Vec3f shifted_origin;  // world position of node 0 plus dx/2 (see shiftedCoord)
  float dx = 0.0f;
  float inv_dx = 0.0f;  // 1/dx, the same value the binner used
  float dt = 0.0f;
  TransferScheme scheme = TransferScheme::Apic;
  float flip_ratio = 0.95f;
  // The domain box: the walls keep material inside, and positions are clamped
  // to it so that no particle can tunnel out in one step at extreme speed.
  Vec3f domain_lo, domain_hi;
};

// Per-set facts that G2P gathers for the next step's time step.
struct G2PStats {
  float max_speed = 0.0f;  // largest particle speed, m/s
  bool finite = true;      // every particle's state finite
};

// P2G with the stress folded in (MLS-MPM): each particle's Kirchhoff
// stress tau (plastic models project F onto their yield surface first) and
// its APIC affine velocity C make its affine momentum
// m C dx - dt V0 (4/dx^2) tau dx (nothing of C for PIC/FLIP), which
// scatters with its mass and momentum into `grid` (sized
// layout.gridBlocks() * 64). C itself is left as it is. The material
// variant is visited once per block and set.
// With FLIP, `flip` receives the momentum without the stress impulse.
// Where the layout marks layered blocks (a split run), their sums go to
// `layers` (and `flip_layers`) instead, 64 nodes per (slot * 8 + colour).
// Particles of sleeping blocks are left as they are; with `sleeping`, the
// blocks scatter their kept sums at rest instead (sim/mpm/sleep.h), which
// they compute first where they have none.
// Returns the largest stiffness scale (snow hardening; 1 for the others).
float particlesToGrid(std::vector<ParticleSet>& sets, const GridLayout& layout,
                      const TransferParams& p, std::vector<GridNode>& grid,
                      std::vector<GridNode>* flip, std::vector<GridNode>* layers = nullptr,
                      std::vector<GridNode>* flip_layers = nullptr, SleepHalos* sleeping = nullptr);

// Gather velocities (and, with FLIP, velocity changes) back to particles,
// advect them, and update each particle's F (or J for water). Sleeping
// blocks are skipped (and so is their scatter). With `block_speed2`, each
// awake particle block's largest squared particle speed is written there.
G2PStats gridToParticles(std::vector<ParticleSet>& sets, const GridLayout& layout,
                         const TransferParams& p, const std::vector<GridNode>& grid,
                         const std::vector<GridNode>* flip,
                         std::vector<float>* block_speed2 = nullptr);

// Per particle block, 1 where the block sleeps and one of its particles
// would gather a velocity faster than `speed` from `grid` (0 elsewhere).
void sleepersThatWouldMove(const std::vector<ParticleSet>& sets, const GridLayout& layout,
                           const TransferParams& p, const std::vector<GridNode>& grid, float speed,
                           std::vector<uint8_t>& moving);

// Quadratic B-spline stencil of a particle: base node and per-axis weights.
struct Stencil {
  Vec3i base;
  float fx[3];    // position relative to base, in cells, in [0.5, 1.5)
  float w[3][3];  // w[axis][offset]
};

// The scatter inlines it always (returned through memory, it cost a tenth
// of the scatter); the gather calls it out of line, as GCC chooses, which
// measured faster there (inlined, the gather's loop compiled worse).
[[gnu::always_inline]] inline Stencil stencilAlwaysInline(const Vec3f& x,
                                                          const Vec3f& shifted_origin,
                                                          float inv_dx) {
  Stencil s;
  for (int d = 0; d < 3; ++d) {
    const float t = shiftedCoord(x[d], shifted_origin[d], inv_dx);
    const float b = std::floor(t);
    const float f = t - b + 0.5f;
    s.base[d] = static_cast<int>(b);
    s.fx[d] = f;
    s.w[d][0] = 0.5f * (1.5f - f) * (1.5f - f);
    s.w[d][1] = 0.75f - (f - 1.0f) * (f - 1.0f);
    s.w[d][2] = 0.5f * (f - 0.5f) * (f - 0.5f);
  }
  return s;
}

inline Stencil stencilAt(const Vec3f& x, const Vec3f& shifted_origin, float inv_dx) {
  return stencilAlwaysInline(x, shifted_origin, inv_dx);
}

}  // namespace triad
