#pragma once
// Rigid bodies: uniform density, mass properties from their collision
// particles, orientation as a quaternion, and a free-rotation integrator
// that conserves angular momentum exactly and energy to a bounded error.
//
// Frames: the rest frame is the world at t = 0 translated to the centre of
// mass. The principal frame diagonalises the inertia; the body's state is
// kept there (q_principal maps principal to world), which is what the
// splitting integrator needs. `orientation()` is the rotation from the rest
// frame, the identity at t = 0: what caches and renderers want.
#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "sim/math.h"
#include "sim/shot/animation.h"
#include "sim/shot/deforming.h"
#include "sim/solids/collision_particles.h"

namespace triad {

// What a checkpoint must keep of a body to continue it exactly.
struct RigidState {
  Vec3d x = Vec3d::Zero();                  // centre of mass, world
  Quatd q_principal = Quatd::Identity();    // principal frame -> world
  Vec3d v = Vec3d::Zero();                  // linear velocity
  Vec3d L = Vec3d::Zero();                  // angular momentum about the centre, world
};

// Where a body's distance can be found: its bounding sphere and, for a
// body of rigid samples, its sample lattice's box in the rest frame, which
// is much tighter for a long or flat body (a wall, a floor) whose sphere
// covers most of a scene. Both with a margin: a point or a sphere that
// misses them is certainly outside the lattice.
struct LatticeBox {
  Vec3d centre = Vec3d::Zero();  // the bounding sphere's
  double radius = 0.0;
  bool boxed = false;  // false: the sphere only (a deforming body)
  Mat3d to_rest = Mat3d::Identity();
  Vec3d lo = Vec3d::Zero(), hi = Vec3d::Zero();
  // Whether a point within `reach` of world point p may lie in the lattice.
  bool mayReach(const Vec3d& p, double reach) const {
    const double sphere = radius + reach;
    if ((p - centre).squaredNorm() > sphere * sphere) return false;
    if (!boxed) return true;
    const Vec3d rest = to_rest * (p - centre);
    return (lo - rest).cwiseMax(rest - hi).cwiseMax(0.0).squaredNorm() <= reach * reach;
  }
};

struct RigidBody {
  int object = -1;  // index into SceneDesc::objects
  std::string name;
  bool fixed = false;     // infinite mass: a fixed rigid body or a collider
  bool collider = false;  // a collider object (kind "collider")
  float friction = 0.0f;  // Coulomb coefficient against MPM material

  // An animated collider: its pose is the animation's at every time, its
  // centre (state.x) the shape's centroid as written moved by the pose.
  // `spin` is its angular velocity (zero for other fixed bodies).
  bool animated = false;
  Animation animation;
  Vec3d pivot = Vec3d::Zero();          // centroid of the shape as written
  Quatd rest_principal = Quatd::Identity();  // q_principal at t = 0
  Vec3d spin = Vec3d::Zero();
  // A deforming collider (a mesh sequence): its samples ride on the
  // sequence's surface (kept samples, in the order of r), and `surface`
  // follows it. Always animated (its animation may be the identity).
  std::shared_ptr<const DeformingSurface> deform;
  // Its samples as placed at the last pose (poseAt), world: what contacts
  // and the push-out query in place of the frame-0 lattice, and what the
  // coupling scatters.
  std::shared_ptr<PlacedSamples> placed;

  // Mass properties.
  double mass = 0.0;
  Vec3d moments = Vec3d::Ones();         // principal moments of inertia
  Quatd principal = Quatd::Identity();   // principal frame -> rest frame

  // Collision particles in the principal frame, relative to the centre of
  // mass; only those within kCouplingDepth of the surface are kept (deeper
  // ones never share a node with MPM material).
  std::vector<Vec3f> r;       // positions
  std::vector<Vec3f> n;       // outward unit normals
  std::vector<float> phi;     // signed distance to the surface (negative inside)
  float sample_mass = 0.0f;   // kg per sample
  float spacing = 0.0f;       // sample lattice spacing h
  float radius = 0.0f;        // largest |r| + h: bounding sphere about the centre (now, if deforming)

  // Lookup of samples by lattice cell in the rest frame, for contacts
  // between bodies: cell (i,j,k) of the box [cell_lo, cell_lo + cell_dims)
  // holds a sample index or -1.
  Vec3d lattice_origin = Vec3d::Zero();  // rest-frame position of cell (0,0,0)'s centre
  Eigen::Vector3i cell_dims = Eigen::Vector3i::Zero();
  std::vector<int32_t> cells;

  TriSurface surface;  // in the principal frame, relative to the centre of mass

  RigidState state;

  Mat3d rotation() const { return state.q_principal.toRotationMatrix(); }
  // Rotation from the rest frame to the world: identity at t = 0.
  Quatd orientation() const { return (state.q_principal * principal.conjugate()).normalized(); }
  // Angular velocity, world: omega = R I^-1 R^T L.
  Vec3d omega() const;
  // Kinetic energy, translational plus rotational.
  double kineticEnergy() const;
  // World-space velocity of the body at point p.
  Vec3d velocityAt(const Vec3d& p) const { return state.v + omega().cross(p - state.x); }
  // World inverse inertia applied to a vector.
  Vec3d applyInverseInertia(const Vec3d& a) const;
  // Apply an impulse j at world point p (no-op for fixed bodies).
  void applyImpulse(const Vec3d& j, const Vec3d& p);
  // Index of the sample whose lattice cell holds world point p, or -1.
  int sampleAt(const Vec3d& p) const;
  // The lattice cell that holds world point p, and the sample in a cell
  // (-1: none, or outside the lattice).
  Eigen::Vector3i latticeCell(const Vec3d& p) const;
  int sampleIn(const Eigen::Vector3i& cell) const;
  // The distance field near world point p, to first order from the sample
  // whose cell holds it: signed distance (negative inside) and outward
  // normal, with R = rotation(). False outside the bounding sphere or the
  // sample lattice (outside, or deeper than the kept samples).
  bool distanceAt(const Vec3d& p, const Mat3d& R, double& phi_out, Vec3d& n_out) const;
  // Where distanceAt can answer, as a box for quick rejects (see LatticeBox).
  LatticeBox latticeBox() const;
  // The sample whose plane (its distance carried along its normal) lies
  // furthest out at world point p, among those of the 27 lattice cells
  // around p's, or -1: the body's surface as the envelope of its samples'
  // planes, which moves continuously with p where the nearest sample's
  // plane jumps from one sample to the next (a ball sampled 4 across).
  int supportAt(const Vec3d& p, const Mat3d& R) const;
  // The envelope's distance at world point p (supportAt's plane), with the
  // normal blended over the planes that lie within a quarter of the sample
  // spacing of it: where several samples' planes nearly tie (under a
  // ball's lowest point, four samples tilted along the diagonals), the
  // envelope's own normal is the tilt of whichever wins by rounding.
  // Returns supportAt's sample (whose velocity is a deforming collider's
  // surface velocity there), or -1 where it finds none.
  int envelopeAt(const Vec3d& p, const Mat3d& R, double& phi_out, Vec3d& n_out) const;
  // Sample q as it is now, world: position, outward normal, velocity. A
  // deforming collider's are where its surface has carried them.
  Vec3d samplePosition(size_t q, const Mat3d& R) const;
  Vec3d sampleNormal(size_t q, const Mat3d& R) const;
  Vec3d sampleVelocity(size_t q, const Mat3d& R) const;
  // The surface's velocity at world point p, whose envelope sample is q
  // (from supportAt or envelopeAt): the body's motion at p, or a deforming
  // collider's sample's own velocity.
  Vec3d surfaceVelocity(int q, const Vec3d& p, const Mat3d& R) const {
    return placed ? sampleVelocity(size_t(q), R) : velocityAt(p);
  }
  // distanceAt's distance and normal from the envelope sample (supportAt),
  // and the surface's velocity there: the body's motion at p, or a
  // deforming collider's sample's own velocity.
  bool surfaceAt(const Vec3d& p, const Mat3d& R, double& phi_out, Vec3d& n_out,
                 Vec3d& v_out) const;

  // An animated body: pose, velocity and spin at time t; a deforming one's
  // surface too.
  void poseAt(double t);

  // Advance position and orientation over dt with the current velocities:
  // x += v dt, and the free rotation by a symmetric splitting into rotations
  // about the principal axes (Dullweber, Leimkuhler, McLachlan 1997), which
  // keeps |L| exactly and the energy within a bounded error.
  void advance(double dt);
};

// Collision particles deeper than this many cells below the surface are
// dropped: a grid node reaches 1.5 cells, so they can only share nodes with
// MPM material that has already passed through the surface layer.
constexpr double kCouplingDepth = 3.0;

// Builds a body from its samples (world positions at t = 0): mass
// properties, principal frame, sample lattice, and the initial state from
// velocity and angular velocity (world). `surface` is in world space.
RigidBody makeRigidBody(int object, const std::string& name, const CollisionSamples& samples,
                        TriSurface surface, bool fixed, double friction, const Vec3d& velocity,
                        const Vec3d& angular_velocity, double dx);

// Makes world point c (at t = 0) the body's reference point instead of its
// centre of mass: state.x, the samples, the lattice and the surface move
// with it. For colliders, whose torque is about their animated centroid and
// whose mass plays no part.
void recentre(RigidBody& body, const Vec3d& c);

// World-space surface of a body now (for caches and previews).
TriSurface worldSurface(const RigidBody& body);

}  // namespace triad
