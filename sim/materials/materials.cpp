// Material construction from scene descriptions, and the batched stress
// kernels (float only, so they live here rather than in the headers).
#include "sim/materials/materials.h"

#include <cmath>
#include <type_traits>

#include "sim/svd3.h"

namespace triad {

Material makeMaterial(const MaterialDesc& d) {
  const float E = float(d.youngs_modulus), nu = float(d.poisson_ratio);
  switch (d.model) {
    case MaterialModel::FixedCorotated:
      return FixedCorotated<float>::fromYoungPoisson(E, nu);
    case MaterialModel::NeoHookean:
      return NeoHookean<float>::fromYoungPoisson(E, nu);
    case MaterialModel::Snow: {
      Snow<float> snow;
      snow.elastic = FixedCorotated<float>::fromYoungPoisson(E, nu);
      snow.critical_compression = float(d.critical_compression);
      snow.critical_stretch = float(d.critical_stretch);
      snow.hardening = float(d.hardening);
      return snow;
    }
    case MaterialModel::DruckerPrager: {
      // Derive the cone in double: cohesion strains are small differences.
      const DruckerPrager<double> dp(d.youngs_modulus, d.poisson_ratio, d.friction_angle_deg,
                                     d.cohesion);
      DruckerPrager<float> sand;
      sand.elastic = {float(dp.elastic.mu), float(dp.elastic.lambda)};
      sand.alpha = float(dp.alpha);
      sand.cohesion_strain = float(dp.cohesion_strain);
      return sand;
    }
    case MaterialModel::MohrCoulomb: {
      MohrCoulomb<float> sand(float(d.youngs_modulus), float(d.poisson_ratio),
                              float(d.friction_angle_deg), float(d.cohesion),
                              float(d.dilatancy_angle_deg));
      if (d.grain_diameter > 0) {
        sand.grain_diameter = float(d.grain_diameter);
        sand.density = float(d.density);
        sand.i_0 = float(d.inertial_number_i0);
        sand.mu_2 = float(std::tan(d.friction_angle_max_deg * M_PI / 180.0));
      }
      return sand;
    }
    case MaterialModel::Water:
      return Water<float>{float(d.bulk_modulus), float(d.gamma), float(d.viscosity)};
  }
  return FixedCorotated<float>{};  // unreachable: the switch covers the enum
}

float waveSpeed(const MaterialDesc& d) {
  if (d.model == MaterialModel::Water) return float(std::sqrt(d.bulk_modulus / d.density));
  const Lame<double> l = lameFromYoungPoisson(d.youngs_modulus, d.poisson_ratio);
  return float(std::sqrt((l.lambda + 2.0 * l.mu) / d.density));
}

const char* modelName(MaterialModel model) {
  switch (model) {
    case MaterialModel::FixedCorotated:
      return "fixed_corotated";
    case MaterialModel::NeoHookean:
      return "neo_hookean";
    case MaterialModel::Snow:
      return "snow";
    case MaterialModel::DruckerPrager:
      return "drucker_prager";
    case MaterialModel::MohrCoulomb:
      return "mohr_coulomb";
    case MaterialModel::Water:
      return "water";
  }
  return "unknown";
}

namespace {

// Particles per svd3Batch call: a few vector passes, small enough for the
// decompositions to stay in L1 between the two loops.
constexpr int kChunk = 64;

}  // namespace

void kirchhoffBatch(const FixedCorotated<float>& m, int n, const Mat3f* F, Mat3f* tau) {
  Mat3f R[kChunk];
  for (int b = 0; b < n; b += kChunk) {
    const int count = std::min(kChunk, n - b);
    polarRotationBatch(count, F + b, R);
    for (int i = 0; i < count; ++i) {
      const Mat3f& A = F[b + i];
      const float J = A.determinant();
      Mat3f t = 2.0f * m.mu * (A - R[i]) * A.transpose();
      t.diagonal().array() += m.lambda * (J - 1.0f) * J;
      tau[b + i] = t;
    }
  }
}

void projectAndKirchhoffBatch(const Snow<float>& m, int n, Mat3f* Fe, float* Jp, Mat3f* tau) {
  Mat3f U[kChunk], V[kChunk];
  Vec3f s[kChunk];
  for (int b = 0; b < n; b += kChunk) {
    const int count = std::min(kChunk, n - b);
    svd3Batch(count, Fe + b, U, s, V);
    for (int i = 0; i < count; ++i)
      tau[b + i] = m.projectSvd(U[i], s[i], V[i], Fe[b + i], Jp[b + i]);
  }
}

namespace {

// The Hencky-strain sands: batched SVDs, then each particle's return and
// stress; with grad_v (Mohr-Coulomb's mu(I)) the return reads each
// particle's velocity gradient.
template <class M>
void henckyPlasticBatch(const M& m, int n, Mat3f* F, const Mat3f* grad_v, Mat3f* tau) {
  Mat3f U[kChunk], V[kChunk];
  Vec3f s[kChunk];
  for (int b = 0; b < n; b += kChunk) {
    const int count = std::min(kChunk, n - b);
    svd3Batch(count, F + b, U, s, V);
    for (int i = 0; i < count; ++i) {
      if constexpr (std::is_same_v<M, MohrCoulomb<float>>) {
        if (grad_v)
          m.projectSvd(U[i], s[i], V[i], F[b + i], grad_v[b + i]);
        else
          m.projectSvd(U[i], s[i], V[i], F[b + i]);
      } else {
        m.projectSvd(U[i], s[i], V[i], F[b + i]);
      }
      tau[b + i] = m.elastic.kirchhoffFromSvd(U[i], s[i]);
    }
  }
}

}  // namespace

void projectAndKirchhoffBatch(const DruckerPrager<float>& m, int n, Mat3f* F, Mat3f* tau) {
  henckyPlasticBatch(m, n, F, nullptr, tau);
}

void projectAndKirchhoffBatch(const MohrCoulomb<float>& m, int n, Mat3f* F, Mat3f* tau) {
  henckyPlasticBatch(m, n, F, nullptr, tau);
}

void projectAndKirchhoffBatch(const MohrCoulomb<float>& m, int n, Mat3f* F, const Mat3f* grad_v,
                              Mat3f* tau) {
  henckyPlasticBatch(m, n, F, grad_v, tau);
}

}  // namespace triad
