#pragma once
// Singular value and polar decompositions of 3x3 matrices, the kernel under
// every constitutive model: the solver calls it per particle per substep.
//
// Convention ("rotation-variant" SVD, Irving et al. 2004): F = U diag(sigma)
// V^T with U and V proper rotations (det = +1) and
//   sigma(0) >= sigma(1) >= |sigma(2)|,
// so sigma(2) < 0 exactly when det F < 0. Inverted elements then keep a
// continuous rotation and report the inversion in one singular value, which
// is what fixed-corotated and plasticity return mappings need.
//
// Single precision runs McAdams et al. 2011 ("Computing the singular value
// decomposition of 3x3 matrices with minimal branching"): four sweeps of
// approximate-Givens Jacobi on A^T A with the rotation kept as a quaternion,
// a column sort, then Givens QR of A V. It is branch-free apart from a few
// selects and needs no transcendental functions. Double precision (tests,
// finite differences, offline tools) calls Eigen's two-sided JacobiSVD and
// fixes the signs, trading speed for accuracy near 1e-15.
#include <cmath>
#include <type_traits>

#include <Eigen/SVD>

#include "sim/math.h"

#if defined(__SSE__) || defined(_M_X64)
#include <immintrin.h>
#define TRIAD_SVD3_HAS_SSE 1
#endif

namespace triad {

template <class T>
void svd3(const Mat3<T>& F, Mat3<T>& U, Vec3<T>& sigma, Mat3<T>& V);
template <class T>
Mat3<T> polarRotation(const Mat3<T>& F);

namespace svd3_detail {

// Jacobi fallback angle: when the first-order Givens estimate is unreliable
// (|tan(theta/2)| > tan(pi/8)) McAdams rotate by pi/4, which still shrinks
// the off-diagonal entry by a constant factor. kGamma = 1 / tan^2(pi/8).
constexpr float kGamma = 5.828427124746190f;  // 3 + 2 sqrt(2)
constexpr float kCosPi8 = 0.9238795325112867f;
constexpr float kSinPi8 = 0.3826834323650898f;
// Below this norm a QR pivot pair is numerically zero (the input is scaled
// so that its largest entry is 1); skipping the rotation costs no accuracy.
constexpr float kQrEpsilon = 1e-12f;
constexpr int kJacobiSweeps = 4;

// Hardware estimate (12 bits) refined by one Newton step (~23 bits): a third
// of the latency of sqrt + divide on the Jacobi dependency chain.
inline float rsqrt(float x) {
#ifdef TRIAD_SVD3_HAS_SSE
  const float y = _mm_cvtss_f32(_mm_rsqrt_ss(_mm_set_ss(x)));
  return y * (1.5f - 0.5f * x * y * y);
#else
  return 1.0f / std::sqrt(x);
#endif
}

// Half-angle (cos, sin) of the Jacobi rotation that (approximately) zeroes
// apq in the symmetric 2x2 block [app apq; apq aqq].
inline void approxGivens(float app, float apq, float aqq, float& ch, float& sh) {
  const float c = 2.0f * (app - aqq);
  const float s = apq;
  const bool accurate = kGamma * s * s < c * c;
  const float w = rsqrt(c * c + s * s);  // unused (maybe inf) when !accurate
  ch = accurate ? w * c : kCosPi8;
  sh = accurate ? w * s : kSinPi8;
}

// Replace S by Q^T S Q for the rotation Q in the (p, q) plane with Q(p, p) =
// Q(q, q) = c, Q(q, p) = -Q(p, q) = s; k is the remaining index.
inline void jacobiConjugate(float& app, float& apq, float& aqq, float& apk, float& aqk,
                            float ch, float sh) {
  const float c = ch * ch - sh * sh;
  const float s = 2.0f * ch * sh;
  const float cc = c * c, ss = s * s, cs = c * s;
  const float npp = cc * app + 2.0f * cs * apq + ss * aqq;
  const float nqq = ss * app - 2.0f * cs * apq + cc * aqq;
  const float npq = (cc - ss) * apq + cs * (aqq - app);
  const float npk = c * apk + s * aqk;
  const float nqk = c * aqk - s * apk;
  app = npp;
  aqq = nqq;
  apq = npq;
  apk = npk;
  aqk = nqk;
}

// Half-angle (cos, sin) of the Givens rotation G = [c s; -s c] with G (a1,
// a2)^T = (rho, 0)^T, rho >= 0. Swapping the pair for a1 < 0 selects the
// stable one of the two half-angle formulas.
inline void qrGivens(float a1, float a2, float& ch, float& sh) {
  const float rho = std::sqrt(a1 * a1 + a2 * a2);
  sh = rho > kQrEpsilon ? a2 : 0.0f;
  ch = std::fabs(a1) + std::fmax(rho, kQrEpsilon);
  const bool negative = a1 < 0.0f;
  const float t = sh;
  sh = negative ? ch : sh;
  ch = negative ? t : ch;
  const float w = rsqrt(ch * ch + sh * sh);
  ch *= w;
  sh *= w;
}

inline void condSwap(bool c, float& x, float& y) {
  const float t = x;
  x = c ? y : x;
  y = c ? t : y;
}

// If c, swap x and y and negate the new y: applied to two columns of a
// rotation this permutes them and keeps the determinant at +1.
inline void condSwapNegate(bool c, float& x, float& y) {
  const float t = x;
  x = c ? y : x;
  y = c ? -t : y;
}

inline void svdMcAdams(const Mat3<float>& F, Mat3<float>& U, Vec3<float>& sigma,
                       Mat3<float>& V) {
  // Scale the input to unit max entry: A^T A squares magnitudes, and the QR
  // epsilon is absolute, so both would otherwise depend on the units of F.
  const float fmax = F.cwiseAbs().maxCoeff();
  const float scale = fmax > 0.0f ? fmax : 1.0f;
  const float inv = 1.0f / scale;
  const float a00 = F(0, 0) * inv, a01 = F(0, 1) * inv, a02 = F(0, 2) * inv;
  const float a10 = F(1, 0) * inv, a11 = F(1, 1) * inv, a12 = F(1, 2) * inv;
  const float a20 = F(2, 0) * inv, a21 = F(2, 1) * inv, a22 = F(2, 2) * inv;

  // Diagonalize S = A^T A by Jacobi sweeps; V accumulates as a quaternion
  float s00 = a00 * a00 + a10 * a10 + a20 * a20;
  float s01 = a00 * a01 + a10 * a11 + a20 * a21;
  float s02 = a00 * a02 + a10 * a12 + a20 * a22;
  float s11 = a01 * a01 + a11 * a11 + a21 * a21;
  float s12 = a01 * a02 + a11 * a12 + a21 * a22;
  float s22 = a02 * a02 + a12 * a12 + a22 * a22;
  float qw = 1.0f, qx = 0.0f, qy = 0.0f, qz = 0.0f;
  for (int sweep = 0; sweep < kJacobiSweeps; ++sweep) {
    float ch, sh, w, x, y, z;
    // Plane (0, 1): rotation about z
    approxGivens(s00, s01, s11, ch, sh);
    jacobiConjugate(s00, s01, s11, s02, s12, ch, sh);
    w = qw * ch - qz * sh;
    x = qx * ch + qy * sh;
    y = qy * ch - qx * sh;
    z = qz * ch + qw * sh;
    qw = w, qx = x, qy = y, qz = z;
    // Plane (1, 2): rotation about x
    approxGivens(s11, s12, s22, ch, sh);
    jacobiConjugate(s11, s12, s22, s01, s02, ch, sh);
    w = qw * ch - qx * sh;
    x = qx * ch + qw * sh;
    y = qy * ch + qz * sh;
    z = qz * ch - qy * sh;
    qw = w, qx = x, qy = y, qz = z;
    // Plane (2, 0): rotation about y
    approxGivens(s22, s02, s00, ch, sh);
    jacobiConjugate(s22, s02, s00, s12, s01, ch, sh);
    w = qw * ch - qy * sh;
    x = qx * ch - qz * sh;
    y = qy * ch + qw * sh;
    z = qz * ch + qx * sh;
    qw = w, qx = x, qy = y, qz = z;
  }
  const float qn = rsqrt(qw * qw + qx * qx + qy * qy + qz * qz);
  qw *= qn, qx *= qn, qy *= qn, qz *= qn;
  float v00 = 1.0f - 2.0f * (qy * qy + qz * qz), v01 = 2.0f * (qx * qy - qw * qz),
        v02 = 2.0f * (qx * qz + qw * qy);
  float v10 = 2.0f * (qx * qy + qw * qz), v11 = 1.0f - 2.0f * (qx * qx + qz * qz),
        v12 = 2.0f * (qy * qz - qw * qx);
  float v20 = 2.0f * (qx * qz - qw * qy), v21 = 2.0f * (qy * qz + qw * qx),
        v22 = 1.0f - 2.0f * (qx * qx + qy * qy);

  // Form B = A V and sort its columns by decreasing norm
  float b00 = a00 * v00 + a01 * v10 + a02 * v20, b01 = a00 * v01 + a01 * v11 + a02 * v21,
        b02 = a00 * v02 + a01 * v12 + a02 * v22;
  float b10 = a10 * v00 + a11 * v10 + a12 * v20, b11 = a10 * v01 + a11 * v11 + a12 * v21,
        b12 = a10 * v02 + a11 * v12 + a12 * v22;
  float b20 = a20 * v00 + a21 * v10 + a22 * v20, b21 = a20 * v01 + a21 * v11 + a22 * v21,
        b22 = a20 * v02 + a21 * v12 + a22 * v22;
  float rho0 = b00 * b00 + b10 * b10 + b20 * b20;
  float rho1 = b01 * b01 + b11 * b11 + b21 * b21;
  float rho2 = b02 * b02 + b12 * b12 + b22 * b22;
  bool c = rho0 < rho1;
  condSwapNegate(c, b00, b01), condSwapNegate(c, b10, b11), condSwapNegate(c, b20, b21);
  condSwapNegate(c, v00, v01), condSwapNegate(c, v10, v11), condSwapNegate(c, v20, v21);
  condSwap(c, rho0, rho1);
  c = rho0 < rho2;
  condSwapNegate(c, b00, b02), condSwapNegate(c, b10, b12), condSwapNegate(c, b20, b22);
  condSwapNegate(c, v00, v02), condSwapNegate(c, v10, v12), condSwapNegate(c, v20, v22);
  condSwap(c, rho0, rho2);
  c = rho1 < rho2;
  condSwapNegate(c, b01, b02), condSwapNegate(c, b11, b12), condSwapNegate(c, b21, b22);
  condSwapNegate(c, v01, v02), condSwapNegate(c, v11, v12), condSwapNegate(c, v21, v22);

  // QR-factor B by Givens rotations; U = G1^T G2^T G3^T, R's diagonal = sigma
  float ch, sh;
  qrGivens(b00, b10, ch, sh);
  float gc = ch * ch - sh * sh, gs = 2.0f * ch * sh;
  float t0, t1, t2;
  // Rows (0, 1), zeroing b10
  t0 = gc * b00 + gs * b10, t1 = gc * b01 + gs * b11, t2 = gc * b02 + gs * b12;
  b11 = gc * b11 - gs * b01, b12 = gc * b12 - gs * b02;
  b00 = t0, b01 = t1, b02 = t2;
  float u00 = gc, u01 = -gs, u02 = 0.0f;
  float u10 = gs, u11 = gc, u12 = 0.0f;
  float u20 = 0.0f, u21 = 0.0f, u22 = 1.0f;
  // Rows (0, 2), zeroing b20
  qrGivens(b00, b20, ch, sh);
  gc = ch * ch - sh * sh, gs = 2.0f * ch * sh;
  t0 = gc * b00 + gs * b20, t1 = gc * b01 + gs * b21, t2 = gc * b02 + gs * b22;
  b21 = gc * b21 - gs * b01, b22 = gc * b22 - gs * b02;
  b00 = t0, b01 = t1, b02 = t2;
  t0 = gc * u00 + gs * u02, u02 = gc * u02 - gs * u00, u00 = t0;
  t1 = gc * u10 + gs * u12, u12 = gc * u12 - gs * u10, u10 = t1;
  t2 = gc * u20 + gs * u22, u22 = gc * u22 - gs * u20, u20 = t2;
  // Rows (1, 2), zeroing b21
  qrGivens(b11, b21, ch, sh);
  gc = ch * ch - sh * sh, gs = 2.0f * ch * sh;
  t1 = gc * b11 + gs * b21;
  b22 = gc * b22 - gs * b12;
  b11 = t1;
  t0 = gc * u01 + gs * u02, u02 = gc * u02 - gs * u01, u01 = t0;
  t1 = gc * u11 + gs * u12, u12 = gc * u12 - gs * u11, u11 = t1;
  t2 = gc * u21 + gs * u22, u22 = gc * u22 - gs * u21, u21 = t2;

  // Enforce sigma0 >= sigma1 >= |sigma2| exactly
  // The QR gives this up to rounding and unconverged Jacobi; a swap of two
  // singular values swaps the matching columns of U and V and negates one
  // pair so that both stay rotations and U diag(sigma) V^T is unchanged.
  float sg0 = b00, sg1 = b11, sg2 = b22;
  c = sg0 < sg1;
  condSwap(c, sg0, sg1);
  condSwapNegate(c, u00, u01), condSwapNegate(c, u10, u11), condSwapNegate(c, u20, u21);
  condSwapNegate(c, v00, v01), condSwapNegate(c, v10, v11), condSwapNegate(c, v20, v21);
  c = sg1 < std::fabs(sg2);
  // New order (|s2|, sign(s2) s1): U' = [u2 sign(s2), -u1 sign(s2)], V' = [v2, -v1].
  const float sgn = sg2 < 0.0f ? -1.0f : 1.0f;
  const float n1 = std::fabs(sg2), n2 = sgn * sg1;
  sg1 = c ? n1 : sg1;
  sg2 = c ? n2 : sg2;
  const float flip = c ? sgn : 1.0f;
  condSwapNegate(c, u01, u02), condSwapNegate(c, u11, u12), condSwapNegate(c, u21, u22);
  u01 *= flip, u11 *= flip, u21 *= flip, u02 *= flip, u12 *= flip, u22 *= flip;
  condSwapNegate(c, v01, v02), condSwapNegate(c, v11, v12), condSwapNegate(c, v21, v22);

  U << u00, u01, u02, u10, u11, u12, u20, u21, u22;
  V << v00, v01, v02, v10, v11, v12, v20, v21, v22;
  sigma << sg0 * scale, sg1 * scale, sg2 * scale;
}

template <class T>
void svdEigen(const Mat3<T>& F, Mat3<T>& U, Vec3<T>& sigma, Mat3<T>& V) {
  const Eigen::JacobiSVD<Mat3<T>> svd(F, Eigen::ComputeFullU | Eigen::ComputeFullV);
  U = svd.matrixU();
  V = svd.matrixV();
  sigma = svd.singularValues();
  // Eigen returns orthogonal factors and sigma >= 0; moving a reflection
  // into the smallest singular value makes them rotations.
  if (U.determinant() < 0) {
    U.col(2) = -U.col(2);
    sigma(2) = -sigma(2);
  }
  if (V.determinant() < 0) {
    V.col(2) = -V.col(2);
    sigma(2) = -sigma(2);
  }
}

}  // namespace svd3_detail

// F = U diag(sigma) V^T, U and V rotations, sigma(0) >= sigma(1) >= |sigma(2)|.
// float: McAdams et al. (about 1e-6 relative accuracy); any other T: Eigen.
template <class T>
void svd3(const Mat3<T>& F, Mat3<T>& U, Vec3<T>& sigma, Mat3<T>& V) {
  if constexpr (std::is_same_v<T, float>) {
    svd3_detail::svdMcAdams(F, U, sigma, V);
  } else {
    svd3_detail::svdEigen(F, U, sigma, V);
  }
}

// Rotation R of the polar decomposition F = R S (det R = +1; S symmetric and
// indefinite when det F < 0). Equal to U V^T of svd3.
template <class T>
Mat3<T> polarRotation(const Mat3<T>& F) {
  Mat3<T> U, V;
  Vec3<T> sigma;
  svd3(F, U, sigma, V);
  return U * V.transpose();
}

}  // namespace triad

#undef TRIAD_SVD3_HAS_SSE
