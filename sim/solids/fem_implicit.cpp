// GCC 12 warns of uninitialised AVX-512 lanes inside Eigen's small dense
// solvers (a false positive reported in the intrinsics header, which the
// first include pulls in: hence before it).
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
// Backward Euler for FEM bodies: Newton's method on the incremental
// potential (Gast et al. 2015, "Optimization integrator"), with contact
// penalties and lagged friction. The sparsity pattern and the direct
// solver's ordering are computed once per body; each Newton iteration
// refills the values element by element in parallel.
#include <algorithm>
#include <cmath>

#include <Eigen/Eigenvalues>
#include <Eigen/IterativeLinearSolvers>
#include <Eigen/SparseCholesky>

#include "sim/solids/fem.h"

namespace triad {

using SparseMat = Eigen::SparseMatrix<double>;

struct ImplicitCache {
  SparseMat H;                  // full symmetric pattern: every node pair sharing a tet
  std::vector<int> tet_index;   // per tet, 144 positions in H's values (a, b, r, c order)
  std::vector<int> diag_index;  // per node, 9 positions of its own 3x3 block
  std::vector<double> ke;       // per tet 12x12 stiffness (scratch)
  std::vector<double> elements; // H's values from the elements alone
  Eigen::SimplicialLDLT<SparseMat> direct;
  bool analysed = false;
  // Conjugate gradients are cheap while the mass term dominates (small
  // steps); a body whose solves stop converging switches to the direct
  // solver for good.
  bool use_direct = false;
  FemBody::SolveStats stats;
};

namespace {

constexpr int kMaxNewton = 20;
constexpr int kMaxCg = 2000;

ImplicitCache& cacheFor(const FemBody& b) {
  if (b.implicit_cache_) return *b.implicit_cache_;
  auto c = std::make_shared<ImplicitCache>();
  const size_t n = b.nodes(), nt = b.mesh.tets.size();
  std::vector<Eigen::Triplet<double>> trip;
  trip.reserve(nt * 144 + 9 * n);
  for (size_t i = 0; i < n; ++i)
    for (int r = 0; r < 3; ++r)
      for (int s = 0; s < 3; ++s) trip.emplace_back(int(3 * i + r), int(3 * i + s), 0.0);
  for (const auto& nd : b.mesh.tets)
    for (int a = 0; a < 4; ++a)
      for (int bb = 0; bb < 4; ++bb)
        for (int r = 0; r < 3; ++r)
          for (int s = 0; s < 3; ++s) trip.emplace_back(3 * nd[a] + r, 3 * nd[bb] + s, 0.0);
  c->H.resize(int(3 * n), int(3 * n));
  c->H.setFromTriplets(trip.begin(), trip.end());
  c->H.makeCompressed();
  // Where entry (row, col) sits in the compressed column-major values.
  const SparseMat& H = c->H;
  auto at = [&H](int row, int col) {
    const int* begin = H.innerIndexPtr() + H.outerIndexPtr()[col];
    const int* end = H.innerIndexPtr() + H.outerIndexPtr()[col + 1];
    return int(std::lower_bound(begin, end, row) - H.innerIndexPtr());
  };
  c->diag_index.resize(9 * n);
  for (size_t i = 0; i < n; ++i)
    for (int r = 0; r < 3; ++r)
      for (int s = 0; s < 3; ++s) c->diag_index[9 * i + 3 * r + s] = at(int(3 * i + r), int(3 * i + s));
  c->tet_index.resize(144 * nt);
  for (size_t t = 0; t < nt; ++t) {
    const auto& nd = b.mesh.tets[t];
    for (int a = 0; a < 4; ++a)
      for (int bb = 0; bb < 4; ++bb)
        for (int r = 0; r < 3; ++r)
          for (int s = 0; s < 3; ++s)
            c->tet_index[144 * t + 36 * a + 9 * bb + 3 * r + s] = at(3 * nd[a] + r, 3 * nd[bb] + s);
  }
  c->ke.resize(144 * nt);
  b.implicit_cache_ = std::move(c);
  return *b.implicit_cache_;
}

// d vec(F) / d x for a tetrahedron with inverse rest edge matrix B: 9 x 12.
Eigen::Matrix<double, 9, 12> deformationJacobian(const Mat3d& B) {
  Eigen::Matrix<double, 9, 12> G = Eigen::Matrix<double, 9, 12>::Zero();
  for (int j = 0; j < 3; ++j)
    for (int i = 0; i < 3; ++i) {
      double sum = 0.0;
      for (int k = 0; k < 3; ++k) {
        G(i + 3 * j, 3 * (k + 1) + i) = B(k, j);
        sum += B(k, j);
      }
      G(i + 3 * j, i) = -sum;
    }
  return G;
}

// Penetration of node position y into the walls along each axis: positive
// below lo (pushed up), negative above hi (pushed down), zero between.
Vec3d wallPenetration(const FemContacts& c, const Vec3d& y) {
  Vec3d p = Vec3d::Zero();
  for (int d = 0; d < 3; ++d) {
    if (y[d] < c.lo[d]) p[d] = c.lo[d] - y[d];
    if (y[d] > c.hi[d]) p[d] = c.hi[d] - y[d];
  }
  return p;
}

}  // namespace

Mat9<double> svdFrameDerivative(const ElasticModel& model, const Mat3d& F, bool psd) {
  Mat3d U, V, A;
  Vec3d s, plus, minus;
  const double size = F.norm();
  if (F.determinant() > 1e-3 * size * size * size) {
    // Uninverted and well conditioned (nearly every element): F = R S, S
    // symmetric positive definite, S = V diag(s) V^T by the closed-form 3x3
    // eigensolver and U = R V: cheaper than a Jacobi SVD in double (a jelly
    // slab's implicit run on water, 64 s with the SVD, 56 s so).
    const Mat3d R = polarRotation(F);
    const Mat3d S = R.transpose() * F;
    Eigen::SelfAdjointEigenSolver<Mat3d> eig;
    eig.computeDirect(0.5 * (S + S.transpose()));
    V = eig.eigenvectors();
    if (V.determinant() < 0) V.col(0) = -V.col(0);
    s = eig.eigenvalues();
    U = R * V;
  } else {
    svd3(F, U, s, V);
  }
  std::visit([&](const auto& mat) { mat.svdFrameHessian(s, A, plus, minus); }, model);
  if (psd) {
    // The 3x3 block loses its negative eigenvalues (most blocks have none:
    // a Cholesky factorisation shows it); each pair's two modes are
    // eigenvectors already.
    if (Eigen::LLT<Mat3d>(A).info() != Eigen::Success) {
      Eigen::SelfAdjointEigenSolver<Mat3d> eig;
      eig.computeDirect(A);
      A = eig.eigenvectors() * eig.eigenvalues().cwiseMax(0.0).asDiagonal() *
          eig.eigenvectors().transpose();
    }
    plus = plus.cwiseMax(0.0);
    minus = minus.cwiseMax(0.0);
  }
  // The frame's 9x9 matrix on vec(U^T dF V), column-major as vec().
  Mat9<double> H = Mat9<double>::Zero();
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b) H(4 * a, 4 * b) = A(a, b);
  for (int k = 0; k < 3; ++k) {
    const int ij = (k + 1) % 3 + 3 * ((k + 2) % 3), ji = (k + 2) % 3 + 3 * ((k + 1) % 3);
    H(ij, ij) = H(ji, ji) = 0.5 * (plus(k) + minus(k));
    H(ij, ji) = H(ji, ij) = 0.5 * (plus(k) - minus(k));
  }
  // vec(U X V^T) = W vec(X), W = V (x) U, orthogonal: dP/dF = W H W^T.
  Mat9<double> W;
  for (int j = 0; j < 3; ++j)
    for (int i = 0; i < 3; ++i)
      for (int b = 0; b < 3; ++b)
        for (int a = 0; a < 3; ++a) W(i + 3 * j, a + 3 * b) = U(i, a) * V(j, b);
  return W * H * W.transpose();
}

Eigen::Matrix<double, 12, 12> FemBody::elementStiffness(const std::vector<Vec3d>& y, size_t t,
                                                        bool psd) const {
  const Mat3d F = edges(y, mesh.tets[t]) * dm_inv[t];
  const Eigen::Matrix<double, 9, 12> G = deformationJacobian(dm_inv[t]);
  const Mat9<double> dP =
      psd ? svdFrameDerivative(model, F, true)
          : std::visit([&](const auto& mat) { return mat.firstPiolaDerivative(F); }, model);
  return volume[t] * G.transpose() * dP * G;
}

FemBody::SolveStats FemBody::lastSolve() const {
  return implicit_cache_ ? implicit_cache_->stats : SolveStats{};
}

double FemBody::heldMassAlong(size_t i, const Vec3d& n, double dt) const {
  const ImplicitCache* c = implicit_cache_.get();
  if (!c || c->elements.empty()) return mass[i];
  Mat3d H;
  for (int r = 0; r < 3; ++r)
    for (int s = 0; s < 3; ++s) H(r, s) = c->elements[size_t(c->diag_index[9 * i + 3 * r + s])];
  return mass[i] + dt * dt * n.dot(H * n);
}

double FemBody::incrementalPotential(const std::vector<Vec3d>& y,
                                     const std::vector<Vec3d>& target, double dt,
                                     const FemContacts* contacts) const {
  const double inv_dt2 = 1.0 / (dt * dt);
  double e = 0.0;
  for (size_t i = 0; i < y.size(); ++i) e += 0.5 * mass[i] * inv_dt2 * (y[i] - target[i]).squaredNorm();
  // Element energies in parallel, summed in element order (thread-count
  // independent results).
  std::vector<double> psi(mesh.tets.size());
  std::visit(
      [&](const auto& mat) {
#pragma omp parallel for schedule(static) if (mesh.tets.size() > 512)
        for (int64_t t = 0; t < int64_t(mesh.tets.size()); ++t)
          psi[t] = volume[t] * mat.psi(edges(y, mesh.tets[t]) * dm_inv[t]);
      },
      model);
  for (double p : psi) e += p;
  if (contacts) {
    const double k = contacts->kappa * inv_dt2;
    if (contacts->walls)
      for (size_t i = 0; i < y.size(); ++i)
        if (!pinned[i]) e += 0.5 * k * mass[i] * wallPenetration(*contacts, y[i]).squaredNorm();
    for (const NodePlane& p : contacts->planes) {
      const double d = p.b - p.n.dot(y[p.node]);
      if (d > 0.0 && !pinned[p.node]) e += 0.5 * k * mass[p.node] * d * d;
    }
  }
  return e;
}

int FemBody::implicitVelocities(double dt, const Vec3d& gravity, std::vector<Vec3d>& v_new,
                                FemContacts* contacts) const {
  ImplicitCache& cache = cacheFor(*this);
  cache.stats = {};
  const size_t n = x.size(), nt = mesh.tets.size();
  const double inv_dt2 = 1.0 / (dt * dt);
  const double k_contact = contacts ? contacts->kappa * inv_dt2 : 0.0;
  std::vector<Vec3d> target(n), y = x, f, trial(n);
  for (size_t i = 0; i < n; ++i)
    target[i] = pinned[i] ? x[i] : Vec3d(x[i] + dt * v[i] + dt * dt * gravity);
  const double tol = 1e-6 * mesh.spacing;
  Eigen::VectorXd grad(3 * n), p(3 * n);
  int it = 0;
  for (; it < kMaxNewton; ++it) {
    // Gradient: inertia, elastic forces, contact penalties; pinned nodes stay.
    forcesAt(y, f);
    for (size_t i = 0; i < n; ++i) {
      Vec3d gi = mass[i] * inv_dt2 * (y[i] - target[i]) - f[i];
      if (contacts && contacts->walls) gi -= k_contact * mass[i] * wallPenetration(*contacts, y[i]);
      grad.segment<3>(3 * i) = gi;
    }
    if (contacts)
      for (const NodePlane& pl : contacts->planes) {
        const double d = pl.b - pl.n.dot(y[pl.node]);
        if (d > 0.0) grad.segment<3>(3 * pl.node) -= k_contact * mass[pl.node] * d * pl.n;
      }
    for (size_t i = 0; i < n; ++i)
      if (pinned[i]) grad.segment<3>(3 * i).setZero();

    // Hessian: element stiffnesses in parallel, added in element order. They
    // are computed at the step's first iteration and kept for the others
    // (a chord method: the line search keeps every iteration descending,
    // and the elements' eigenproblems are most of an iteration's cost).
    if (it == 0) {
#pragma omp parallel for schedule(static) if (nt > 256)
      for (int64_t t = 0; t < int64_t(nt); ++t) {
        Eigen::Map<Eigen::Matrix<double, 12, 12>> K(cache.ke.data() + 144 * t);
        K = elementStiffness(y, size_t(t));
      }
      cache.elements.assign(size_t(cache.H.nonZeros()), 0.0);
      for (size_t t = 0; t < nt; ++t) {
        const auto& nd = mesh.tets[t];
        const Eigen::Map<const Eigen::Matrix<double, 12, 12>> K(cache.ke.data() + 144 * t);
        const int* idx = cache.tet_index.data() + 144 * t;
        for (int a = 0; a < 4; ++a)
          for (int b = 0; b < 4; ++b) {
            if (pinned[nd[a]] || pinned[nd[b]]) continue;
            for (int r = 0; r < 3; ++r)
              for (int s = 0; s < 3; ++s)
                cache.elements[idx[36 * a + 9 * b + 3 * r + s]] += K(3 * a + r, 3 * b + s);
          }
      }
    }
    double* values = cache.H.valuePtr();
    std::copy(cache.elements.begin(), cache.elements.end(), values);
    for (size_t i = 0; i < n; ++i) {
      Mat3d D = Mat3d::Identity() * (pinned[i] ? 1.0 : mass[i] * inv_dt2);
      if (!pinned[i] && contacts && contacts->walls) {
        const Vec3d pen = wallPenetration(*contacts, y[i]);
        for (int d = 0; d < 3; ++d)
          if (pen[d] != 0.0) D(d, d) += k_contact * mass[i];
      }
      for (int r = 0; r < 3; ++r)
        for (int s = 0; s < 3; ++s) values[cache.diag_index[9 * i + 3 * r + s]] += D(r, s);
    }
    if (contacts)
      for (const NodePlane& pl : contacts->planes) {
        if (pinned[pl.node] || pl.b - pl.n.dot(y[pl.node]) <= 0.0) continue;
        const Mat3d D = k_contact * mass[pl.node] * pl.n * pl.n.transpose();
        for (int r = 0; r < 3; ++r)
          for (int s = 0; s < 3; ++s) values[cache.diag_index[9 * pl.node + 3 * r + s]] += D(r, s);
      }

    // Newton direction: conjugate gradients, or the direct solver when they
    // do not converge (stiff bodies at large steps).
    bool solved = false;
    if (!cache.use_direct) {
      Eigen::ConjugateGradient<SparseMat, Eigen::Lower | Eigen::Upper> cg;
      cg.setMaxIterations(kMaxCg);
      cg.setTolerance(1e-4);
      cg.compute(cache.H);
      p = -cg.solve(grad);
      cache.stats.cg_iterations += int(cg.iterations());
      solved = cg.info() == Eigen::Success;
      if (!solved) cache.use_direct = true;
    }
    if (!solved) {
      if (!cache.analysed) {
        cache.direct.analyzePattern(cache.H);
        cache.analysed = true;
      }
      cache.direct.factorize(cache.H);
      if (cache.direct.info() != Eigen::Success) break;
      p = -cache.direct.solve(grad);
      cache.stats.direct++;
    }
    if (p.cwiseAbs().maxCoeff() < tol) break;
    // Backtracking line search on the incremental potential (Armijo).
    const double e0 = incrementalPotential(y, target, dt, contacts), slope = grad.dot(p);
    double alpha = 1.0;
    for (int ls = 0; ls < 20; ++ls, alpha *= 0.5) {
      for (size_t i = 0; i < n; ++i) trial[i] = y[i] + alpha * Vec3d(p.segment<3>(3 * i));
      if (incrementalPotential(trial, target, dt, contacts) <= e0 + 1e-4 * alpha * slope) break;
    }
    y.swap(trial);
    if (alpha * p.cwiseAbs().maxCoeff() < tol) break;
  }
  cache.stats.newton = it + 1;
  v_new.resize(n);
  for (size_t i = 0; i < n; ++i) v_new[i] = (y[i] - x[i]) / dt;
  if (!contacts) return it + 1;

  // Contact impulses at the end positions, and friction from them: a node
  // slides relative to its obstacle at most as fast as the normal velocity
  // it was given allows (Coulomb, lagged).
  auto applyFriction = [](Vec3d& vel, const Vec3d& normal, const Vec3d& v_obstacle, double dvn,
                          double mu) -> Vec3d {
    Vec3d vt = vel - v_obstacle;
    vt -= normal.dot(vt) * normal;
    const double speed = vt.norm();
    if (speed <= 0.0) return Vec3d::Zero();
    const Vec3d dv = -std::min(speed, mu * dvn) / speed * vt;
    vel += dv;
    return dv;
  };
  for (NodePlane& pl : contacts->planes) {
    const double d = pl.b - pl.n.dot(y[pl.node]);
    pl.impulse = d > 0.0 && !pinned[pl.node] ? k_contact * mass[pl.node] * d * dt : 0.0;
    pl.friction_impulse.setZero();
    if (pl.impulse > 0.0)
      pl.friction_impulse = mass[pl.node] * applyFriction(v_new[pl.node], pl.n, pl.velocity,
                                                          pl.impulse / mass[pl.node], pl.friction);
  }
  if (contacts->walls)
    for (size_t i = 0; i < n; ++i) {
      if (pinned[i]) continue;
      const Vec3d pen = wallPenetration(*contacts, y[i]);
      for (int d = 0; d < 3; ++d)
        if (pen[d] != 0.0)
          applyFriction(v_new[i], Vec3d::Unit(d) * (pen[d] > 0 ? 1.0 : -1.0), Vec3d::Zero(),
                        contacts->kappa * std::abs(pen[d]) / dt, contacts->wall_friction);
    }
  return it + 1;
}

}  // namespace triad
