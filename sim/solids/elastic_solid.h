#pragma once
// Volumetric elastic solids (issue 5): a voxel tetrahedral mesh whose nodes
// are the solid's collision particles (coupling.md), finite-element forces,
// and the imported surface embedded in the mesh for caches and previews.
#include <array>
#include <cstdint>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "sim/solids/collision_particles.h"
#include "sim/solids/fem.h"
#include "sim/solids/tet_mesh.h"

namespace triad {

struct ElasticSolid {
  int object = -1;  // index into SceneDesc::objects
  std::string name;
  float friction = 0.0f;  // Coulomb coefficient against MPM material
  bool implicit = false;  // backward Euler instead of symplectic Euler
  FemBody fem;
  // Per node: outward normal at rest (mean of its cells' SDF normals) and
  // one element it belongs to, whose deformation turns the normal.
  std::vector<Vec3d> normal0;
  std::vector<int> node_tet;
  // Per node: signed distance to the mesh's boundary at rest (0 on it, the
  // mean of its eight cells' sample distances inside), which the coupling
  // carries along the node's normal as it does a rigid sample's.
  std::vector<float> phi0;
  // The voxel cells at rest by lattice coordinates (mesh.cells[c] =
  // cells[0] + spacing * ijk): where the solid's boundary is, for contact
  // with other elastic solids (sim/elastic_contact.h).
  std::unordered_set<uint64_t> cell_keys;  // packBlock of the lattice index
  std::unordered_map<uint64_t, int> node_keys;  // corner lattice -> node
  Eigen::Vector3i cellIndex(const Vec3d& rest) const;
  bool hasCell(const Eigen::Vector3i& ijk) const;
  // The node at the lowest corner of cell ijk (so corners of cell c are
  // nodeAt(c + {0,1}^3)), or -1.
  int nodeAt(const Eigen::Vector3i& ijk) const;
  TriSurface surface;                 // at rest, world space
  std::vector<Embedding> embedding;   // per surface vertex

  // Outward normal of node i now: F^-T N, normalised.
  Vec3d normal(size_t i) const;
  // The same from the F^-T that the last fem.forces() kept, where it kept
  // one (only right after forces(), before the nodes move).
  Vec3d normalAfterForces(size_t i) const;
  // The surface moved with the mesh.
  TriSurface worldSurface() const;

 private:
  Vec3d turned(size_t i, const Mat3d& inv_t) const;  // F^-T N of node i, normalised
};

// The domain walls a solid spans from one to the other, along each axis
// (sim/world.cpp): its faces there are no surface.
struct SpannedWalls {
  std::array<bool, 3> axis{false, false, false};
  Vec3d min = Vec3d::Zero(), max = Vec3d::Zero();  // the domain's box
};

// Builds the solid from its collision samples (cells of side h centred on
// them), with an initial velocity. Nodes on spanned walls lie inside it.
ElasticSolid makeElasticSolid(int object, const std::string& name, const CollisionSamples& samples,
                              TriSurface surface, const MaterialDesc& material, double friction,
                              const Vec3d& velocity, const SpannedWalls& walls = {});

}  // namespace triad
