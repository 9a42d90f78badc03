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
#include <cstring>

#include "sim/coupling/coupling.h"
#include "sim/svd3.h"

namespace triad {

namespace {

using Vec6d = Eigen::Matrix<double, 6, 1>;
using Mat6d = Eigen::Matrix<double, 6, 6>;

using svd3_detail::kLanes;
using svd3_detail::Pack;

// relaxMoving's quantities, one array each: the normal, the node's offset
// from the body's centre, the material's and the solid's velocities, the
// material's mass, the approach the gap allows, the reduced mass, the
// friction coefficient, 1 where the node has a normal, and the impulses.
enum MovingField {
  kNx,
  kNy,
  kNz,
  kRx,
  kRy,
  kRz,
  kCx,
  kCy,
  kCz,
  kWx,
  kWy,
  kWz,
  kMass,
  kClose,
  kReduced,
  kMu,
  kActive,
  kLambda,
  kTx,
  kTy,
  kTz,
  kPx,
  kPy,
  kPz,
  kDx,
  kDy,
  kDz,
  kMovingFields
};

inline Pack load(const float* a) {
  Pack v;
  std::memcpy(&v, a, sizeof(v));
  return v;
}
inline void store(float* a, const Pack& v) {
  std::memcpy(a, &v, sizeof(v));
}
inline float lane(const Pack& v, int l) {
  float a[kLanes];
  std::memcpy(a, &v, sizeof(v));
  return a[l];
}

}  // namespace

int GridCoupling::relaxMoving(const SolidPoints& pts, const std::vector<float>& share, int pass,
                              int passes, std::vector<Vec3f>& dV, std::vector<Vec3f>& dW) {
  const size_t nsolids = pts.solids();
  // Each body's nodes, in the order of moving_, padded to whole lanes.
  moving_start_.assign(nsolids + 1, 0);
  for (uint32_t k : moving_) ++moving_start_[size_t(shared_[k].solid) + 1];
  for (size_t b = 0; b < nsolids; ++b)
    moving_start_[b + 1] = moving_start_[b] + (moving_start_[b + 1] + kLanes - 1) / kLanes * kLanes;
  const size_t lanes = moving_start_[nsolids];
  moving_lanes_.assign(kMovingFields * lanes, 0.0f);
  float* f[kMovingFields];
  for (int q = 0; q < kMovingFields; ++q) f[q] = moving_lanes_.data() + size_t(q) * lanes;
  std::fill(f[kMass], f[kMass] + lanes, 1.0f);  // padding: no division by zero
  std::vector<uint32_t> at(moving_start_.begin(), moving_start_.end() - 1), node(lanes);
  for (uint32_t k : moving_) {
    const Shared& c = shared_[k];
    const size_t j = at[size_t(c.solid)]++;
    node[j] = k;
    const Vec3f r = c.x - pts.centre[size_t(c.solid)];
    const float m_solid = c.m_vol * share[size_t(c.solid)];
    auto put = [&](int q, const Vec3f& a) {
      for (int d = 0; d < 3; ++d) f[q + d][j] = a[d];
    };
    put(kNx, c.n);
    put(kRx, r);
    put(kCx, c.v_cmp);
    put(kWx, c.v_vol);
    put(kTx, c.T);
    put(kPx, c.P);
    put(kDx, c.dP);
    f[kMass][j] = c.m_mpm;
    f[kClose][j] = c.close;
    f[kReduced][j] = c.m_mpm * m_solid / (c.m_mpm + m_solid);
    f[kMu][j] = c.mu;
    f[kActive][j] = c.n.isZero() ? 0.0f : 1.0f;
    f[kLambda][j] = c.lambda;
  }
  const Pack zero = svd3_detail::splat<Pack>(0.0f);
  // A body whose nodes have converged takes no more passes: each body
  // converges on its own impulses' scale, whatever other bodies do.
  std::vector<uint8_t> done(nsolids, 0);
  for (;; ++pass) {
    // Each body takes the opposite of its nodes' new impulses, summed lane
    // by lane and then over the lanes in order.
    for (size_t b = 0; b < nsolids; ++b) {
      if (done[b] || moving_start_[b] == moving_start_[b + 1]) continue;
      Pack dp[3] = {zero, zero, zero}, dl[3] = {zero, zero, zero};
      for (size_t j = moving_start_[b]; j < moving_start_[b + 1]; j += kLanes) {
        const Pack rx = load(f[kRx] + j), ry = load(f[kRy] + j), rz = load(f[kRz] + j);
        const Pack px = load(f[kDx] + j), py = load(f[kDy] + j), pz = load(f[kDz] + j);
        dp[0] -= px;
        dp[1] -= py;
        dp[2] -= pz;
        dl[0] -= ry * pz - rz * py;
        dl[1] -= rz * px - rx * pz;
        dl[2] -= rx * py - ry * px;
      }
      Vec3f sp = Vec3f::Zero(), sl = Vec3f::Zero();
      for (int l = 0; l < kLanes; ++l)
        for (int d = 0; d < 3; ++d) {
          sp[d] += lane(dp[d], l);
          sl[d] += lane(dl[d], l);
        }
      dV[b] += pts.inv_mass[b] * sp;
      dW[b] += pts.inv_inertia[b] * sl;
    }
    if (pass >= passes) break;
    // One relaxation of every node against its body's current velocity
    // (normal impulse never pulling, friction within the Coulomb cone and
    // never reversing the sliding). A body has converged when none of its
    // nodes' impulses changes by more than a thousandth of its largest.
    bool all_done = true;
    for (size_t b = 0; b < nsolids; ++b) {
      if (done[b] || moving_start_[b] == moving_start_[b + 1]) continue;
      const Vec3f v = dV[b], w = dW[b];
      Pack change = zero, largest = zero;
      for (size_t j = moving_start_[b]; j < moving_start_[b + 1]; j += kLanes) {
        const Pack rx = load(f[kRx] + j), ry = load(f[kRy] + j), rz = load(f[kRz] + j);
        const Pack nx = load(f[kNx] + j), ny = load(f[kNy] + j), nz = load(f[kNz] + j);
        const Pack m = load(f[kMass] + j), lambda = load(f[kLambda] + j);
        Pack P[3] = {load(f[kPx] + j), load(f[kPy] + j), load(f[kPz] + j)};
        const Pack T[3] = {load(f[kTx] + j), load(f[kTy] + j), load(f[kTz] + j)};
        // The solid's velocity at the node; the material's relative to it.
        const Pack sx = load(f[kWx] + j) + v.x() + (w.y() * rz - w.z() * ry);
        const Pack sy = load(f[kWy] + j) + v.y() + (w.z() * rx - w.x() * rz);
        const Pack sz = load(f[kWz] + j) + v.z() + (w.x() * ry - w.y() * rx);
        const Pack ux = load(f[kCx] + j) + P[0] / m - sx;
        const Pack uy = load(f[kCy] + j) + P[1] / m - sy;
        const Pack uz = load(f[kCz] + j) + P[2] / m - sz;
        const Pack un = ux * nx + uy * ny + uz * nz + load(f[kClose] + j);
        const Pack reduced = load(f[kReduced] + j);
        Pack next = lambda - reduced * un;
        next = next > zero ? next : zero;
        Pack Tn[3] = {T[0] - reduced * (ux - un * nx), T[1] - reduced * (uy - un * ny),
                      T[2] - reduced * (uz - un * nz)};
        const Pack limit = load(f[kMu] + j) * next;
        const Pack len = svd3_detail::sqrtv(Tn[0] * Tn[0] + Tn[1] * Tn[1] + Tn[2] * Tn[2]);
        const Pack cut = limit / len;
        const Pack keep = len > limit ? cut : svd3_detail::splat<Pack>(1.0f);
        // Separating material leaves freely; a node without a normal takes nothing.
        const auto free_leaving = un >= zero && lambda <= zero;
        const auto idle = load(f[kActive] + j) == zero;
        const auto hold = free_leaving || idle;
        Pack dP[3];
        for (int d = 0; d < 3; ++d) {
          Tn[d] *= keep;
          const Pack n_d = d == 0 ? nx : d == 1 ? ny : nz;
          const Pack step = (next - lambda) * n_d + (Tn[d] - T[d]);
          dP[d] = hold ? zero : step;
          const Pack t_d = hold ? T[d] : Tn[d];
          P[d] += dP[d];
          store(f[kTx + d] + j, t_d);
          store(f[kPx + d] + j, P[d]);
          store(f[kDx + d] + j, dP[d]);
        }
        const Pack l_next = hold ? lambda : next;
        store(f[kLambda] + j, l_next);
        const Pack c2 = dP[0] * dP[0] + dP[1] * dP[1] + dP[2] * dP[2];
        const Pack p2 = P[0] * P[0] + P[1] * P[1] + P[2] * P[2];
        change = c2 > change ? c2 : change;
        largest = p2 > largest ? p2 : largest;
      }
      done[b] = std::sqrt(svd3_detail::laneMax(change)) <=
                1e-3f * std::sqrt(svd3_detail::laneMax(largest));
      all_done = all_done && done[b];
    }
    if (all_done) {
      ++pass;  // count the pass just done
      break;
    }
  }
  // The impulses back to the nodes.
  for (size_t b = 0; b < nsolids; ++b)
    for (size_t j = moving_start_[b]; j < at[b]; ++j) {
      Shared& c = shared_[node[j]];
      c.lambda = f[kLambda][j];
      c.T = Vec3f(f[kTx][j], f[kTy][j], f[kTz][j]);
      c.P = Vec3f(f[kPx][j], f[kPy][j], f[kPz][j]);
      c.dP = Vec3f(f[kDx][j], f[kDy][j], f[kDz][j]);
    }
  return pass;
}

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
