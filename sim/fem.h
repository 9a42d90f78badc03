#pragma once
// Lagrangian finite elements for volumetric elastic solids (issue 5):
// linear tetrahedra, lumped masses, hyperelastic forces from the same
// material models as MPM (psi, P, dP/dF in sim/elastic_models.h), in
// double precision. This file holds the element mechanics and the explicit
// integrator; coupling to MPM goes through the solid's nodes as collision
// particles (coupling.md), to be wired in with the implicit integrator.
#include <variant>
#include <vector>

#include "sim/elastic_models.h"
#include "sim/math.h"
#include "sim/scene_desc.h"
#include "sim/tet_mesh.h"

namespace triad {

using ElasticModel = std::variant<FixedCorotated<double>, NeoHookean<double>>;

// The elastic models FEM takes; throws InputError for the others.
ElasticModel makeElasticModel(const MaterialDesc& desc);

struct FemBody {
  TetMesh mesh;
  ElasticModel model;
  double density = 0.0;
  double wave_speed = 0.0;  // dilatational, sqrt((lambda + 2 mu) / rho)
  double min_height = 0.0;  // smallest element height at rest

  std::vector<Vec3d> x, v;      // node positions and velocities
  std::vector<double> mass;     // lumped: a quarter of each element's mass
  std::vector<Mat3d> dm_inv;    // per element: inverse of the rest edge matrix
  std::vector<double> volume;   // per element: rest volume
  std::vector<char> pinned;     // nodes held in place (boundary conditions)
  mutable std::vector<Mat3d> h_;  // per element force matrices (scratch of forces())

  size_t nodes() const { return x.size(); }
  double totalMass() const;
  // Elastic forces on the nodes, -dE/dx: f is resized and overwritten.
  void forces(std::vector<Vec3d>& f) const;
  // The same at node positions y.
  void forcesAt(const std::vector<Vec3d>& y, std::vector<Vec3d>& f) const;
  double elasticEnergy() const;
  double kineticEnergy() const;
  // Largest stable explicit step: cfl times the time a dilatational wave
  // takes to cross the smallest element height.
  double stableDt(double cfl) const;
  // Symplectic Euler: v += dt (f / m + g), then x += dt v; pinned nodes
  // keep their velocity zero.
  void stepExplicit(double dt, const Vec3d& gravity, std::vector<Vec3d>& scratch);
  // Backward Euler: the velocities v* = (x_new - x) / dt where x_new
  // minimises the incremental potential sum m/(2 dt^2) |x - x^|^2 + E(x),
  // x^ = x + dt v + dt^2 g, by Newton's method (element Hessians projected
  // to positive semi-definite, Eigen's sparse LDL^T, backtracking line
  // search). Positions are not moved. Returns the Newton iterations taken.
  int implicitVelocities(double dt, const Vec3d& gravity, std::vector<Vec3d>& v_new) const;
  // Incremental potential at positions y (for the line search and tests).
  double incrementalPotential(const std::vector<Vec3d>& y, const std::vector<Vec3d>& target,
                              double dt) const;
};

FemBody makeFemBody(TetMesh mesh, const MaterialDesc& material);

}  // namespace triad
