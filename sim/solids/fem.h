#pragma once
// Lagrangian finite elements for volumetric elastic solids (issue 5):
// linear tetrahedra, lumped masses, hyperelastic forces from the same
// material models as MPM (psi, P, dP/dF in sim/elastic_models.h), in
// double precision. This file holds the element mechanics and the explicit
// integrator; the implicit one is in sim/fem_implicit.cpp. Coupling to MPM
// goes through the solid's nodes as collision particles (coupling.md).
#include <memory>
#include <variant>
#include <vector>

#include "sim/materials/elastic_models.h"
#include "sim/math.h"
#include "sim/scene_desc.h"
#include "sim/solids/tet_mesh.h"

namespace triad {

using ElasticModel = std::variant<FixedCorotated<double>, NeoHookean<double>>;

// The elastic models FEM takes; throws InputError for the others.
ElasticModel makeElasticModel(const MaterialDesc& desc);

// dP/dF of the model at F assembled from its singular values' frame
// (Teran et al. 2005: a 3x3 block and three pairs of modes with closed-form
// eigenvalues); with `psd`, every negative eigenvalue set to zero, as the
// implicit solve's Newton step needs, at a fraction of a 9x9
// eigendecomposition's cost.
Mat9<double> svdFrameDerivative(const ElasticModel& model, const Mat3d& F, bool psd);

// Edge matrix [p1 - p0, p2 - p0, p3 - p0] of a tetrahedron.
Mat3d edges(const std::vector<Vec3d>& p, const std::array<int, 4>& n);

// One side of an obstacle near a node, for the implicit solve: the node
// ends the step with n . y >= b. Friction acts against the obstacle's
// velocity there.
struct NodePlane {
  int node = 0;
  Vec3d n = Vec3d::UnitY();  // unit, out of the obstacle
  double b = 0.0;
  Vec3d velocity = Vec3d::Zero();
  double friction = 0.0;
  double impulse = 0.0;                    // out: normal impulse the node received, N s
  Vec3d friction_impulse = Vec3d::Zero();  // out: and the friction's
};

// What the implicit solve keeps its nodes out of: the walls of the box
// [lo, hi] and planes of obstacles. Each is a one-sided quadratic penalty
// on the incremental potential, kappa m / dt^2 per node, which leaves a
// node 1 / (1 + kappa) of the penetration it would otherwise make; the
// solver's velocity clamps remove the rest. Friction is lagged: after the
// solve a node's tangential velocity loses up to mu times the normal
// velocity its contacts gave it.
struct FemContacts {
  bool walls = false;
  Vec3d lo = Vec3d::Zero(), hi = Vec3d::Zero();
  double wall_friction = 0.0;
  std::vector<NodePlane> planes;
  double kappa = 100.0;
};

struct ImplicitCache;  // sparsity pattern and symbolic factorisation (fem_implicit.cpp)

struct FemBody {
  TetMesh mesh;
  ElasticModel model;
  double density = 0.0;
  double wave_speed = 0.0;  // dilatational, sqrt((lambda + 2 mu) / rho)
  double min_height = 0.0;  // smallest element height at rest
  // Kelvin-Voigt viscosity, Pa s: a viscous stress 2 eta D beside the
  // elastic one, D the rate of deformation (explicit integration only).
  double damping = 0.0;

  std::vector<Vec3d> x, v;      // node positions and velocities
  std::vector<double> mass;     // lumped: a quarter of each element's mass
  std::vector<Mat3d> dm_inv;    // per element: inverse of the rest edge matrix
  std::vector<double> volume;   // per element: rest volume
  std::vector<char> pinned;     // nodes held in place (boundary conditions)
  mutable std::vector<Mat3d> h_;  // per element force matrices (scratch of forces())
  // Per node, the elements that hold it, as 4 t + its corner, in element
  // order (CSR, built by the first forces()): each node sums its forces on
  // its own, in the order a serial loop over the elements would.
  mutable std::vector<uint32_t> incidence_start_, incidence_;
  // Per group of eight elements: Dm^-1 (nine entries, each eight lanes)
  // and -V (eight lanes), built by the first forces(): what the
  // fixed-corotated forces read in vector lanes.
  mutable std::vector<double> dm_lanes_, minus_v_lanes_;
  // Elements whose F^-T the fixed-corotated lanes keep as they form the
  // forces (an elastic solid's node normals turn with one element each, and
  // forming its F again cost a tenth of the solid's step): per element its
  // slot or -1; what the last forces() kept, and whether it kept them.
  std::vector<int32_t> kept_slot_;
  mutable std::vector<Mat3d> kept_inv_t_;
  mutable bool kept_fresh_ = false;

  size_t nodes() const { return x.size(); }
  double totalMass() const;
  Vec3d centreOfMass() const;  // of the lumped node masses
  // Elastic forces on the nodes, -dE/dx, and with `damping` the viscous
  // forces of the velocities v: f is resized and overwritten.
  void forces(std::vector<Vec3d>& f) const;
  // The same at node positions y.
  void forcesAt(const std::vector<Vec3d>& y, std::vector<Vec3d>& f) const;
  // Elements whose F^-T forces() keeps when it can (fixed-corotated
  // elements without damping, formed in vector lanes).
  void keepInverseTransposes(const std::vector<int>& elements);
  // F^-T of element t as the last forces() formed it at x, or nullptr if
  // it kept none (another model, damping, or forcesAt since). Valid until x
  // moves.
  const Mat3d* keptInverseTranspose(size_t t) const;
  double elasticEnergy() const;
  double kineticEnergy() const;
  // Largest stable explicit step: cfl times the time a dilatational wave
  // takes to cross the smallest element height, and with `damping` the
  // viscous limit, cfl rho h^2 / (6 eta).
  double stableDt(double cfl) const;
  // Symplectic Euler: v += dt (f / m + g), then x += dt v; pinned nodes
  // keep their velocity zero.
  void stepExplicit(double dt, const Vec3d& gravity, std::vector<Vec3d>& scratch);
  // Backward Euler: the velocities v* = (x_new - x) / dt where x_new
  // minimises the incremental potential sum m/(2 dt^2) |x - x^|^2 + E(x),
  // x^ = x + dt v + dt^2 g, by Newton's method (element Hessians projected
  // to positive semi-definite, Eigen's sparse LDL^T, backtracking line
  // search), with the contacts' penalties when given. Positions are not
  // moved. Returns the Newton iterations taken.
  int implicitVelocities(double dt, const Vec3d& gravity, std::vector<Vec3d>& v_new,
                         FemContacts* contacts = nullptr) const;
  // Stiffness of element t at node positions y: d^2 E_t / dx^2 (12 x 12,
  // the element's nodes in order), the implicit solve's Hessian block;
  // `psd`: with dP/dF made positive semi-definite, as the solve uses it.
  Eigen::Matrix<double, 12, 12> elementStiffness(const std::vector<Vec3d>& y, size_t t,
                                                 bool psd = true) const;
  // Incremental potential at positions y (for the line search and tests).
  double incrementalPotential(const std::vector<Vec3d>& y, const std::vector<Vec3d>& target,
                              double dt, const FemContacts* contacts = nullptr) const;
  // Linear solves of the last implicit step: conjugate-gradient iterations
  // and whether the direct solver was used.
  struct SolveStats {
    int newton = 0, cg_iterations = 0, direct = 0;
  };
  SolveStats lastSolve() const;
  // The mass that a push along unit n at node i meets over the last
  // implicit step's dt, were its neighbours held: m_i + dt^2 n.H_ii n, H
  // the elements' stiffness there. An upper bound on what a push there
  // moves (free neighbours give way); the node's mass before any solve.
  double heldMassAlong(size_t i, const Vec3d& n, double dt) const;

  // Built on the first implicit step; shared by copies (same mesh).
  mutable std::shared_ptr<ImplicitCache> implicit_cache_;
};

FemBody makeFemBody(TetMesh mesh, const MaterialDesc& material);

}  // namespace triad
