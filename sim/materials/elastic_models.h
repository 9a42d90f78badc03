#pragma once
// Hyperelastic constitutive models as small value types (ziran2020 style),
// templated on the scalar: float in the solver, double in tests. Included
// through sim/materials.h.
//
// Conventions shared by every model:
//  - psi(F) is the strain energy density per unit reference volume; P =
//    dpsi/dF the first Piola-Kirchhoff stress; tau = P F^T the Kirchhoff
//    stress, which is what MLS-MPM scatters (f_i = -V0 sum_p tau_p ...).
//  - Mat9 derivatives use column-major vectorization, matching Eigen's
//    storage: vec(A)(i + 3 j) = A(i, j), and dP/dF(a, b) = d vec(P)_a /
//    d vec(F)_b, so vec(dP) = dPdF * vec(dF).
//  - Inverted F (det F < 0) uses the rotation-variant SVD of sim/svd3.h.
#include <algorithm>
#include <cmath>

#include <Eigen/LU>  // determinant()

#include "sim/math.h"
#include "sim/svd3.h"

namespace triad {

// Lame parameters from Young's modulus and Poisson's ratio (nu < 1/2).
template <class T>
struct Lame {
  T mu = 0;
  T lambda = 0;
};

template <class T>
Lame<T> lameFromYoungPoisson(T youngs_modulus, T poisson_ratio) {
  const T E = youngs_modulus, nu = poisson_ratio;
  return {E / (T(2) * (T(1) + nu)), E * nu / ((T(1) + nu) * (T(1) - T(2) * nu))};
}

namespace material_detail {

// cof(F) = J F^{-T}, whose columns are cross products of F's columns:
// defined (and smooth) for singular F, unlike the inverse.
template <class T>
Mat3<T> cofactor(const Mat3<T>& F) {
  Mat3<T> C;
  C.col(0) = F.col(1).cross(F.col(2));
  C.col(1) = F.col(2).cross(F.col(0));
  C.col(2) = F.col(0).cross(F.col(1));
  return C;
}

// [a]_x, the matrix of the cross product a x (.)
template <class T>
Mat3<T> crossMatrix(const Vec3<T>& a) {
  Mat3<T> X;
  X << 0, -a(2), a(1), a(2), 0, -a(0), -a(1), a(0), 0;
  return X;
}

// d vec(cof F) / d vec(F). Column j of cof F is f_{j+1} x f_{j+2}, so block
// (j, k) is -[f_{j+2}]_x for k = j + 1 and [f_{j+1}]_x for k = j + 2.
template <class T>
Mat9<T> cofactorDerivative(const Mat3<T>& F) {
  Mat9<T> D = Mat9<T>::Zero();
  for (int j = 0; j < 3; ++j) {
    const int j1 = (j + 1) % 3, j2 = (j + 2) % 3;
    D.template block<3, 3>(3 * j, 3 * j1) = -crossMatrix<T>(F.col(j2));
    D.template block<3, 3>(3 * j, 3 * j2) = crossMatrix<T>(F.col(j1));
  }
  return D;
}

template <class T>
Eigen::Map<const Eigen::Matrix<T, 9, 1>> vec(const Mat3<T>& A) {
  return Eigen::Map<const Eigen::Matrix<T, 9, 1>>(A.data());
}

}  // namespace material_detail

// Fixed corotated elasticity (Stomakhin et al. 2012):
//   psi = mu |F - R|^2 + lambda/2 (J - 1)^2,  F = R S the polar decomposition.
// Well defined and restoring for inverted F: R stays a rotation and the
// volume term pushes J back through zero.
template <class T>
struct FixedCorotated {
  static constexpr bool kUsesF = true;
  static constexpr bool kUsesPlasticJ = false;

  T mu = 0;
  T lambda = 0;

  static FixedCorotated fromYoungPoisson(T youngs_modulus, T poisson_ratio) {
    const Lame<T> l = lameFromYoungPoisson(youngs_modulus, poisson_ratio);
    return {l.mu, l.lambda};
  }

  T psi(const Mat3<T>& F) const {
    const T J = F.determinant();
    return mu * (F - polarRotation(F)).squaredNorm() + T(0.5) * lambda * (J - 1) * (J - 1);
  }

  // P = 2 mu (F - R) + lambda (J - 1) cof(F)
  Mat3<T> firstPiola(const Mat3<T>& F) const { return firstPiola(F, polarRotation(F)); }
  // The same with F's polar rotation R already known (batched by the FEM).
  Mat3<T> firstPiola(const Mat3<T>& F, const Mat3<T>& R) const {
    const T J = F.determinant();
    return T(2) * mu * (F - R) + lambda * (J - 1) * material_detail::cofactor(F);
  }

  // tau = 2 mu (F - R) F^T + lambda (J - 1) J I: the solver's hot call.
  Mat3<T> kirchhoff(const Mat3<T>& F) const {
    const T J = F.determinant();
    Mat3<T> tau = T(2) * mu * (F - polarRotation(F)) * F.transpose();
    tau.diagonal().array() += lambda * (J - 1) * J;
    return tau;
  }

  // dP/dF = 2 mu (I - dR/dF) + lambda cof (x) cof + lambda (J - 1) dcof/dF.
  // The rotation differential comes from the SVD F = U Sigma V^T: with dF^ =
  // U^T dF V, U^T dR V is skew with entries (dF^_ij - dF^_ji) / (s_i + s_j).
  // s_i + s_j >= 0 in the rotation-variant SVD and vanishes only for
  // degenerate inverted F; it is floored at kMinSingularSum there.
  Mat9<T> firstPiolaDerivative(const Mat3<T>& F) const {
    using material_detail::vec;
    static constexpr T kMinSingularSum = T(1e-6);
    Mat3<T> U, V;
    Vec3<T> s;
    svd3(F, U, s, V);
    const T inv01 = T(1) / std::max(s(0) + s(1), kMinSingularSum);
    const T inv02 = T(1) / std::max(s(0) + s(2), kMinSingularSum);
    const T inv12 = T(1) / std::max(s(1) + s(2), kMinSingularSum);
    Mat9<T> dRdF;
    for (int l = 0; l < 3; ++l) {
      for (int k = 0; k < 3; ++k) {
        // dF = e_k e_l^T, so dF^ = (row k of U)^T (row l of V)
        const Mat3<T> dFhat = U.row(k).transpose() * V.row(l);
        Mat3<T> W = Mat3<T>::Zero();
        W(0, 1) = (dFhat(0, 1) - dFhat(1, 0)) * inv01;
        W(0, 2) = (dFhat(0, 2) - dFhat(2, 0)) * inv02;
        W(1, 2) = (dFhat(1, 2) - dFhat(2, 1)) * inv12;
        W(1, 0) = -W(0, 1), W(2, 0) = -W(0, 2), W(2, 1) = -W(1, 2);
        const Mat3<T> dR = U * W * V.transpose();
        dRdF.col(k + 3 * l) = vec(dR);
      }
    }
    const T J = F.determinant();
    const Mat3<T> C = material_detail::cofactor(F);
    return T(2) * mu * (Mat9<T>::Identity() - dRdF) + lambda * vec(C) * vec(C).transpose() +
           lambda * (J - 1) * material_detail::cofactorDerivative(F);
  }

  // dP/dF in the singular values' frame (Teran et al. 2005), for singular
  // values s of the rotation-variant SVD: A = d2psi/ds2 acts on the
  // diagonal of U^T dF V, and for the pair (i, j) opposite axis k two modes
  // of its off-diagonal entries, (1, 1) with eigenvalue plus(k) = (psi_i -
  // psi_j) / (s_i - s_j) and (1, -1) with minus(k) = (psi_i + psi_j) /
  // (s_i + s_j); here both without a division by s_i - s_j.
  void svdFrameHessian(const Vec3<T>& s, Mat3<T>& A, Vec3<T>& plus, Vec3<T>& minus) const {
    static constexpr T kMinSingularSum = T(1e-6);
    const T J = s.prod();
    const Vec3<T> c(s(1) * s(2), s(0) * s(2), s(0) * s(1));  // J / s_i, the cofactor's
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        A(i, j) = lambda * c(i) * c(j) + (i == j ? T(2) * mu : lambda * (J - 1) * s(3 - i - j));
    for (int k = 0; k < 3; ++k) {
      const T sum = std::max(s((k + 1) % 3) + s((k + 2) % 3), kMinSingularSum);
      plus(k) = T(2) * mu - lambda * (J - 1) * s(k);
      minus(k) = T(2) * mu - T(4) * mu / sum + lambda * (J - 1) * s(k);
    }
  }
};

// Compressible neo-Hookean elasticity:
//   psi = mu/2 (tr(F^T F) - 3) + h(J),  h(J) = -mu log J + lambda/2 (log J)^2.
// h is undefined for J <= 0. Below kMinJ it continues as its second-order
// Taylor expansion at kMinJ, so psi, P and dP/dF stay finite and consistent
// for degenerate and inverted F, and the volume term keeps pushing J back
// up. kMinJ = 1e-2 (a hundredfold compression, far past any physical state)
// keeps the extension's stiffness, h''(kMinJ) ~ 1e4 (mu + 5.6 lambda),
// comfortably inside float range.
template <class T>
struct NeoHookean {
  static constexpr bool kUsesF = true;
  static constexpr bool kUsesPlasticJ = false;
  static constexpr T kMinJ = T(1e-2);

  T mu = 0;
  T lambda = 0;

  static NeoHookean fromYoungPoisson(T youngs_modulus, T poisson_ratio) {
    const Lame<T> l = lameFromYoungPoisson(youngs_modulus, poisson_ratio);
    return {l.mu, l.lambda};
  }

  // h(J) and its first two derivatives, extended below kMinJ.
  void volumeTerms(T J, T& h, T& dh, T& d2h) const {
    const T Jc = std::max(J, kMinJ);
    const T logJ = std::log(Jc);
    h = -mu * logJ + T(0.5) * lambda * logJ * logJ;
    dh = (-mu + lambda * logJ) / Jc;
    d2h = (mu + lambda - lambda * logJ) / (Jc * Jc);
    if (J < kMinJ) {
      const T d = J - kMinJ;
      h += dh * d + T(0.5) * d2h * d * d;
      dh += d2h * d;
    }
  }

  T psi(const Mat3<T>& F) const {
    T h, dh, d2h;
    volumeTerms(F.determinant(), h, dh, d2h);
    return T(0.5) * mu * (F.squaredNorm() - 3) + h;
  }

  // P = mu F + h'(J) cof(F) = mu (F - F^{-T}) + lambda log J F^{-T} for J >= kMinJ
  Mat3<T> firstPiola(const Mat3<T>& F) const {
    T h, dh, d2h;
    volumeTerms(F.determinant(), h, dh, d2h);
    return mu * F + dh * material_detail::cofactor(F);
  }

  // tau = mu F F^T + J h'(J) I = mu (F F^T - I) + lambda log J I for J >= kMinJ
  Mat3<T> kirchhoff(const Mat3<T>& F) const {
    const T J = F.determinant();
    T h, dh, d2h;
    volumeTerms(J, h, dh, d2h);
    Mat3<T> tau = mu * F * F.transpose();
    tau.diagonal().array() += J * dh;
    return tau;
  }

  // dP/dF = mu I + h''(J) cof (x) cof + h'(J) dcof/dF
  Mat9<T> firstPiolaDerivative(const Mat3<T>& F) const {
    using material_detail::vec;
    T h, dh, d2h;
    volumeTerms(F.determinant(), h, dh, d2h);
    const Mat3<T> C = material_detail::cofactor(F);
    return mu * Mat9<T>::Identity() + d2h * vec(C) * vec(C).transpose() +
           dh * material_detail::cofactorDerivative(F);
  }

  // dP/dF in the singular values' frame, as FixedCorotated's: psi_i = mu
  // s_i + h'(J) J / s_i, so plus(k) = mu - h'(J) s_k and minus(k) = mu +
  // h'(J) s_k.
  void svdFrameHessian(const Vec3<T>& s, Mat3<T>& A, Vec3<T>& plus, Vec3<T>& minus) const {
    T h, dh, d2h;
    volumeTerms(s.prod(), h, dh, d2h);
    const Vec3<T> c(s(1) * s(2), s(0) * s(2), s(0) * s(1));
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) A(i, j) = d2h * c(i) * c(j) + (i == j ? mu : dh * s(3 - i - j));
    plus = (mu - dh * s.array()).matrix();
    minus = (mu + dh * s.array()).matrix();
  }
};

// St. Venant-Kirchhoff energy in Hencky (logarithmic) strain, the elastic
// part of Drucker-Prager sand (Klar et al. 2016). With F = U diag(s) V^T and
// eps = log|s|:
//   psi = mu |eps|^2 + lambda/2 (tr eps)^2,
//   P = U diag((2 mu eps + lambda tr eps) / s) V^T,
//   tau = U diag(2 mu eps + lambda tr eps) U^T.
// |s| is floored at kMinSingular (keeping its sign) before the log and the
// division; below it P is finite but no longer the exact gradient of psi.
template <class T>
struct StvkHencky {
  static constexpr bool kUsesF = true;
  static constexpr bool kUsesPlasticJ = false;
  static constexpr T kMinSingular = T(1e-4);

  T mu = 0;
  T lambda = 0;

  static StvkHencky fromYoungPoisson(T youngs_modulus, T poisson_ratio) {
    const Lame<T> l = lameFromYoungPoisson(youngs_modulus, poisson_ratio);
    return {l.mu, l.lambda};
  }

  // Singular values floored away from zero, sign kept (0 counts as positive).
  static Vec3<T> clampSingular(const Vec3<T>& s) {
    Vec3<T> c;
    for (int i = 0; i < 3; ++i)
      c(i) = s(i) < 0 ? std::min(s(i), -kMinSingular) : std::max(s(i), kMinSingular);
    return c;
  }

  static Vec3<T> henckyStrain(const Vec3<T>& s) {
    return clampSingular(s).array().abs().log().matrix();
  }

  // Principal Kirchhoff stresses 2 mu eps + lambda tr(eps).
  Vec3<T> principalKirchhoff(const Vec3<T>& eps) const {
    return (T(2) * mu * eps.array() + lambda * eps.sum()).matrix();
  }

  T psiFromStrain(const Vec3<T>& eps) const {
    const T tr = eps.sum();
    return mu * eps.squaredNorm() + T(0.5) * lambda * tr * tr;
  }

  T psi(const Mat3<T>& F) const {
    Mat3<T> U, V;
    Vec3<T> s;
    svd3(F, U, s, V);
    return psiFromStrain(henckyStrain(s));
  }

  Mat3<T> firstPiola(const Mat3<T>& F) const {
    Mat3<T> U, V;
    Vec3<T> s;
    svd3(F, U, s, V);
    const Vec3<T> p =
        (principalKirchhoff(henckyStrain(s)).array() / clampSingular(s).array()).matrix();
    return U * p.asDiagonal() * V.transpose();
  }

  Mat3<T> kirchhoff(const Mat3<T>& F) const {
    Mat3<T> U, V;
    Vec3<T> s;
    svd3(F, U, s, V);
    return kirchhoffFromSvd(U, s);
  }

  // tau from a decomposition the caller already has (plastic models).
  Mat3<T> kirchhoffFromSvd(const Mat3<T>& U, const Vec3<T>& s) const {
    return U * principalKirchhoff(henckyStrain(s)).asDiagonal() * U.transpose();
  }
};

}  // namespace triad
