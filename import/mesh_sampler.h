#pragma once
// Mesh shapes as particles: a cache of loaded and voxelized meshes, the
// MeshSampler that buildWorld calls for `mesh` shapes of MPM objects, and
// collision particles of any shape (box, sphere, mesh) for rigid and
// elastic solids.
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "import/mesh_loader.h"
#include "import/mesh_volume.h"
#include "sim/solids/collision_particles.h"
#include "sim/mpm/sampling.h"
#include "sim/scene_desc.h"
#include "sim/world.h"

namespace triad {

// The signed distance field's voxel size is this fraction of domain.dx by
// default. dx/2 keeps sampled volumes within 1% of exact at 10 cells across
// (tests/test_mesh_import.cpp, bench/RESULTS.md "Voxelization cost").
inline constexpr double kDefaultVoxelRatio = 0.5;

struct MeshWarning {
  std::string file;  // the mesh file (resolved path)
  std::string text;  // one repair or oddity, e.g. "inconsistent winding: ..."
};

// A loaded mesh (world space, repaired) and its distance field.
struct MeshAsset {
  std::string file;  // resolved path, for messages
  MeshLoadResult load;
  std::shared_ptr<const MeshVolume> volume;
};

// Loads each mesh file once per placement (resolved path, scale, rotation,
// translation) and voxelizes it once per voxel grid (voxel size and the
// origin its voxel centres are aligned to). Thread-safe.
class MeshCache {
 public:
  // Throws InputError naming the file (see loadMesh).
  std::shared_ptr<const MeshAsset> get(const MeshDesc& mesh, double voxel_size,
                                       const Vec3d& origin = Vec3d::Zero());
  // The grid the samplers use for `domain`: voxel size voxel_ratio * dx,
  // centres on domain.min + (n + 1/2) voxel_size, which for voxel_ratio 1/2
  // are exactly the points of particles_per_cell = 8 and of collision
  // samples: no interpolation there.
  std::shared_ptr<const MeshAsset> get(const MeshDesc& mesh, const DomainDesc& domain,
                                       double voxel_ratio);

  size_t loads() const;          // files read and repaired
  size_t voxelizations() const;  // distance fields built
  // Warnings of every load so far, in load order (each mesh once). The caller
  // prints them, e.g. "<file>: warning: <text>".
  std::vector<MeshWarning> warnings() const;

 private:
  mutable std::mutex mutex_;
  std::map<std::string, std::shared_ptr<const MeshLoadResult>> loaded_;
  std::map<std::string, std::shared_ptr<const MeshAsset>> assets_;
  std::vector<MeshWarning> warnings_;
  size_t loads_ = 0, voxelizations_ = 0;
};

// The sampler buildWorld takes: the particles of the domain's cell lattice
// (cells x cellSampleOffsets(ppc), exactly as for boxes and spheres) where
// the mesh's signed distance is negative, inside the domain; deterministic.
// Throws InputError naming the mesh file when it cannot be read or lies
// entirely outside the domain. Voxel size: voxel_ratio * domain.dx.
MeshSampler makeMeshSampler(std::shared_ptr<MeshCache> cache,
                            double voxel_ratio = kDefaultVoxelRatio);

// Collision particles of a rigid or elastic solid of uniform `density`: the
// points domain.min + spacing (n + 1/2) inside the shape (for the default
// spacing dx/2, the same points as particles_per_cell = 8), each with the
// outward unit normal of the shape's signed distance field (analytic for
// boxes and spheres, the mesh's SDF gradient for meshes). A mesh is read
// through the domain's distance field (voxel_ratio dx), or through one at
// the spacing when that is finer.
//
// Why dx/2 by default: a grid node gets mass from a sample within 1.5 dx
// (quadratic B-spline support). With samples at most dx/2 apart along each
// axis, every point of the solid lies within dx/4 * sqrt(3) < dx/2 of a
// sample, so every node whose support overlaps the solid by more than about
// half a cell sees it, and thin parts down to about dx/2 thick still get
// samples. A scene object's `sample_spacing` (spacing > 0 here; the loader
// keeps it within [dx/8, dx]) trades that for cost or detail.
//
// Samples are not clipped to the domain (a body's mass properties are its
// own); a shape entirely outside the domain is an InputError (`where` names
// the mesh file; for primitives it is empty, for the caller to fill in).
CollisionSamples sampleCollision(const ShapeDesc& shape, const DomainDesc& domain,
                                 double density, MeshCache& cache,
                                 double voxel_ratio = kDefaultVoxelRatio, double spacing = 0.0);

// The SolidSampler buildWorld takes for rigid (and elastic) objects:
// sampleCollision plus the shape's surface (the loaded mesh, or
// primitiveSurface) in world space.
SolidSampler makeSolidSampler(std::shared_ptr<MeshCache> cache,
                              double voxel_ratio = kDefaultVoxelRatio);

// The SequenceLoader buildWorld takes for mesh-sequence colliders: every
// frame through loadMesh, each checked against frame 0's topology.
MeshFrames loadMeshSequence(const MeshDesc& sequence, int frames);

// buildWorld with both samplers over one mesh cache (a new one if null),
// keeping only what `share` keeps when it is given.
World buildSceneWorld(const SceneDesc& scene, std::shared_ptr<MeshCache> cache = nullptr,
                      ParticleShare* share = nullptr);

}  // namespace triad
