// Tests for sim/materials/materials.h: energies, stresses and their derivatives
// against finite differences (in double), frame invariance, and the plastic
// return mappings of snow and sand.
#include "sim/materials/materials.h"

#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Geometry>
#include <Eigen/SVD>

#include "tests/material_helpers.h"

namespace triad {
namespace {

using namespace test;

using Mat9d = Mat9<double>;

constexpr double kE = 1e4, kNu = 0.3;  // moduli of order 1e3..1e4

// Rotated stretches in [0.4, 2.5]: large but uninverted deformations.
Mat3d largeDeformation(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(std::log(0.4), std::log(2.5));
  const Vec3d s(std::exp(u(rng)), std::exp(u(rng)), std::exp(u(rng)));
  return randomRotation(rng) * s.asDiagonal() * randomRotation(rng);
}

// Samples for the generic checks: near rest and large.
std::vector<Mat3d> sampleDeformations(unsigned seed) {
  std::mt19937 rng(seed);
  std::vector<Mat3d> out;
  for (int i = 0; i < 6; ++i) out.push_back(nearIdentity(rng));
  for (int i = 0; i < 6; ++i) out.push_back(largeDeformation(rng));
  return out;
}

// Central differences of a scalar function of F (h = 1e-6 relative to |F|:
// truncation ~1e-12, rounding ~1e-10 relative).
template <class Fn>
Mat3d gradientFD(Fn&& psi, const Mat3d& F) {
  const double h = 1e-6 * std::max(1.0, F.norm());
  Mat3d P;
  for (int k = 0; k < 9; ++k) {
    Mat3d Fp = F, Fm = F;
    Fp.data()[k] += h;
    Fm.data()[k] -= h;
    P.data()[k] = (psi(Fp) - psi(Fm)) / (2 * h);
  }
  return P;
}

// Central differences of a matrix function of F, in the column-major
// vectorization that firstPiolaDerivative documents.
template <class Fn>
Mat9d jacobianFD(Fn&& P, const Mat3d& F) {
  const double h = 1e-6 * std::max(1.0, F.norm());
  Mat9d D;
  for (int k = 0; k < 9; ++k) {
    Mat3d Fp = F, Fm = F;
    Fp.data()[k] += h;
    Fm.data()[k] -= h;
    const Mat3d dP = (P(Fp) - P(Fm)) / (2 * h);
    D.col(k) = Eigen::Map<const Eigen::Matrix<double, 9, 1>>(dP.data());
  }
  return D;
}

// Every model with psi(F) / firstPiola(F) / kirchhoff(F), wrapped so that
// snow (which also takes Jp) runs through the same checks.
template <class M>
struct Elastic {
  M m;
  double psi(const Mat3d& F) const { return m.psi(F); }
  Mat3d P(const Mat3d& F) const { return m.firstPiola(F); }
  Mat3d tau(const Mat3d& F) const { return m.kirchhoff(F); }
};
struct HardenedSnow {
  Snow<double> m;
  double jp;
  double psi(const Mat3d& F) const { return m.psi(F, jp); }
  Mat3d P(const Mat3d& F) const { return m.firstPiola(F, jp); }
  Mat3d tau(const Mat3d& F) const { return m.kirchhoff(F, jp); }
};

Snow<double> makeSnow() {
  Snow<double> s;
  s.elastic = FixedCorotated<double>::fromYoungPoisson(kE, kNu);
  return s;
}

template <class W>
void checkHyperelastic(const W& w, unsigned seed) {
  SCOPED_TRACE(seed);
  // Rest state: no energy, no stress
  const Mat3d I = Mat3d::Identity();
  EXPECT_NEAR(w.psi(I), 0.0, 1e-12 * kE);
  EXPECT_LE(w.P(I).norm(), 1e-12 * kE);
  EXPECT_LE(w.tau(I).norm(), 1e-12 * kE);
  std::mt19937 rng(seed);
  for (const Mat3d& F : sampleDeformations(seed)) {
    // P is the gradient of psi
    const Mat3d P = w.P(F);
    EXPECT_LT(relErr(P, gradientFD([&](const Mat3d& G) { return w.psi(G); }, F)), 1e-6) << F;
    // tau = P F^T
    EXPECT_LT(relErr(w.tau(F), P * F.transpose()), 1e-12) << F;
    // Frame indifference: psi(QF) = psi(F), P(QF) = Q P(F)
    const Mat3d Q = randomRotation(rng);
    EXPECT_NEAR(w.psi(Q * F), w.psi(F), 1e-12 * std::max(1.0, std::abs(w.psi(F))));
    EXPECT_LT(relErr(w.P(Q * F), Q * P), 1e-10) << F;
    // Deformed states store energy
    EXPECT_GT(w.psi(F), 0.0) << F;
  }
}

TEST(Lame, FromYoungPoisson) {
  const Lame<double> l = lameFromYoungPoisson(1e6, 0.25);
  EXPECT_DOUBLE_EQ(l.mu, 1e6 / 2.5);
  EXPECT_DOUBLE_EQ(l.lambda, 1e6 * 0.25 / (1.25 * 0.5));
}

TEST(FixedCorotated, HyperelasticConsistency) {
  checkHyperelastic(
      Elastic<FixedCorotated<double>>{FixedCorotated<double>::fromYoungPoisson(kE, kNu)}, 1);
}

TEST(NeoHookean, HyperelasticConsistency) {
  checkHyperelastic(Elastic<NeoHookean<double>>{NeoHookean<double>::fromYoungPoisson(kE, kNu)}, 2);
}

TEST(StvkHencky, HyperelasticConsistency) {
  checkHyperelastic(Elastic<StvkHencky<double>>{StvkHencky<double>::fromYoungPoisson(kE, kNu)}, 3);
}

TEST(Snow, HyperelasticConsistency) {
  for (const double jp : {0.8, 1.0, 1.3}) checkHyperelastic(HardenedSnow{makeSnow(), jp}, 4);
}

TEST(DruckerPrager, HyperelasticConsistency) {
  checkHyperelastic(Elastic<DruckerPrager<double>>{DruckerPrager<double>(kE, kNu, 30, 0)}, 5);
}

TEST(FixedCorotated, DerivativeMatchesFiniteDifferences) {
  const auto m = FixedCorotated<double>::fromYoungPoisson(kE, kNu);
  std::vector<Mat3d> samples = sampleDeformations(6);
  // Inverted ones too: the SVD path must handle a negative sigma(2)
  std::mt19937 rng(6);
  for (int i = 0; i < 4; ++i) {
    samples.push_back(randomRotation(rng) * Vec3d(1.2, 0.9, -0.3 - 0.1 * i).asDiagonal() *
                      randomRotation(rng));
  }
  for (const Mat3d& F : samples) {
    const Mat9d fd = jacobianFD([&](const Mat3d& G) { return m.firstPiola(G); }, F);
    EXPECT_LT(relErr(m.firstPiolaDerivative(F), fd), 1e-6) << F;
  }
  // At rest dP/dF is the linear-elastic stiffness: dP = mu (dF + dF^T) + lambda tr(dF) I
  const Mat9d D = m.firstPiolaDerivative(Mat3d::Identity());
  Mat3d dF;
  dF << 0.1, 0.2, -0.3, 0.4, 0.5, 0.6, -0.7, 0.8, 0.9;
  const Mat3d expected = m.mu * (dF + dF.transpose()) + m.lambda * dF.trace() * Mat3d::Identity();
  const Eigen::Matrix<double, 9, 1> dP =
      D * Eigen::Map<const Eigen::Matrix<double, 9, 1>>(dF.data());
  EXPECT_LT(relErr(Eigen::Map<const Mat3d>(dP.data()), expected), 1e-12);
}

TEST(NeoHookean, DerivativeMatchesFiniteDifferences) {
  const auto m = NeoHookean<double>::fromYoungPoisson(kE, kNu);
  for (const Mat3d& F : sampleDeformations(7)) {
    const Mat9d fd = jacobianFD([&](const Mat3d& G) { return m.firstPiola(G); }, F);
    EXPECT_LT(relErr(m.firstPiolaDerivative(F), fd), 1e-6) << F;
  }
}

TEST(FixedCorotated, InvertedIsFiniteAndRestoring) {
  const auto m = FixedCorotated<double>::fromYoungPoisson(kE, kNu);
  std::mt19937 rng(8);
  for (int i = 0; i < 20; ++i) {
    const Mat3d F = randomRotation(rng) * Vec3d(1.1, 0.9, -0.2).asDiagonal() * randomRotation(rng);
    ASSERT_LT(F.determinant(), 0);
    const Mat3d P = m.firstPiola(F);
    ASSERT_TRUE(P.allFinite());
    ASSERT_TRUE(m.kirchhoff(F).allFinite());
    EXPECT_LT(relErr(m.kirchhoff(F), P * F.transpose()), 1e-12);
    EXPECT_LT(relErr(P, gradientFD([&](const Mat3d& G) { return m.psi(G); }, F)), 1e-6);
    // A small step down the gradient lowers the energy, toward un-inverting.
    const double step = 1e-3 / P.norm();
    EXPECT_LT(m.psi(F - step * P), m.psi(F));
    EXPECT_GT((F - step * P).determinant(), F.determinant());
  }
  // Fully collapsed F: finite, and the volume term pushes outward.
  const Mat3d Z = Mat3d::Zero();
  EXPECT_TRUE(m.firstPiola(Z).allFinite());
  EXPECT_TRUE(m.firstPiolaDerivative(Z).allFinite());
}

TEST(NeoHookean, DegenerateAndInvertedStayFiniteAndConsistent) {
  const auto m = NeoHookean<double>::fromYoungPoisson(kE, kNu);
  const Mat3d samples[] = {Vec3d(0.1, 0.1, 0.5).asDiagonal(),   // J = 0.005 < kMinJ
                           Vec3d(0.5, 0.5, -0.2).asDiagonal(),  // inverted
                           Vec3d(1.0, 1.0, 0.0).asDiagonal()};  // flat
  for (const Mat3d& F : samples) {
    EXPECT_TRUE(std::isfinite(m.psi(F))) << F;
    EXPECT_TRUE(m.firstPiola(F).allFinite()) << F;
    EXPECT_TRUE(m.kirchhoff(F).allFinite()) << F;
    EXPECT_TRUE(m.firstPiolaDerivative(F).allFinite()) << F;
    // The extension keeps P = dpsi/dF and dP/dF exact.
    EXPECT_LT(relErr(m.firstPiola(F), gradientFD([&](const Mat3d& G) { return m.psi(G); }, F)),
              1e-6)
        << F;
    EXPECT_LT(relErr(m.firstPiolaDerivative(F),
                     jacobianFD([&](const Mat3d& G) { return m.firstPiola(G); }, F)),
              1e-6)
        << F;
    EXPECT_LT(relErr(m.kirchhoff(F), m.firstPiola(F) * F.transpose()), 1e-12) << F;
  }
  // Compression resists: the (Cauchy) pressure -tr(tau) / 3J grows as J
  // shrinks, across kMinJ too.
  const auto pressure = [&](double J) {
    return -m.kirchhoff(std::cbrt(J) * Mat3d::Identity()).trace() / (3 * J);
  };
  EXPECT_GT(pressure(0.005), pressure(0.02));
  EXPECT_GT(pressure(0.02), pressure(0.5));
  EXPECT_GT(pressure(0.5), 0.0);
}

TEST(StvkHencky, MatchesPrincipalStressesAndSurvivesSingularF) {
  const auto m = StvkHencky<double>::fromYoungPoisson(kE, kNu);
  // Principal axes: tau = 2 mu eps + lambda tr(eps) along each.
  const Vec3d s(1.3, 0.8, 0.95);
  const Vec3d eps = s.array().log();
  const Mat3d tau = m.kirchhoff(s.asDiagonal());
  for (int i = 0; i < 3; ++i)
    EXPECT_NEAR(tau(i, i), 2 * m.mu * eps(i) + m.lambda * eps.sum(), 1e-9);
  EXPECT_NEAR(m.psi(s.asDiagonal()),
              m.mu * eps.squaredNorm() + 0.5 * m.lambda * eps.sum() * eps.sum(), 1e-9);
  const Mat3d flat = Vec3d(1.0, 1.0, 0.0).asDiagonal();
  EXPECT_TRUE(std::isfinite(m.psi(flat)));
  EXPECT_TRUE(m.firstPiola(flat).allFinite());
  EXPECT_TRUE(m.kirchhoff(flat).allFinite());
}

// Singular values (rotation-variant) of F in double.
TEST(Snow, ProjectClampsStretchesAndKeepsTotalVolume) {
  const Snow<double> snow = makeSnow();
  const double lo = 1 - snow.critical_compression, hi = 1 + snow.critical_stretch;
  std::mt19937 rng(9);
  for (int i = 0; i < 200; ++i) {
    Mat3d Fe = i % 2 ? nearIdentity(rng, 0.05) : largeDeformation(rng);
    double jp = 0.7 + 0.01 * i;
    const double total = jp * Fe.determinant();
    snow.project(Fe, jp);
    const Vec3d s = singularValues(Fe);
    EXPECT_GE(s.minCoeff(), lo - 1e-12);
    EXPECT_LE(s.maxCoeff(), hi + 1e-12);
    EXPECT_NEAR(jp * Fe.determinant(), total, 1e-12 * std::abs(total));
    // Idempotent: a projected state is admissible.
    const Mat3d once = Fe;
    const double jp_once = jp;
    snow.project(Fe, jp);
    EXPECT_LE((Fe - once).norm(), 1e-12);
    EXPECT_NEAR(jp, jp_once, 1e-12 * jp_once);
  }
  // An admissible state is left alone.
  const Mat3d R = randomRotation(rng);
  Mat3d Fe = R * Vec3d(1.005, 0.99, 0.98).asDiagonal();
  double jp = 1.1;
  const Mat3d before = Fe;
  snow.project(Fe, jp);
  EXPECT_LE((Fe - before).norm(), 1e-13);
  EXPECT_NEAR(jp, 1.1, 1e-13);
}

TEST(Snow, InvertedTrialComesOutUprightWithPositiveJp) {
  const Snow<double> snow = makeSnow();
  Mat3d Fe = Vec3d(1.0, 1.0, -0.5).asDiagonal();
  double jp = 1.0;
  snow.project(Fe, jp);
  EXPECT_GT(Fe.determinant(), 0);
  EXPECT_GT(jp, 0);
  EXPECT_NEAR(jp * Fe.determinant(), 0.5, 1e-12);
}

TEST(Snow, HardeningScalesTheModuliWithClampedJp) {
  const Snow<double> snow = makeSnow();
  EXPECT_DOUBLE_EQ(snow.stiffnessScale(1.0), 1.0);
  EXPECT_NEAR(snow.stiffnessScale(0.9), std::exp(snow.hardening * 0.1), 1e-12);
  EXPECT_NEAR(snow.stiffnessScale(1.2), std::exp(-snow.hardening * 0.2), 1e-12);
  EXPECT_DOUBLE_EQ(snow.stiffnessScale(0.01), snow.stiffnessScale(snow.min_jp));
  EXPECT_DOUBLE_EQ(snow.stiffnessScale(1e3), snow.stiffnessScale(snow.max_jp));
  const FixedCorotated<double> h = snow.hardened(0.9);
  EXPECT_NEAR(h.mu, snow.elastic.mu * std::exp(1.0), 1e-9);
  EXPECT_NEAR(h.lambda, snow.elastic.lambda * std::exp(1.0), 1e-9);
}

TEST(Snow, ProjectAndKirchhoffEqualsTheTwoCalls) {
  const Snow<double> snow = makeSnow();
  std::mt19937 rng(10);
  for (int i = 0; i < 50; ++i) {
    Mat3d a = nearIdentity(rng, 0.05), b = a;
    double ja = 0.95, jb = 0.95;
    const Mat3d tau = snow.projectAndKirchhoff(a, ja);
    snow.project(b, jb);
    EXPECT_LE((a - b).norm(), 1e-14);
    EXPECT_DOUBLE_EQ(ja, jb);
    EXPECT_LT(relErr(tau, snow.kirchhoff(b, jb)), 1e-12);
  }
}

// Hencky strain log|s| of F.
TEST(DruckerPrager, ConeParameters) {
  const DruckerPrager<double> dp(kE, kNu, 30, 100);
  const double sin30 = 0.5;
  EXPECT_NEAR(dp.alpha, std::sqrt(2.0 / 3.0) * 2 * sin30 / (3 - sin30), 1e-15);
  const double bulk = dp.elastic.lambda + 2 * dp.elastic.mu / 3;
  EXPECT_NEAR(dp.cohesion_strain, 100 / std::tan(M_PI / 6) / (3 * bulk), 1e-15);
  // The apex really is at hydrostatic tension c cot(phi).
  const Mat3d apex = std::exp(dp.cohesion_strain) * Mat3d::Identity();
  EXPECT_NEAR(dp.kirchhoff(apex).trace() / 3, 100 / std::tan(M_PI / 6), 1e-9);
  EXPECT_NEAR(dp.yield(apex), 0.0, 1e-12);
}

TEST(DruckerPrager, OutsideStatesLandOnTheYieldSurface) {
  for (const double cohesion : {0.0, 50.0}) {
    const DruckerPrager<double> dp(kE, kNu, 35, cohesion);
    std::mt19937 rng(11);
    std::normal_distribution<double> g(0, 0.05);
    int projected = 0;
    for (int i = 0; i < 300; ++i) {
      // Compressive mean strain with a random deviatoric part
      const Vec3d dev(g(rng), g(rng), g(rng));
      const Vec3d eps = (dev.array() - dev.mean() - 0.01 + dp.cohesion_strain).matrix();
      Mat3d F = withStrain(rng, eps);
      const Mat3d before = F;
      const double f = dp.yield(F);
      const bool moved = dp.project(F);
      EXPECT_EQ(moved, f > 0);
      if (!moved) {
        EXPECT_EQ(F, before);  // untouched, bit for bit
        continue;
      }
      ++projected;
      EXPECT_LT(std::abs(dp.yield(F)), 1e-9);
      // The same surface in Kirchhoff stress, from the inputs alone (Klar et
      // al.): |dev tau| + alpha (tr tau - 3 c cot(phi)) = 0.
      const Mat3d tau = dp.kirchhoff(F);
      const Mat3d dev_tau = tau - tau.trace() / 3 * Mat3d::Identity();
      const double tension = cohesion / std::tan(35 * M_PI / 180);
      EXPECT_NEAR(dev_tau.norm() + dp.alpha * (tau.trace() - 3 * tension), 0.0, 1e-9 * tau.norm());
      // Radial return: the volumetric strain is kept, the shear direction too.
      const Vec3d e0 = henckyStrain(before), e1 = henckyStrain(F);
      EXPECT_NEAR(e1.sum(), e0.sum(), 1e-12);
      const Vec3d d0 = (e0.array() - e0.mean()).matrix(), d1 = (e1.array() - e1.mean()).matrix();
      EXPECT_LT(d1.norm(), d0.norm());
      EXPECT_NEAR(d1.dot(d0), d1.norm() * d0.norm(), 1e-9 * d0.squaredNorm());
      // The principal directions do not change: F^T F commutes with before^T before
      const Mat3d C0 = before.transpose() * before, C1 = F.transpose() * F;
      EXPECT_LT((C0 * C1 - C1 * C0).norm(), 1e-10);
      // Idempotent
      const Mat3d once = F;
      dp.project(F);
      EXPECT_LE((F - once).norm(), 1e-12);
    }
    EXPECT_GT(projected, 50);  // the sample really exercised the cone
    EXPECT_LT(projected, 300);
  }
}

TEST(DruckerPrager, InsideStatesAreUnchanged) {
  expectInsideStatesUnchanged(DruckerPrager<double>(kE, kNu, 30, 0), 12);
}

TEST(DruckerPrager, TensionGoesToTheApex) {
  for (const double cohesion : {0.0, 50.0}) {
    const DruckerPrager<double> dp(kE, kNu, 30, cohesion);
    std::mt19937 rng(13);
    for (int i = 0; i < 50; ++i) {
      const Vec3d eps = Vec3d(0.02, -0.01, 0.005) + Vec3d::Constant(dp.cohesion_strain);
      Mat3d F = withStrain(rng, eps);
      ASSERT_GT(dp.yield(F), 0);
      EXPECT_TRUE(dp.project(F));
      const Vec3d s = singularValues(F);
      EXPECT_LT((s - Vec3d::Constant(std::exp(dp.cohesion_strain))).norm(), 1e-12);
      EXPECT_NEAR(dp.yield(F), 0.0, 1e-12);
      const Mat3d once = F;
      dp.project(F);
      EXPECT_LE((F - once).norm(), 1e-12);
    }
  }
}

TEST(DruckerPrager, CohesionHoldsSmallHydrostaticTension) {
  const DruckerPrager<double> loose(kE, kNu, 30, 0), sticky(kE, kNu, 30, 20);
  ASSERT_GT(sticky.cohesion_strain, 1e-3);
  const Mat3d F = std::exp(0.5 * sticky.cohesion_strain) * Mat3d::Identity();
  Mat3d a = F, b = F;
  EXPECT_TRUE(loose.project(a));
  EXPECT_LT((a - Mat3d::Identity()).norm(), 1e-12);  // cohesionless: to the apex at rest
  EXPECT_FALSE(sticky.project(b));
  EXPECT_EQ(b, F);
  EXPECT_GT(sticky.kirchhoff(b).trace(), 0);  // and it carries tension
}

TEST(DruckerPrager, ProjectAndKirchhoffEqualsTheTwoCalls) {
  const DruckerPrager<double> dp(kE, kNu, 30, 10);
  std::mt19937 rng(14);
  for (int i = 0; i < 50; ++i) {
    Mat3d a = nearIdentity(rng, 0.05), b = a;
    const Mat3d tau = dp.projectAndKirchhoff(a);
    dp.project(b);
    EXPECT_LE((a - b).norm(), 1e-14);
    // tau comes from the SVD before projection, kirchhoff(b) from a new one.
    EXPECT_LT(relErr(tau, dp.kirchhoff(b)), 1e-10);
  }
}

TEST(Water, PressureIsMinusEnergyDerivative) {
  for (const double gamma : {7.0, 1.0, 3.5}) {
    const Water<double> w{2e5, gamma, 1e-3};
    EXPECT_EQ(w.pressure(1.0), 0.0);
    EXPECT_EQ(w.psi(1.0), 0.0);
    for (const double J : {0.05, 0.3, 0.9, 0.999, 1.05, 2.0, 15.0}) {
      const double h = 1e-6 * J;
      const double dpsi = (w.psi(J + h) - w.psi(J - h)) / (2 * h);
      EXPECT_NEAR(-dpsi, w.pressure(J), 1e-6 * std::max(1.0, std::abs(w.pressure(J)))) << J;
    }
    EXPECT_GT(w.pressure(0.9), 0.0);  // compression pushes out
    EXPECT_LT(w.pressure(1.1), 0.0);
  }
  const Water<double> w{2e5, 7, 0};
  EXPECT_NEAR(w.pressure(0.9), 2e5 / 7 * (std::pow(0.9, -7) - 1), 1e-9);
  // The clamp bounds the pressure instead of overflowing.
  EXPECT_EQ(w.pressure(1e-3), w.pressure(Water<double>::kMinJ));
  EXPECT_EQ(w.pressure(1e3), w.pressure(Water<double>::kMaxJ));
  EXPECT_TRUE(std::isfinite(Water<float>{2e9f, 7, 0}.pressure(0.0f)));
}

TEST(Water, KirchhoffIsPressurePlusSymmetricViscousStress) {
  const Water<double> w{2e5, 7, 0.5};
  const double J = 0.95;
  EXPECT_LT(relErr(w.kirchhoff(J, Mat3d::Zero()), -J * w.pressure(J) * Mat3d::Identity()), 1e-15);
  Mat3d G;
  G << 0.1, 2.0, -0.3, 0.0, -0.2, 0.5, 1.0, 0.4, 0.1;
  const Mat3d tau = w.kirchhoff(J, G);
  EXPECT_LT((tau - tau.transpose()).norm(), 1e-15 * tau.norm());
  // The viscous part alone (no pressure to cancel against)
  const Water<double> syrup{0, 7, 0.5};
  EXPECT_LT(relErr(syrup.kirchhoff(J, G), J * 0.5 * (G + G.transpose())), 1e-15);
  EXPECT_LT(relErr(tau, syrup.kirchhoff(J, G) - J * w.pressure(J) * Mat3d::Identity()), 1e-15);
  // A rigid rotation (skew velocity gradient) is free of viscous stress.
  Mat3d W;
  W << 0, -1, 2, 1, 0, -3, -2, 3, 0;
  EXPECT_LT(relErr(w.kirchhoff(J, W), w.kirchhoff(J, Mat3d::Zero())), 1e-15);
}

TEST(MakeMaterial, BuildsEveryModelFromItsDescription) {
  MaterialDesc d;
  d.density = 1000;
  d.youngs_modulus = 1e5;
  d.poisson_ratio = 0.25;
  const double mu = 1e5 / 2.5, lambda = 1e5 * 0.25 / (1.25 * 0.5);

  d.model = MaterialModel::FixedCorotated;
  const auto fc = std::get<FixedCorotated<float>>(makeMaterial(d));
  EXPECT_FLOAT_EQ(fc.mu, float(mu));
  EXPECT_FLOAT_EQ(fc.lambda, float(lambda));
  EXPECT_FLOAT_EQ(waveSpeed(d), float(std::sqrt((lambda + 2 * mu) / 1000)));

  d.model = MaterialModel::NeoHookean;
  EXPECT_FLOAT_EQ(std::get<NeoHookean<float>>(makeMaterial(d)).mu, float(mu));

  d.model = MaterialModel::Snow;
  d.critical_compression = 0.03;
  d.critical_stretch = 0.006;
  d.hardening = 8;
  const auto snow = std::get<Snow<float>>(makeMaterial(d));
  EXPECT_FLOAT_EQ(snow.elastic.lambda, float(lambda));
  EXPECT_FLOAT_EQ(snow.critical_compression, 0.03f);
  EXPECT_FLOAT_EQ(snow.critical_stretch, 0.006f);
  EXPECT_FLOAT_EQ(snow.hardening, 8.0f);

  d.model = MaterialModel::DruckerPrager;
  d.friction_angle_deg = 35;
  d.cohesion = 30;
  const auto sand = std::get<DruckerPrager<float>>(makeMaterial(d));
  const DruckerPrager<double> ref(1e5, 0.25, 35, 30);
  EXPECT_FLOAT_EQ(sand.elastic.mu, float(mu));
  EXPECT_FLOAT_EQ(sand.alpha, float(ref.alpha));
  EXPECT_FLOAT_EQ(sand.cohesion_strain, float(ref.cohesion_strain));

  d.model = MaterialModel::Water;
  d.bulk_modulus = 2e6;
  d.gamma = 7;
  d.viscosity = 1e-3;
  const auto water = std::get<Water<float>>(makeMaterial(d));
  EXPECT_FLOAT_EQ(water.bulk, 2e6f);
  EXPECT_FLOAT_EQ(water.gamma, 7.0f);
  EXPECT_FLOAT_EQ(water.viscosity, 1e-3f);
  EXPECT_FLOAT_EQ(waveSpeed(d), float(std::sqrt(2e6 / 1000)));
}

TEST(MakeMaterial, StateFlagsAndNames) {
  EXPECT_TRUE(FixedCorotated<float>::kUsesF && !FixedCorotated<float>::kUsesPlasticJ);
  EXPECT_TRUE(NeoHookean<float>::kUsesF && !NeoHookean<float>::kUsesPlasticJ);
  EXPECT_TRUE(Snow<float>::kUsesF && Snow<float>::kUsesPlasticJ);
  EXPECT_TRUE(DruckerPrager<float>::kUsesF && !DruckerPrager<float>::kUsesPlasticJ);
  EXPECT_TRUE(!Water<float>::kUsesF && !Water<float>::kUsesPlasticJ);
  EXPECT_STREQ(modelName(MaterialModel::FixedCorotated), "fixed_corotated");
  EXPECT_STREQ(modelName(MaterialModel::NeoHookean), "neo_hookean");
  EXPECT_STREQ(modelName(MaterialModel::Snow), "snow");
  EXPECT_STREQ(modelName(MaterialModel::DruckerPrager), "drucker_prager");
  EXPECT_STREQ(modelName(MaterialModel::Water), "water");
}

// The float models as the solver runs them: the batched paths agree with
// single calls, and single precision stays close to double.
TEST(FloatModels, BatchesMatchSingleCallsAndDouble) {
  std::mt19937 rng(15);
  const int n = 100;  // spans more than one chunk tail
  std::vector<Mat3f> F(n), tau(n);
  for (Mat3f& A : F) A = nearIdentity(rng, 0.05).cast<float>();

  const auto fc = FixedCorotated<float>::fromYoungPoisson(1e5f, 0.3f);
  const auto fcd = FixedCorotated<double>::fromYoungPoisson(1e5, 0.3);
  kirchhoffBatch(fc, n, F.data(), tau.data());
  for (int i = 0; i < n; ++i) {
    EXPECT_LT(relErr(tau[i].cast<double>(), fc.kirchhoff(F[i]).cast<double>()), 1e-5);
    EXPECT_LT(relErr(tau[i].cast<double>(), fcd.kirchhoff(F[i].cast<double>())), 1e-4);
  }

  Snow<float> snow;
  snow.elastic = fc;
  std::vector<Mat3f> Fe = F;
  std::vector<float> jp(n, 1.0f);
  projectAndKirchhoffBatch(snow, n, Fe.data(), jp.data(), tau.data());
  for (int i = 0; i < n; ++i) {
    Mat3f a = F[i];
    float ja = 1.0f;
    const Mat3f t = snow.projectAndKirchhoff(a, ja);
    EXPECT_LT((Fe[i] - a).norm(), 1e-5f);
    EXPECT_NEAR(jp[i], ja, 1e-5f);
    EXPECT_LT(relErr(tau[i].cast<double>(), t.cast<double>()), 1e-4);
  }

  const DruckerPrager<float> sand(1e5f, 0.3f, 30.0f, 0.0f);
  std::vector<Mat3f> Fs = F;
  projectAndKirchhoffBatch(sand, n, Fs.data(), tau.data());
  for (int i = 0; i < n; ++i) {
    Mat3f a = F[i];
    const Mat3f t = sand.projectAndKirchhoff(a);
    EXPECT_LT((Fs[i] - a).norm(), 1e-5f);
    // The float SVD resolves s to ~1e-6, so log(s) and the stress carry an
    // absolute error up to ~(2 mu + 3 lambda) 1e-6 (0.25 Pa here).
    const float noise = 2e-6f * (2 * sand.elastic.mu + 3 * sand.elastic.lambda);
    EXPECT_LT((tau[i] - t).norm(), 1e-4f * t.norm() + noise);
  }

  // Water's pressure in the lanes, J compressed and stretched past both
  // clamps, with and without viscosity.
  for (const float viscosity : {0.0f, 0.5f}) {
    const Water<float> water{2e5f, 7.0f, viscosity};
    std::vector<float> J(n);
    std::vector<Mat3f> grad(n);
    for (int i = 0; i < n; ++i) {
      J[size_t(i)] = i == 0 ? 0.05f : i == 1 ? 12.0f : float(0.9 + 0.2 * i / n);
      grad[size_t(i)] = nearIdentity(rng, 1.0).cast<float>() - Mat3f::Identity();
    }
    kirchhoffBatch(water, n, J.data(), grad.data(), tau.data());
    for (int i = 0; i < n; ++i) {
      const Mat3f t = water.kirchhoff(J[size_t(i)], grad[size_t(i)]);
      EXPECT_LT((tau[size_t(i)] - t).norm(), 2e-6f * t.norm() + 1e-3f) << "J " << J[size_t(i)];
    }
  }

  // The batch's return runs in the SVD's lanes: every case of the cone
  // against the single call, with and without cohesion (which moves the
  // apex into tension): states inside, compressed states that yield,
  // stretched ones that go to the apex, and inverted F (det < 0).
  const DruckerPrager<float> sticky(1e5f, 0.3f, 35.0f, 2e3f);
  std::vector<Mat3f> G(n);
  for (int i = 0; i < n; ++i) {
    Mat3d A = nearIdentity(rng, 0.2);
    if (i % 4 == 1) A *= 0.8;
    if (i % 4 == 2) A *= 1.05;
    if (i % 10 == 3) A.col(2) *= -1.0;
    G[size_t(i)] = A.cast<float>();
  }
  for (const DruckerPrager<float>* model : {&sand, &sticky}) {
    std::vector<Mat3f> Fb = G;
    projectAndKirchhoffBatch(*model, n, Fb.data(), tau.data());
    int moved = 0;
    for (int i = 0; i < n; ++i) {
      Mat3f a = G[size_t(i)];
      const Mat3f t = model->projectAndKirchhoff(a);
      moved += a != G[size_t(i)];
      EXPECT_LT((Fb[size_t(i)] - a).norm(), 2e-5f * a.norm()) << "matrix " << i;
      // Unmoved states keep their F bit for bit.
      if (a == G[size_t(i)]) {
        EXPECT_EQ(Fb[size_t(i)], G[size_t(i)]);
      }
      const float noise = 2e-6f * (2 * model->elastic.mu + 3 * model->elastic.lambda);
      EXPECT_LT((tau[size_t(i)] - t).norm(), 1e-4f * t.norm() + noise) << "matrix " << i;
    }
    // Both branches are exercised.
    EXPECT_GT(moved, n / 4);
    EXPECT_LT(moved, n);
  }
}

}  // namespace
}  // namespace triad
