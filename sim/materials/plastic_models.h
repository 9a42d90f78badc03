#pragma once
// Elastoplastic models: an elastic energy on the elastic part Fe of F = Fe Fp
// plus a return mapping ("project") that the solver applies to the trial Fe
// after every deformation update. Included through sim/materials.h.
#include <algorithm>
#include <cmath>

#include "sim/materials/elastic_models.h"
#include "sim/math.h"
#include "sim/svd3.h"

namespace triad {

// Snow (Stomakhin et al. 2013): fixed-corotated elasticity whose moduli
// harden with plastic compaction, mu, lambda *= exp(xi (1 - Jp)), and a
// return mapping that clamps the principal stretches of Fe to
// [1 - theta_c, 1 + theta_s]. Per-particle state: Fe and Jp = det Fp.
//
// Jp itself is never clamped, so that Jp det(Fe) = det F holds exactly;
// only the hardening law reads it through [min_jp, max_jp]. The lower clamp
// bounds the stiffening at exp(xi (1 - min_jp)) (e^4 ~ 55 for the defaults,
// worth remembering for the time step); the upper one is far into the
// powder regime, where exp(xi (1 - Jp)) has long underflowed to nothing.
template <class T>
struct Snow {
  static constexpr bool kUsesF = true;
  static constexpr bool kUsesPlasticJ = true;

  FixedCorotated<T> elastic;
  T critical_compression = T(2.5e-2);  // theta_c
  T critical_stretch = T(7.5e-3);      // theta_s
  T hardening = T(10);                 // xi
  T min_jp = T(0.6);
  T max_jp = T(20);

  T stiffnessScale(T Jp) const {
    return std::exp(hardening * (T(1) - std::clamp(Jp, min_jp, max_jp)));
  }

  FixedCorotated<T> hardened(T Jp) const {
    const T h = stiffnessScale(Jp);
    return {elastic.mu * h, elastic.lambda * h};
  }

  T psi(const Mat3<T>& Fe, T Jp) const { return hardened(Jp).psi(Fe); }
  Mat3<T> firstPiola(const Mat3<T>& Fe, T Jp) const { return hardened(Jp).firstPiola(Fe); }
  Mat3<T> kirchhoff(const Mat3<T>& Fe, T Jp) const { return hardened(Jp).kirchhoff(Fe); }

  // Return mapping: Fe = U diag(s) V^T -> U diag(clamp(s)) V^T, and Jp
  // absorbs the volume change. An inverted Fe (s2 < 0) comes out upright;
  // Jp then takes |det Fe| so that it stays positive.
  void project(Mat3<T>& Fe, T& Jp) const {
    Mat3<T> U, V;
    Vec3<T> s;
    svd3(Fe, U, s, V);
    projectSvd(U, s, V, Fe, Jp);
  }

  // project(), then the Kirchhoff stress of the projected state from the
  // same SVD (tau = U 2 mu (S - I) S U^T + lambda (J - 1) J I): one
  // decomposition per particle instead of two.
  Mat3<T> projectAndKirchhoff(Mat3<T>& Fe, T& Jp) const {
    Mat3<T> U, V;
    Vec3<T> s;
    svd3(Fe, U, s, V);
    return projectSvd(U, s, V, Fe, Jp);
  }

  // The body of both, on a decomposition of Fe; returns the new tau.
  Mat3<T> projectSvd(const Mat3<T>& U, const Vec3<T>& s, const Mat3<T>& V, Mat3<T>& Fe,
                     T& Jp) const {
    const T lo = T(1) - critical_compression, hi = T(1) + critical_stretch;
    Vec3<T> c;
    for (int i = 0; i < 3; ++i) c(i) = std::clamp(s(i), lo, hi);
    Fe = U * c.asDiagonal() * V.transpose();
    const T Je = c.prod();
    Jp *= std::abs(s.prod()) / Je;
    const FixedCorotated<T> m = hardened(Jp);
    const Vec3<T> principal =
        (T(2) * m.mu * (c.array() - T(1)) * c.array() + m.lambda * (Je - 1) * Je).matrix();
    return U * principal.asDiagonal() * U.transpose();
  }
};

// Drucker-Prager sand (Klar et al. 2016) on Hencky-strain StVK elasticity,
// with the return mapping of ziran's DruckerPragerStvkHencky.
//
// The cone lives in log-strain space: eps = log|s| - s_c, with s_c =
// cohesion_strain the apex offset; yield is |dev eps| + k alpha tr(eps) <= 0,
// k = (3 lambda + 2 mu) / (2 mu) (that is |dev tau| + alpha tr(tau) <= 0 in
// Kirchhoff stress, divided by 2 mu). alpha = sqrt(2/3) 2 sin(phi) /
// (3 - sin(phi)) matches the Mohr-Coulomb friction angle phi.
//
// Cohesion c (pascals, Mohr-Coulomb) moves the apex from zero to the
// hydrostatic tension p_t = c cot(phi). With eps = s_c (1, 1, 1) the
// Kirchhoff stress is 3 K s_c I, K = lambda + 2 mu / 3 the bulk modulus, so
// s_c = p_t / (3 K): sand with cohesion holds a small tension, cohesionless
// sand none. A friction angle of zero cannot carry cohesion in this model
// (the apex would be at infinity); s_c is then zero.
template <class T>
struct DruckerPrager {
  static constexpr bool kUsesF = true;
  static constexpr bool kUsesPlasticJ = false;

  StvkHencky<T> elastic;
  T alpha = 0;
  T cohesion_strain = 0;

  DruckerPrager() = default;
  DruckerPrager(T youngs_modulus, T poisson_ratio, T friction_angle_deg, T cohesion_pa)
      : elastic(StvkHencky<T>::fromYoungPoisson(youngs_modulus, poisson_ratio)) {
    const T phi = friction_angle_deg * T(3.14159265358979323846 / 180.0);
    const T sin_phi = std::sin(phi);
    alpha = std::sqrt(T(2) / T(3)) * T(2) * sin_phi / (T(3) - sin_phi);
    const T bulk = elastic.lambda + T(2) * elastic.mu / T(3);
    const T tan_phi = std::tan(phi);
    cohesion_strain = tan_phi > T(1e-6) ? cohesion_pa / tan_phi / (T(3) * bulk) : T(0);
  }

  T psi(const Mat3<T>& F) const { return elastic.psi(F); }
  Mat3<T> firstPiola(const Mat3<T>& F) const { return elastic.firstPiola(F); }
  Mat3<T> kirchhoff(const Mat3<T>& F) const { return elastic.kirchhoff(F); }

  // Yield function in strain units: <= 0 inside the cone, 0 on its surface.
  // Every state in hydrostatic tension beyond the apex (tr eps > 0) is
  // outside, and the apex itself reads 0.
  T yield(const Mat3<T>& F) const {
    Mat3<T> U, V;
    Vec3<T> s;
    svd3(F, U, s, V);
    const Vec3<T> eps = (StvkHencky<T>::henckyStrain(s).array() - cohesion_strain).matrix();
    const T tr = eps.sum();
    const Vec3<T> dev = (eps.array() - tr / T(3)).matrix();
    return dev.norm() + coneSlope() * tr;
  }

  // Return mapping on the elastic F. Tension (tr eps >= 0) goes to the apex,
  // a state outside the cone radially onto its surface in the deviatoric
  // plane at constant tr(eps). Returns false, leaving F alone, iff F was
  // inside the cone.
  bool project(Mat3<T>& F) const {
    Mat3<T> U, V;
    Vec3<T> s;
    svd3(F, U, s, V);
    return projectSvd(U, s, V, F);
  }

  // project(), then tau of the resulting state from the same SVD.
  Mat3<T> projectAndKirchhoff(Mat3<T>& F) const {
    Mat3<T> U, V;
    Vec3<T> s;
    svd3(F, U, s, V);
    projectSvd(U, s, V, F);
    return elastic.kirchhoffFromSvd(U, s);
  }

  // The body of both; s is updated to the projected singular values.
  bool projectSvd(const Mat3<T>& U, Vec3<T>& s, const Mat3<T>& V, Mat3<T>& F) const {
    const Vec3<T> eps = (StvkHencky<T>::henckyStrain(s).array() - cohesion_strain).matrix();
    const T tr = eps.sum();
    if (tr >= 0) {
      s.setConstant(std::exp(cohesion_strain));
    } else {
      const Vec3<T> dev = (eps.array() - tr / T(3)).matrix();
      const T dev_norm = dev.norm();
      const T dgamma = dev_norm + coneSlope() * tr;
      if (dgamma <= 0) return false;  // inside; dev_norm > 0 below
      const Vec3<T> H = eps - (dgamma / dev_norm) * dev;
      s = (H.array() + cohesion_strain).exp().matrix();
    }
    F = U * s.asDiagonal() * V.transpose();
    return true;
  }

 private:
  T coneSlope() const {
    return (T(3) * elastic.lambda + T(2) * elastic.mu) / (T(2) * elastic.mu) * alpha;
  }
};

}  // namespace triad
