#include "sim/solids/rigid_body.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>

namespace triad {

namespace {

// Rotation by angle a about principal axis k.
Quatd axisRotation(int k, double a) {
  return Quatd(Eigen::AngleAxisd(a, Vec3d::Unit(k)));
}

}  // namespace

Vec3d RigidBody::applyInverseInertia(const Vec3d& a) const {
  if (fixed) return Vec3d::Zero();
  const Mat3d R = rotation();
  return R * (R.transpose() * a).cwiseQuotient(moments);
}

Vec3d RigidBody::omega() const { return fixed ? spin : applyInverseInertia(state.L); }

void RigidBody::poseAt(double t) {
  const Pose p = animation.at(t);
  // The reference point is the pivot itself (recentre): it only translates.
  state.x = pivot + p.translate;
  state.q_principal = (p.rotation * rest_principal).normalized();
  state.v = p.velocity;
  spin = p.omega;
  if (deform) {
    // The surface in the body's frame: rest_principal^T (x - pivot).
    std::vector<Vec3d> x, v;
    deform->vertices(t, x, v);
    const Mat3d Pt = rest_principal.toRotationMatrix().transpose();
    surface.vertices.resize(x.size());
    for (size_t i = 0; i < x.size(); ++i) surface.vertices[i] = (Pt * (x[i] - pivot)).cast<float>();
    // The samples ride on the sequence's surface, then the animation's pose.
    if (!placed) placed = std::make_shared<PlacedSamples>();
    if (placed->time != t || placed->x.size() != r.size()) {
      const size_t n_samples = r.size();
      placed->x.resize(n_samples);
      placed->v.resize(n_samples);
      placed->n.resize(n_samples);
      const Mat3d A = (state.q_principal * rest_principal.conjugate()).toRotationMatrix();
      deform->placeAll(t, A, pivot, state.x, state.v, omega(), placed->x, placed->v, placed->n, 0);
      // Cells of two spacings, the samples within two spacings of the
      // surface: a quarter of the work of all of them at one spacing, and
      // the 27 cells around a point still hold samples within three
      // spacings of it.
      placed->index(2.0f * spacing, phi, -2.0f * spacing);
      placed->time = t;
      radius = placed->radiusAbout(state.x);
    }
  }
}

double RigidBody::kineticEnergy() const {
  const Vec3d pi = rotation().transpose() * state.L;
  return 0.5 * mass * state.v.squaredNorm() + 0.5 * pi.cwiseProduct(pi).cwiseQuotient(moments).sum();
}

void RigidBody::applyImpulse(const Vec3d& j, const Vec3d& p) {
  if (fixed) return;
  state.v += j / mass;
  state.L += (p - state.x).cross(j);
}

Eigen::Vector3i RigidBody::latticeCell(const Vec3d& p) const {
  // World -> rest frame: rest = P R^T (p - x), with P the principal frame in the rest frame.
  const Vec3d rest = principal * (state.q_principal.conjugate() * (p - state.x));
  const Vec3d c = (rest - lattice_origin) / double(spacing);
  return {int(std::lround(c.x())), int(std::lround(c.y())), int(std::lround(c.z()))};
}

int RigidBody::sampleIn(const Eigen::Vector3i& i) const {
  for (int d = 0; d < 3; ++d)
    if (i[d] < 0 || i[d] >= cell_dims[d]) return -1;
  return cells[(size_t(i.x()) * cell_dims.y() + i.y()) * cell_dims.z() + i.z()];
}

int RigidBody::sampleAt(const Vec3d& p) const {
  return placed ? placed->at(p) : sampleIn(latticeCell(p));
}

Vec3d RigidBody::samplePosition(size_t q, const Mat3d& R) const {
  return placed ? placed->x[q].cast<double>() : Vec3d(state.x + R * r[q].cast<double>());
}

Vec3d RigidBody::sampleNormal(size_t q, const Mat3d& R) const {
  return placed ? placed->n[q].cast<double>() : Vec3d(R * n[q].cast<double>());
}

Vec3d RigidBody::sampleVelocity(size_t q, const Mat3d& R) const {
  return placed ? placed->v[q].cast<double>() : velocityAt(samplePosition(q, R));
}

bool RigidBody::surfaceAt(const Vec3d& p, const Mat3d& R, double& phi_out, Vec3d& n_out,
                          Vec3d& v_out) const {
  if (!placed) {
    if (!distanceAt(p, R, phi_out, n_out)) return false;
    v_out = velocityAt(p);
    return true;
  }
  const int q = supportAt(p, R);
  if (q < 0) return false;
  n_out = placed->n[size_t(q)].cast<double>();
  phi_out = double(phi[size_t(q)]) + n_out.dot(p - placed->x[size_t(q)].cast<double>());
  v_out = placed->v[size_t(q)].cast<double>();
  return true;
}

int RigidBody::supportAt(const Vec3d& p, const Mat3d& R) const {
  if ((p - state.x).squaredNorm() > double(radius) * radius) return -1;
  if (placed) {
    // The same envelope over the placed samples near p.
    int best = -1;
    double best_d = -std::numeric_limits<double>::infinity();
    placed->around(p, [&](int q) {
      const double d = double(phi[size_t(q)]) +
                       placed->n[size_t(q)].cast<double>().dot(p - placed->x[size_t(q)].cast<double>());
      if (d > best_d) best_d = d, best = q;
    });
    return best;
  }
  const Vec3d body = R.transpose() * (p - state.x);  // the frame of r and n
  const Eigen::Vector3i mid = latticeCell(p);
  int best = -1;
  double best_d = -std::numeric_limits<double>::infinity();
  for (int i = -1; i <= 1; ++i)
    for (int j = -1; j <= 1; ++j)
      for (int k = -1; k <= 1; ++k) {
        const int q = sampleIn(mid + Eigen::Vector3i(i, j, k));
        if (q < 0) continue;
        const double d = double(phi[size_t(q)]) +
                         n[size_t(q)].cast<double>().dot(body - r[size_t(q)].cast<double>());
        if (d > best_d) best_d = d, best = q;
      }
  return best;
}

int RigidBody::envelopeAt(const Vec3d& p, const Mat3d& R, double& phi_out, Vec3d& n_out) const {
  const int best = supportAt(p, R);
  if (best < 0) return -1;
  auto planeAt = [&](int q) {
    return double(phi[size_t(q)]) +
           sampleNormal(size_t(q), R).dot(p - samplePosition(size_t(q), R));
  };
  phi_out = planeAt(best);
  if (placed) {
    n_out = sampleNormal(size_t(best), R);
    return best;
  }
  // Planes within a quarter spacing of the envelope, weighted down to zero
  // at that distance.
  const double band = 0.25 * double(spacing);
  const Eigen::Vector3i mid = latticeCell(p);
  Vec3d sum = Vec3d::Zero();
  for (int i = -1; i <= 1; ++i)
    for (int j = -1; j <= 1; ++j)
      for (int k = -1; k <= 1; ++k) {
        const int q = sampleIn(mid + Eigen::Vector3i(i, j, k));
        if (q < 0) continue;
        const double w = 1.0 - (phi_out - planeAt(q)) / band;
        if (w > 0.0) sum += w * n[size_t(q)].cast<double>();
      }
  n_out = R * sum.normalized();
  return best;
}

LatticeBox RigidBody::latticeBox() const {
  LatticeBox box;
  box.centre = state.x;
  box.radius = double(radius);
  if (placed) return box;
  box.boxed = true;
  // latticeCell's map to the rest frame, as one matrix.
  box.to_rest = principal.toRotationMatrix() * state.q_principal.conjugate().toRotationMatrix();
  // The cells reach half a spacing beyond their centres; as much again
  // covers the rounding of either map.
  const double h = double(spacing);
  box.lo = lattice_origin - Vec3d::Constant(h);
  box.hi = lattice_origin + h * cell_dims.cast<double>();
  return box;
}

bool RigidBody::distanceAt(const Vec3d& p, const Mat3d& R, double& phi_out, Vec3d& n_out) const {
  if ((p - state.x).squaredNorm() > double(radius) * radius) return false;
  if (placed) {
    Vec3d v;
    return surfaceAt(p, R, phi_out, n_out, v);
  }
  const int k = sampleAt(p);
  if (k < 0) return false;
  n_out = R * n[size_t(k)].cast<double>();
  const Vec3d xk = state.x + R * r[size_t(k)].cast<double>();
  phi_out = double(phi[size_t(k)]) + n_out.dot(p - xk);
  return true;
}

void RigidBody::advance(double dt) {
  if (fixed) return;
  state.x += dt * state.v;
  // Body-frame angular momentum pi; each sub-flow rotates the body about
  // principal axis k by pi_k tau / I_k and pi the opposite way, which leaves
  // the world angular momentum R pi unchanged.
  Quatd q = state.q_principal;
  Vec3d pi = q.conjugate() * state.L;
  auto flow = [&](int k, double tau) {
    const double a = pi[k] * tau / moments[k];
    q = q * axisRotation(k, a);
    pi = axisRotation(k, -a) * pi;
  };
  flow(0, 0.5 * dt);
  flow(1, 0.5 * dt);
  flow(2, dt);
  flow(1, 0.5 * dt);
  flow(0, 0.5 * dt);
  state.q_principal = q.normalized();
  // L is conserved by the free flow; recomputing it from pi would only add rounding.
}

RigidBody makeRigidBody(int object, const std::string& name, const CollisionSamples& samples,
                        TriSurface surface, bool fixed, double friction, const Vec3d& velocity,
                        const Vec3d& angular_velocity, double dx) {
  RigidBody b;
  b.object = object;
  b.name = name;
  b.fixed = fixed;
  b.friction = static_cast<float>(friction);
  const MassProperties mp = computeMassProperties(samples);
  b.mass = mp.mass;
  b.sample_mass = samples.mass_per_sample;
  b.spacing = static_cast<float>(samples.spacing);

  // Principal frame: eigenvectors of the inertia, made a proper rotation.
  Eigen::SelfAdjointEigenSolver<Mat3d> eig(mp.inertia);
  Mat3d P = eig.eigenvectors();
  if (P.determinant() < 0) P.col(2) = -P.col(2);
  b.moments = eig.eigenvalues().cwiseMax(1e-12 * std::max(1e-300, eig.eigenvalues().maxCoeff()));
  b.principal = Quatd(P).normalized();
  const Mat3d Pt = P.transpose();

  // Sample lattice in the rest frame (all samples, so that contact queries
  // find the interior too).
  const double h = samples.spacing;
  Vec3d lo = Vec3d::Constant(1e300), hi = Vec3d::Constant(-1e300);
  for (const Vec3f& x : samples.x) {
    lo = lo.cwiseMin(x.cast<double>() - mp.centre);
    hi = hi.cwiseMax(x.cast<double>() - mp.centre);
  }
  if (!samples.x.empty()) {
    b.lattice_origin = lo;
    for (int d = 0; d < 3; ++d) b.cell_dims[d] = static_cast<int>(std::lround((hi[d] - lo[d]) / h)) + 1;
    b.cells.assign(size_t(b.cell_dims.prod()), -1);
  }

  // Keep the samples near the surface, in the principal frame.
  const double depth = kCouplingDepth * dx;
  double rmax = 0.0;
  for (size_t q = 0; q < samples.size(); ++q) {
    const Vec3d rest = samples.x[q].cast<double>() - mp.centre;
    rmax = std::max(rmax, rest.norm());
    const float phi = samples.phi.empty() ? 0.0f : samples.phi[q];
    int32_t index = -1;
    if (phi >= -depth) {
      index = static_cast<int32_t>(b.r.size());
      b.r.push_back((Pt * rest).cast<float>());
      b.n.push_back((Pt * samples.normal[q].cast<double>()).cast<float>());
      b.phi.push_back(phi);
    }
    Eigen::Vector3i c;
    for (int d = 0; d < 3; ++d) c[d] = static_cast<int>(std::lround((rest[d] - lo[d]) / h));
    // Deep samples mark the cell as inside with the nearest kept sample unknown:
    // -2 tells contact queries "deep inside".
    b.cells[(size_t(c.x()) * b.cell_dims.y() + c.y()) * b.cell_dims.z() + c.z()] =
        index >= 0 ? index : -2;
  }
  b.radius = static_cast<float>(rmax + h);

  for (Vec3f& v : surface.vertices) v = (Pt * (v.cast<double>() - mp.centre)).cast<float>();
  b.surface = std::move(surface);

  b.state.x = mp.centre;
  b.state.q_principal = b.principal;
  if (!fixed) {
    b.state.v = velocity;
    b.state.L = mp.inertia * angular_velocity;
  }
  return b;
}

void recentre(RigidBody& b, const Vec3d& c) {
  // World at t = 0 is the rest frame; the principal frame rotates it.
  const Vec3d d = b.state.x - c;  // old centre from the new one, rest frame
  const Vec3f dp = (b.principal.conjugate() * d).cast<float>();
  double rmax = 0.0;
  for (Vec3f& r : b.r) {
    r += dp;
    rmax = std::max(rmax, double(r.norm()));
  }
  for (Vec3f& v : b.surface.vertices) v += dp;
  b.lattice_origin += d;
  // The bounding sphere must hold the deep samples too: every lattice corner.
  for (int k = 0; k < 8; ++k) {
    Vec3d corner = b.lattice_origin;
    for (int a = 0; a < 3; ++a)
      if (k >> a & 1) corner[a] += double(b.spacing) * (b.cell_dims[a] - 1);
    rmax = std::max(rmax, corner.norm());
  }
  b.radius = static_cast<float>(rmax + b.spacing);
  b.state.x = c;
}

TriSurface worldSurface(const RigidBody& body) {
  TriSurface s;
  s.triangles = body.surface.triangles;
  const Mat3d R = body.rotation();
  s.vertices.reserve(body.surface.vertices.size());
  for (const Vec3f& v : body.surface.vertices)
    s.vertices.push_back((body.state.x + R * v.cast<double>()).cast<float>());
  return s;
}

}  // namespace triad
