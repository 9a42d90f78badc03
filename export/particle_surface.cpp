#include "export/particle_surface.h"

#include "export/particle_level_set.h"

#include <openvdb/tools/Filter.h>
#include <openvdb/tools/VolumeToMesh.h>

#include <vector>

namespace triad {

TriSurface materialSurfaceMesh(const World& world, int material,
                               const SurfaceMeshSettings& settings, const LevelSetParts* made) {
  TriSurface out;
  const SurfaceSampling s =
      made ? made->sampling : surfaceSampling(world, settings.voxel_size, material);
  if (!(s.radius > 0.0)) return out;

  // Level set of the spheres, eroded onto the material's faces, smoothed.
  // The mesh needs only the values near the zero crossing, not a level set
  // kept a distance: the erosion is a shift of the band's values and the
  // smoothing a plain filter of them (LevelSetFilter would renormalise the
  // band after each, which costs more than building it).
  openvdb::FloatGrid::Ptr ls =
      made ? levelSetFromParts(*made) : particleLevelSet(world, s, material);
  const float erosion = float(s.erosion);
  for (auto it = ls->beginValueOn(); it; ++it) it.setValue(*it + erosion);
  if (settings.smoothing > 0) {
    openvdb::tools::Filter<openvdb::FloatGrid> filter(*ls);
    filter.gaussian(/*width=*/1, settings.smoothing);
  }

  // Mesh the zero crossing; quads become two triangles each.
  std::vector<openvdb::Vec3s> points;
  std::vector<openvdb::Vec3I> triangles;
  std::vector<openvdb::Vec4I> quads;
  openvdb::tools::volumeToMesh(*ls, points, triangles, quads, 0.0, settings.adaptivity);
  out.vertices.reserve(points.size());
  for (const openvdb::Vec3s& p : points) out.vertices.emplace_back(p.x(), p.y(), p.z());
  // OpenVDB winds its polygons clockwise seen from outside (Houdini's
  // convention); the cache's meshes are counter-clockwise, so each polygon's
  // order is reversed.
  out.triangles.reserve(triangles.size() + 2 * quads.size());
  for (const openvdb::Vec3I& t : triangles) out.triangles.push_back({t[2], t[1], t[0]});
  for (const openvdb::Vec4I& q : quads) {
    out.triangles.push_back({q[2], q[1], q[0]});
    out.triangles.push_back({q[3], q[2], q[0]});
  }
  return out;
}

}  // namespace triad
