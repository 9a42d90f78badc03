// Water that starts at rest under its own weight. Particles are sampled with
// J = 1, so water placed in a tank carries no pressure in its first step,
// falls, compresses and rings until the ringing dies away: the water of a
// tank 0.2 m deep (K 2e5 Pa) swings at 25 Hz, and a body held in it rises
// and falls by up to 0.1 m/s with it (bench/RESULTS.md, "The water beside
// a moving body moves with it"). An MPM object of water with
// "initial_pressure": "hydrostatic" starts instead with the J whose pressure
// carries the water above it.
#pragma once

#include <array>
#include <cstdint>
#include <unordered_map>
#include <vector>

#include "sim/math.h"
#include "sim/scene_desc.h"

namespace triad {

// The levels of the bodies of water the particles added make: cells that
// hold water and touch across a face are one body, whose level is its
// highest particle's height (along gravity) and half a particle spacing. A
// particle's depth is measured to its own body's level, so the water under
// a submerged body or beside a wall takes the level of the water round it,
// and a block falling onto a pool keeps its own until it lands.
class WaterLevels {
 public:
  // `spacing`: the particles' spacing along an axis, dx / cbrt(ppc).
  WaterLevels(const DomainDesc& domain, const Vec3d& gravity, double spacing);
  // One water particle.
  void add(const Vec3f& x);
  // Joins the cells into bodies; call once, after the last add().
  void finish();
  // The depth of x under its body's level (m, >= 0); 0 where no water was
  // added in x's cell.
  double depth(const Vec3f& x) const;
  // The magnitude of gravity (m/s^2).
  double gravity() const { return g_; }

 private:
  using Cell = std::array<int32_t, 3>;
  struct CellHash {
    size_t operator()(const Cell& c) const {
      return size_t(uint32_t(c[0])) * 0x9E3779B97F4A7C15ull ^
             size_t(uint32_t(c[1])) * 0xC2B2AE3D27D4EB4Full ^ size_t(uint32_t(c[2]));
    }
  };
  Vec3d up_ = Vec3d::UnitY();  // against gravity, unit
  double g_ = 0.0;
  double dx_ = 1.0, half_spacing_ = 0.0;
  Vec3d origin_ = Vec3d::Zero();
  std::unordered_map<Cell, uint32_t, CellHash> index_;  // cell -> its entry below
  std::vector<float> highest_;  // per cell, its highest particle's height; then its body's level
  Cell cellOf(const Vec3f& x) const;
  double heightOf(const Vec3f& x) const { return up_.dot(x.cast<double>() - origin_); }
};

// Gives every particle of the world's objects that ask for a hydrostatic
// start (ObjectDesc::initial_pressure) the J of the pressure rho g depth
// under its body of water's level.
struct World;
void startHydrostatic(World& world, const WaterLevels& levels);

}  // namespace triad
