#pragma once
// The runtime state of a simulation, built from a SceneDesc in one place.
#include <cstdint>
#include <string>
#include <vector>

#include "sim/solids/collision_particles.h"
#include "sim/solids/elastic_solid.h"
#include "sim/mpm/particles.h"
#include "sim/solids/rigid_body.h"
#include "sim/mpm/sampling.h"
#include "sim/scene_desc.h"
#include "sim/shot/deforming.h"
#include "sim/shot/emitters.h"

namespace triad {

struct World {
  SceneDesc scene;
  std::vector<ParticleSet> sets;         // one per material (MPM objects)
  std::vector<RigidBody> bodies;         // rigid objects, in scene order
  std::vector<ElasticSolid> elastics;    // elastic objects, in scene order
  std::vector<Source> sources;           // MPM objects with emit, in scene order
  std::vector<Sink> sinks;               // sink objects, in scene order
  std::vector<size_t> object_particles;  // particle (or collision sample) count per scene object at t = 0
  uint32_t next_id = 0;                  // the id the next particle made takes
  // Built with a ParticleShare: per set, each particle's index in the set
  // the whole world would hold (the order one process holds them in), and
  // the whole world's particle count. Empty when the world is whole.
  std::vector<std::vector<uint64_t>> share_index;
  size_t whole_particles = 0;
  double time = 0.0;                     // simulated time, s
  int64_t steps = 0;                     // substeps taken

  size_t particleCount() const;
  size_t particleBytes() const;
};

// Under a run split over processes: which of the particles the scene makes
// at the start this process builds, so that no process holds the whole
// world's particles at once (dist/ provides one).
class ParticleShare {
 public:
  virtual ~ParticleShare() = default;
  // The positions of every particle the start makes (each MPM object's,
  // then the first particles of sources that start at once), before any
  // particle is built: fixes the share.
  virtual void plan(const std::vector<const std::vector<Vec3f>*>& positions) = 0;
  virtual bool keeps(const Vec3f& x) const = 0;
};

// Sample every object and group particles by material. Throws InputError
// (naming the object's key path) for what the scene asks but cannot be built.
// Mesh shapes are sampled through `mesh_sampler` (import/ provides one).
// Rigid objects get their collision particles and surface from
// `solid_sampler` (import/ provides one for every shape).
// Mesh-sequence colliders are read through `sequence_loader`. With `share`,
// only the particles it keeps are built (and `share_index` says which).
World buildWorld(const SceneDesc& scene, const MeshSampler& mesh_sampler = {},
                 const SolidSampler& solid_sampler = {}, const SequenceLoader& sequence_loader = {},
                 ParticleShare* share = nullptr);

}  // namespace triad
