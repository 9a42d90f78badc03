// GCC 12 warns of uninitialised AVX-512 lanes inside Eigen's 9x9 eigen
// solver (a false positive reported in the intrinsics header, which the
// first include pulls in: hence before it).
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#include "sim/fem.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Eigenvalues>
#include <Eigen/SparseCholesky>

#include "sim/errors.h"

namespace triad {

namespace {

Mat3d edges(const std::vector<Vec3d>& p, const std::array<int, 4>& n) {
  Mat3d D;
  for (int k = 0; k < 3; ++k) D.col(k) = p[n[k + 1]] - p[n[0]];
  return D;
}

}  // namespace

ElasticModel makeElasticModel(const MaterialDesc& d) {
  switch (d.model) {
    case MaterialModel::FixedCorotated:
      return FixedCorotated<double>::fromYoungPoisson(d.youngs_modulus, d.poisson_ratio);
    case MaterialModel::NeoHookean:
      return NeoHookean<double>::fromYoungPoisson(d.youngs_modulus, d.poisson_ratio);
    default:
      throw InputError("", "elastic solids take a fixed_corotated or neo_hookean material");
  }
}

FemBody makeFemBody(TetMesh mesh, const MaterialDesc& material) {
  FemBody b;
  b.model = makeElasticModel(material);
  b.density = material.density;
  const Lame<double> l = lameFromYoungPoisson(material.youngs_modulus, material.poisson_ratio);
  b.wave_speed = std::sqrt((l.lambda + 2 * l.mu) / material.density);
  b.x = mesh.nodes;
  b.v.assign(mesh.nodes.size(), Vec3d::Zero());
  b.mass.assign(mesh.nodes.size(), 0.0);
  b.pinned.assign(mesh.nodes.size(), 0);
  for (size_t t = 0; t < mesh.tets.size(); ++t) {
    const Mat3d D = edges(mesh.nodes, mesh.tets[t]);
    b.dm_inv.push_back(D.inverse());
    b.volume.push_back(D.determinant() / 6.0);
    for (int k = 0; k < 4; ++k) b.mass[mesh.tets[t][k]] += 0.25 * material.density * b.volume.back();
  }
  // Smallest element height 3V / (largest face area), at rest: the
  // explicit step's length scale (Kuhn tetrahedra of a cube of side h have
  // heights down to h / sqrt(3)).
  b.min_height = mesh.spacing;
  for (size_t t = 0; t < mesh.tets.size(); ++t) {
    const auto& n = mesh.tets[t];
    double face = 0.0;
    for (int k = 0; k < 4; ++k) {
      const Vec3d& a = mesh.nodes[n[(k + 1) % 4]];
      const Vec3d& p = mesh.nodes[n[(k + 2) % 4]];
      const Vec3d& c = mesh.nodes[n[(k + 3) % 4]];
      face = std::max(face, 0.5 * (p - a).cross(c - a).norm());
    }
    b.min_height = std::min(b.min_height, 3.0 * b.volume[t] / face);
  }
  b.mesh = std::move(mesh);
  return b;
}

double FemBody::totalMass() const {
  double m = 0.0;
  for (double mi : mass) m += mi;
  return m;
}

void FemBody::forces(std::vector<Vec3d>& f) const { forcesAt(x, f); }

void FemBody::forcesAt(const std::vector<Vec3d>& y, std::vector<Vec3d>& f) const {
  // Element stresses in parallel (the polar decomposition is the cost),
  // then a serial scatter in element order: the same sums on any number of
  // threads.
  h_.resize(mesh.tets.size());
  // The material is visited once for the whole body, not per element.
  std::visit(
      [&](const auto& mat) {
#pragma omp parallel for schedule(static) if (mesh.tets.size() > 512)
        for (int64_t t = 0; t < int64_t(mesh.tets.size()); ++t) {
          const Mat3d F = edges(y, mesh.tets[t]) * dm_inv[t];
          // H = -V P Dm^-T: the forces on nodes 1..3; node 0 takes minus their sum.
          h_[t] = -volume[t] * mat.firstPiola(F) * dm_inv[t].transpose();
        }
      },
      model);
  f.assign(y.size(), Vec3d::Zero());
  for (size_t t = 0; t < mesh.tets.size(); ++t) {
    const auto& n = mesh.tets[t];
    for (int k = 0; k < 3; ++k) {
      f[n[k + 1]] += h_[t].col(k);
      f[n[0]] -= h_[t].col(k);
    }
  }
}

double FemBody::elasticEnergy() const {
  double e = 0.0;
  std::visit(
      [&](const auto& mat) {
        for (size_t t = 0; t < mesh.tets.size(); ++t)
          e += volume[t] * mat.psi(edges(x, mesh.tets[t]) * dm_inv[t]);
      },
      model);
  return e;
}

double FemBody::kineticEnergy() const {
  double e = 0.0;
  for (size_t i = 0; i < x.size(); ++i) e += 0.5 * mass[i] * v[i].squaredNorm();
  return e;
}

double FemBody::stableDt(double cfl) const { return cfl * min_height / wave_speed; }

void FemBody::stepExplicit(double dt, const Vec3d& gravity, std::vector<Vec3d>& f) {
  forces(f);
  for (size_t i = 0; i < x.size(); ++i) {
    if (pinned[i]) {
      v[i].setZero();
      continue;
    }
    v[i] += dt * (f[i] / mass[i] + gravity);
    x[i] += dt * v[i];
  }
}

double FemBody::incrementalPotential(const std::vector<Vec3d>& y,
                                     const std::vector<Vec3d>& target, double dt) const {
  double e = 0.0;
  for (size_t i = 0; i < y.size(); ++i) e += 0.5 * mass[i] / (dt * dt) * (y[i] - target[i]).squaredNorm();
  std::visit(
      [&](const auto& mat) {
        for (size_t t = 0; t < mesh.tets.size(); ++t)
          e += volume[t] * mat.psi(edges(y, mesh.tets[t]) * dm_inv[t]);
      },
      model);
  return e;
}

int FemBody::implicitVelocities(double dt, const Vec3d& gravity, std::vector<Vec3d>& v_new) const {
  using Sparse = Eigen::SparseMatrix<double>;
  const size_t n = x.size();
  std::vector<Vec3d> target(n), y = x, f;
  for (size_t i = 0; i < n; ++i)
    target[i] = pinned[i] ? x[i] : Vec3d(x[i] + dt * v[i] + dt * dt * gravity);
  const double tol = 1e-6 * mesh.spacing;
  int it = 0;
  for (; it < 20; ++it) {
    // Gradient of the incremental potential; pinned nodes stay.
    forcesAt(y, f);
    Eigen::VectorXd grad(3 * n);
    for (size_t i = 0; i < n; ++i) {
      const Vec3d gi = pinned[i] ? Vec3d::Zero()
                                 : Vec3d(mass[i] / (dt * dt) * (y[i] - target[i]) - f[i]);
      grad.segment<3>(3 * i) = gi;
    }
    // Hessian: M / dt^2 plus the elements' stiffness, each projected to be
    // positive semi-definite so that Newton's step always descends.
    std::vector<Eigen::Triplet<double>> trip;
    trip.reserve(mesh.tets.size() * 144 + 3 * n);
    for (size_t i = 0; i < n; ++i)
      for (int d = 0; d < 3; ++d)
        trip.emplace_back(int(3 * i + d), int(3 * i + d), pinned[i] ? 1.0 : mass[i] / (dt * dt));
    std::visit(
        [&](const auto& mat) {
          for (size_t t = 0; t < mesh.tets.size(); ++t) {
            const auto& nd = mesh.tets[t];
            const Mat3d& B = dm_inv[t];
            const Mat3d F = edges(y, nd) * B;
            Eigen::SelfAdjointEigenSolver<Mat9<double>> eig(mat.firstPiolaDerivative(F));
            const Mat9<double> A = eig.eigenvectors() *
                                   eig.eigenvalues().cwiseMax(0.0).asDiagonal() *
                                   eig.eigenvectors().transpose();
            // G: d vec(F) / d x, 9 x 12.
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
            const Eigen::Matrix<double, 12, 12> K = volume[t] * G.transpose() * A * G;
            for (int a = 0; a < 4; ++a)
              for (int b = 0; b < 4; ++b) {
                if (pinned[nd[a]] || pinned[nd[b]]) continue;
                for (int r = 0; r < 3; ++r)
                  for (int c = 0; c < 3; ++c)
                    trip.emplace_back(3 * nd[a] + r, 3 * nd[b] + c, K(3 * a + r, 3 * b + c));
              }
          }
        },
        model);
    Sparse H(int(3 * n), int(3 * n));
    H.setFromTriplets(trip.begin(), trip.end());
    Eigen::SimplicialLDLT<Sparse> solver(H);
    if (solver.info() != Eigen::Success) break;
    const Eigen::VectorXd p = -solver.solve(grad);
    if (p.cwiseAbs().maxCoeff() < tol) break;
    // Backtracking line search on the incremental potential (Armijo).
    const double e0 = incrementalPotential(y, target, dt), slope = grad.dot(p);
    double alpha = 1.0;
    std::vector<Vec3d> trial(n);
    for (int ls = 0; ls < 20; ++ls, alpha *= 0.5) {
      for (size_t i = 0; i < n; ++i) trial[i] = y[i] + alpha * Vec3d(p.segment<3>(3 * i));
      if (incrementalPotential(trial, target, dt) <= e0 + 1e-4 * alpha * slope) break;
    }
    y.swap(trial);
    if (alpha * p.cwiseAbs().maxCoeff() < tol) break;
  }
  v_new.resize(n);
  for (size_t i = 0; i < n; ++i) v_new[i] = (y[i] - x[i]) / dt;
  return it + 1;
}

}  // namespace triad
