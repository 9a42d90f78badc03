// Tests for the Mohr-Coulomb return mapping (sim/materials/plastic_models.h):
// every return lands on the surface and stays there, the three branches
// (main plane, edge, apex) each do what the surface's geometry says, the
// strength is the same friction angle in triaxial compression and
// extension (where Drucker-Prager's cone differs), dilatancy sets the
// plastic volume change, and the results do not depend on the frame.
#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "sim/materials/materials.h"
#include "tests/material_helpers.h"

namespace triad {
namespace {

using namespace test;

constexpr double kE = 1e4, kNu = 0.3;

// Principal Kirchhoff stresses of F, sorted tau_1 >= tau_2 >= tau_3.
Vec3d sortedStress(const MohrCoulomb<double>& mc, const Mat3d& F) {
  Vec3d t = mc.elastic.principalKirchhoff(henckyStrain(F));
  std::sort(t.data(), t.data() + 3, [](double a, double b) { return a > b; });
  return t;
}

// Mobilised friction of a cohesionless state: sin(phi_m) = (t1 - t3) / -(t1 + t3).
double mobilisedSin(const Vec3d& t) {
  return (t(0) - t(2)) / -(t(0) + t(2));
}

// Which part of the surface a returned stress lies on (2: main plane,
// 1: an edge, 0: the apex), from how many distinct principal values it has.
int branchOf(const Vec3d& t, double scale) {
  const double tol = 1e-7 * scale;
  const bool upper = t(0) - t(1) < tol, lower = t(1) - t(2) < tol;
  return upper && lower ? 0 : (upper || lower ? 1 : 2);
}

TEST(MohrCoulomb, OutsideStatesLandOnTheSurfaceAndStay) {
  for (const double cohesion : {0.0, 50.0}) {
    for (const double dilatancy : {0.0, 15.0}) {
      const MohrCoulomb<double> mc(kE, kNu, 35, cohesion, dilatancy);
      std::mt19937 rng(21);
      std::normal_distribution<double> g(0, 0.03);
      int branches[3] = {0, 0, 0}, projected = 0;
      for (int i = 0; i < 600; ++i) {
        // Mean strains from compression to a little tension, random shear.
        const double mean = -0.02 + 0.025 * double(i % 10) / 9.0;
        const Vec3d dev(g(rng), g(rng), g(rng));
        Mat3d F = withStrain(rng, (dev.array() - dev.mean() + mean).matrix());
        const Mat3d before = F;
        const double f = mc.yield(F);
        const bool moved = mc.project(F);
        ASSERT_EQ(moved, f > 0);
        if (!moved) {
          EXPECT_EQ(F, before);  // untouched, bit for bit
          continue;
        }
        ++projected;
        const Vec3d t = sortedStress(mc, F);
        const double scale = std::abs(t(0)) + std::abs(t(2)) + cohesion + 1.0;
        EXPECT_NEAR(mc.yield(F), 0.0, 1e-9 * scale) << "trial f " << f;
        const int branch = branchOf(t, scale);
        ++branches[branch];
        if (dilatancy == 0) {
          // Plane and edge returns flow at constant volume; only a trial
          // state in tension beyond the apex goes to it.
          const double tr0 = henckyStrain(before).sum(), tr1 = henckyStrain(F).sum();
          if (branch != 0) {
            EXPECT_NEAR(tr1, tr0, 1e-12);
          }
          const double trial_mean = mc.elastic.principalKirchhoff(henckyStrain(before)).mean();
          const double apex = cohesion * mc.cos_phi / mc.sin_phi;
          if (branch == 0) {
            EXPECT_GE(trial_mean, apex - 1e-9 * scale);
          }
        }
        // The principal directions do not change.
        const Mat3d C0 = before.transpose() * before, C1 = F.transpose() * F;
        EXPECT_LT((C0 * C1 - C1 * C0).norm(), 1e-10);
        // Idempotent: a state on the surface is not moved again.
        const Mat3d once = F;
        mc.project(F);
        EXPECT_LE((F - once).norm(), 1e-12);
      }
      EXPECT_GT(projected, 200);
      // Every branch was exercised: main plane, edges and apex.
      EXPECT_GT(branches[2], 50) << cohesion << " " << dilatancy;
      EXPECT_GT(branches[1], 20) << cohesion << " " << dilatancy;
      EXPECT_GT(branches[0], 5) << cohesion << " " << dilatancy;
    }
  }
}

TEST(MohrCoulomb, InsideStatesAreUnchanged) {
  expectInsideStatesUnchanged(MohrCoulomb<double>(kE, kNu, 30, 0), 22);
}

TEST(MohrCoulomb, SameFrictionAngleInTriaxialCompressionAndExtension) {
  // Strain paths at a fixed compressive mean: triaxial compression (one
  // principal strain shorter than the other two) and extension (one
  // longer). After the return the mobilised friction angle is phi in both;
  // a Drucker-Prager cone through the same phi (matched in compression)
  // gives a larger angle in extension.
  const double phi = 30, sin_phi = 0.5;
  const MohrCoulomb<double> mc(kE, kNu, phi, 0);
  const DruckerPrager<double> dp(kE, kNu, phi, 0);
  std::mt19937 rng(23);
  for (const double shear : {0.02, 0.05}) {
    const Vec3d compression(-0.01 - 2 * shear, -0.01 + shear, -0.01 + shear);
    const Vec3d extension(-0.01 + 2 * shear, -0.01 - shear, -0.01 - shear);
    for (const Vec3d& eps : {compression, extension}) {
      Mat3d F = withStrain(rng, eps);
      ASSERT_TRUE(mc.project(F));
      const Vec3d t = sortedStress(mc, F);
      EXPECT_NEAR(mobilisedSin(t), sin_phi, 1e-9);
      // Two equal principal stresses: the return ended on the edge.
      EXPECT_EQ(branchOf(t, std::abs(t(2))), 1);
    }
    Mat3d Fc = withStrain(rng, compression), Fe = withStrain(rng, extension);
    dp.project(Fc);
    dp.project(Fe);
    const double sc = mobilisedSin(sortedStress(mc, Fc)), se = mobilisedSin(sortedStress(mc, Fe));
    // The cone q = M (-p), M = 6 sin(phi) / (3 - sin(phi)), is matched in
    // compression; in extension it mobilises sin(phi_e) = 3 M / (6 - M):
    // 0.75 (48.6 degrees) for phi = 30.
    EXPECT_NEAR(sc, sin_phi, 1e-9);
    EXPECT_NEAR(se, 0.75, 1e-9);
  }
}

TEST(MohrCoulomb, DilatancySetsThePlasticVolumeChange) {
  // On the main plane the plastic strain is dgamma (1 + sin psi, 0,
  // -(1 - sin psi)) in sorted principal axes: its volume over its shear
  // (eps_1 - eps_3) is sin(psi).
  for (const double psi : {0.0, 10.0, 30.0}) {
    const MohrCoulomb<double> mc(kE, kNu, 30, 0, psi);
    std::mt19937 rng(24);
    int checked = 0;
    for (int i = 0; i < 50; ++i) {
      const Vec3d eps(-0.06 - 0.0005 * i, -0.02 + 0.0002 * i, 0.02);
      const Mat3d R = randomRotation(rng);
      Mat3d F = R * eps.array().exp().matrix().asDiagonal();
      const Vec3d t0 = mc.elastic.principalKirchhoff(eps);
      if (mc.yield(F) <= 0) continue;
      mc.project(F);
      // Principal axes are kept, so the strains pair up by direction.
      const Vec3d e1 = (R.transpose() * F).diagonal().array().log();
      const Vec3d t = sortedStress(mc, F);
      if (branchOf(t, std::abs(t0(0)) + 1) != 2) continue;
      const Vec3d dp = eps - e1;  // plastic strain, axis order of eps: 3, 2, 1
      EXPECT_NEAR(dp.sum() / (dp(2) - dp(0)), std::sin(psi * M_PI / 180), 1e-7);
      EXPECT_NEAR(dp(1), 0.0, 1e-9);
      ++checked;
    }
    EXPECT_GT(checked, 20) << psi;
  }
}

TEST(MohrCoulomb, TensionBeyondTheApexReturnsToIt) {
  for (const double cohesion : {0.0, 30.0}) {
    const MohrCoulomb<double> mc(kE, kNu, 30, cohesion);
    const double apex = cohesion / std::tan(M_PI / 6);
    std::mt19937 rng(25);
    for (int i = 0; i < 20; ++i) {
      Mat3d F = withStrain(rng, Vec3d(0.02, 0.01 + 0.0005 * i, 0.015));
      ASSERT_TRUE(mc.project(F));
      const Vec3d t = sortedStress(mc, F);
      EXPECT_NEAR(t(0), apex, 1e-9 * (apex + 1));
      EXPECT_NEAR(t(2), apex, 1e-9 * (apex + 1));
    }
  }
  // Below the apex, hydrostatic tension is held by cohesion.
  const MohrCoulomb<double> sticky(kE, kNu, 30, 30);
  Mat3d F = std::exp(1e-4) * Mat3d::Identity();
  ASSERT_LT(sticky.elastic.principalKirchhoff(Vec3d::Constant(1e-4))(0), 30 / std::tan(M_PI / 6));
  EXPECT_FALSE(sticky.project(F));
}

TEST(MohrCoulomb, TrescaWithoutFriction) {
  // phi = 0: the largest shear stress is the cohesion, whatever the pressure.
  const MohrCoulomb<double> mc(kE, kNu, 0, 40);
  std::mt19937 rng(26);
  for (const double mean : {-0.05, 0.0, 0.05}) {
    Mat3d F = withStrain(rng, Vec3d(mean + 0.03, mean - 0.01, mean - 0.02));
    ASSERT_TRUE(mc.project(F));
    const Vec3d t = sortedStress(mc, F);
    EXPECT_NEAR(t(0) - t(2), 80.0, 1e-8);
  }
}

TEST(MohrCoulomb, ReturnsDoNotDependOnTheFrame) {
  const MohrCoulomb<double> mc(kE, kNu, 35, 20, 5);
  std::mt19937 rng(27);
  for (int i = 0; i < 50; ++i) {
    const Mat3d F = nearIdentity(rng, 0.06);
    const Mat3d R = randomRotation(rng), Q = randomRotation(rng);
    Mat3d a = F, b = R * F * Q;
    mc.project(a);
    mc.project(b);
    EXPECT_LT((R * a * Q - b).norm(), 1e-10);
  }
}

TEST(MohrCoulomb, ProjectAndKirchhoffEqualsTheTwoCallsAndTheFloatBatch) {
  const MohrCoulomb<double> mc(kE, kNu, 30, 10, 5);
  std::mt19937 rng(28);
  for (int i = 0; i < 50; ++i) {
    Mat3d a = nearIdentity(rng, 0.05), b = a;
    const Mat3d tau = mc.projectAndKirchhoff(a);
    mc.project(b);
    EXPECT_LE((a - b).norm(), 1e-14);
    EXPECT_LT(relErr(tau, mc.kirchhoff(b)), 1e-10);
  }
  const int n = 100;
  std::vector<Mat3f> F(n), tau(n);
  for (Mat3f& A : F) A = nearIdentity(rng, 0.05).cast<float>();
  const MohrCoulomb<float> sand(1e5f, 0.3f, 30.0f, 0.0f);
  std::vector<Mat3f> Fs = F;
  projectAndKirchhoffBatch(sand, n, Fs.data(), tau.data());
  for (int i = 0; i < n; ++i) {
    Mat3f a = F[i];
    const Mat3f t = sand.projectAndKirchhoff(a);
    EXPECT_LT((Fs[i] - a).norm(), 1e-5f);
    const float noise = 2e-6f * (2 * sand.elastic.mu + 3 * sand.elastic.lambda);
    EXPECT_LT((tau[i] - t).norm(), 1e-4f * t.norm() + noise);
  }
  // Under mu(I) the batch reads each particle's velocity gradient: a fast
  // shear raises the friction, so fewer states move, and those less.
  MohrCoulomb<float> rated = sand;
  rated.grain_diameter = 0.01f;
  rated.density = 1600.0f;
  rated.mu_2 = std::tan(0.7f);
  std::vector<Mat3f> grad_v(n, Mat3f::Zero()), Fr = F;
  for (Mat3f& g : grad_v) g(0, 1) = 50.0f;
  projectAndKirchhoffBatch(rated, n, Fr.data(), grad_v.data(), tau.data());
  int differ = 0;
  for (int i = 0; i < n; ++i) {
    Mat3f a = F[i];
    Vec3f sv;
    Mat3f U, V;
    svd3(a, U, sv, V);
    rated.projectSvd(U, sv, V, a, grad_v[i]);
    EXPECT_LT((Fr[i] - a).norm(), 1e-5f);
    differ += (Fr[i] - Fs[i]).norm() > 1e-4f;
  }
  EXPECT_GT(differ, 10);
}

TEST(MohrCoulomb, RateDependentFrictionFollowsMuOfI) {
  // mu(I) = mu_s + (mu_2 - mu_s) I / (I_0 + I): at rest the static
  // surface; at I = I_0 the friction coefficient halfway to mu_2.
  MohrCoulomb<double> mc(kE, kNu, 25, 0);
  mc.grain_diameter = 1e-3;
  mc.density = 1600;
  mc.mu_2 = std::tan(37 * M_PI / 180);
  mc.i_0 = 0.3;
  const MohrCoulomb<double> rest(kE, kNu, 25, 0);
  std::mt19937 rng(29);
  const Vec3d eps(-0.06, 0.01, 0.01);  // triaxial compression beyond 37 degrees
  const double p = -mc.elastic.principalKirchhoff(eps).mean();
  for (const double inertial : {0.0, 0.3, 3.0}) {
    // Simple shear at gamma_dot = I sqrt(p / rho) / d.
    Mat3d grad_v = Mat3d::Zero();
    grad_v(0, 1) = inertial * std::sqrt(p / mc.density) / mc.grain_diameter;
    Mat3d U, V, F = withStrain(rng, eps);
    Vec3d s;
    svd3(F, U, s, V);
    ASSERT_TRUE(mc.projectSvd(U, s, V, F, grad_v));
    const double mu_s = std::tan(25 * M_PI / 180);
    const double mu = mu_s + (mc.mu_2 - mu_s) * inertial / (mc.i_0 + inertial);
    const Vec3d t = sortedStress(mc, F);
    EXPECT_NEAR(mobilisedSin(t), mu / std::sqrt(1 + mu * mu), 1e-9) << "I " << inertial;
    if (inertial == 0.0) {
      Mat3d G = withStrain(rng, eps);
      rest.project(G);
      EXPECT_NEAR(mobilisedSin(sortedStress(rest, G)), mobilisedSin(t), 1e-12);
    }
  }
}

TEST(MohrCoulomb, MadeFromItsDescription) {
  MaterialDesc d;
  d.model = MaterialModel::MohrCoulomb;
  d.youngs_modulus = 1e5;
  d.poisson_ratio = 0.25;
  d.friction_angle_deg = 35;
  d.cohesion = 30;
  d.dilatancy_angle_deg = 5;
  const auto sand = std::get<MohrCoulomb<float>>(makeMaterial(d));
  EXPECT_NEAR(sand.sin_phi, std::sin(35 * M_PI / 180), 1e-6);
  EXPECT_NEAR(sand.sin_psi, std::sin(5 * M_PI / 180), 1e-6);
  EXPECT_EQ(sand.cohesion, 30.0f);
  EXPECT_STREQ(modelName(MaterialModel::MohrCoulomb), "mohr_coulomb");
  EXPECT_TRUE(MohrCoulomb<float>::kUsesF && !MohrCoulomb<float>::kUsesPlasticJ);
}

}  // namespace
}  // namespace triad
