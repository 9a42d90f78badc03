// Finite elements of volumetric elastic solids (issue 5, first part): the
// voxel tetrahedralization, element forces and the explicit integrator.
// GCC 12 reports Eigen's AVX-512 reductions (12 x 12 LDL^T, norms),
// inlined here, as reading uninitialized lanes: a known false positive.
// The pragma must come before Eigen's headers to take effect.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include "sim/mpm/particles.h"
#include "sim/solids/elastic_contact.h"
#include "sim/solids/elastic_solid.h"
#include "sim/solids/fem.h"
#include "sim/solids/tet_mesh.h"

namespace triad {
namespace {

std::vector<Vec3d> boxCells(const Vec3d& lo, const Eigen::Vector3i& n, double h) {
  std::vector<Vec3d> c;
  for (int i = 0; i < n.x(); ++i)
    for (int j = 0; j < n.y(); ++j)
      for (int k = 0; k < n.z(); ++k) c.push_back(lo + h * (Vec3d(i, j, k) + Vec3d::Constant(0.5)));
  return c;
}

MaterialDesc rubber(double E, double nu, MaterialModel model = MaterialModel::FixedCorotated) {
  MaterialDesc m;
  m.model = model;
  m.density = 1000;
  m.youngs_modulus = E;
  m.poisson_ratio = nu;
  return m;
}

TEST(TetMesh, VoxelsConformAndFillTheirVolume) {
  const double h = 0.01;
  const TetMesh m = tetsFromVoxels(boxCells(Vec3d(0.1, 0.2, 0.3), {3, 4, 5}, h), h);
  EXPECT_EQ(m.tets.size(), 6u * 60u);
  EXPECT_EQ(m.nodes.size(), 4u * 5u * 6u);  // corners shared between cells
  double vol = 0.0;
  for (size_t t = 0; t < m.tets.size(); ++t) {
    ASSERT_GT(m.restVolume(t), 0.0);
    vol += m.restVolume(t);
  }
  EXPECT_NEAR(vol, 60 * h * h * h, 1e-12);
  // Conforming: every interior face is shared by exactly two tetrahedra,
  // so the boundary faces are exactly the box's 2 (3x4 + 4x5 + 3x5) x 2.
  std::map<std::array<int, 3>, int> faces;
  for (const auto& t : m.tets)
    for (int k = 0; k < 4; ++k) {
      std::array<int, 3> f{t[(k + 1) % 4], t[(k + 2) % 4], t[(k + 3) % 4]};
      std::sort(f.begin(), f.end());
      faces[f]++;
    }
  int boundary = 0;
  for (const auto& [f, count] : faces) {
    ASSERT_LE(count, 2);
    boundary += count == 1;
  }
  EXPECT_EQ(boundary, 2 * (12 + 20 + 15) * 2);
}

TEST(TetMesh, EmbeddedPointsFollowTheMesh) {
  const double h = 0.01;
  const TetMesh m = tetsFromVoxels(boxCells(Vec3d::Zero(), {2, 2, 2}, h), h);
  const std::vector<Vec3d> pts = {{0.003, 0.011, 0.017}, {0.02, 0.02, 0.02}, {0.0, 0.005, 0.01}};
  const auto emb = embed(m, pts);
  // An affine map of the nodes moves embedded points by the same map.
  Mat3d A;
  A << 1.1, 0.2, 0.0, -0.1, 0.9, 0.3, 0.05, 0.0, 1.2;
  const Vec3d b(0.5, -0.2, 0.1);
  std::vector<Vec3d> x;
  for (const Vec3d& p : m.nodes) x.push_back(A * p + b);
  for (size_t i = 0; i < pts.size(); ++i)
    EXPECT_LT((embeddedPosition(m, x, emb[i]) - (A * pts[i] + b)).norm(), 1e-12);
}

// Rigid motions store no energy and make no force, for both models.
TEST(Fem, RotatedSolidHasNoForce) {
  for (MaterialModel model : {MaterialModel::FixedCorotated, MaterialModel::NeoHookean}) {
    FemBody b = makeFemBody(tetsFromVoxels(boxCells(Vec3d::Zero(), {3, 3, 3}, 0.01), 0.01),
                            rubber(1e6, 0.3, model));
    const Mat3d R = Eigen::AngleAxisd(1.1, Vec3d(1, 2, 3).normalized()).toRotationMatrix();
    for (Vec3d& p : b.x) p = R * p + Vec3d(3, -1, 2);
    std::vector<Vec3d> f;
    b.forces(f);
    double fmax = 0.0;
    for (const Vec3d& fi : f) fmax = std::max(fmax, fi.norm());
    // Scale: E h^2 = 100 N for a 1% strain.
    EXPECT_LT(fmax, 1e-8 * 1e6 * 0.01 * 0.01);
    EXPECT_LT(b.elasticEnergy(), 1e-12);
    EXPECT_NEAR(b.totalMass(), 1000 * 27e-6, 1e-12);
  }
}

// Forces are minus the gradient of the energy (finite differences).
TEST(Fem, ForcesAreMinusEnergyGradient) {
  FemBody b = makeFemBody(tetsFromVoxels(boxCells(Vec3d::Zero(), {2, 2, 2}, 0.01), 0.01),
                          rubber(1e5, 0.3));
  for (size_t i = 0; i < b.x.size(); ++i)
    b.x[i] += 0.001 * Vec3d(std::sin(3.0 * i), std::cos(5.0 * i), std::sin(7.0 * i + 1));
  std::vector<Vec3d> f;
  b.forces(f);
  const double eps = 1e-7;
  for (size_t i = 0; i < b.x.size(); i += 5)
    for (int d = 0; d < 3; ++d) {
      const double x0 = b.x[i][d];
      b.x[i][d] = x0 + eps;
      const double ep = b.elasticEnergy();
      b.x[i][d] = x0 - eps;
      const double em = b.elasticEnergy();
      b.x[i][d] = x0;
      EXPECT_NEAR(f[i][d], -(ep - em) / (2 * eps), 1e-5 * (1 + std::abs(f[i][d])));
    }
}

// The implicit solve's Hessian is the derivative of the forces: the
// assembled element stiffnesses times a displacement match a central
// difference of the forces along it, for both models (to 1e-5 of its size),
// and the projection to positive semi-definite leaves an element that is
// already so unchanged while an inverted one loses its negative eigenvalues.
TEST(Fem, StiffnessIsTheDerivativeOfTheForces) {
  for (MaterialModel model : {MaterialModel::FixedCorotated, MaterialModel::NeoHookean}) {
    FemBody b = makeFemBody(tetsFromVoxels(boxCells(Vec3d::Zero(), {2, 2, 2}, 0.01), 0.01),
                            rubber(1e5, 0.3, model));
    for (size_t i = 0; i < b.x.size(); ++i)
      b.x[i] += 0.002 * Vec3d(std::sin(3.0 * i), std::cos(5.0 * i), std::sin(7.0 * i + 1));
    std::vector<Vec3d> dir(b.x.size());
    for (size_t i = 0; i < dir.size(); ++i)
      dir[i] = Vec3d(std::cos(2.0 * i + 0.3), std::sin(11.0 * i), std::cos(13.0 * i));
    // K dir, element by element.
    std::vector<Vec3d> kd(b.x.size(), Vec3d::Zero());
    for (size_t t = 0; t < b.mesh.tets.size(); ++t) {
      const auto K = b.elementStiffness(b.x, t, false);
      const auto& nd = b.mesh.tets[t];
      for (int a = 0; a < 4; ++a)
        for (int c = 0; c < 4; ++c) kd[nd[a]] += K.block<3, 3>(3 * a, 3 * c) * dir[nd[c]];
    }
    // -(f(x + eps dir) - f(x - eps dir)) / (2 eps).
    const double eps = 1e-7;
    std::vector<Vec3d> yp = b.x, ym = b.x, fp, fm;
    for (size_t i = 0; i < dir.size(); ++i) yp[i] += eps * dir[i], ym[i] -= eps * dir[i];
    b.forcesAt(yp, fp);
    b.forcesAt(ym, fm);
    double err = 0.0, scale = 0.0;
    for (size_t i = 0; i < dir.size(); ++i) {
      err = std::max(err, (kd[i] + (fp[i] - fm[i]) / (2 * eps)).norm());
      scale = std::max(scale, kd[i].norm());
    }
    EXPECT_GT(scale, 100.0);  // E h = 1000 N/m a unit displacement: a real stiffness
    EXPECT_LT(err, 1e-5 * scale) << "model " << int(model);
    // At rest every element is positive semi-definite already: the
    // projection keeps it. (Deformed ones need not be: a corotated
    // element's twist modes soften, and go negative, under compression.)
    const std::vector<Vec3d> rest = b.mesh.nodes;
    for (size_t t = 0; t < b.mesh.tets.size(); t += 7)
      EXPECT_TRUE(b.elementStiffness(rest, t, true).isApprox(b.elementStiffness(rest, t, false), 1e-12));
    // Squash one element flat and through: its projected stiffness has no
    // negative eigenvalue, the raw one does.
    std::vector<Vec3d> y = b.x;
    const auto& nd = b.mesh.tets[0];
    y[nd[3]] = (y[nd[0]] + y[nd[1]] + y[nd[2]]) / 3.0 - 0.3 * (y[nd[3]] - y[nd[0]]);
    // (Sylvester: the pivots of a pivoted LDL^T have the eigenvalues' signs.)
    const Eigen::LDLT<Eigen::MatrixXd> raw(Eigen::MatrixXd(b.elementStiffness(y, 0, false)));
    const Eigen::LDLT<Eigen::MatrixXd> psd(Eigen::MatrixXd(b.elementStiffness(y, 0, true)));
    const double size = raw.vectorD().cwiseAbs().maxCoeff();
    EXPECT_LT(raw.vectorD().minCoeff(), -1e-6 * size);
    EXPECT_GT(psd.vectorD().minCoeff(), -1e-9 * size);
  }
}

// dP/dF assembled in the singular values' frame is the model's own dP/dF,
// and its projection is what a 9x9 eigendecomposition gives, for stretched,
// squashed, sheared, nearly flat and inverted F, with two equal singular
// values too (where the pairs' formulas would divide by their difference).
TEST(Fem, SvdFrameDerivativeMatchesTheModelAndItsProjection) {
  const std::vector<Mat3d> cases = [] {
    std::vector<Mat3d> fs;
    Mat3d F;
    F << 1.1, 0.2, -0.1, 0.05, 0.9, 0.3, -0.2, 0.1, 1.05;
    fs.push_back(F);                                       // general
    fs.push_back(0.7 * Mat3d::Identity());                 // squashed, three equal
    fs.push_back(Vec3d(1.3, 1.3, 0.6).asDiagonal());       // two equal
    fs.push_back(Vec3d(1.0, 1.0, 0.02).asDiagonal());      // nearly flat
    fs.push_back(Vec3d(0.9, 1.1, -0.4).asDiagonal() * F);  // inverted
    F << 0.95, 0.6, 0, 0, 0.95, 0, 0, 0, 0.97;
    fs.push_back(F);  // sheared, compressed
    for (int k = 0; k < 20; ++k) {
      Mat3d R;
      for (int i = 0; i < 9; ++i) R(i) = std::sin(1.7 * k + 2.3 * i) * 0.45;
      fs.push_back(Mat3d::Identity() + R);
    }
    return fs;
  }();
  for (MaterialModel m : {MaterialModel::FixedCorotated, MaterialModel::NeoHookean}) {
    const ElasticModel model = makeElasticModel(rubber(1e5, 0.3, m));
    for (size_t c = 0; c < cases.size(); ++c) {
      const Mat3d& F = cases[c];
      const Mat9<double> exact =
          std::visit([&](const auto& mat) { return mat.firstPiolaDerivative(F); }, model);
      const double scale = exact.cwiseAbs().maxCoeff();
      const Mat9<double> raw = svdFrameDerivative(model, F, false);
      EXPECT_LT((raw - exact).cwiseAbs().maxCoeff(), 1e-9 * scale)
          << "model " << int(m) << ", case " << c;
      const Eigen::SelfAdjointEigenSolver<Mat9<double>> eig(0.5 * (exact + exact.transpose()));
      const Mat9<double> projected = eig.eigenvectors() *
                                     eig.eigenvalues().cwiseMax(0.0).asDiagonal() *
                                     eig.eigenvectors().transpose();
      const Mat9<double> psd = svdFrameDerivative(model, F, true);
      EXPECT_LT((psd - projected).cwiseAbs().maxCoeff(), 1e-8 * scale)
          << "model " << int(m) << ", case " << c;
    }
  }
}

// A stretched, released block vibrates freely: symplectic Euler at its
// stable step keeps the total energy, neither gaining nor losing it.
TEST(Fem, ExplicitFreeVibrationKeepsEnergy) {
  FemBody b = makeFemBody(tetsFromVoxels(boxCells(Vec3d::Zero(), {6, 3, 3}, 0.01), 0.01),
                          rubber(1e5, 0.3));
  for (Vec3d& p : b.x) p.x() *= 1.05;
  const double e0 = b.elasticEnergy();
  ASSERT_GT(e0, 0.0);
  const double dt = b.stableDt(0.5);
  std::vector<Vec3d> f;
  // Symplectic Euler's energy oscillates with the step (velocities live
  // half a step off the positions): its peaks wander by 2% as the modes
  // beat, its mean over a thousand steps by 0.3% (16000 steps measured).
  // What must not happen is drift: the mean late in the run is the mean
  // of the start.
  double early = 0.0, late = 0.0, peak = 0.0, ke_max = 0.0;
  for (int s = 0; s < 4000; ++s) {
    b.stepExplicit(dt, Vec3d::Zero(), f);
    const double ke = b.kineticEnergy(), e = ke + b.elasticEnergy();
    if (s < 1000) early += e / 1000, peak = std::max(peak, e);
    if (s >= 3000) late += e / 1000;
    ke_max = std::max(ke_max, ke);
  }
  EXPECT_GT(ke_max, 0.3 * e0);      // it does vibrate
  EXPECT_LT(late, 1.005 * early);   // gains no energy over 4000 steps
  EXPECT_GT(late, 0.995 * early);   // and loses none
  EXPECT_LT(peak, 1.2 * e0);        // the oscillation of the measured energy is bounded
}

// A column H tall on nodes pinned at its base (nu = 0: a 1D bar), which
// sags under its own weight by rho g H^2 / (2 E) at the top once settled.
constexpr double kColumnH = 0.2, kColumnE = 2e5, kColumnRho = 1000, kG = 9.81;
constexpr double kColumnSag = kColumnRho * kG * kColumnH * kColumnH / (2 * kColumnE);  // 0.98 mm

FemBody pinnedColumn() {
  const double h = 0.02;
  FemBody b = makeFemBody(tetsFromVoxels(boxCells(Vec3d::Zero(), {2, 10, 2}, h), h),
                          rubber(kColumnE, 0.0));
  for (size_t i = 0; i < b.x.size(); ++i) b.pinned[i] = b.x[i].y() < 1e-9;
  return b;
}

// How far the column's top nodes have come down, on average.
double topSag(const FemBody& b) {
  double top = 0.0;
  int n = 0;
  for (size_t i = 0; i < b.x.size(); ++i)
    if (std::abs(b.mesh.nodes[i].y() - kColumnH) < 1e-9) top += b.x[i].y(), ++n;
  return kColumnH - top / n;
}

TEST(Fem, ColumnSagsByRhoGHSquaredOverTwoE) {
  const double g = kG;
  FemBody b = pinnedColumn();
  const double dt = b.stableDt(0.5);
  std::vector<Vec3d> f;
  // Settle with mass-proportional damping (the test's, not the solver's).
  for (int s = 0; s < 4000; ++s) {
    b.stepExplicit(dt, Vec3d(0, -g, 0), f);
    for (Vec3d& vi : b.v) vi *= 1.0 - 50.0 * dt;
  }
  EXPECT_NEAR(topSag(b), kColumnSag, 0.05 * kColumnSag);
  EXPECT_LT(b.kineticEnergy(), 1e-9);
}

// Backward Euler at 20 times the explicit stable step: explicit blows up
// there, implicit stays finite and never gains energy (at this step its
// numerical damping is strong: the block moves, then settles).
TEST(Fem, ImplicitIsStableWhereExplicitIsNot) {
  auto stretched = []() {
    FemBody b = makeFemBody(tetsFromVoxels(boxCells(Vec3d::Zero(), {6, 3, 3}, 0.01), 0.01),
                            rubber(1e5, 0.3));
    for (Vec3d& p : b.x) p.x() *= 1.05;
    return b;
  };
  FemBody ex = stretched(), im = stretched();
  const double dt = 20 * ex.stableDt(0.5);
  std::vector<Vec3d> f, v;
  for (int s = 0; s < 50; ++s) ex.stepExplicit(dt, Vec3d::Zero(), f);
  double ex_max = 0.0;
  for (const Vec3d& p : ex.x) ex_max = std::max(ex_max, std::isfinite(p.norm()) ? p.norm() : 1e300);
  EXPECT_GT(ex_max, 1.0);  // exploded (or went non-finite)

  const double e0 = im.elasticEnergy();
  double e_prev = e0, ke_max = 0.0;
  for (int s = 0; s < 50; ++s) {
    im.implicitVelocities(dt, Vec3d::Zero(), v);
    im.v = v;
    for (size_t i = 0; i < im.nodes(); ++i) im.x[i] += dt * im.v[i];
    const double e = im.kineticEnergy() + im.elasticEnergy();
    ASSERT_TRUE(std::isfinite(e));
    EXPECT_LE(e, e_prev * (1 + 1e-9));  // backward Euler never adds energy
    e_prev = e;
    ke_max = std::max(ke_max, im.kineticEnergy());
  }
  EXPECT_GT(ke_max, 0.02 * e0);  // it moved before the damping took the energy
}

// Implicit steps of a pinned column settle to the static sag, at steps far
// beyond the explicit limit, with no added damping.
TEST(Fem, ImplicitColumnSettlesToStaticSag) {
  const double g = kG;
  FemBody b = pinnedColumn();
  const double dt = 50 * b.stableDt(0.5);
  std::vector<Vec3d> v;
  for (int s = 0; s < 60; ++s) {
    b.implicitVelocities(dt, Vec3d(0, -g, 0), v);
    b.v = v;
    for (size_t i = 0; i < b.nodes(); ++i) b.x[i] += dt * b.v[i];
  }
  EXPECT_NEAR(topSag(b), kColumnSag, 0.05 * kColumnSag);
}

// The column's first axial mode, sin(pi y / 2H): its share of the sag,
// the nodes' displacements weighted by mass and the mode. The top alone
// carries the higher modes too, which shift its extrema by up to 1.5% of
// a period from one to the next in an undamped run.
double firstModeSag(const FemBody& b) {
  double num = 0.0, den = 0.0;
  for (size_t i = 0; i < b.x.size(); ++i) {
    const double phi = std::sin(M_PI * b.mesh.nodes[i].y() / (2 * kColumnH));
    num += b.mass[i] * phi * (b.mesh.nodes[i].y() - b.x[i].y());
    den += b.mass[i] * phi * phi;
  }
  return num / den;
}

// The column released under gravity, stepped by `step` until `t_end`: its
// first mode's sag at every step.
template <class Step>
std::vector<double> modeHistory(FemBody& b, double dt, double t_end, Step step) {
  std::vector<double> u;
  for (double t = 0; t < t_end; t += dt) {
    step(b, dt);
    u.push_back(firstModeSag(b));
  }
  return u;
}

// Successive extrema of a sampled signal: (time, value), a parabola through
// each extreme sample and its neighbours.
std::vector<std::pair<double, double>> extrema(const std::vector<double>& u, double dt) {
  std::vector<std::pair<double, double>> e;
  for (size_t i = 1; i + 1 < u.size(); ++i) {
    const double a = u[i - 1], b = u[i], c = u[i + 1];
    if ((b > a && b >= c) || (b < a && b <= c)) {
      const double den = a - 2 * b + c, off = den != 0 ? 0.5 * (a - c) / den : 0.0;
      e.emplace_back((double(i) + off) * dt, b - 0.25 * (a - c) * off);
    }
  }
  return e;
}

// Kelvin-Voigt damping (the solid's `damping`, eta): on the pinned column
// (nu = 0, so every element is in uniaxial strain) the viscous stress is
// 2 eta de/dt beside E e, and the first mode rings down at the damping
// ratio zeta = eta w / E: amplitude exp(-2 pi zeta / sqrt(1 - zeta^2)) per
// period, the period 1 / sqrt(1 - zeta^2) longer. Higher modes, damped in
// proportion to their frequency, are gone by the second period.
TEST(Fem, DampingRingsDownAtItsDampingRatio) {
  const Vec3d g(0, -kG, 0);
  FemBody free_col = pinnedColumn();
  std::vector<Vec3d> f;
  const double dt0 = free_col.stableDt(0.5);
  const auto e0 = extrema(modeHistory(free_col, dt0, 0.25, [&](FemBody& b, double h) {
    b.stepExplicit(h, g, f);
  }), dt0);
  ASSERT_GE(e0.size(), 5u);
  const double period = 0.5 * (e0[4].first - e0[0].first), w = 2 * M_PI / period;
  for (double zeta : {0.02, 0.1}) {
    FemBody b = pinnedColumn();
    b.damping = zeta * kColumnE / w;
    const double dt = b.stableDt(0.5);
    EXPECT_LT(dt, dt0 + 1e-15);  // the viscous limit, where it is the smaller
    const auto e = extrema(modeHistory(b, dt, 6 * period, [&](FemBody& c, double h) {
      c.stepExplicit(h, g, f);
    }), dt);
    ASSERT_GE(e.size(), 7u);
    const double amp1 = std::abs(e[2].second - e[1].second);
    const double amp2 = std::abs(e[4].second - e[3].second);
    const double expect = std::exp(-2 * M_PI * zeta / std::sqrt(1 - zeta * zeta));
    const double damped_period = 0.5 * (e[5].first - e[1].first);
    std::printf("zeta %.2f (eta %.1f Pa s): amplitude per period %.4f (Kelvin-Voigt %.4f), period "
                "%.5f s (undamped %.5f, expected %.5f)\n",
                zeta, b.damping, amp2 / amp1, expect, damped_period, period,
                period / std::sqrt(1 - zeta * zeta));
    EXPECT_NEAR(amp2 / amp1, expect, 0.01);
    EXPECT_NEAR(damped_period, period / std::sqrt(1 - zeta * zeta), 0.01 * period);
  }
  // A rigid motion is not damped: a spinning, moving column keeps its
  // kinetic energy.
  FemBody spin = pinnedColumn();
  spin.damping = 100.0;
  for (size_t i = 0; i < spin.nodes(); ++i) {
    spin.pinned[i] = 0;
    const Vec3d r = spin.x[i] - Vec3d(0.02, 0.1, 0.02);
    spin.v[i] = Vec3d(0.3, 0, 0) + Vec3d(0, 0, 2.0).cross(r);
  }
  const double ke0 = spin.kineticEnergy(), h = spin.stableDt(0.5);
  for (int k = 0; k < 200; ++k) spin.stepExplicit(h, Vec3d::Zero(), f);
  EXPECT_NEAR(spin.kineticEnergy(), ke0, 0.01 * ke0);
}

// Backward Euler's own dynamics on the pinned column suddenly loaded by its
// weight. For an oscillation of angular frequency w it multiplies the
// amplitude by (1 + w^2 h^2)^(-1/2) and advances the phase by atan(w h)
// each step h. The mesh's own frequency is measured with symplectic Euler
// (its error, (w h)^2 / 24, is 2.6e-4 here); at h = T / 40 the implicit run
// must then ring at atan(w h) / h (period 0.8% longer) and lose 39% of its
// amplitude per period, the first mode alone once the higher ones are damped.
// Both runs follow the first mode's share of the displacement, which the
// higher modes do not shift. Measured: period 1.0082 T against 1.0081,
// amplitude ratio per period 0.612 against 0.614; the explicit period
// 0.05664 s, the 1D bar's 4 H / c 0.05657. A wrong stiffness changes the
// period; a solver that is not backward Euler (or adds damping) the decay.
TEST(Fem, ImplicitVibrationRingsAndDecaysAsBackwardEuler) {
  const Vec3d g(0, -kG, 0);
  FemBody ex = pinnedColumn();
  const double dt_ex = ex.stableDt(0.5);
  std::vector<Vec3d> f, v;
  const std::vector<double> u_ex = modeHistory(ex, dt_ex, 0.25, [&](FemBody& b, double h) {
    b.stepExplicit(h, g, f);
  });
  const auto e_ex = extrema(u_ex, dt_ex);
  ASSERT_GE(e_ex.size(), 5u);
  // Maxima are every other extreme: the period from the first to the third.
  const double period = 0.5 * (e_ex[4].first - e_ex[0].first);
  const double w = 2 * M_PI / period;
  std::printf("explicit: period %.5f s (1D bar: %.5f)\n", period,
              4 * kColumnH / std::sqrt(kColumnE / kColumnRho));

  FemBody im = pinnedColumn();
  const double h = period / 40;
  const std::vector<double> u_im = modeHistory(im, h, 3 * period, [&](FemBody& b, double step) {
    b.implicitVelocities(step, g, v);
    b.v = v;
    for (size_t i = 0; i < b.nodes(); ++i) b.x[i] += step * b.v[i];
  });
  const auto e_im = extrema(u_im, h);
  ASSERT_GE(e_im.size(), 5u);
  // From the second extreme on (the higher modes are gone by then): the
  // period from each extreme to the next but one.
  const double period_im = 0.5 * (e_im[3].first - e_im[1].first + e_im[4].first - e_im[2].first);
  const double amp1 = 0.5 * std::abs(e_im[1].second - e_im[2].second);
  const double amp2 = 0.5 * std::abs(e_im[3].second - e_im[4].second);
  const double expect_period = 2 * M_PI * h / std::atan(w * h);
  const double expect_ratio = std::pow(1 + w * w * h * h, -20.0);  // 40 steps, half power each
  std::printf("implicit: period %.5f s (backward Euler %.5f), amplitude ratio per period %.3f "
              "(backward Euler %.3f)\n",
              period_im, expect_period, amp2 / amp1, expect_ratio);
  EXPECT_NEAR(period_im / period, expect_period / period, 0.002);
  EXPECT_NEAR(amp2 / amp1, expect_ratio, 0.04);
}

// A box of n cells of side h from lo as an elastic solid: each cell's
// sample at its distance to the box's faces, its normal up or (`radial`)
// away from the box's centre.
ElasticSolid elasticBox(const Vec3d& lo, const Eigen::Vector3i& n, double h, bool radial) {
  const Vec3d hi = lo + h * n.cast<double>();
  CollisionSamples samples;
  samples.spacing = h;
  for (const Vec3d& c : boxCells(lo, n, h)) {
    samples.x.push_back(c.cast<float>());
    samples.phi.push_back(-float(std::min((c - lo).minCoeff(), (hi - c).minCoeff())));
    const Vec3d up(0, 1, 0), out = (c - 0.5 * (lo + hi)).normalized();
    samples.normal.push_back((radial ? out : up).cast<float>());
  }
  return makeElasticSolid(0, "box", samples, TriSurface{}, rubber(1e5, 0.3), 0.5, Vec3d::Zero());
}

// An elastic solid's nodes carry their distance to the mesh's boundary at
// rest, as the coupling reads it: 0 on the boundary; -h one layer in under
// a face (half its cells a half spacing deep, half one and a half); never
// deeper than the node really is, and at least half a spacing deep (the
// mean of a node's cells' distances is shallower along edges and on the
// medial axis: -0.75 h one layer in under an edge, -0.625 h under a
// corner).
TEST(ElasticSolid, NodesCarryTheirDistanceAtRest) {
  const double h = 0.01;
  const Vec3d lo(0.1, 0.2, 0.3);
  const Eigen::Vector3i n(4, 4, 6);
  const Vec3d hi = lo + h * n.cast<double>();
  const ElasticSolid e = elasticBox(lo, n, h, false);
  ASSERT_EQ(e.phi0.size(), size_t(5 * 5 * 7));
  int boundary = 0, under_a_face = 0;
  for (size_t i = 0; i < e.phi0.size(); ++i) {
    // Depth along each axis, in spacings (the samples are floats).
    const Vec3d x = e.fem.mesh.nodes[i];
    const Vec3d d = (x - lo).cwiseMin(hi - x) / h;
    const double depth = h * d.minCoeff();
    if (d.minCoeff() < 1e-4) {
      EXPECT_EQ(e.phi0[i], 0.0f);
      ++boundary;
      continue;
    }
    EXPECT_LE(e.phi0[i], -0.5 * h + 1e-6);
    EXPECT_GE(e.phi0[i], -depth - 1e-6);
    int shallow = 0;
    for (int a = 0; a < 3; ++a) shallow += d[a] < 1.5;
    if (shallow == 1) {
      EXPECT_NEAR(e.phi0[i], -h, 1e-6);
      ++under_a_face;
    }
  }
  EXPECT_EQ(boundary, 5 * 5 * 7 - 3 * 3 * 5);
  EXPECT_EQ(under_a_face, 6 + 6 + 2);
}

// A particle found inside an elastic solid leaves it through an inelastic
// collision with the solid's point under it: momentum kept, no kinetic
// energy made, and the two moving alike along the face's normal after.
// A water particle can outweigh a light solid's corner node thirty times:
// handing the node the particle's whole approach momentum threw it off at
// many times the particle's speed.
TEST(ElasticSolid, ParticlePushedOutMeetsTheSolidInelastically) {
  const double h = 0.02, dt = 1e-4;
  for (const double ratio : {30.0, 0.03}) {  // particle mass over the corner node's
    ElasticSolid e = elasticBox(Vec3d::Zero(), {2, 2, 2}, h, false);
    const FemBody& fem = e.fem;
    const double corner = *std::min_element(fem.mass.begin(), fem.mass.end());
    ParticleSet set;
    set.mass = float(ratio * corner);
    // Just under the top face, near a corner, moving down into the solid.
    const Vec3d x0(0.1 * h, 2 * h - 0.05 * h, 0.1 * h), v0(0.3, -1.0, 0.2);
    set.push(x0.cast<float>(), v0.cast<float>(), 0, 0);
    std::vector<ParticleSet> sets{set};
    const std::vector<std::vector<uint32_t>> offsets{{0, 1}};
    ParticleBlocks blocks;
    blocks.offsets = &offsets;
    blocks.centre = {x0};
    blocks.radius = h;
    ASSERT_EQ(pushParticlesOut(e, sets, dt, blocks), 1u) << ratio;

    const double mp = double(set.mass);
    const Vec3d vp = sets[0].v[0].cast<double>();
    Vec3d momentum = mp * vp;
    double energy = 0.5 * mp * vp.squaredNorm();
    for (size_t i = 0; i < fem.nodes(); ++i) {
      momentum += fem.mass[i] * fem.v[i];
      energy += 0.5 * fem.mass[i] * fem.v[i].squaredNorm();
    }
    const double before = 0.5 * mp * v0.squaredNorm();
    EXPECT_LT((momentum - mp * v0).norm(), 1e-6 * mp) << ratio;
    EXPECT_LE(energy, before) << ratio;
    // On the face, moving with the solid's point where it was found (its
    // tetrahedron's barycentric weights) along the face's normal, up.
    EXPECT_NEAR(double(sets[0].x[0].y()), 2 * h, 1e-6) << ratio;
    double vb = std::nan("");
    for (const auto& t : fem.mesh.tets) {
      Mat3d E;
      for (int k = 0; k < 3; ++k) E.col(k) = fem.x[size_t(t[k + 1])] - fem.x[size_t(t[0])];
      const Vec3d l = E.inverse() * (x0 - fem.x[size_t(t[0])]);
      if (l.minCoeff() < -1e-9 || l.sum() > 1 + 1e-9) continue;
      vb = (1 - l.sum()) * fem.v[size_t(t[0])].y();
      for (int k = 0; k < 3; ++k) vb += l[k] * fem.v[size_t(t[k + 1])].y();
      break;
    }
    EXPECT_NEAR(vp.y(), vb, 1e-6) << ratio;
    // A light particle is stopped; a heavy one keeps most of its speed.
    if (ratio < 1.0)
      EXPECT_NEAR(vp.y(), 0.0, 0.05) << ratio;
    else
      EXPECT_LT(vp.y(), -0.5) << ratio;
    // Tangential motion passes through.
    EXPECT_NEAR(vp.x(), v0.x(), 1e-6) << ratio;
  }
}

// The node normals the poses read from the forces' kept F^-T are those
// formed from the nodes (F^-T N, normalised), on a solid deformed by a
// shear, a stretch and a rotation; the forces at other positions, or with
// damping, keep none, and the normals are formed from the nodes then.
TEST(ElasticSolid, NormalsFromTheForcesMatchThoseFromTheNodes) {
  const double h = 0.01;
  const Vec3d lo(0.1, 0.2, 0.3);
  const Eigen::Vector3i n(5, 3, 4);  // 60 cells, 360 elements: many lane groups
  ElasticSolid e = elasticBox(lo, n, h, true);
  Mat3d A;
  A << 1.2, 0.3, 0.0, -0.1, 0.9, 0.2, 0.05, 0.0, 1.1;
  const Mat3d R = Eigen::AngleAxisd(0.7, Vec3d(1, 2, 3).normalized()).toRotationMatrix();
  for (size_t i = 0; i < e.fem.nodes(); ++i) {
    const Vec3d p = e.fem.mesh.nodes[i];
    // Plus a bend and a twist, so that every element's F differs (the six
    // Kuhn tetrahedra of a cell see the cross terms differently).
    const Vec3d q = (p - lo) / h;
    e.fem.x[i] =
        R * A * p + 1e-3 * Vec3d(q.y() * q.z(), q.x() * q.x() + q.x() * q.z(), q.x() * q.y());
  }
  std::vector<Vec3d> f;
  e.fem.forces(f);
  size_t kept = 0;
  for (size_t i = 0; i < e.fem.nodes(); ++i) {
    kept += e.fem.keptInverseTranspose(size_t(e.node_tet[i])) != nullptr;
    EXPECT_LT((e.normalAfterForces(i) - e.normal(i)).norm(), 1e-12) << "node " << i;
  }
  EXPECT_EQ(kept, e.fem.nodes());
  // Not at x: nothing kept for the poses.
  std::vector<Vec3d> y = e.fem.x;
  e.fem.forcesAt(y, f);
  EXPECT_EQ(e.fem.keptInverseTranspose(size_t(e.node_tet[0])), nullptr);
  e.fem.damping = 1.0;
  e.fem.forces(f);
  EXPECT_EQ(e.fem.keptInverseTranspose(size_t(e.node_tet[0])), nullptr);
}

}  // namespace
}  // namespace triad
