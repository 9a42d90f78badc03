#pragma once
// The particle level set shared by the VDB writer and the surface meshes.
// Includes OpenVDB: only export/'s .cpp files include this header.
#include <openvdb/openvdb.h>

#include <functional>
#include <vector>

#include "export/particle_surface.h"

namespace triad {

// A narrow-band signed distance (negative inside, `half_width` voxels each
// side, voxel s.voxel_size) to the union of spheres of radius s.radius
// around the particles of `material` (-1: every material). The spheres are
// rasterised by OpenVDB's ParticlesToLevelSet, whose values inside the union
// are only distances to the nearest sphere (a few millimetres even deep in a
// bed of sand); the distance is solved again from that union's zero crossing
// (fast sweeping, tools::sdfToSdf) and cut to the band, so that it is a true
// distance across the band and inactive inside, where offsets and filters
// can use it.
// It is put together from its leaf nodes that hold an active value, as
// levelSetFromLeaves puts together a split run's (particle_surface.h).
openvdb::FloatGrid::Ptr particleLevelSet(const World& world, const SurfaceSampling& s, int material,
                                         double half_width = 3.0);

// The leaf nodes of `grid` that hold an active value and whose origin (world
// space) `keep` accepts, each as its origin, active mask and values.
std::vector<unsigned char> levelSetLeaves(const openvdb::FloatGrid& grid,
                                          const std::function<bool(const Vec3d&)>& keep);
// A narrow-band level set (voxel `voxel_size`, background half_width
// voxels) of the leaves of `parts` (levelSetLeaves'; no two holding the same
// leaf), the signs of the tiles between them flood-filled from them.
// Throws std::runtime_error on malformed parts.
// The same of a level set made in parts (particle_surface.h).
openvdb::FloatGrid::Ptr levelSetFromParts(const LevelSetParts& parts, double half_width = 3.0);
openvdb::FloatGrid::Ptr levelSetFromLeaves(
    const std::vector<const std::vector<unsigned char>*>& parts, double voxel_size,
    double half_width = 3.0);

}  // namespace triad
