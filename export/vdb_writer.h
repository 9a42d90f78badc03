#pragma once
// OpenVDB volume caches (volumes/density.FFFF.vdb), as the cache contract says:
//
//   density  float, GRID_FOG_VOLUME: material density in kg/m^3 (mass per
//            voxel volume; not normalised to [0,1])
//   v        vec3s, GRID_UNKNOWN, VEC_CONTRAVARIANT_RELATIVE: mass-weighted
//            velocity in m/s, active where density is
//   surface  float, GRID_LEVEL_SET (optional): narrow-band signed distance in
//            metres to the union of particle spheres
//
// density and v are a trilinear (cloud-in-cell) splat of particle mass and
// momentum onto voxel centres, serial and in particle order: the weights of
// one particle sum to one, so the voxels hold the particles' total mass and
// momentum exactly (to float rounding), and the bytes depend only on the
// particles (a resumed run writes the same file as an uninterrupted one).
// surface uses OpenVDB's tools::ParticlesToLevelSet. Only vdb_writer.cpp
// includes OpenVDB.
#include <string>

#include "sim/world.h"

namespace triad {

struct VdbFrameInfo {
  int frame = 0;
  double time = 0.0;       // s
  std::string scene_name;
  double voxel_size = 0.0;  // density and v, m (> 0)
  bool surface = false;     // also write the level set `surface`
};

// Voxel size of the `surface` level set and the particle sphere radius, both
// in metres: the radius covers a particle's sampling cell, cbrt(rest volume)
// * sqrt(3)/2 (the largest over the sets), and the voxel is at most half the
// radius so that every sphere is at least 2 voxels wide (ParticlesToLevelSet
// skips spheres under 1.5 voxels).
struct SurfaceSampling {
  double radius = 0.0;
  double voxel_size = 0.0;
};
SurfaceSampling surfaceSampling(const World& world, double density_voxel_size);

// Writes the file atomically: OpenVDB writes a temporary file in the same
// directory, its per-write random UUID is replaced by one derived from the
// file's contents (so equal grids give equal bytes), and it is renamed to
// `path`. Throws std::runtime_error naming the file.
void writeVolumesVdb(const std::string& path, const World& world, const VdbFrameInfo& info);

// Opens a volume cache with OpenVDB and checks that it holds the grids
// `density` and `v`. Returns an empty string if so, else what is wrong.
std::string checkVolumesVdb(const std::string& path);

}  // namespace triad
