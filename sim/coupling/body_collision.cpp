// The normal part of the collision of MPM material with moving rigid
// bodies, solved for each body's velocity change. Given the body's velocity
// change z = (dV, dW), every node's normal impulse is explicit: the
// material's approach beyond what its gap allows is stopped. The z for
// which the body takes exactly the opposite of its nodes' impulses
// minimises the convex
//   E(z) = 1/2 z^T M z + sum_i 1/2 m_i min(0, u_n,i(z))^2,
// M = diag(M I, I_world), u_n,i the node's approach after the body moved
// by z. Newton's method with a backtracking line search converges on it in
// a few iterations whatever the body's share of each node, where Jacobi
// passes move a node that holds a sliver of solid only by its sliver and
// stop short, letting bodies creep into water. Friction is left to the
// Jacobi passes that follow: with Coulomb's cone the response is no
// gradient, and Newton on it diverges for fast sliding contacts.
#include <Eigen/Dense>
#include <cmath>

#include "sim/coupling/coupling.h"

namespace triad {

namespace {

using Vec6d = Eigen::Matrix<double, 6, 1>;
using Mat6d = Eigen::Matrix<double, 6, 6>;

inline Mat3d crossMatrix(const Vec3d& r) {
  Mat3d m;
  m << 0, -r.z(), r.y(), r.z(), 0, -r.x(), -r.y(), r.x(), 0;
  return m;
}

}  // namespace

int GridCoupling::solveBodyNormals(const SolidPoints& pts, int max_iterations,
                                   std::vector<Vec3f>& dV, std::vector<Vec3f>& dW) {
  const size_t nsolids = pts.solids();
  // The moving nodes of each body, contiguous.
  std::vector<std::vector<uint32_t>> nodes(nsolids);
  for (uint32_t k : moving_) nodes[size_t(shared_[k].solid)].push_back(k);
  int most = 0;
  for (size_t b = 0; b < nsolids; ++b) {
    if (nodes[b].empty() || pts.body_mass[b] <= 0.0) continue;
    Mat6d M = Mat6d::Zero();
    M.topLeftCorner<3, 3>() = Mat3d::Identity() / double(pts.inv_mass[b]);
    M.bottomRightCorner<3, 3>() = pts.inv_inertia[b].cast<double>().inverse();
    const Vec3d centre = pts.centre[b].cast<double>();
    // Each node's approach at z = 0 and its row u_n(z) = g - a . z.
    const size_t n = nodes[b].size();
    std::vector<double> g(n), m(n);
    std::vector<Vec6d> a(n);
    for (size_t k = 0; k < n; ++k) {
      const Shared& c = shared_[nodes[b][k]];
      const Vec3d nn = c.n.cast<double>();
      const Vec3d r = c.x.cast<double>() - centre;
      g[k] = (c.v_cmp - c.v_vol).cast<double>().dot(nn) + double(c.close);
      a[k].head<3>() = nn;
      a[k].tail<3>() = r.cross(nn);
      m[k] = c.n.isZero() ? 0.0 : double(c.m_mpm);
    }
    auto energy = [&](const Vec6d& z) {
      double e = 0.5 * z.dot(M * z);
      for (size_t k = 0; k < n; ++k) {
        const double un = g[k] - a[k].dot(z);
        if (un < 0.0) e += 0.5 * m[k] * un * un;
      }
      return e;
    };
    Vec6d z = Vec6d::Zero();
    const double scale = M.diagonal().maxCoeff();
    int it = 0;
    for (; it < max_iterations; ++it) {
      // Gradient M z - sum m min(0, u_n) a and the active nodes' Hessian.
      Vec6d grad = M * z;
      Mat6d H = M;
      for (size_t k = 0; k < n; ++k) {
        const double un = g[k] - a[k].dot(z);
        if (un >= 0.0) continue;
        grad -= m[k] * un * a[k];
        H += m[k] * a[k] * a[k].transpose();
      }
      if (grad.norm() <= 1e-10 * scale * (1.0 + z.norm())) break;
      const Vec6d step = -H.ldlt().solve(grad);
      // Backtrack until the energy falls enough (Armijo).
      const double e0 = energy(z), slope = grad.dot(step);
      double t = 1.0;
      while (t > 1e-6 && energy(z + t * step) > e0 + 1e-4 * t * slope) t *= 0.5;
      z += t * step;
      if ((t * step).norm() <= 1e-9 * (1.0 + z.norm())) {
        ++it;
        break;
      }
    }
    most = std::max(most, it + 1);
    // The nodes' normal impulses at the solution; the body's change is
    // what the Jacobi passes start from.
    for (size_t k = 0; k < n; ++k) {
      Shared& c = shared_[nodes[b][k]];
      const double un = g[k] - a[k].dot(z);
      const double lambda = un < 0.0 ? -m[k] * un : 0.0;
      c.lambda = float(lambda);
      c.T.setZero();
      c.P = c.lambda * c.n;
      c.dP.setZero();
    }
    dV[b] = z.head<3>().cast<float>();
    dW[b] = z.tail<3>().cast<float>();
  }
  return most;
}

}  // namespace triad
