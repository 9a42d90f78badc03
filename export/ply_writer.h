#pragma once
// PLY particle caches (binary little-endian), as the cache contract says:
// float x y z vx vy vz, int object, float J, plus int id (stable across frames).
#include <string>

#include "sim/world.h"

namespace triad {

void writeParticlesPly(const std::string& path, const World& world);

}  // namespace triad
