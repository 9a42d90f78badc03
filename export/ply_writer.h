#pragma once
// PLY particle caches (binary little-endian), as the cache contract says:
// float x y z vx vy vz, int object, float J, plus int id (stable across frames).
#include <cstdint>
#include <string>
#include <vector>

#include "sim/world.h"

namespace triad {

void writeParticlesPly(const std::string& path, const World& world);

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
