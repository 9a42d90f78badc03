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
// momentum onto voxel centres, serial and in particle order: the weights of
// one particle sum to one, so the voxels hold the particles' total mass and
// momentum exactly (to float rounding), and the bytes depend only on the
// particles (a resumed run writes the same file as an uninterrupted one).
// surface is particleLevelSet's (particle_level_set.h).
#include <string>

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

// Writes the file atomically: OpenVDB writes a temporary file in the same
// directory, its per-write random UUID is replaced by one derived from the
// file's contents (so equal grids give equal bytes), and it is renamed to
// `path`. Throws std::runtime_error naming the file.
void writeVolumesVdb(const std::string& path, const World& world, const VdbFrameInfo& info);

// Opens a volume cache with OpenVDB and checks that it holds the grids
// `density` and `vel`. Returns an empty string if so, else what is wrong.
std::string checkVolumesVdb(const std::string& path);

}  // namespace triad
