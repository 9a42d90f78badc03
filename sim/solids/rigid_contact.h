#pragma once
// Contacts of rigid bodies with the domain walls and with each other,
// resolved by sequential impulses (accumulated, clamped normal impulses with
// a Coulomb cone) on the bodies' velocities before positions advance.
// Bodies touch MPM material only through the grids (coupling.h); here they
// touch what the grids cannot express: walls and other bodies.
#include <vector>

#include "sim/math.h"
#include "sim/solids/rigid_body.h"
#include "sim/scene_desc.h"

namespace triad {

struct ContactSettings {
  Vec3d lo = Vec3d::Zero(), hi = Vec3d::Ones();  // domain walls
  BoundaryType wall_type = BoundaryType::Slip;
  double wall_friction = 0.0;
  int iterations = 20;
  // Share of a penetration removed per step (by position, not velocity);
  // an open contact closes exactly (speculative contacts), so fast bodies
  // never pass a wall.
  double push_out = 0.5;
  // |g|, m/s^2: the position correction's passes stop once one changes no
  // contact's pseudo-velocity by more than 1e-4 of what gravity adds in the
  // step (0: all passes).
  double gravity = 0.0;
};

struct ContactStats {
  size_t wall_contacts = 0;
  size_t body_contacts = 0;
};

// One contact point between body a and body b (b = -1: a wall), normal n
// pointing from b towards a, and the gap along n (negative: penetration).
struct Contact {
  int a = -1, b = -1;
  Vec3d p = Vec3d::Zero();
  Vec3d n = Vec3d::Zero();
  double gap = 0.0;
  double mu = 0.0;  // < 0: no sliding (sticky walls)
  // A deforming collider's surface moves on its own: its velocity at p
  // (the side's body motion otherwise).
  bool own_a = false, own_b = false;
  Vec3d va = Vec3d::Zero(), vb = Vec3d::Zero();
};

// Contacts the bodies would make over the next dt with their current
// velocities: with the walls (every surface sample whose sphere of radius
// h/2 comes within reach of a wall) and between bodies (surface samples of
// one inside the sample lattice of the other, with the other's distance
// field reconstructed from its nearest sample).
std::vector<Contact> findContacts(const std::vector<RigidBody>& bodies, const ContactSettings& s,
                                  double dt);

// Changes the bodies' velocities so that no contact closes beyond its gap
// over dt and friction opposes sliding. Fixed bodies do not move.
ContactStats resolveContacts(std::vector<RigidBody>& bodies, const ContactSettings& s, double dt);

}  // namespace triad
