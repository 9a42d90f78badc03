#pragma once
// Surfaces of MPM material built from its particles with OpenVDB: the
// narrow-band level set `surface` of the VDB cache, and the closed triangle
// meshes surfaces/MATERIAL.FFFF.ply that a renderer shades as water, sand or
// snow. OpenVDB stays out of this header (particle_level_set.h is the one
// that includes it, for export/'s own files).
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "sim/solids/collision_particles.h"
#include "sim/world.h"

namespace triad {

// Voxel size of a particle level set and the particle sphere radius, both in
// metres: the radius covers a particle's sampling cell, cbrt(rest volume) *
// sqrt(3)/2 (the largest over the sets), and the voxel is at most half the
// radius so that every sphere is at least 2 voxels wide (ParticlesToLevelSet
// skips spheres under 1.5 voxels). `erosion` is how far the union of spheres
// lies outside the material on average: 0.261 sampling spacings (the
// smallest spacing over the sets), which puts a block's surface on its faces.
struct SurfaceSampling {
  double radius = 0.0;
  double voxel_size = 0.0;
  double erosion = 0.0;
};
// Over the particle sets of `material` (an index into the scene's materials),
// or of every material for -1. `density_voxel_size` bounds the voxel.
// `whole_counts`: each set's particle count in the whole world, where the
// world holds a share of them (a split run), else the sets' own.
SurfaceSampling surfaceSampling(const World& world, double density_voxel_size, int material = -1,
                                const std::vector<uint64_t>* whole_counts = nullptr);

// A particle level set made in parts, as the processes of a split run make
// it: each part rasterises the particles within levelSetReach of the
// region it owns (its own and those of other parts near it), with the
// whole world's sampling, and keeps the leaf nodes whose origin it owns.
// Each leaf's values depend only on particles within that reach, so the
// parts' leaves put together (levelSetFromLeaves) are particleLevelSet of
// every particle, byte for byte.
double levelSetReach(const SurfaceSampling& s, double half_width = 3.0);
std::vector<unsigned char> particleLevelSetLeaves(const World& world, const SurfaceSampling& s,
                                                  int material,
                                                  const std::function<bool(const Vec3d&)>& owns,
                                                  double half_width = 3.0);
// A level set's parts and the sampling they were made with.
struct LevelSetParts {
  SurfaceSampling sampling;
  std::vector<std::vector<unsigned char>> leaves;
};

// How a material's surface mesh is made from its level set: the level set
// is eroded by SurfaceSampling::erosion, smoothed by `smoothing` passes of
// a Gaussian filter one voxel wide, and meshed by OpenVDB's volume-to-mesh
// with `adaptivity` in [0, 1] (0: uniform quads, each split in two
// triangles; larger values merge flat regions into fewer polygons).
struct SurfaceMeshSettings {
  double voxel_size = 0.0;  // bound on the voxel (the cache's VDB voxel), m
  int smoothing = 1;
  double adaptivity = 0.0;
};

// The closed, outward-wound (counter-clockwise seen from outside) triangle
// surface of `material`'s particles, world space. Empty when the material
// has no particles.
// `made`: its level set made in parts (a split run's processes), in place
// of the world's particles.
TriSurface materialSurfaceMesh(const World& world, int material,
                               const SurfaceMeshSettings& settings,
                               const LevelSetParts* made = nullptr);

}  // namespace triad
