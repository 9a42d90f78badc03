// The collision of MPM material with a moving rigid body, solved for the
// body's velocity change (contract step 6 with the body's response fed
// back). Given the body's velocity, every node's impulse is explicit: the
// material's approach is stopped and its sliding reduced within the Coulomb
// cone, relative to the body at that node. What remains is six unknowns per
// body, the velocity change z = (dV, dW) for which the body takes exactly
// the opposite of its nodes' impulses:
//   z + A sum_i B_i^T P_i(z) = 0,   A = diag(1/M, I^-1),  B_i z = dV + dW x r_i.
// P_i is piecewise linear in z, so Newton's method with the active nodes'
// Jacobian converges in a few iterations. Jacobi passes over the nodes
// reach the same state, but a node holding a sliver of solid moves only by
// its own share of solid mass per pass and needs hundreds of passes.
#include <Eigen/Dense>
#include <cmath>

#include "sim/coupling/coupling.h"

namespace triad {

namespace {

using Vec6d = Eigen::Matrix<double, 6, 1>;
using Mat6d = Eigen::Matrix<double, 6, 6>;

inline Mat3d cross(const Vec3d& r) {
  Mat3d m;
  m << 0, -r.z(), r.y(), r.z(), 0, -r.x(), -r.y(), r.x(), 0;
  return m;
}

}  // namespace

int GridCoupling::solveBodies(const SolidPoints& pts, int max_iterations) {
  const size_t nsolids = pts.solids();
  std::vector<Vec6d> z(nsolids, Vec6d::Zero());
  std::vector<Vec6d> force(nsolids);
  std::vector<Mat6d> stiff(nsolids);
  std::vector<uint8_t> done(nsolids, 0);
  // A body's length scale, to weigh its angular velocity against its linear.
  std::vector<double> reach(nsolids, 0.0);
  for (uint32_t k : moving_) {
    const Shared& c = shared_[k];
    const double r = (c.x - pts.centre[size_t(c.solid)]).cast<double>().norm();
    reach[size_t(c.solid)] = std::max(reach[size_t(c.solid)], r);
  }

  // Each node's impulse against the body moving at z; with `sum`, adds it
  // to its body's force and the active nodes' Jacobian.
  auto respond = [&](Shared& c, bool sum) {
    const size_t b = size_t(c.solid);
    const Vec3d r = (c.x - pts.centre[b]).cast<double>();
    const Vec3d dv = z[b].head<3>() + z[b].tail<3>().cross(r);
    const Vec3d n = c.n.cast<double>();
    const Vec3d u = (c.v_cmp - c.v_vol).cast<double>() - dv;
    const double un = u.dot(n), m = c.m_mpm;
    c.P.setZero();
    c.T.setZero();
    c.lambda = 0.0f;
    if (un >= 0.0 || c.n.isZero()) return;  // separating: material leaves freely
    const double lambda = -m * un;
    // Coulomb friction: can stop sliding, never reverse it.
    Vec3d T = -m * (u - un * n);
    const double limit = double(c.mu) * lambda, len = T.norm();
    const bool slides = len > limit;
    if (slides) T *= len > 0.0 ? limit / len : 0.0;
    const Vec3d P = lambda * n + T;
    c.lambda = float(lambda);
    c.T = T.cast<float>();
    c.P = P.cast<float>();
    if (!sum) return;
    force[b].head<3>() += P;
    force[b].tail<3>() += r.cross(P);
    // dP/dz = m S B with S the projection the node applies (normal only
    // while sliding, everything while it sticks).
    Eigen::Matrix<double, 3, 6> B;
    B.leftCols<3>() = Mat3d::Identity();
    B.rightCols<3>() = -cross(r);
    const Mat3d S = slides ? Mat3d(n * n.transpose()) : Mat3d::Identity();
    stiff[b] += m * B.transpose() * S * B;
  };

  int iteration = 0;
  for (; iteration < max_iterations; ++iteration) {
    for (size_t b = 0; b < nsolids; ++b) {
      force[b].setZero();
      stiff[b].setZero();
    }
    // Serial, in node order: every sum has one order for any thread count.
    for (uint32_t k : moving_)
      if (!done[size_t(shared_[k].solid)]) respond(shared_[k], true);
    bool all_done = true;
    for (size_t b = 0; b < nsolids; ++b) {
      if (done[b] || pts.body_mass[b] <= 0.0) continue;
      Mat6d A = Mat6d::Zero();
      A.topLeftCorner<3, 3>() = double(pts.inv_mass[b]) * Mat3d::Identity();
      A.bottomRightCorner<3, 3>() = pts.inv_inertia[b].cast<double>();
      // Newton step on z + A F(z) = 0 with F's Jacobian m S B summed.
      const Vec6d g = z[b] + A * force[b];
      const Mat6d J = Mat6d::Identity() + A * stiff[b];
      const Vec6d step = J.partialPivLu().solve(g);
      z[b] -= step;
      const double moved = step.head<3>().norm() + reach[b] * step.tail<3>().norm();
      const double scale = z[b].head<3>().norm() + reach[b] * z[b].tail<3>().norm();
      if (moved <= 1e-6 * scale + 1e-9) done[b] = 1;
      else all_done = false;
    }
    if (all_done) {
      ++iteration;
      break;
    }
  }
  // The nodes' impulses at the final velocity: what the body takes back,
  // node by node, so momentum is exact even where Newton stopped early.
  for (uint32_t k : moving_) respond(shared_[k], false);
  return iteration;
}

}  // namespace triad
