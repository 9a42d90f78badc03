#pragma once
// Surfaces of MPM material built from its particles with OpenVDB: the
// narrow-band level set `surface` of the VDB cache, and the closed triangle
// meshes surfaces/MATERIAL.FFFF.ply that a renderer shades as water, sand or
// snow. OpenVDB stays out of this header (particle_level_set.h is the one
// that includes it, for export/'s own files).
#include <string>

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
SurfaceSampling surfaceSampling(const World& world, double density_voxel_size, int material = -1);

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
TriSurface materialSurfaceMesh(const World& world, int material,
                               const SurfaceMeshSettings& settings);

}  // namespace triad
