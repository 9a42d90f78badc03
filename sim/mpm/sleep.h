#pragma once
// Sleeping material: particle blocks whose material has been still for a
// while skip the stress pass, the scatter and the gather. A sleeping block's
// particles keep their place and deformation with zero velocity, and it
// scatters the sums its particles gave the grid at rest (their mass, and
// their stress's momentum per unit time step), kept from the step it fell
// asleep: the grid then holds what it would hold with those particles
// awake and still, so awake material beside them meets the same support,
// mass and stress as without sleep.
//
// A block sleeps when its particles (and, with `neighbours`, those of the
// 26 blocks around it) have been slower than `speed` for `delay` seconds,
// no particle entered or left it in the last step, and no solid moving
// faster than `speed` has its bounds (plus a margin) reach it. It wakes in the step
// where one of its particles would gather a velocity faster than `speed`
// from the grid (after the grid update and the collision with solids), and
// gathers in that step: moving material, a body or a wave reaching it wakes
// it before any of its particles would have moved faster than `speed`.
#include <cstddef>
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

// The halo sums of sleeping blocks (mass, and momentum per unit time step:
// particles at rest carry none but their stress's), kept while a block
// sleeps. Rebuilt from the particles whenever it is missing (the block
// just fell asleep, or the run resumed), from copies of F so that the
// state stays as it was and a resumed run computes the same sums.
struct SleepHalos {
  static constexpr size_t kFloats = size_t(kHaloNodes) * 4;
  std::vector<uint64_t> keys;   // sorted
  std::vector<float> sums;      // kFloats per key
  std::vector<uint8_t> filled;  // per key
  std::vector<int32_t> slot;    // per particle block of the layout: its key's index, or -1

  // Keeps the sums of the blocks that sleep in `layout` and had them, and
  // makes room for the newly asleep.
  void prepare(const GridLayout& layout);
  size_t bytes() const;
};

class SleepTracker {
 public:
  explicit SleepTracker(const SleepDesc& desc) : desc_(desc) {}

  // After binning: carries the still times over to the new blocks and fills
  // layout.asleep. Blocks touched by `wake` (world boxes) stay awake.
  // `origin`, `inv_dx`: the binner's shifted origin and inverse spacing.
  // Returns the number of sleeping particles. Split over processes
  // (`split`), a block's neighbours may be another process's: each process
  // sends the still times of its blocks beside another's to that process
  // (and, after a new cut, the state of blocks it no longer owns to their
  // owners).
  size_t classify(GridLayout& layout, const std::vector<WakeBox>& wake, const Vec3f& origin,
                  float inv_dx, DomainExchange* split = nullptr);

  // After the grid update and the collision: wakes every sleeping block
  // that `moving` marks (sleepersThatWouldMove, sim/mpm/transfer.h), for
  // the rest of the step (it gathers) and for the delay after it, and
  // drops its sums. Returns the number of particles woken.
  size_t wakeMoving(GridLayout& layout, const std::vector<uint8_t>& moving, SleepHalos& halos);

  // After the gather: `speed2` holds each awake block's largest squared
  // particle speed (sleeping blocks: anything). Advances the still times;
  // split over processes, each keeps its own blocks' state.
  void update(const GridLayout& layout, const std::vector<float>& speed2, double dt,
              DomainExchange* split = nullptr);

  // Whether every particle block of the last step within `box` had been
  // still for the delay (blocks that a body resting there would let sleep).
  // Split over processes, of the blocks this process kept: the solver
  // combines every process's answer.
  bool calmWithin(const WakeBox& box, const Vec3f& origin, float inv_dx) const;

  // Seconds each rigid body (world order) has been slower than the speed;
  // kept by the solver, saved with the rest.
  std::vector<double>& bodyStill() { return state_.body_still; }
  double delay() const { return desc_.delay; }
  double speed() const { return desc_.speed; }

  // The state a checkpoint saves: split over processes, gathered first
  // (gatherState, collective).
  const SleepState& state() const { return state_; }
  void gatherState(DomainExchange& split);
  void restore(SleepState s) {
    state_ = std::move(s);
    own_only_ = false;
  }

 private:
  // After a new cut: sends the state of blocks another process owns now
  // to it, and keeps those this one owns, its own and those it received.
  void handOver(DomainExchange& split);

  SleepDesc desc_;
  SleepState state_;
  // Split over processes: whether state_ holds this process's blocks only
  // (after update) or every process's (restored, or gathered), and the
  // domain's cut count when it was kept.
  bool own_only_ = false;
  uint64_t cuts_ = 0;
  std::vector<double> still_;       // per block of the current layout
  std::vector<uint32_t> counts_;  // per block of the current layout
  std::vector<uint8_t> woken_;    // per block of the current layout
};

// Sets the velocity and affine matrix of sleeping blocks' particles to zero:
// they stay where they are until woken, and wake from rest.
void stillSleepingParticles(const GridLayout& layout, std::vector<ParticleSet>& sets);

}  // namespace triad
