#include "sim/solids/rigid_contact.h"

#include <algorithm>
#include <cmath>

namespace triad {

namespace {

// What the impulse loop needs of a body, with its world inverse inertia
// formed once: orientation does not change while velocities are solved.
struct SolverBody {
  Vec3d x = Vec3d::Zero(), v = Vec3d::Zero(), w = Vec3d::Zero();
  double inv_m = 0.0;
  Mat3d inv_i = Mat3d::Zero();
};

SolverBody solverBody(const RigidBody& b) {
  SolverBody s;
  s.x = b.state.x;
  s.v = b.state.v;
  s.w = b.omega();
  if (!b.fixed) {
    const Mat3d R = b.rotation();
    s.inv_m = 1.0 / b.mass;
    s.inv_i = R * b.moments.cwiseInverse().asDiagonal() * R.transpose();
  }
  return s;
}

// A body more than this many times another's size (bounding radius) is
// the flatter of the two where they touch.
constexpr float kFlatter = 2.0f;

// Surface samples: within a sample spacing of the surface. Walls and other
// bodies meet these first.
inline bool onSurface(const RigidBody& b, size_t q) { return b.phi[q] > -b.spacing; }

void wallContacts(const RigidBody& body, int index, const ContactSettings& s, double dt,
                  std::vector<Contact>& out) {
  const Mat3d R = body.rotation();
  const Vec3d w = body.omega();
  const double half = 0.5 * body.spacing;
  const double mu = s.wall_type == BoundaryType::Sticky ? -1.0 : s.wall_friction;
  // Skip bodies whose bounding sphere cannot reach a wall this step.
  const double reach = body.radius + (body.state.v.norm() + w.norm() * body.radius) * dt + half;
  if (((body.state.x - s.lo).minCoeff() > reach) && ((s.hi - body.state.x).minCoeff() > reach))
    return;
  for (size_t q = 0; q < body.r.size(); ++q) {
    if (!onSurface(body, q)) continue;
    const Vec3d r = R * body.r[q].cast<double>();
    const Vec3d p = body.state.x + r;
    const Vec3d vq = body.state.v + w.cross(r);
    // Contacts a sample could make within the step, and one spacing more.
    const double margin = vq.norm() * dt + body.spacing;
    for (int d = 0; d < 3; ++d) {
      const double gap_lo = p[d] - half - s.lo[d];
      if (gap_lo < margin) out.push_back({index, -1, p, Vec3d::Unit(d), gap_lo, mu});
      const double gap_hi = s.hi[d] - p[d] - half;
      if (gap_hi < margin) out.push_back({index, -1, p, -Vec3d::Unit(d), gap_hi, mu});
    }
  }
}

// Surface samples of body a inside body b's sample lattice.
void pairContacts(const std::vector<RigidBody>& bodies, int ia, int ib,
                  std::vector<Contact>& out) {
  const RigidBody& a = bodies[ia];
  const RigidBody& b = bodies[ib];
  const Mat3d Ra = a.rotation(), Rb = b.rotation();
  const double mu = std::sqrt(double(a.friction) * double(b.friction));
  // b's bounding sphere in a's frame: most of a big body's samples are
  // rejected without a rotation.
  const Vec3f cb = (Ra.transpose() * (b.state.x - a.state.x)).cast<float>();
  const float rb2 = b.radius * b.radius;
  for (size_t q = 0; q < a.r.size(); ++q) {
    // A deforming collider's samples are where its surface carried them.
    if (!a.placed && (a.r[q] - cb).squaredNorm() > rb2) continue;
    if (!onSurface(a, q)) continue;
    const Vec3d p = a.samplePosition(q, Ra);
    if (a.placed && (p - b.state.x).squaredNorm() > double(rb2)) continue;
    // b's distance there, from the envelope of its sample planes: it
    // answers just outside b too, and not far from b's samples.
    double phi_b;
    Vec3d nb;
    const int qb = b.envelopeAt(p, Rb, phi_b, nb);
    if (qb < 0) continue;
    const Vec3d vb = b.surfaceVelocity(qb, p, Rb);
    // A contact pushes a's surface out through b's: their normals face each
    // other. Inside b near one of its edges the distance field points out
    // through the side face, across a's surface (a slab's top samples under
    // a box's bottom edge would push the box sideways and spin it).
    if (a.sampleNormal(q, Ra).dot(nb) > -0.5) continue;
    // a's surface lies -phi_a beyond its sample.
    Contact c{ia, ib, p, nb, phi_b + double(a.phi[q]), mu};
    c.own_a = bool(a.deform);
    c.va = c.own_a ? a.sampleVelocity(q, Ra) : Vec3d::Zero();
    c.own_b = bool(b.deform);
    c.vb = vb;
    out.push_back(c);
  }
}

}  // namespace

std::vector<Contact> findContacts(const std::vector<RigidBody>& bodies, const ContactSettings& s,
                                  double dt) {
  std::vector<Contact> out;
  for (size_t i = 0; i < bodies.size(); ++i)
    if (!bodies[i].fixed) wallContacts(bodies[i], int(i), s, dt, out);
  for (size_t i = 0; i < bodies.size(); ++i)
    for (size_t j = i + 1; j < bodies.size(); ++j) {
      const RigidBody& a = bodies[i];
      const RigidBody& b = bodies[j];
      if (a.fixed && b.fixed) continue;
      const double reach = a.radius + b.radius +
                           (a.state.v - b.state.v).norm() * dt +
                           (a.omega().norm() * a.radius + b.omega().norm() * b.radius) * dt;
      if ((a.state.x - b.state.x).norm() > reach) continue;
      // Each body's surface samples against the other's distance, the
      // contact's normal from the other, except that a body more than
      // twice the other's size is taken as the flatter surface: its
      // samples under a ball took the ball's normal, tilted by the few
      // samples in the contact patch, and the ball rolled off a table.
      if (a.radius <= kFlatter * b.radius) pairContacts(bodies, int(i), int(j), out);
      if (b.radius <= kFlatter * a.radius) pairContacts(bodies, int(j), int(i), out);
    }
  return out;
}

ContactStats resolveContacts(std::vector<RigidBody>& bodies, const ContactSettings& s, double dt) {
  ContactStats stats;
  const std::vector<Contact> contacts = findContacts(bodies, s, dt);
  if (contacts.empty()) return stats;
  std::vector<SolverBody> sb;
  sb.reserve(bodies.size());
  for (const RigidBody& b : bodies) sb.push_back(solverBody(b));
  SolverBody wall;  // immovable, at rest
  std::vector<char> touched(bodies.size(), 0);

  // Per contact: lever arms, normal effective mass, target normal velocity,
  // accumulated normal and tangential impulses.
  struct Row {
    Vec3d ra, rb;
    double k_n, target, lambda_n = 0.0;
    Vec3d lambda_t = Vec3d::Zero();
    double push = 0.0, lambda_p = 0.0;  // split impulse: position correction
  };
  std::vector<Row> rows(contacts.size());
  auto body = [&](int i) -> SolverBody& { return i < 0 ? wall : sb[size_t(i)]; };
  auto effMass = [&](const Contact& c, const Row& r, const Vec3d& dir) {
    const SolverBody& A = body(c.a);
    const SolverBody& B = body(c.b);
    const Vec3d ca = r.ra.cross(dir), cb = r.rb.cross(dir);
    return A.inv_m + B.inv_m + ca.dot(A.inv_i * ca) + cb.dot(B.inv_i * cb);
  };
  // Single-precision positions in the domain are good to about 1e-7 of
  // its extent.
  const double slop = 1e-6 * (s.hi - s.lo).maxCoeff();
  for (size_t k = 0; k < contacts.size(); ++k) {
    const Contact& c = contacts[k];
    Row& r = rows[k];
    r.ra = c.p - body(c.a).x;
    r.rb = c.b < 0 ? Vec3d::Zero() : Vec3d(c.p - body(c.b).x);
    r.k_n = effMass(c, r, c.n);
    // Approach at most the gap in one step. A penetration is pushed out by
    // a separate position correction that adds no velocity (split impulse):
    // a velocity bias would throw the bodies apart, a bounce from nowhere.
    // Penetrations within the positions' rounding are left alone: a body
    // exactly as wide as the domain touches both walls at once, and pushing
    // it off each by the other's rounding ran every correction pass.
    r.target = c.gap >= 0.0 ? -c.gap / dt : 0.0;
    r.push = c.gap >= -slop ? 0.0 : -s.push_out * c.gap / dt;
    (c.b < 0 ? stats.wall_contacts : stats.body_contacts)++;
    touched[size_t(c.a)] = 1;
    if (c.b >= 0) touched[size_t(c.b)] = 1;
  }
  // A deforming collider (fixed: no impulse changes it) moves at its
  // surface's own velocity at the contact.
  auto relVel = [&](const Contact& c, const Row& r) {
    const SolverBody& A = body(c.a);
    const SolverBody& B = body(c.b);
    const Vec3d va = c.own_a ? c.va : Vec3d(A.v + A.w.cross(r.ra));
    const Vec3d vb = c.own_b ? c.vb : Vec3d(B.v + B.w.cross(r.rb));
    return Vec3d(va - vb);
  };
  auto apply = [&](const Contact& c, const Row& r, const Vec3d& j) {
    SolverBody& A = body(c.a);
    A.v += A.inv_m * j;
    A.w += A.inv_i * r.ra.cross(j);
    if (c.b >= 0) {
      SolverBody& B = body(c.b);
      B.v -= B.inv_m * j;
      B.w -= B.inv_i * r.rb.cross(j);
    }
  };

  for (int it = 0; it < s.iterations; ++it) {
    for (size_t k = 0; k < contacts.size(); ++k) {
      const Contact& c = contacts[k];
      Row& r = rows[k];
      if (r.k_n <= 0.0) continue;
      // Normal: the accumulated impulse never pulls.
      const double vn = relVel(c, r).dot(c.n);
      const double new_n = std::max(0.0, r.lambda_n + (r.target - vn) / r.k_n);
      apply(c, r, (new_n - r.lambda_n) * c.n);
      r.lambda_n = new_n;
      // Tangent: cancel sliding within the Coulomb cone (none without
      // friction).
      if (c.mu == 0.0) continue;
      const Vec3d u = relVel(c, r);
      const Vec3d ut = u - u.dot(c.n) * c.n;
      const double speed = ut.norm();
      if (speed <= 0.0) continue;
      const Vec3d t = ut / speed;
      const double k_t = effMass(c, r, t);
      Vec3d new_t = r.lambda_t - (speed / k_t) * t;
      const double limit = c.mu < 0.0 ? INFINITY : c.mu * r.lambda_n;
      if (new_t.norm() > limit) new_t *= limit / new_t.norm();
      apply(c, r, new_t - r.lambda_t);
      r.lambda_t = new_t;
    }
  }

  // Position correction: the same rows on pseudo-velocities that move the
  // bodies this step only. A pass that changes no contact's pseudo-velocity
  // by more than 1e-4 of what gravity adds to a velocity in the step leaves
  // the next passes only rounding to move: stop there. (The velocity passes
  // above run in full: stopping them as early moved where a dropped slab
  // comes to rest within the band of rest, bench/RESULTS.md.)
  const double settled = 1e-4 * s.gravity * dt;
  std::vector<SolverBody> pseudo = sb;
  for (SolverBody& p : pseudo) p.v = p.w = Vec3d::Zero();
  SolverBody wall_p;
  auto pbody = [&](int i) -> SolverBody& { return i < 0 ? wall_p : pseudo[size_t(i)]; };
  for (int it = 0; it < s.iterations; ++it) {
    double moved = 0.0;
    for (size_t k = 0; k < contacts.size(); ++k) {
      const Contact& c = contacts[k];
      Row& r = rows[k];
      if (r.k_n <= 0.0 || r.push <= 0.0) continue;
      SolverBody& A = pbody(c.a);
      SolverBody& B = pbody(c.b);
      const double vn = (A.v + A.w.cross(r.ra) - B.v - B.w.cross(r.rb)).dot(c.n);
      const double new_p = std::max(0.0, r.lambda_p + (r.push - vn) / r.k_n);
      const Vec3d j = (new_p - r.lambda_p) * c.n;
      moved = std::max(moved, std::abs(new_p - r.lambda_p) * r.k_n);
      r.lambda_p = new_p;
      A.v += sb[size_t(c.a)].inv_m * j;
      A.w += sb[size_t(c.a)].inv_i * r.ra.cross(j);
      if (c.b >= 0) {
        B.v -= sb[size_t(c.b)].inv_m * j;
        B.w -= sb[size_t(c.b)].inv_i * r.rb.cross(j);
      }
    }
    if (moved <= settled) break;
  }

  for (size_t i = 0; i < bodies.size(); ++i) {
    RigidBody& b = bodies[i];
    if (b.fixed || !touched[i]) continue;
    b.state.v = sb[i].v;
    // L = I w with the same world inertia the loop used.
    const Mat3d R = b.rotation();
    b.state.L = R * b.moments.asDiagonal() * R.transpose() * sb[i].w;
    // Then the position correction.
    b.state.x += dt * pseudo[i].v;
    const double angle = pseudo[i].w.norm() * dt;
    if (angle > 0.0)
      b.state.q_principal =
          (Quatd(Eigen::AngleAxisd(angle, pseudo[i].w.normalized())) * b.state.q_principal)
              .normalized();
  }
  return stats;
}

}  // namespace triad
