// Material construction from scene descriptions, and the batched stress
// kernels (float only, so they live here rather than in the headers).
#include "sim/materials/materials.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "sim/lane_math.h"
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
  // tau = 2 mu (F - R) F^T + lambda (J - 1) J I across the vector lanes,
  // in the passes that find R: one matrix at a time it cost half as much
  // as the SVD that found R then. tau is symmetric (R F^T = R S R^T), so
  // six entries are computed.
  using svd3_detail::Pack;
  const Pack two_mu = svd3_detail::splat<Pack>(2.0f * m.mu);
  const Pack lambda = svd3_detail::splat<Pack>(m.lambda);
  const Pack one = svd3_detail::splat<Pack>(1.0f);
  polarRotationLanes(n, F, [&](int b, int count, const Pack(&f)[9], const Pack(&r)[9]) {
    const Pack J = f[0] * (f[4] * f[8] - f[5] * f[7]) - f[1] * (f[3] * f[8] - f[5] * f[6]) +
                   f[2] * (f[3] * f[7] - f[4] * f[6]);
    Pack d[9];
    for (int k = 0; k < 9; ++k) d[k] = f[k] - r[k];
    Pack t[9];
    for (int i = 0; i < 3; ++i)
      for (int j = i; j < 3; ++j) {
        t[3 * i + j] = two_mu * (d[3 * i] * f[3 * j] + d[3 * i + 1] * f[3 * j + 1] +
                                 d[3 * i + 2] * f[3 * j + 2]);
        t[3 * j + i] = t[3 * i + j];
      }
    const Pack p = lambda * (J - one) * J;
    t[0] += p;
    t[4] += p;
    t[8] += p;
    svd3_detail::storeLanes(count, t, tau + b);
  });
}

void kirchhoffBatch(const Water<float>& m, int n, const float* J, const Mat3f* grad_v, Mat3f* tau) {
  // Tait's J^-gamma across the vector lanes as exp(-gamma ln J): libm's
  // powf, one call per particle, was 40% of the water's stress.
  using svd3_detail::kLanes;
  using svd3_detail::Pack;
  using svd3_detail::splat;
  const float k = m.bulk / m.gamma;
  for (int b = 0; b < n; b += kLanes) {
    const int count = std::min(kLanes, n - b);
    alignas(64) float in[kLanes], jc[kLanes], jp[kLanes];
    for (int l = 0; l < kLanes; ++l) in[l] = l < count ? J[b + l] : 1.0f;
    Pack x;
    std::memcpy(&x, in, sizeof(x));
    x = x < Water<float>::kMinJ ? splat<Pack>(Water<float>::kMinJ) : x;
    x = x > Water<float>::kMaxJ ? splat<Pack>(Water<float>::kMaxJ) : x;
    const Pack p = k * (svd3_detail::expv(-m.gamma * svd3_detail::logv(x)) - 1.0f);
    const Pack xp = x * p;
    std::memcpy(jc, &x, sizeof(jc));
    std::memcpy(jp, &xp, sizeof(jp));
    for (int l = 0; l < count; ++l) {
      Mat3f& t = tau[b + l];
      if (m.viscosity != 0.0f) {
        const Mat3f& g = grad_v[b + l];
        t = jc[l] * m.viscosity * (g + g.transpose());
      } else {
        t.setZero();
      }
      t.diagonal().array() -= jp[l];
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

// Mohr-Coulomb sand: batched SVDs, then each particle's return (its
// principal stresses sorted, plane, edge or apex) and stress; with grad_v
// (mu(I)) the return reads each particle's velocity gradient.
void mohrCoulombBatch(const MohrCoulomb<float>& m, int n, Mat3f* F, const Mat3f* grad_v,
                      Mat3f* tau) {
  Mat3f U[kChunk], V[kChunk];
  Vec3f s[kChunk];
  for (int b = 0; b < n; b += kChunk) {
    const int count = std::min(kChunk, n - b);
    svd3Batch(count, F + b, U, s, V);
    for (int i = 0; i < count; ++i) {
      if (grad_v)
        m.projectSvd(U[i], s[i], V[i], F[b + i], grad_v[b + i]);
      else
        m.projectSvd(U[i], s[i], V[i], F[b + i]);
      tau[b + i] = m.elastic.kirchhoffFromSvd(U[i], s[i]);
    }
  }
}

}  // namespace

void projectAndKirchhoffBatch(const DruckerPrager<float>& m, int n, Mat3f* F, Mat3f* tau) {
  // DruckerPrager::projectSvd and StvkHencky::kirchhoffFromSvd across the
  // SVD's lanes: the return, the new F and tau without leaving the vector
  // registers (one particle at a time, the return cost more than the SVD).
  using svd3_detail::Pack;
  using svd3_detail::splat;
  const float c = m.cohesion_strain, slope = m.coneSlope();
  const float min_log = std::log(StvkHencky<float>::kMinSingular);
  const Pack two_mu = splat<Pack>(2.0f * m.elastic.mu), lambda = splat<Pack>(m.elastic.lambda);
  svdLanes(n, F,
           [&](int b, int count, const Pack(&f)[9], const Pack(&u)[9], const Pack(&s)[3],
               const Pack(&v)[9]) {
             // Hencky strain of the singular values floored away from zero.
             Pack eps[3];
             for (int i = 0; i < 3; ++i) {
               const Pack a = svd3_detail::absv(s[i]);
               eps[i] = svd3_detail::logv(a < StvkHencky<float>::kMinSingular
                                              ? splat<Pack>(StvkHencky<float>::kMinSingular)
                                              : a) -
                        c;
             }
             const Pack tr = eps[0] + eps[1] + eps[2];
             Pack dev[3];
             for (int i = 0; i < 3; ++i) dev[i] = eps[i] - tr * (1.0f / 3.0f);
             const Pack dev_norm =
                 svd3_detail::sqrtv(dev[0] * dev[0] + dev[1] * dev[1] + dev[2] * dev[2]);
             const Pack dgamma = dev_norm + slope * tr;
             // Tension to the apex; outside the cone radially onto it at constant tr.
             const auto tension = tr >= 0.0f;
             const auto yield = dgamma > 0.0f;
             const Pack shrink = dgamma / (dev_norm > 0.0f ? dev_norm : splat<Pack>(1.0f));
             const auto moved = tension || yield;
             Pack h[3];  // log of the new singular values
             for (int i = 0; i < 3; ++i) {
               const Pack returned = tension ? splat<Pack>(c) : eps[i] - shrink * dev[i] + c;
               h[i] = moved ? returned : eps[i] + c;
             }
             if (svd3_detail::laneMax(moved ? splat<Pack>(1.0f) : splat<Pack>(0.0f)) > 0.0f) {
               // F = U diag(e^h) V^T where the return moved the state.
               Pack e[3], g[9];
               for (int i = 0; i < 3; ++i) e[i] = svd3_detail::expv(h[i]);
               for (int i = 0; i < 3; ++i)
                 for (int j = 0; j < 3; ++j) {
                   const Pack fij = u[3 * i] * e[0] * v[3 * j] +
                                    u[3 * i + 1] * e[1] * v[3 * j + 1] +
                                    u[3 * i + 2] * e[2] * v[3 * j + 2];
                   g[3 * i + j] = moved ? fij : f[3 * i + j];
                 }
               svd3_detail::storeLanes(count, g, F + b);
             }
             // tau = U diag(2 mu h + lambda tr h) U^T, h floored as the SVD's values are.
             Pack t[3];
             for (int i = 0; i < 3; ++i) h[i] = h[i] < min_log ? splat<Pack>(min_log) : h[i];
             const Pack trh = lambda * (h[0] + h[1] + h[2]);
             for (int i = 0; i < 3; ++i) t[i] = two_mu * h[i] + trh;
             Pack out[9];
             for (int i = 0; i < 3; ++i)
               for (int j = i; j < 3; ++j) {
                 out[3 * i + j] = u[3 * i] * t[0] * u[3 * j] + u[3 * i + 1] * t[1] * u[3 * j + 1] +
                                  u[3 * i + 2] * t[2] * u[3 * j + 2];
                 out[3 * j + i] = out[3 * i + j];
               }
             svd3_detail::storeLanes(count, out, tau + b);
           });
}

void projectAndKirchhoffBatch(const MohrCoulomb<float>& m, int n, Mat3f* F, Mat3f* tau) {
  mohrCoulombBatch(m, n, F, nullptr, tau);
}

void projectAndKirchhoffBatch(const MohrCoulomb<float>& m, int n, Mat3f* F, const Mat3f* grad_v,
                              Mat3f* tau) {
  mohrCoulombBatch(m, n, F, grad_v, tau);
}

}  // namespace triad
