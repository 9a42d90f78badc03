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

// What the plastic models on Hencky-strain StVK elasticity share: the
// elastic energy and stresses of the (projected) F, and the return mapping
// through one SVD. Model supplies projectSvd(U, s, V, F), which moves s to
// the projected singular values, writes F and says whether it moved.
template <class T, class Model>
struct HenckyPlastic {
  static constexpr bool kUsesF = true;
  static constexpr bool kUsesPlasticJ = false;

  StvkHencky<T> elastic;

  T psi(const Mat3<T>& F) const { return elastic.psi(F); }
  Mat3<T> firstPiola(const Mat3<T>& F) const { return elastic.firstPiola(F); }
  Mat3<T> kirchhoff(const Mat3<T>& F) const { return elastic.kirchhoff(F); }

  // Return mapping on the elastic F. Returns false, leaving F alone, iff F
  // was inside the yield surface.
  bool project(Mat3<T>& F) const {
    Mat3<T> U, V;
    Vec3<T> s;
    svd3(F, U, s, V);
    return static_cast<const Model&>(*this).projectSvd(U, s, V, F);
  }

  // project(), then tau of the resulting state from the same SVD.
  Mat3<T> projectAndKirchhoff(Mat3<T>& F) const {
    Mat3<T> U, V;
    Vec3<T> s;
    svd3(F, U, s, V);
    static_cast<const Model&>(*this).projectSvd(U, s, V, F);
    return elastic.kirchhoffFromSvd(U, s);
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
struct DruckerPrager : HenckyPlastic<T, DruckerPrager<T>> {
  using HenckyPlastic<T, DruckerPrager<T>>::elastic;
  T alpha = 0;
  T cohesion_strain = 0;

  DruckerPrager() = default;
  DruckerPrager(T youngs_modulus, T poisson_ratio, T friction_angle_deg, T cohesion_pa) {
    elastic = StvkHencky<T>::fromYoungPoisson(youngs_modulus, poisson_ratio);
    const T phi = friction_angle_deg * T(3.14159265358979323846 / 180.0);
    const T sin_phi = std::sin(phi);
    alpha = std::sqrt(T(2) / T(3)) * T(2) * sin_phi / (T(3) - sin_phi);
    const T bulk = elastic.lambda + T(2) * elastic.mu / T(3);
    const T tan_phi = std::tan(phi);
    cohesion_strain = tan_phi > T(1e-6) ? cohesion_pa / tan_phi / (T(3) * bulk) : T(0);
  }

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

  // The return mapping on a decomposition of the elastic F (project() and
  // projectAndKirchhoff() come from HenckyPlastic). Tension (tr eps >= 0)
  // goes to the apex, a state outside the cone radially onto its surface
  // in the deviatoric plane at constant tr(eps).
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

  // The cone's slope in strain units: k alpha.
  T coneSlope() const {
    return (T(3) * elastic.lambda + T(2) * elastic.mu) / (T(2) * elastic.mu) * alpha;
  }
};

// Mohr-Coulomb sand on the same Hencky-strain StVK elasticity: the friction
// angle means one strength in every stress state (triaxial compression and
// extension, plane strain), where Drucker-Prager's cone matches it in one.
// The principal Kirchhoff stresses tau_i = lambda tr(eps) + 2 mu eps_i are
// linear in the principal log strains, so the return mapping is the
// small-strain one in principal space (de Souza Neto, Peric & Owen 2008,
// section 8.2): onto the main plane, else onto the edge the ordering says,
// else onto the apex. With tau_1 >= tau_2 >= tau_3 (tension positive),
//   f = (tau_1 - tau_3) + (tau_1 + tau_3) sin(phi) - 2 c cos(phi) <= 0,
// and the plastic flow follows g = (tau_1 - tau_3) + (tau_1 + tau_3) sin(psi):
// a dilatancy angle psi of 0 (the default) flows at constant volume, as the
// Drucker-Prager return does; psi = phi is associative. The apex is the
// hydrostatic tension c cot(phi); with phi = 0 (Tresca) there is none.
template <class T>
struct MohrCoulomb : HenckyPlastic<T, MohrCoulomb<T>> {
  using HenckyPlastic<T, MohrCoulomb<T>>::elastic;
  T sin_phi = 0, cos_phi = 1, sin_psi = 0;
  T cohesion = 0;  // c, pascals
  // Rate dependence, mu(I) (Jop, Forterre & Pouliquen 2006), on when
  // grain_diameter > 0: the friction coefficient tan(phi) rises from
  // mu_s = tan(phi) at rest to mu_2 as the inertial number
  // I = gamma_dot d / sqrt(p / rho) grows, mu = mu_s + (mu_2 - mu_s) I / (I_0 + I).
  T mu_2 = 0;
  T i_0 = T(0.279);
  T grain_diameter = 0;  // d, m
  T density = 0;         // rho, kg/m^3

  // The friction angle at which one particle's state yields.
  struct Friction {
    T sin_phi, cos_phi;
  };

  MohrCoulomb() = default;
  MohrCoulomb(T youngs_modulus, T poisson_ratio, T friction_angle_deg, T cohesion_pa,
              T dilatancy_angle_deg = T(0))
      : cohesion(cohesion_pa) {
    elastic = StvkHencky<T>::fromYoungPoisson(youngs_modulus, poisson_ratio);
    const T rad = T(3.14159265358979323846 / 180.0);
    sin_phi = std::sin(friction_angle_deg * rad);
    cos_phi = std::cos(friction_angle_deg * rad);
    sin_psi = std::sin(dilatancy_angle_deg * rad);
  }

  bool rateDependent() const { return grain_diameter > T(0); }
  Friction staticFriction() const { return {sin_phi, cos_phi}; }

  // The friction of a state of principal stresses tau under the velocity
  // gradient grad_v: mu(I), with the shear rate |gamma_dot| = sqrt(2) |dev
  // D| (D the rate of deformation) and the pressure p = -mean(tau). A state
  // without pressure has no finite I: it takes mu_2.
  Friction frictionAt(const Vec3<T>& tau, const Mat3<T>& grad_v) const {
    if (!rateDependent()) return staticFriction();
    const Mat3<T> D = T(0.5) * (grad_v + grad_v.transpose());
    const T rate = std::sqrt(T(2)) * (D - D.trace() / T(3) * Mat3<T>::Identity()).norm();
    const T p = -tau.mean();
    const T mu_s = sin_phi / cos_phi;
    T mu = mu_2;
    if (p > T(0)) {
      const T inertial = rate * grain_diameter / std::sqrt(p / density);
      mu = mu_s + (mu_2 - mu_s) * inertial / (i_0 + inertial);
    }
    const T r = T(1) / std::sqrt(T(1) + mu * mu);
    return {mu * r, r};
  }

  // Yield function of principal stresses in any order, in pascals: <= 0
  // inside, 0 on the surface.
  T yieldOfStress(const Vec3<T>& tau) const { return yieldOfStress(tau, staticFriction()); }
  T yieldOfStress(const Vec3<T>& tau, const Friction& fr) const {
    const T hi = tau.maxCoeff(), lo = tau.minCoeff();
    return (hi - lo) + (hi + lo) * fr.sin_phi - T(2) * cohesion * fr.cos_phi;
  }

  T yield(const Mat3<T>& F) const {
    Mat3<T> U, V;
    Vec3<T> s;
    svd3(F, U, s, V);
    return yieldOfStress(elastic.principalKirchhoff(StvkHencky<T>::henckyStrain(s)));
  }

  // The return mapping on a decomposition of the elastic F (project() and
  // projectAndKirchhoff() come from HenckyPlastic).
  bool projectSvd(const Mat3<T>& U, Vec3<T>& s, const Mat3<T>& V, Mat3<T>& F) const {
    const Vec3<T> tau = elastic.principalKirchhoff(StvkHencky<T>::henckyStrain(s));
    return projectSvd(U, s, V, F, tau, staticFriction());
  }

  // The same under mu(I), for a particle deforming at grad_v.
  bool projectSvd(const Mat3<T>& U, Vec3<T>& s, const Mat3<T>& V, Mat3<T>& F,
                  const Mat3<T>& grad_v) const {
    const Vec3<T> tau = elastic.principalKirchhoff(StvkHencky<T>::henckyStrain(s));
    return projectSvd(U, s, V, F, tau, frictionAt(tau, grad_v));
  }

  // The body of both: tau the trial principal stresses of s.
  bool projectSvd(const Mat3<T>& U, Vec3<T>& s, const Mat3<T>& V, Mat3<T>& F, const Vec3<T>& tau,
                  const Friction& fr) const {
    if (yieldOfStress(tau, fr) <= T(0)) return false;
    // Sort the principal stresses: tau(o[0]) >= tau(o[1]) >= tau(o[2]).
    int o[3] = {0, 1, 2};
    if (tau(o[0]) < tau(o[1])) std::swap(o[0], o[1]);
    if (tau(o[1]) < tau(o[2])) std::swap(o[1], o[2]);
    if (tau(o[0]) < tau(o[1])) std::swap(o[0], o[1]);
    const Vec3<T> sorted(tau(o[0]), tau(o[1]), tau(o[2]));
    const Vec3<T> ret = returnSorted(sorted, fr);
    // Back to log strains: eps = (tau - lambda tr(tau) / (3 lambda + 2 mu)) / (2 mu).
    const T mean = elastic.lambda * ret.sum() / (T(3) * elastic.lambda + T(2) * elastic.mu);
    for (int i = 0; i < 3; ++i) s(o[i]) = std::exp((ret(i) - mean) / (T(2) * elastic.mu));
    F = U * s.asDiagonal() * V.transpose();
    return true;
  }

  // The stress a sorted trial state outside the surface returns to.
  Vec3<T> returnSorted(const Vec3<T>& t) const { return returnSorted(t, staticFriction()); }
  Vec3<T> returnSorted(const Vec3<T>& t, const Friction& fr) const {
    const T sp = fr.sin_phi, cp = fr.cos_phi;
    const T k = T(2) * cohesion * cp;
    // Gradients of the yield planes and flow directions, in sorted
    // principal space: the main plane (1, 3), the edge planes (1, 2) and
    // (2, 3).
    const Vec3<T> df_main(T(1) + sp, T(0), -(T(1) - sp));
    const Vec3<T> dg_main(T(1) + sin_psi, T(0), -(T(1) - sin_psi));
    const T f_main = df_main.dot(t) - k;
    const Vec3<T> dn_main = stiffness(dg_main);
    // Main plane.
    const T dgamma = f_main / df_main.dot(dn_main);
    const Vec3<T> main = t - dgamma * dn_main;
    if (main(0) >= main(1) && main(1) >= main(2)) return main;
    // An edge: tau_1 = tau_2 if the main return overtook tau_1 with tau_2,
    // else tau_2 = tau_3. On the first the planes (1, 3) and (2, 3) are
    // both active (either of the two largest is the maximum), on the second
    // (1, 3) and (1, 2).
    const bool upper = main(1) > main(0);
    const Vec3<T> df_edge =
        upper ? Vec3<T>(T(0), T(1) + sp, -(T(1) - sp)) : Vec3<T>(T(1) + sp, -(T(1) - sp), T(0));
    const Vec3<T> dg_edge = upper ? Vec3<T>(T(0), T(1) + sin_psi, -(T(1) - sin_psi))
                                  : Vec3<T>(T(1) + sin_psi, -(T(1) - sin_psi), T(0));
    const Vec3<T> dn_edge = stiffness(dg_edge);
    const T f_edge = df_edge.dot(t) - k;
    const T a11 = df_main.dot(dn_main), a12 = df_main.dot(dn_edge);
    const T a21 = df_edge.dot(dn_main), a22 = df_edge.dot(dn_edge);
    const T det = a11 * a22 - a12 * a21;
    const T ga = (a22 * f_main - a12 * f_edge) / det;
    const T gb = (a11 * f_edge - a21 * f_main) / det;
    const Vec3<T> edge = t - ga * dn_main - gb * dn_edge;
    // Round-off leaves the two equal stresses a few ulps apart: equal them.
    const T tol = T(1e-5) * (std::abs(t(0)) + std::abs(t(2)) + cohesion);
    if (ga >= T(0) && gb >= T(0) && edge(0) + tol >= edge(1) && edge(1) + tol >= edge(2)) {
      Vec3<T> e = edge;
      if (upper)
        e(0) = e(1) = T(0.5) * (edge(0) + edge(1));
      else
        e(1) = e(2) = T(0.5) * (edge(1) + edge(2));
      return e;
    }
    // The apex: hydrostatic tension c cot(phi) (Tresca has none; its
    // edges hold every state, so this is reached only through round-off).
    const T apex = sp > T(1e-6) ? cohesion * cp / sp : t.mean();
    return Vec3<T>::Constant(apex);
  }

 private:
  // Principal stress of a principal strain: lambda tr(e) + 2 mu e.
  Vec3<T> stiffness(const Vec3<T>& e) const { return elastic.principalKirchhoff(e); }
};

}  // namespace triad
