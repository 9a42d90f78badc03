#include "export/ply_writer.h"

#include <algorithm>
#include <cstring>
#include <sstream>
#include <utility>
#include <vector>

#include "export/atomic_file.h"

namespace triad {

PlyParticle plyParticle(const ParticleSet& set, size_t i) {
  const Vec3f& x = set.x[i];
  const Vec3f& v = set.v[i];
  return {x.x(),
          x.y(),
          x.z(),
          v.x(),
          v.y(),
          v.z(),
          int32_t(set.object[i]),
          set.volumeRatio(i),
          int32_t(set.id[i])};
}

std::string particlesPlyHeader(size_t n, double time) {
  std::ostringstream out;
  out << "ply\nformat binary_little_endian 1.0\n"
      << "comment triad particles t=" << time << "\n"
      << "element vertex " << n << "\n"
      << "property float x\nproperty float y\nproperty float z\n"
      << "property float vx\nproperty float vy\nproperty float vz\n"
      << "property int object\nproperty float J\nproperty int id\n"
      << "end_header\n";
  return out.str();
}

std::vector<ParticleRef> particlesById(const World& world) {
  // Ids are unique, so the order is total.
  std::vector<std::pair<uint32_t, ParticleRef>> keyed;
  keyed.reserve(world.particleCount());
  for (size_t s = 0; s < world.sets.size(); ++s)
    for (size_t i = 0; i < world.sets[s].size(); ++i)
      keyed.push_back({world.sets[s].id[i], ParticleRef{uint32_t(s), i}});
  std::sort(keyed.begin(), keyed.end(),
            [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<ParticleRef> out;
  out.reserve(keyed.size());
  for (const auto& k : keyed) out.push_back(k.second);
  return out;
}

void writeParticlesPly(const std::string& path, const World& world) {
  static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "PLY writer assumes little-endian");
  const size_t n = world.particleCount();
  writeFileAtomically(path, [&](std::ostream& out) {
    out << particlesPlyHeader(n, world.time);
    const std::vector<ParticleRef> order = particlesById(world);
    // Stream in chunks to bound the temporary memory.
    std::vector<PlyParticle> chunk;
    chunk.reserve(65536);
    for (const ParticleRef& r : order) {
      chunk.push_back(plyParticle(world.sets[r.set], r.index));
      if (chunk.size() == chunk.capacity()) {
        out.write(reinterpret_cast<const char*>(chunk.data()),
                  std::streamsize(chunk.size() * sizeof(PlyParticle)));
        chunk.clear();
      }
    }
    out.write(reinterpret_cast<const char*>(chunk.data()),
              std::streamsize(chunk.size() * sizeof(PlyParticle)));
  });
}

}  // namespace triad
