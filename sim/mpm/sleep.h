#pragma once
// Sleeping material: particle blocks whose material has been still for a
// while skip the stress pass, the scatter and the gather. A sleeping block's
// particles keep their place and deformation with zero velocity, and the
// grid nodes its stencils reach are held at rest, so that awake material
// next to it meets a still support, as it did before.
//
// A block sleeps when it and every particle block around it (its 26
// neighbours) have been slower than `speed` for `delay` seconds, no particle
// entered or left any of them in the last step, and no moving solid's
// bounds (plus a margin) reach it. Material moves less than a cell a step,
// so motion wakes a sleeping block one step before it could reach the nodes
// that block holds still.
#include <cstdint>
#include <vector>

#include "sim/math.h"
#include "sim/mpm/sparse_grid.h"
#include "sim/scene_desc.h"

namespace triad {

struct ParticleSet;
class DomainExchange;

// World-space box that keeps the blocks it touches awake.
struct WakeBox {
  Vec3d lo, hi;
};

// What carries over between steps (and into checkpoints): per particle
// block of the last step, its key, its particle count and how long its
// material has been still.
struct SleepState {
  std::vector<uint64_t> keys;    // sorted
  std::vector<uint32_t> counts;  // particles of all sets in the block
  std::vector<double> still;     // seconds below the speed threshold
  std::vector<double> body_still;  // per rigid body (world order), likewise
  bool operator==(const SleepState& o) const {
    return keys == o.keys && counts == o.counts && still == o.still && body_still == o.body_still;
  }
};

class SleepTracker {
 public:
  explicit SleepTracker(const SleepDesc& desc) : desc_(desc) {}

  // After binning: carries the still times over to the new blocks and fills
  // layout.asleep. Blocks touched by `wake` (world boxes) stay awake.
  // `origin`, `inv_dx`: the binner's shifted origin and inverse spacing.
  // Returns the number of sleeping particles. Split over processes
  // (`split`), a block's neighbours may be another process's: every
  // process's blocks and still times are gathered first, and every process
  // decides for all blocks alike (asleepEverywhere()).
  size_t classify(GridLayout& layout, const std::vector<WakeBox>& wake, const Vec3f& origin,
                  float inv_dx, DomainExchange* split = nullptr);

  // After the gather: `speed2` holds each awake block's largest squared
  // particle speed (sleeping blocks: anything). Advances the still times;
  // split over processes, the state kept is every process's.
  void update(const GridLayout& layout, const std::vector<float>& speed2, double dt,
              DomainExchange* split = nullptr);

  // The keys of every particle block asleep in this step, sorted (on every
  // process of a split run).
  const std::vector<uint64_t>& asleepEverywhere() const { return asleep_keys_; }

  // Whether every particle block of the last step within `box` had been
  // still for the delay (blocks that a body resting there would let sleep).
  bool calmWithin(const WakeBox& box, const Vec3f& origin, float inv_dx) const;

  // Seconds each rigid body (world order) has been slower than the speed;
  // kept by the solver, saved with the rest.
  std::vector<double>& bodyStill() { return state_.body_still; }
  double delay() const { return desc_.delay; }
  double speed() const { return desc_.speed; }

  const SleepState& state() const { return state_; }
  void restore(SleepState s) { state_ = std::move(s); }

 private:
  SleepDesc desc_;
  SleepState state_;
  std::vector<double> still_;       // per block of the current layout
  std::vector<uint32_t> counts_;  // per block of the current layout
  std::vector<uint64_t> asleep_keys_;
};

// Holds the grid nodes of sleeping blocks' stencils at rest (after the grid
// update; with FLIP, their velocity change too). Split over processes,
// `asleep` lists every process's sleeping blocks, whose stencils may reach
// this process's nodes.
void freezeSleepingNodes(const GridLayout& layout, std::vector<GridNode>& grid,
                         std::vector<GridNode>* flip,
                         const std::vector<uint64_t>* asleep = nullptr);

// Sets the velocity and affine matrix of sleeping blocks' particles to zero:
// they stay where they are until woken, and wake from rest.
void stillSleepingParticles(const GridLayout& layout, std::vector<ParticleSet>& sets);

}  // namespace triad
