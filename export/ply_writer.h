#pragma once
// PLY particle caches (binary little-endian), as the cache contract says:
// float x y z vx vy vz, int object, float J, plus int id (stable across frames).
#include <cstdint>
#include <string>
#include <vector>

#include "sim/world.h"

namespace triad {

void writeParticlesPly(const std::string& path, const World& world);

// One particle as the file lists it, and the file's header for n particles
// at `time` (a split run's processes write their particles into one file).
#pragma pack(push, 1)
struct PlyParticle {
  float x, y, z, vx, vy, vz;
  int32_t object;
  float J;
  int32_t id;
};
#pragma pack(pop)
static_assert(sizeof(PlyParticle) == 36, "PLY vertex must be packed");
PlyParticle plyParticle(const ParticleSet& set, size_t i);
std::string particlesPlyHeader(size_t n, double time);

// Where each particle is: its set and its index in that set.
struct ParticleRef {
  uint32_t set = 0;
  size_t index = 0;
};
// Every particle of the world in increasing id, the order the particle caches
// list them in (the contract): tools that match points by index across
// frames see the same point, whatever order the solver keeps them in.
std::vector<ParticleRef> particlesById(const World& world);

}  // namespace triad
