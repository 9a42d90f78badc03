#include "export/vdb_writer.h"

#include "export/atomic_file.h"
#include "export/particle_level_set.h"

// OpenVDB (slow to compile) is included by this file and particle_level_set.cpp
// and particle_surface.cpp only.
#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <mutex>
#include <stdexcept>
#include <system_error>
#include <unistd.h>
#include <vector>

namespace triad {

namespace {

namespace fs = std::filesystem;
using openvdb::Coord;
using openvdb::FloatGrid;
using openvdb::Vec3SGrid;

void initOpenVdb() {
  static std::once_flag once;
  std::call_once(once, [] { openvdb::initialize(); });
}

// The metadata every grid (and the file) carries.
void addFrameMetadata(openvdb::MetaMap& meta, const VdbFrameInfo& info, const char* units) {
  meta.insertMeta("frame", openvdb::Int32Metadata(info.frame));
  meta.insertMeta("time", openvdb::DoubleMetadata(info.time));
  meta.insertMeta("scene", openvdb::StringMetadata(info.scene_name));
  if (units) meta.insertMeta("units", openvdb::StringMetadata(units));
}

// The grids of summed mass and momentum: momentum to velocity, mass to
// density, voxel by voxel. Returns {density in kg/m^3, mass-weighted
// velocity in m/s}.
std::pair<FloatGrid::Ptr, Vec3SGrid::Ptr> gridsOfSums(const std::vector<VoxelSum>& sums,
                                                      const VolumeScale& scale, double h) {
  FloatGrid::Ptr density = FloatGrid::create(0.0f);
  Vec3SGrid::Ptr velocity = Vec3SGrid::create(openvdb::Vec3s(0.0f));
  FloatGrid::Accessor da = density->getAccessor();
  Vec3SGrid::Accessor va = velocity->getAccessor();
  const double inv_volume = 1.0 / (h * h * h);
  for (const VoxelSum& v : sums) {
    const Coord ijk(v.ijk[0], v.ijk[1], v.ijk[2]);
    const double m = double(v.m) / scale.mass;
    da.setValue(ijk, float(m * inv_volume));
    openvdb::Vec3s u(0.0f);
    if (m > 0.0)
      for (int d = 0; d < 3; ++d) u[d] = float(double(v.p[d]) / scale.momentum / m);
    va.setValue(ijk, u);
  }
  return {density, velocity};
}

// 64-bit FNV-1a over a byte range, continuing from `h`.
uint64_t fnv1a(const char* p, size_t n, uint64_t h) {
  for (size_t i = 0; i < n; ++i) {
    h ^= static_cast<unsigned char>(p[i]);
    h *= 1099511628211ull;
  }
  return h;
}

// OpenVDB writes a random UUID into every file header (magic, file version,
// library version, has-grid-offsets flag, then 36 ASCII characters). Replace
// it with one derived from the rest of the file, so equal grids give equal
// files. Throws if the header is not laid out as expected.
void makeUuidDeterministic(const std::string& file) {
  constexpr size_t kUuidAt = 8 + 4 + 4 + 4 + 1, kUuidLen = 36;
  std::fstream io(file, std::ios::in | std::ios::out | std::ios::binary);
  std::vector<char> bytes((std::istreambuf_iterator<char>(io)), std::istreambuf_iterator<char>());
  if (bytes.size() < kUuidAt + kUuidLen) throw std::runtime_error("OpenVDB wrote a short file");
  for (size_t k = 0; k < kUuidLen; ++k) {
    const char c = bytes[kUuidAt + k];
    const bool dash = k == 8 || k == 13 || k == 18 || k == 23;
    if (dash ? c != '-' : !std::isxdigit(static_cast<unsigned char>(c)))
      throw std::runtime_error("unexpected OpenVDB header layout (no UUID at byte 21)");
  }
  uint64_t h1 = fnv1a(bytes.data(), kUuidAt, 1469598103934665603ull);
  h1 = fnv1a(bytes.data() + kUuidAt + kUuidLen, bytes.size() - kUuidAt - kUuidLen, h1);
  const uint64_t h2 = fnv1a(reinterpret_cast<const char*>(&h1), sizeof(h1), h1 ^ 0x9e3779b97f4a7c15ull);
  char uuid[40];
  std::snprintf(uuid, sizeof(uuid), "%08x-%04x-%04x-%04x-%012llx", unsigned(h1 >> 32),
                unsigned((h1 >> 16) & 0xffff), unsigned(h1 & 0xffff), unsigned(h2 >> 48),
                static_cast<unsigned long long>(h2 & 0xffffffffffffull));
  io.clear();
  io.seekp(std::streamoff(kUuidAt));
  io.write(uuid, std::streamsize(kUuidLen));
  io.flush();
  if (!io) throw std::runtime_error("cannot rewrite the header");
}

}  // namespace

VolumeScale volumeScale(double max_mass, double max_momentum) {
  // Each contribution is at most 2^46 units: a voxel may sum 2^17 of them
  // (a voxel of 4 cells at 8 particles a cell takes about 4,000).
  auto unit = [](double largest) {
    if (!(largest > 0.0) || !std::isfinite(largest)) return std::ldexp(1.0, 46);
    int e = 0;
    std::frexp(largest, &e);  // largest < 2^e
    return std::ldexp(1.0, 46 - e);
  };
  return {unit(max_mass), unit(max_momentum)};
}

void largestMassAndMomentum(const World& world, double& mass, double& momentum) {
  mass = momentum = 0.0;
  for (const ParticleSet& set : world.sets) {
    if (set.size() == 0) continue;
    mass = std::max(mass, double(set.mass));
    float v = 0.0f;
    for (const Vec3f& u : set.v) v = std::max(v, u.cwiseAbs().maxCoeff());
    momentum = std::max(momentum, double(set.mass) * double(v));
  }
}

std::vector<VoxelSum> splatVolumeSums(const World& world, double h, const VolumeScale& scale) {
  // Each voxel's place in `sums`, through a tree of indices.
  openvdb::Int32Grid::Ptr index = openvdb::Int32Grid::create(-1);
  openvdb::Int32Grid::Accessor ia = index->getAccessor();
  std::vector<VoxelSum> sums;
  const double inv_h = 1.0 / h;
  // Scatter each particle's mass and momentum to its 8 surrounding voxels.
  for (const ParticleSet& set : world.sets) {
    const double m = set.mass;
    for (size_t i = 0; i < set.size(); ++i) {
      int base[3];
      double w[3][2];
      for (int d = 0; d < 3; ++d) {
        const double g = double(set.x[i][d]) * inv_h;
        const double b = std::floor(g);
        base[d] = static_cast<int>(b);
        w[d][1] = g - b;
        w[d][0] = 1.0 - w[d][1];
      }
      double mv[3];
      for (int d = 0; d < 3; ++d) mv[d] = m * double(set.v[i][d]) * scale.momentum;
      for (int c = 0; c < 8; ++c) {
        const int a = (c >> 2) & 1, b = (c >> 1) & 1, e = c & 1;
        const double wc = w[0][a] * w[1][b] * w[2][e];
        if (wc <= 0.0) continue;  // a particle exactly on a voxel centre
        const Coord ijk(base[0] + a, base[1] + b, base[2] + e);
        int32_t k = ia.getValue(ijk);
        if (k < 0) {
          k = int32_t(sums.size());
          ia.setValue(ijk, k);
          sums.push_back({{ijk.x(), ijk.y(), ijk.z()}, 0, 0, {0, 0, 0}});
        }
        // Rounded to the nearest unit (an instruction, not a libm call).
        VoxelSum& v = sums[size_t(k)];
        v.m += int64_t(std::nearbyint(wc * m * scale.mass));
        for (int d = 0; d < 3; ++d) v.p[d] += int64_t(std::nearbyint(wc * mv[d]));
      }
    }
  }
  std::sort(sums.begin(), sums.end(), voxelBefore);
  return sums;
}

void addVolumeSums(std::vector<VoxelSum>& sums) {
  std::sort(sums.begin(), sums.end(), voxelBefore);
  size_t out = 0;
  for (size_t i = 0; i < sums.size(); ++i) {
    if (out > 0 && !voxelBefore(sums[out - 1], sums[i])) {
      VoxelSum& v = sums[out - 1];
      v.m += sums[i].m;
      for (int d = 0; d < 3; ++d) v.p[d] += sums[i].p[d];
    } else {
      sums[out++] = sums[i];
    }
  }
  sums.resize(out);
}

void writeVolumesVdb(const std::string& path, const World& world, const VdbFrameInfo& info) {
  double mass, momentum;
  largestMassAndMomentum(world, mass, momentum);
  const VolumeScale scale = volumeScale(mass, momentum);
  writeVolumesVdb(path, splatVolumeSums(world, info.voxel_size, scale), scale, world, info);
}

void writeVolumesVdb(const std::string& path, const std::vector<VoxelSum>& sums,
                     const VolumeScale& scale, const World& world, const VdbFrameInfo& info,
                     const LevelSetParts* made) {
  if (!(info.voxel_size > 0.0)) throw std::runtime_error(path + ": voxel size must be positive");
  initOpenVdb();

  // Density and velocity from one splat, on a transform shared by both.
  auto [density, velocity] = gridsOfSums(sums, scale, info.voxel_size);
  const openvdb::math::Transform::Ptr xform =
      openvdb::math::Transform::createLinearTransform(info.voxel_size);
  density->setTransform(xform);
  density->setName("density");
  density->setGridClass(openvdb::GRID_FOG_VOLUME);
  addFrameMetadata(*density, info, "kg/m^3");
  velocity->setTransform(xform);
  velocity->setName("vel");
  velocity->setGridClass(openvdb::GRID_UNKNOWN);
  velocity->setVectorType(openvdb::VEC_CONTRAVARIANT_RELATIVE);
  addFrameMetadata(*velocity, info, "m/s");
  openvdb::GridPtrVec grids{density, velocity};

  // The optional level set of the material's surface.
  if (info.surface) {
    const SurfaceSampling s = made ? made->sampling : surfaceSampling(world, info.voxel_size);
    FloatGrid::Ptr surface =
        made ? levelSetFromParts(*made) : particleLevelSet(world, s, /*material=*/-1);
    surface->setName("surface");
    addFrameMetadata(*surface, info, "m");
    surface->insertMeta("particle_radius", openvdb::DoubleMetadata(s.radius));
    grids.push_back(surface);
  }
  for (auto& g : grids) g->setCreator("triad 0.1.0");

  // Write beside the target, make the UUID deterministic, rename into place.
  openvdb::MetaMap file_meta;
  addFrameMetadata(file_meta, info, nullptr);
  writeFileViaTemporary(path, [&](const std::string& tmp) {
    openvdb::io::File file(tmp);
    file.write(grids, file_meta);
    file.close();
    makeUuidDeterministic(tmp);
  });
}

std::string checkVolumesVdb(const std::string& path) {
  initOpenVdb();
  try {
    openvdb::io::File file(path);
    file.open(/*delayLoad=*/false);
    std::string missing;
    for (const char* name : {"density", "vel"})
      if (!file.hasGrid(name)) missing += missing.empty() ? name : std::string(", ") + name;
    file.close();
    return missing.empty() ? std::string() : "no grid " + missing;
  } catch (const std::exception& e) {
    return e.what();
  }
}

}  // namespace triad
