// The solver's steps for elastic solids: their velocities before the grid
// (explicit forces, or the implicit solve against walls and rigid bodies),
// their constraints after it, and their motion.

#include <algorithm>
#include <cmath>
#include <optional>
#include <sstream>

#include "sim/errors.h"
#include "sim/phase_timer.h"
#include "sim/solver.h"

namespace triad {

void Solver::predictElastic(ElasticSolid& e, double dt, const Vec3d& g) {
  SolidsTimes& parts = times_.solid_parts;
  FemBody& fem = e.fem;
  std::optional<PhaseTimer> part(std::in_place, parts.elastic_forces);
  if (e.implicit) {
    FemContacts contacts = elasticContacts(e, dt);
    solveAgainstBodies(e, dt, g, contacts);
    fem.v.swap(fem_force_);
  } else {
    fem.forces(fem_force_);
    for (size_t i = 0; i < fem.nodes(); ++i) fem.v[i] += dt * (fem_force_[i] / fem.mass[i] + g);
  }
  part.emplace(parts.poses);
  points_.addSolid(0.0f, e.friction, SolidKind::Moving, 0.0);
  // Each node carries its distance at rest along its normal now, as a
  // rigid sample does: the distance's normal and the contact reach apply
  // to elastic solids too (with the summed normals a jelly dropped on sand
  // came to rest 0.35 dx off it). The collision gives them no gap.
  const size_t first = points_.size(), nodes = fem.nodes();
  for (auto* a : {&points_.x, &points_.v, &points_.n}) a->resize(first + nodes);
  points_.phi.resize(first + nodes);
  points_.point_mass.resize(first + nodes);
  // The deformed normals turn with F^-T, which the explicit forces above
  // kept for the elements that turn them.
#pragma omp parallel for schedule(static) if (nodes > 2048)
  for (int64_t i = 0; i < int64_t(nodes); ++i) {
    const size_t q = first + size_t(i);
    points_.x[q] = fem.x[size_t(i)].cast<float>();
    points_.v[q] = fem.v[size_t(i)].cast<float>();
    points_.n[q] = e.normalAfterForces(size_t(i)).cast<float>();
    points_.phi[q] = e.phi0[size_t(i)];
    points_.point_mass[q] = float(fem.mass[size_t(i)]);
  }
}

namespace {

// One moving body's side of the block Gauss-Seidel between an implicit
// solid and the rigid bodies it touches: the velocities its contact planes
// move with, and the Aitken relaxation that takes them towards what the
// body takes from the solve (Kuettler & Wall 2008).
struct BodyRelaxation {
  RigidState assumed;
  Eigen::Matrix<double, 6, 1> r = Eigen::Matrix<double, 6, 1>::Zero();
  double omega = 1.0;
  bool started = false;
  // Over the nodes it pushed in the first pass: their held masses, and its
  // inverse mass at them weighted by their impulses.
  double held_mass = 0.0, weighted_inverse = 0.0, impulse = 0.0;
};

}  // namespace

void Solver::solveAgainstBodies(ElasticSolid& e, double dt, const Vec3d& g, FemContacts& contacts) {
  FemBody& fem = e.fem;
  // The bodies take the reaction of the contacts in the solve. A body that
  // moves is pushed back in turn, so its planes move on with the velocity
  // it would take and the solid is solved again until the two agree (block
  // Gauss-Seidel): one staggered pass would let a stiff solid be squeezed
  // by the body's full approach and then throw it back with more energy
  // than it came with. A body lighter than the nodes it pushes would
  // take, by the plain iteration, more than their whole approach: the
  // planes would leave the nodes behind and the next pass push nothing,
  // the passes alternating between the two (a light ball on a coarse jelly
  // was thrown up by each step's last pass). So each pass moves the planes
  // only part way: first by the share that an inelastic collision with
  // the pushed nodes would give the body, their mass taken as what they
  // meet with their neighbours held (FemBody::heldMassAlong, an upper
  // bound, so that the first move falls short of agreement rather than
  // past the point where the contact lets go), then by Aitken's secant on
  // the body's residual, exact while the contacts stay the same. Two or
  // three solves a step agree within a hundredth of the change.
  bool dynamic = false;
  for (const auto& cb : contact_bodies_) dynamic |= !world_.bodies[cb.second].fixed;
  const size_t nb = world_.bodies.size();
  std::vector<RigidState> before;
  for (const RigidBody& b : world_.bodies) before.push_back(b.state);
  std::vector<BodyRelaxation> relax(nb);
  for (size_t k = 0; k < nb; ++k) relax[k].assumed = before[k];
  // The residual of body k: what it took less what its planes assumed, its
  // turning as the speed at its bounding radius.
  auto residual = [&](size_t k) {
    const RigidBody& b = world_.bodies[k];
    Eigen::Matrix<double, 6, 1> r;
    r.head<3>() = b.state.v - relax[k].assumed.v;
    r.tail<3>() = double(b.radius) * b.applyInverseInertia(b.state.L - relax[k].assumed.L);
    return r;
  };
  for (int pass = 0;; ++pass) {
    fem.implicitVelocities(dt, g, fem_force_, &contacts);
    for (size_t k = 0; k < nb; ++k) world_.bodies[k].state = before[k];
    for (const auto& [plane, body] : contact_bodies_)
      if (contacts.planes[plane].impulse > 0.0) {
        // At the surface point, on the normal's line: a sphere's normal
        // impulse has no moment about its centre.
        const NodePlane& pl = contacts.planes[plane];
        world_.bodies[body].applyImpulse(-(pl.impulse * pl.n + pl.friction_impulse),
                                         contact_surface_[plane]);
      }
    // Agreed when every body's residual is a small part of the change the
    // contacts made to it.
    bool agreed = true;
    for (size_t k = 0; k < nb && dynamic; ++k) {
      const RigidBody& b = world_.bodies[k];
      if (b.fixed) continue;
      const double change =
          (b.state.v - before[k].v).norm() +
          double(b.radius) * b.applyInverseInertia(b.state.L - before[k].L).norm();
      agreed = agreed && residual(k).norm() <= kContactAgreement * change + 1e-9;  // m/s
    }
    if (agreed || pass == kMaxContactPasses - 1) break;
    if (pass == 0)
      for (const auto& [plane, body] : contact_bodies_) {
        const NodePlane& pl = contacts.planes[plane];
        const RigidBody& b = world_.bodies[body];
        if (b.fixed || pl.impulse <= 0.0 || fem.pinned[size_t(pl.node)]) continue;
        const Vec3d arm = (contact_surface_[plane] - b.state.x).cross(pl.n);
        BodyRelaxation& rk = relax[body];
        rk.held_mass += fem.heldMassAlong(size_t(pl.node), pl.n, dt);
        rk.weighted_inverse += pl.impulse * (1.0 / b.mass + arm.dot(b.applyInverseInertia(arm)));
        rk.impulse += pl.impulse;
      }
    for (size_t k = 0; k < nb; ++k) {
      BodyRelaxation& rk = relax[k];
      if (world_.bodies[k].fixed) continue;
      const Eigen::Matrix<double, 6, 1> r = residual(k);
      if (!rk.started) {
        const double w = rk.impulse > 0.0 ? rk.weighted_inverse / rk.impulse : 0.0;
        rk.omega = 1.0 / (1.0 + rk.held_mass * w);
      } else {
        const Eigen::Matrix<double, 6, 1> dr = r - rk.r;
        const double dr2 = dr.squaredNorm();
        if (dr2 > 0.0) rk.omega = std::clamp(-rk.omega * rk.r.dot(dr) / dr2, 0.01, 1.0);
      }
      rk.started = true;
      rk.r = r;
      const RigidState& took = world_.bodies[k].state;
      rk.assumed.v += rk.omega * (took.v - rk.assumed.v);
      rk.assumed.L += rk.omega * (took.L - rk.assumed.L);
    }
    // The planes move with the velocities assumed now.
    for (const auto& [plane, body] : contact_bodies_) {
      RigidBody& b = world_.bodies[body];
      if (b.fixed) continue;  // moved by nothing here
      NodePlane& pl = contacts.planes[plane];
      const Vec3d surface = contact_surface_[plane];
      const RigidState took = b.state;
      b.state = relax[body].assumed;
      pl.velocity = b.velocityAt(surface);
      b.state = took;
      pl.b = pl.n.dot(surface + dt * pl.velocity);
    }
  }
  for (const auto& [plane, body] : contact_bodies_)
    if (contacts.planes[plane].impulse > 0.0) {
      const NodePlane& pl = contacts.planes[plane];
      addLoad(body, -(pl.impulse * pl.n + pl.friction_impulse), contact_surface_[plane]);
    }
}

double Solver::wallFriction() const {
  const BoundaryDesc& wall = world_.scene.domain.boundary;
  return wall.type == BoundaryType::Sticky ? 1e30 : wall.friction;
}

FemContacts Solver::elasticContacts(const ElasticSolid& e, double dt) {
  const FemBody& fem = e.fem;
  FemContacts c;
  c.walls = true;
  c.lo = contact_.lo;
  c.hi = contact_.hi;
  c.wall_friction = wallFriction();
  // Rigid bodies: a node headed inside one meets the plane of its surface
  // there (the envelope of the samples' planes, its normal blended where
  // they nearly tie), moved on by the body's velocity over the step.
  contact_bodies_.clear();
  contact_surface_.clear();
  for (size_t k = 0; k < world_.bodies.size(); ++k) {
    const RigidBody& b = world_.bodies[k];
    const Mat3d R = b.rotation();
    const double mu = std::sqrt(double(e.friction) * double(b.friction));
    for (size_t i = 0; i < fem.nodes(); ++i) {
      const Vec3d y = fem.x[i] + dt * fem.v[i];
      if ((y - b.state.x).squaredNorm() > double(b.radius) * b.radius) continue;
      double phi;
      Vec3d n;
      const int q = b.envelopeAt(y, R, phi, n);
      if (q < 0) continue;
      NodePlane& pl = c.planes.emplace_back();
      pl.node = int(i);
      pl.n = n;
      const Vec3d surface = y - phi * n;
      // A deforming collider's surface moves as its sample does.
      pl.velocity = b.surfaceVelocity(q, surface, R);
      // A node already inside stays no deeper, rather than being thrown out
      // with the velocity of its whole penetration (which would add energy):
      // moveElastic moves it out, position only.
      const double depth = std::max(0.0, pl.n.dot(surface - fem.x[i]));
      pl.b = pl.n.dot(surface + dt * pl.velocity) - depth;
      pl.friction = mu;
      contact_bodies_.emplace_back(c.planes.size() - 1, k);
      contact_surface_.push_back(surface - depth * pl.n);
    }
  }
  return c;
}

void Solver::constrainElastic(ElasticSolid& e, size_t first, double dt) {
  FemBody& fem = e.fem;
  const int64_t nodes = int64_t(fem.nodes());
  // Each node on its own (in parallel: a solid of a few thousand nodes took
  // a serial stretch long enough for the other threads to fall asleep):
  // what the grid gave it (step 8), then the walls. A node may close at
  // most its gap to a wall in this step (as rigid samples do); the normal
  // velocity it loses bounds its friction.
  const double mu = wallFriction();
#pragma omp parallel for schedule(static) if (nodes > 2048)
  for (int64_t i = 0; i < nodes; ++i) {
    Vec3d& v = fem.v[size_t(i)];
    v += points_.dv[first + size_t(i)].cast<double>();
    for (int d = 0; d < 3; ++d)
      for (int side = 0; side < 2; ++side) {
        const double sign = side == 0 ? 1.0 : -1.0;  // inward normal along axis d
        const double gap =
            side == 0 ? fem.x[size_t(i)][d] - contact_.lo[d] : contact_.hi[d] - fem.x[size_t(i)][d];
        const double vn = sign * v[d];
        const double limit = -std::max(0.0, gap) / dt;
        if (vn >= limit) continue;
        v[d] += sign * (limit - vn);
        Vec3d vt = v;
        vt[d] = 0.0;
        const double speed = vt.norm();
        if (speed > 0.0) {
          const double keep = std::max(0.0, speed - mu * (limit - vn)) / speed;
          for (int a = 0; a < 3; ++a)
            if (a != d) v[a] *= keep;
        }
      }
  }
  // Rigid bodies: a node that would end the step inside one (against the
  // body's surface moved on by its velocity) meets it in an inelastic
  // collision that ends it on the surface, the impulse shared by the
  // node's and the body's inverse masses at the node (the body's turning
  // included), its sliding reduced by Coulomb friction (the pair's
  // geometric mean) within what the push bounds. (Implicit solids met them
  // in their solve.) Pushing the node against the body's pose alone, the
  // body taking its whole change, threw a body lighter than the nodes under
  // it off them, and against a body lifting off the nodes that followed it
  // pushed it on: a ball dropped on a jelly bounced higher than it fell.
  // The nodes inside are found in parallel. Their pushes are then solved
  // together by projected Gauss-Seidel on accumulated impulses (normal ones
  // never pulling, friction within the Coulomb disc), sweeping the nodes
  // forwards and backwards until the pushes settle. One pass in node order,
  // each node against the body's velocity the ones before it left, let the
  // first nodes under a light body take all its approach: a 5 g cube
  // dropped flat on a jelly slab left with 0.1 m/s sideways and tilted 8°.
  for (size_t k = 0; k < world_.bodies.size() && !e.implicit; ++k) {
    RigidBody& b = world_.bodies[k];
    const Mat3d R = b.rotation();
    const double mu_pair = std::sqrt(double(e.friction) * double(b.friction));
    // The depth from the envelope of the samples' planes round x, which
    // answers in the cells just outside the samples too: the nearest
    // sample's plane alone answers only in cells that hold a sample, and a
    // node came into such a cell up to a cell deep, to be thrown out.
    auto depthAt = [&](const Vec3d& x, Vec3d& n, Vec3d& vb) {
      double phi;
      const int q = b.envelopeAt(x, R, phi, n);
      if (q < 0) return 0.0;
      vb = b.surfaceVelocity(q, x, R);
      return dt * vb.dot(n) - phi;
    };
    std::vector<uint32_t> inside;
#pragma omp parallel if (nodes > 2048)
    {
      std::vector<uint32_t> mine;
#pragma omp for schedule(static) nowait
      for (int64_t i = 0; i < nodes; ++i) {
        Vec3d n, vb;
        if (depthAt(fem.x[size_t(i)] + dt * fem.v[size_t(i)], n, vb) > 0.0)
          mine.push_back(uint32_t(i));
      }
#pragma omp critical
      inside.insert(inside.end(), mine.begin(), mine.end());
    }
    std::sort(inside.begin(), inside.end());
    // Each push's plane, depth and velocities where it was found: the depth
    // changes with them linearly while the same plane holds.
    struct Push {
      uint32_t node;
      Vec3d x, n, v0, vb0;
      double depth0, inv_node, inv_n = 0.0;  // inv_n: along n, node and body
      double jn = 0.0;
      Vec3d jt = Vec3d::Zero();
    };
    // The inverse mass that an impulse along d at p's point meets (the
    // body's inertia stays as it is while the pushes are solved).
    auto inverseMass = [&](const Push& p, const Vec3d& d) {
      const Vec3d a = (p.x - b.state.x).cross(d);
      return p.inv_node + (b.fixed ? 0.0 : 1.0 / b.mass + a.dot(b.applyInverseInertia(a)));
    };
    std::vector<Push> pushes;
    double fastest = 0.0;  // the largest approach to remove, m/s
    for (const uint32_t i : inside) {
      Push p;
      p.node = i;
      p.x = fem.x[i] + dt * fem.v[i];
      p.depth0 = depthAt(p.x, p.n, p.vb0);
      p.v0 = fem.v[i];
      if (p.depth0 <= 0.0) continue;
      p.inv_node = fem.pinned[i] ? 0.0 : 1.0 / fem.mass[i];
      p.inv_n = inverseMass(p, p.n);
      fastest = std::max(fastest, p.depth0 / dt);
      if (p.inv_n > 0.0) pushes.push_back(p);  // not a pinned node on a fixed body
    }
    auto bodyVelocity = [&](const Push& p) { return b.placed ? p.vb0 : b.velocityAt(p.x); };
    auto apply = [&](const Push& p, const Vec3d& j) {  // j onto the node
      fem.v[p.node] += p.inv_node * j;
      b.applyImpulse(-j, p.x);
    };
    for (int sweep = 0; sweep < kMaxElasticContactSweeps && !pushes.empty(); ++sweep) {
      double change = 0.0;
      for (size_t m = 0; m < pushes.size(); ++m) {
        Push& p = pushes[sweep % 2 == 0 ? m : pushes.size() - 1 - m];
        // Normal: end the step on the surface, never pulling.
        const Vec3d& v = fem.v[p.node];
        const double depth = p.depth0 - dt * p.n.dot((v - p.v0) - (bodyVelocity(p) - p.vb0));
        const double jn = std::max(0.0, p.jn + depth / dt / p.inv_n);
        apply(p, (jn - p.jn) * p.n);
        change = std::max(change, std::abs(jn - p.jn) * p.inv_n);
        p.jn = jn;
        // Friction: stop the sliding, within mu times the normal push.
        const Vec3d u = fem.v[p.node] - bodyVelocity(p);
        const Vec3d ut = u - u.dot(p.n) * p.n;
        const double slide = ut.norm();
        if (slide <= 0.0) continue;
        const Vec3d t = ut / slide;
        Vec3d jt = p.jt - (slide / inverseMass(p, t)) * t;
        if (jt.norm() > mu_pair * p.jn) jt *= mu_pair * p.jn / jt.norm();
        apply(p, jt - p.jt);
        change = std::max(change, (jt - p.jt).norm() * inverseMass(p, t));
        p.jt = jt;
      }
      if (change <= 1e-3 * fastest) break;
    }
    for (const Push& p : pushes) addLoad(k, -(p.jn * p.n + p.jt), p.x);
  }
}

void Solver::moveElastic(ElasticSolid& e, double dt) {
  FemBody& fem = e.fem;
  const int64_t nodes = int64_t(fem.nodes());
  int64_t bad = nodes;  // the first node that became non-finite
#pragma omp parallel for schedule(static) reduction(min : bad) if (nodes > 2048)
  for (int64_t i = 0; i < nodes; ++i) {
    fem.x[size_t(i)] += dt * fem.v[size_t(i)];
    if (!std::isfinite(fem.x[size_t(i)].sum() + fem.v[size_t(i)].sum())) bad = std::min(bad, i);
  }
  if (bad < nodes) {
    std::ostringstream msg;
    msg << "step " << world_.steps + 1 << " at t = " << world_.time << " s: elastic object '"
        << e.name << "' became non-finite at node " << bad;
    throw SimulationError(msg.str());
  }
  // Implicit solids: what penetration the contact penalty left (a small
  // fraction) and what a moving body made after the solve is removed by
  // moving the node, not by giving it velocity.
  if (!e.implicit) return;
  for (const RigidBody& b : world_.bodies) {
    const Mat3d R = b.rotation();
    for (size_t i = 0; i < fem.nodes(); ++i) {
      double phi;
      Vec3d n;
      if (b.distanceAt(fem.x[i], R, phi, n) && phi < 0.0) fem.x[i] -= phi * n;
    }
  }
}

}  // namespace triad
