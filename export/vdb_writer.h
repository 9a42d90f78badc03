#pragma once
// OpenVDB volume caches (volumes/density.FFFF.vdb), as the cache contract says:
//
//   density  float, GRID_FOG_VOLUME: material density in kg/m^3 (mass per
//            voxel volume; not normalised to [0,1])
//   vel      vec3s, GRID_UNKNOWN, VEC_CONTRAVARIANT_RELATIVE: mass-weighted
//            velocity in m/s, active where density is
//   surface  float, GRID_LEVEL_SET (optional): narrow-band signed distance in
//            metres to the union of particle spheres, a true distance across
//            its band (3 voxels each side) and inactive inside
//
// density and vel are a trilinear (cloud-in-cell) splat of particle mass and
// momentum onto voxel centres: the weights of one particle sum to one, so
// the voxels hold the particles' total mass and momentum (to float
// rounding). The splat sums in fixed point (VoxelSum), so that its sums
// do not depend on the order of the particles: the bytes depend only on
// the particles, however a split run held them (a resumed run writes the
// same file as an uninterrupted one, any number of processes the same).
// surface is particleLevelSet's (particle_level_set.h).
#include <cstdint>
#include <string>
#include <vector>

#include "export/particle_surface.h"
#include "sim/world.h"

namespace triad {

struct VdbFrameInfo {
  int frame = 0;
  double time = 0.0;       // s
  std::string scene_name;
  double voxel_size = 0.0;  // density and vel, m (> 0)
  bool surface = false;     // also write the level set `surface`
};

// A voxel's splatted mass and momentum in fixed point: units of 1/scale.mass
// kg and 1/scale.momentum kg m/s, summed exactly.
struct VoxelSum {
  int32_t ijk[3];
  int32_t pad;
  int64_t m, p[3];
};
inline bool voxelBefore(const VoxelSum& a, const VoxelSum& b) {
  for (int d = 0; d < 3; ++d)
    if (a.ijk[d] != b.ijk[d]) return a.ijk[d] < b.ijk[d];
  return false;
}
// Units per kg and per kg m/s (powers of two), from the largest particle
// mass and the largest |momentum| along an axis of any particle: every
// process of a split run must take the same.
struct VolumeScale {
  double mass = 1.0, momentum = 1.0;
};
VolumeScale volumeScale(double max_mass, double max_momentum);
void largestMassAndMomentum(const World& world, double& mass, double& momentum);
// The world's particles splatted on voxels of size h, in voxel order.
std::vector<VoxelSum> splatVolumeSums(const World& world, double h, const VolumeScale& scale);
// Sorts `sums` and adds up the entries of each voxel (several processes' splats).
void addVolumeSums(std::vector<VoxelSum>& sums);

// Writes the file atomically: OpenVDB writes a temporary file in the same
// directory, its per-write random UUID is replaced by one derived from the
// file's contents (so equal grids give equal bytes), and it is renamed to
// `path`. Throws std::runtime_error naming the file.
void writeVolumesVdb(const std::string& path, const World& world, const VdbFrameInfo& info);
// The same from sums splatted already (by the processes of a split run);
// `world` serves the level set `surface` only, unless `surface` holds it
// made in parts (by the same processes).
void writeVolumesVdb(const std::string& path, const std::vector<VoxelSum>& sums,
                     const VolumeScale& scale, const World& world, const VdbFrameInfo& info,
                     const LevelSetParts* surface = nullptr);

// Opens a volume cache with OpenVDB and checks that it holds the grids
// `density` and `vel`. Returns an empty string if so, else what is wrong.
std::string checkVolumesVdb(const std::string& path);

}  // namespace triad
