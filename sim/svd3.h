#pragma once
// Singular value and polar decompositions of 3x3 matrices, the kernel under
// every constitutive model: the solver calls it per particle per substep.
//
// Convention ("rotation-variant" SVD, Irving et al. 2004): F = U diag(sigma)
// V^T with U and V proper rotations (det = +1) and
//   sigma(0) >= sigma(1) >= |sigma(2)|,
// so sigma(2) < 0 exactly when det F < 0. Inverted elements then keep a
// continuous rotation and report the inversion in one singular value, which
// is what fixed-corotated elasticity and plastic return mappings need.
//
// Single precision follows McAdams et al. 2011 ("Computing the singular
// value decomposition of 3x3 matrices with minimal branching"): a fixed
// number of cyclic Jacobi sweeps on A^T A, a column sort of A V, then QR by
// Givens rotations, branch-free (selects only) and with hardware rsqrt. One
// deliberate difference: the Jacobi angles are exact (one sqrt per rotation)
// instead of McAdams' approximate Givens quaternions. With four sweeps the
// approximate angles left reconstruction errors up to 8e-3 on random
// matrices and 7e-4 on near-rotations (slow convergence where eigenvalues of
// A^T A are close, i.e. exactly the F ~ R of MPM); exact angles converge
// quadratically to ~1e-6 everywhere for little extra cost.
//
// The kernel is written once over a "lane" type: float for svd3(), and a GCC
// vector of floats for svd3Batch(), which decomposes that many matrices per
// pass. One decomposition is a chain of twelve dependent rotations, so a
// single call is latency bound; batches fill the vector units and are
// several times faster per matrix. Double precision (tests, finite
// differences, tools) calls Eigen's two-sided JacobiSVD and fixes the signs.
#include <cmath>
#include <cstdint>
#include <cstring>
#include <type_traits>

#include <Eigen/SVD>

#include "sim/math.h"

#if defined(__SSE2__)
#include <immintrin.h>
#endif

namespace triad {

namespace svd3_detail {

// Lanes of one vector register: matrices per batch pass.
#if defined(__GNUC__) && defined(__AVX512F__)
constexpr int kLanes = 16;
#elif defined(__GNUC__) && defined(__AVX__)
constexpr int kLanes = 8;
#elif defined(__GNUC__) && defined(__SSE2__)
constexpr int kLanes = 4;
#else
constexpr int kLanes = 1;
#endif

template <int N>
struct PackOf;
#if defined(__GNUC__)
template <int N>
struct PackOf {
  typedef float type __attribute__((vector_size(N * sizeof(float))));
};
#define TRIAD_SVD3_INLINE __attribute__((always_inline)) inline
#else
#define TRIAD_SVD3_INLINE inline
#endif
template <>
struct PackOf<1> {
  using type = float;
};
using Pack = PackOf<kLanes>::type;

constexpr int kJacobiSweeps = 4;
// The kernel scales its input to a max entry in [1, 2), so the largest
// eigenvalue of A^T A is >= 1. Off-diagonal entries and diagonal gaps below
// kJacobiFloor are then far below float resolution and are treated as zero:
// squaring anything smaller would hit denormals (a 100x slowdown on x86 once
// the sweeps have converged quadratically).
constexpr float kJacobiFloor = 1e-15f;
// A QR pivot pair below this norm is numerically zero: skip the rotation.
constexpr float kQrEpsilon = 1e-12f;

// Lane-generic helpers
template <class R>
inline R splat(float x) {
  return R{} + x;
}
inline float absv(float x) {
  return std::fabs(x);
}
inline float sqrtv(float x) {
  return std::sqrt(x);
}
// Hardware reciprocal square root estimate: 12 bits (SSE) or 14 (AVX-512).
inline float rsqrtEstimate(float x) {
#if defined(__AVX512F__)
  const __m128 v = _mm_set_ss(x);
  return _mm_cvtss_f32(_mm_rsqrt14_ss(v, v));
#elif defined(__SSE2__)
  return _mm_cvtss_f32(_mm_rsqrt_ss(_mm_set_ss(x)));
#else
  return 1.0f / std::sqrt(x);
#endif
}
#if defined(__GNUC__) && defined(__SSE2__)
inline Pack absv(Pack x) {
  return x < 0.0f ? -x : x;
}
inline Pack sqrtv(Pack x) {
#if defined(__AVX512F__)
  return (Pack)_mm512_maskz_sqrt_ps(0xFFFF, (__m512)x);
#elif defined(__AVX__)
  return (Pack)_mm256_sqrt_ps((__m256)x);
#else
  return (Pack)_mm_sqrt_ps((__m128)x);
#endif
}
inline Pack rsqrtEstimate(Pack x) {
#if defined(__AVX512F__)
  return (Pack)_mm512_maskz_rsqrt14_ps(0xFFFF, (__m512)x);
#elif defined(__AVX__)
  return (Pack)_mm256_rsqrt_ps((__m256)x);
#else
  return (Pack)_mm_rsqrt_ps((__m128)x);
#endif
}
#endif

// scale = the largest power of two <= x and inv = 1 / scale, both exact;
// 1 for zero and denormal x (nothing to gain from scaling those).
inline void powerOfTwoScale(float x, float& scale, float& inv) {
  std::uint32_t bits;
  std::memcpy(&bits, &x, sizeof(bits));
  const std::uint32_t e = bits & 0x7F800000u;
  const std::uint32_t ie = 0x7F000000u - e;
  std::memcpy(&scale, &e, sizeof(scale));
  std::memcpy(&inv, &ie, sizeof(inv));
  scale = e != 0 ? scale : 1.0f;
  inv = e != 0 ? inv : 1.0f;
}
#if defined(__GNUC__) && defined(__SSE2__)
inline void powerOfTwoScale(Pack x, Pack& scale, Pack& inv) {
  typedef std::int32_t Bits __attribute__((vector_size(sizeof(Pack))));
  const Bits e = (Bits)x & 0x7F800000;
  const Bits ie = 0x7F000000 - e;
  scale = e != 0 ? (Pack)e : splat<Pack>(1.0f);
  inv = e != 0 ? (Pack)ie : splat<Pack>(1.0f);
}
#endif

// Estimate refined by one Newton step: ~23 bits, a third of the latency of
// sqrt + divide. x must be positive and normal.
template <class R>
inline R rsqrtAccurate(R x) {
  const R y = rsqrtEstimate(x);
  return y * (1.5f - 0.5f * x * y * y);
}

// If c: swap x and y.
template <class M, class R>
inline void condSwap(M c, R& x, R& y) {
  const R t = x;
  x = c ? y : x;
  y = c ? t : y;
}

// If c: swap x and y and negate the new y. Applied to two columns of a
// rotation this permutes them and keeps the determinant at +1.
template <class M, class R>
inline void condSwapNegate(M c, R& x, R& y) {
  const R t = x;
  x = c ? y : x;
  y = c ? -t : y;
}

// One Jacobi rotation of the symmetric S in the (p, q) plane (k is the third
// index): S <- Q^T S Q, V <- V Q, with Q(p, p) = Q(q, q) = c and Q(q, p) =
// -Q(p, q) = s, c = cos(theta), s = sin(theta), tan(2 theta) = 2 apq / (app
// - aqq) and |theta| <= pi/4 (Rutishauser's choice, which keeps the diagonal
// from swapping and converges quadratically). (cos, sin)(theta) is taken
// proportional to (|cos 2theta| + 1, sin 2theta): the stable half-angle form.
template <class R>
TRIAD_SVD3_INLINE void jacobiRotate(R& app, R& apq, R& aqq, R& apk, R& aqk, R& vp0, R& vp1, R& vp2,
                                    R& vq0, R& vq1, R& vq2) {
  const R d = app - aqq;
  R x = absv(d);                              // proportional to cos(2 theta)
  R y = d < 0.0f ? -2.0f * apq : 2.0f * apq;  // proportional to sin(2 theta)
  x = x < kJacobiFloor ? R{} : x;
  y = absv(y) < kJacobiFloor ? R{} : y;
  const R cx = x + sqrtv(x * x + y * y);
  const R n2 = cx * cx + y * y;
  const auto rotate = n2 > 0.0f;
  const R w = rsqrtAccurate(n2);  // unused (inf) where !rotate
  const R c = rotate ? w * cx : splat<R>(1.0f);
  const R s = rotate ? w * y : R{};
  const R cc = c * c, ss = s * s, cs = c * s;
  const R npp = cc * app + 2.0f * cs * apq + ss * aqq;
  const R nqq = ss * app - 2.0f * cs * apq + cc * aqq;
  const R npq = (cc - ss) * apq + cs * (aqq - app);
  const R npk = c * apk + s * aqk;
  const R nqk = c * aqk - s * apk;
  app = npp, aqq = nqq, apq = npq, apk = npk, aqk = nqk;
  R t;
  t = c * vp0 + s * vq0, vq0 = c * vq0 - s * vp0, vp0 = t;
  t = c * vp1 + s * vq1, vq1 = c * vq1 - s * vp1, vp1 = t;
  t = c * vp2 + s * vq2, vq2 = c * vq2 - s * vp2, vp2 = t;
}

// (cos, sin) of the Givens rotation G = [c s; -s c] with G (a1, a2)^T =
// (rho, 0)^T, rho >= 0, from its half angle (McAdams' QR step). Swapping the
// pair for a1 < 0 selects the stable one of the two half-angle formulas.
template <class R>
TRIAD_SVD3_INLINE void qrGivens(R a1, R a2, R& c, R& s) {
  const R rho = sqrtv(a1 * a1 + a2 * a2);
  const auto significant = rho > kQrEpsilon;
  R sh = significant ? a2 : R{};
  R ch = absv(a1) + (significant ? rho : splat<R>(kQrEpsilon));
  condSwap(a1 < 0.0f, sh, ch);
  const R w = rsqrtAccurate(ch * ch + sh * sh);
  ch *= w;
  sh *= w;
  c = ch * ch - sh * sh;
  s = 2.0f * ch * sh;
}

// The decomposition of row-major 3x3 matrices, one per lane of R.
template <class R>
inline void svdKernel(const R (&f)[9], R (&u)[9], R (&sigma)[3], R (&v)[9]) {
  // Scale by a power of two to a max entry in [1, 2): A^T A squares
  // magnitudes and the floors above are absolute, so both would otherwise
  // depend on the units of F. Powers of two scale exactly and need no divide.
  R fmax = absv(f[0]);
  for (int k = 1; k < 9; ++k) {
    const R ak = absv(f[k]);
    fmax = ak > fmax ? ak : fmax;
  }
  R scale, inv;
  powerOfTwoScale(fmax, scale, inv);
  const R a00 = f[0] * inv, a01 = f[1] * inv, a02 = f[2] * inv;
  const R a10 = f[3] * inv, a11 = f[4] * inv, a12 = f[5] * inv;
  const R a20 = f[6] * inv, a21 = f[7] * inv, a22 = f[8] * inv;

  // Diagonalize S = A^T A by cyclic Jacobi sweeps, accumulating V
  R s00 = a00 * a00 + a10 * a10 + a20 * a20;
  R s01 = a00 * a01 + a10 * a11 + a20 * a21;
  R s02 = a00 * a02 + a10 * a12 + a20 * a22;
  R s11 = a01 * a01 + a11 * a11 + a21 * a21;
  R s12 = a01 * a02 + a11 * a12 + a21 * a22;
  R s22 = a02 * a02 + a12 * a12 + a22 * a22;
  const R one = splat<R>(1.0f);
  R v00 = one, v01{}, v02{}, v10{}, v11 = one, v12{}, v20{}, v21{}, v22 = one;
  for (int sweep = 0; sweep < kJacobiSweeps; ++sweep) {
    jacobiRotate(s00, s01, s11, s02, s12, v00, v10, v20, v01, v11, v21);
    jacobiRotate(s11, s12, s22, s01, s02, v01, v11, v21, v02, v12, v22);
    jacobiRotate(s22, s02, s00, s12, s01, v02, v12, v22, v00, v10, v20);
  }
  // Each rotation is normalized to ~1e-7; make V's (orthogonal) columns unit.
  R n = rsqrtAccurate(v00 * v00 + v10 * v10 + v20 * v20);
  v00 *= n, v10 *= n, v20 *= n;
  n = rsqrtAccurate(v01 * v01 + v11 * v11 + v21 * v21);
  v01 *= n, v11 *= n, v21 *= n;
  n = rsqrtAccurate(v02 * v02 + v12 * v12 + v22 * v22);
  v02 *= n, v12 *= n, v22 *= n;

  // Form B = A V and sort its columns by decreasing norm
  R b00 = a00 * v00 + a01 * v10 + a02 * v20, b01 = a00 * v01 + a01 * v11 + a02 * v21,
    b02 = a00 * v02 + a01 * v12 + a02 * v22;
  R b10 = a10 * v00 + a11 * v10 + a12 * v20, b11 = a10 * v01 + a11 * v11 + a12 * v21,
    b12 = a10 * v02 + a11 * v12 + a12 * v22;
  R b20 = a20 * v00 + a21 * v10 + a22 * v20, b21 = a20 * v01 + a21 * v11 + a22 * v21,
    b22 = a20 * v02 + a21 * v12 + a22 * v22;
  R rho0 = b00 * b00 + b10 * b10 + b20 * b20;
  R rho1 = b01 * b01 + b11 * b11 + b21 * b21;
  R rho2 = b02 * b02 + b12 * b12 + b22 * b22;
  auto c = rho0 < rho1;
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

  // QR-factor B by Givens rotations: U = G1^T G2^T G3^T, sigma = diag(R)
  R gc, gs, t0, t1, t2;
  // Rows (0, 1), zeroing b10
  qrGivens(b00, b10, gc, gs);
  t0 = gc * b00 + gs * b10, t1 = gc * b01 + gs * b11, t2 = gc * b02 + gs * b12;
  b11 = gc * b11 - gs * b01, b12 = gc * b12 - gs * b02;
  b00 = t0, b01 = t1, b02 = t2;
  R u00 = gc, u01 = -gs, u02{};
  R u10 = gs, u11 = gc, u12{};
  R u20{}, u21{}, u22 = one;
  // Rows (0, 2), zeroing b20
  qrGivens(b00, b20, gc, gs);
  b00 = gc * b00 + gs * b20;
  t1 = gc * b01 + gs * b21, t2 = gc * b02 + gs * b22;
  b21 = gc * b21 - gs * b01, b22 = gc * b22 - gs * b02;
  b01 = t1, b02 = t2;
  t0 = gc * u00 + gs * u02, u02 = gc * u02 - gs * u00, u00 = t0;
  t1 = gc * u10 + gs * u12, u12 = gc * u12 - gs * u10, u10 = t1;
  t2 = gc * u20 + gs * u22, u22 = gc * u22 - gs * u20, u20 = t2;
  // Rows (1, 2), zeroing b21
  qrGivens(b11, b21, gc, gs);
  b22 = gc * b22 - gs * b12;
  b11 = gc * b11 + gs * b21;
  t0 = gc * u01 + gs * u02, u02 = gc * u02 - gs * u01, u01 = t0;
  t1 = gc * u11 + gs * u12, u12 = gc * u12 - gs * u11, u11 = t1;
  t2 = gc * u21 + gs * u22, u22 = gc * u22 - gs * u21, u21 = t2;

  // Enforce sigma0 >= sigma1 >= |sigma2| exactly
  // QR gives this up to rounding. Swapping two singular values swaps the
  // matching columns of U and V and negates one pair, so both stay
  // rotations and U diag(sigma) V^T is unchanged.
  R sg0 = b00, sg1 = b11, sg2 = b22;  // sg0, sg1 >= 0 by construction
  c = sg0 < sg1;
  condSwap(c, sg0, sg1);
  condSwapNegate(c, u00, u01), condSwapNegate(c, u10, u11), condSwapNegate(c, u20, u21);
  condSwapNegate(c, v00, v01), condSwapNegate(c, v10, v11), condSwapNegate(c, v20, v21);
  // (s1, s2) -> (|s2|, sign(s2) s1): U' = sign(s2) [u2, -u1], V' = [v2, -v1]
  c = sg1 < absv(sg2);
  const R sgn = sg2 < 0.0f ? -one : one;
  const R flip = c ? sgn : one;
  const R n1 = absv(sg2), n2 = sgn * sg1;
  sg1 = c ? n1 : sg1;
  sg2 = c ? n2 : sg2;
  condSwapNegate(c, u01, u02), condSwapNegate(c, u11, u12), condSwapNegate(c, u21, u22);
  u01 *= flip, u11 *= flip, u21 *= flip, u02 *= flip, u12 *= flip, u22 *= flip;
  condSwapNegate(c, v01, v02), condSwapNegate(c, v11, v12), condSwapNegate(c, v21, v22);
  c = sg0 < sg1;  // the third comparison of a three-element sorting network
  condSwap(c, sg0, sg1);
  condSwapNegate(c, u00, u01), condSwapNegate(c, u10, u11), condSwapNegate(c, u20, u21);
  condSwapNegate(c, v00, v01), condSwapNegate(c, v10, v11), condSwapNegate(c, v20, v21);

  u[0] = u00, u[1] = u01, u[2] = u02, u[3] = u10, u[4] = u11, u[5] = u12;
  u[6] = u20, u[7] = u21, u[8] = u22;
  v[0] = v00, v[1] = v01, v[2] = v02, v[3] = v10, v[4] = v11, v[5] = v12;
  v[6] = v20, v[7] = v21, v[8] = v22;
  sigma[0] = sg0 * scale, sigma[1] = sg1 * scale, sigma[2] = sg2 * scale;
}

// GCC 12 at -O3 flags JacobiSVD's fully written singular values as "maybe
// uninitialized" once inlined here; the warning is a known false positive.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
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
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif

// Up to kLanes matrices into lanes, entry (i, j) in f[3 i + j]. Eigen
// stores column-major: entry (i, j) of matrix l sits at F[l].data()[3 j + i].
// A short tail is padded with identities.
inline void loadLanes(int count, const Mat3f* F, Pack (&f)[9]) {
  alignas(64) float in[9][kLanes];
  for (int l = 0; l < kLanes; ++l) {
    const float* a = l < count ? F[l].data() : nullptr;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) in[3 * i + j][l] = a ? a[3 * j + i] : float(i == j);
  }
  std::memcpy(f, in, sizeof(f));
}

// The first count lanes of r back into matrices.
inline void storeLanes(int count, const Pack (&r)[9], Mat3f* R) {
  alignas(64) float out[9][kLanes];
  std::memcpy(out, r, sizeof(r));
  for (int l = 0; l < count; ++l) {
    float* pr = R[l].data();
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) pr[3 * j + i] = out[3 * i + j][l];
  }
}

// R = U V^T in the lanes.
TRIAD_SVD3_INLINE void rotationOf(const Pack (&u)[9], const Pack (&v)[9], Pack (&r)[9]) {
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      r[3 * i + j] =
          u[3 * i] * v[3 * j] + u[3 * i + 1] * v[3 * j + 1] + u[3 * i + 2] * v[3 * j + 2];
}

// The largest of the lanes of x.
inline float laneMax(Pack x) {
  alignas(64) float a[kLanes];
  std::memcpy(a, &x, sizeof(a));
  float m = a[0];
  for (int l = 1; l < kLanes; ++l) m = a[l] > m ? a[l] : m;
  return m;
}

// The cofactor matrix of a 3x3 matrix held as nine lane vectors, in the
// same layout as x (row- or column-major alike: cof(X^T) = cof(X)^T);
// each of cof's rows (columns) is the cross of the other two rows
// (columns) of X.
template <class V>
TRIAD_SVD3_INLINE void cofactorLanes(const V (&x)[9], V (&c)[9]) {
  c[0] = x[4] * x[8] - x[5] * x[7];
  c[1] = x[5] * x[6] - x[3] * x[8];
  c[2] = x[3] * x[7] - x[4] * x[6];
  c[3] = x[7] * x[2] - x[8] * x[1];
  c[4] = x[8] * x[0] - x[6] * x[2];
  c[5] = x[6] * x[1] - x[7] * x[0];
  c[6] = x[1] * x[5] - x[2] * x[4];
  c[7] = x[2] * x[3] - x[0] * x[5];
  c[8] = x[0] * x[4] - x[1] * x[3];
}

// Steps of newtonPolar before it gives a batch to the SVD.
constexpr int kNewtonSteps = 12;

// The polar rotation of every lane by Higham's scaled Newton iteration
// X <- (g X + X^-T / g) / 2, g = (|X^-1| / |X|)^(1/2): per step a cofactor
// matrix and one division, where the SVD takes twelve Jacobi rotations and
// a QR. Elastic particles' F are near rotations and converge in three to
// five steps, the scaling bringing stretched ones in as quickly. False if
// some lane is inverted or nearly singular (det F <= 1e-3 |F|^3, as the
// double version) or has not converged; the caller then takes the SVD.
TRIAD_SVD3_INLINE bool newtonPolar(const Pack (&f)[9], Pack (&x)[9]) {
  Pack nf = f[0] * f[0];
  for (int k = 1; k < 9; ++k) nf += f[k] * f[k];
  const Pack det = f[0] * (f[4] * f[8] - f[5] * f[7]) - f[1] * (f[3] * f[8] - f[5] * f[6]) +
                   f[2] * (f[3] * f[7] - f[4] * f[6]);
  // det > 1e-3 |F|^3, squared; NaNs fail it.
  const Pack bound = det * det - 1e-6f * nf * nf * nf;
  const Pack worst_det = (det > 0.0f && bound > 0.0f) ? splat<Pack>(-1.0f) : splat<Pack>(1.0f);
  if (laneMax(worst_det) > 0.0f) return false;
  for (int k = 0; k < 9; ++k) x[k] = f[k];
  bool scaled = true;
  for (int it = 0; it < kNewtonSteps; ++it) {
    // X^-T = cof(X) / det X.
    Pack c[9];
    cofactorLanes(x, c);
    const Pack inv_det = 1.0f / (x[0] * c[0] + x[1] * c[1] + x[2] * c[2]);
    Pack half_g = splat<Pack>(0.5f), half_inv_g = splat<Pack>(0.5f);
    for (int k = 0; k < 9; ++k) c[k] *= inv_det;
    if (scaled) {
      Pack xx = x[0] * x[0], cc = c[0] * c[0];
      for (int k = 1; k < 9; ++k) xx += x[k] * x[k], cc += c[k] * c[k];
      const Pack g = sqrtv(sqrtv(cc / xx));
      half_g = 0.5f * g;
      half_inv_g = 0.5f / g;
    }
    Pack d2 = splat<Pack>(0.0f);
    for (int k = 0; k < 9; ++k) {
      const Pack next = half_g * x[k] + half_inv_g * c[k];
      d2 += (next - x[k]) * (next - x[k]);
      x[k] = next;
    }
    // Quadratic convergence: a change under 3e-6 leaves an error of about
    // its square, far under float's resolution.
    const float change2 = laneMax(d2);
    if (change2 < 1e-11f) return true;
    if (change2 < 1e-4f) scaled = false;
  }
  return false;
}

template <bool kWantSvd>
inline void batchPass(int count, const Mat3f* F, Mat3f* U, Vec3f* sigma, Mat3f* V, Mat3f* R) {
  Pack f[9], u[9], s[3], v[9];
  loadLanes(count, F, f);
  svdKernel(f, u, s, v);
  if constexpr (kWantSvd) {
    alignas(64) float ou[9][kLanes], os[3][kLanes], ov[9][kLanes];
    std::memcpy(ou, u, sizeof(u));
    std::memcpy(os, s, sizeof(s));
    std::memcpy(ov, v, sizeof(v));
    for (int l = 0; l < count; ++l) {
      float* pu = U[l].data();
      float* pv = V[l].data();
      for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j)
          pu[3 * j + i] = ou[3 * i + j][l], pv[3 * j + i] = ov[3 * i + j][l];
        sigma[l](i) = os[i][l];
      }
    }
  } else {
    // R = U V^T in the lanes: nine results to scatter instead of 21
    Pack r[9];
    rotationOf(u, v, r);
    storeLanes(count, r, R);
  }
}

}  // namespace svd3_detail

// F = U diag(sigma) V^T, U and V rotations, sigma(0) >= sigma(1) >= |sigma(2)|.
// float: the kernel above (about 1e-6 relative to |F|); other T: Eigen.
template <class T>
void svd3(const Mat3<T>& F, Mat3<T>& U, Vec3<T>& sigma, Mat3<T>& V) {
  if constexpr (std::is_same_v<T, float>) {
    float f[9], u[9], s[3], v[9];
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) f[3 * i + j] = F(i, j);
    svd3_detail::svdKernel(f, u, s, v);
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) U(i, j) = u[3 * i + j], V(i, j) = v[3 * i + j];
    sigma = Vec3<float>(s[0], s[1], s[2]);
  } else {
    svd3_detail::svdEigen(F, U, sigma, V);
  }
}

// Rotation R of the polar decomposition F = R S (det R = +1; S symmetric and
// indefinite when det F < 0). Equal to U V^T of svd3.
template <class T>
Mat3<T> polarRotation(const Mat3<T>& F) {
  if constexpr (std::is_same_v<T, double>) {
    // Uninverted, well-conditioned F (FEM elements, nearly always): Higham's
    // scaled Newton iteration X <- (g X + X^-T / g) / 2 converges to R
    // quadratically, in a few 3x3 inverses: several times cheaper than a
    // Jacobi SVD in double.
    const double scale = F.norm();
    if (F.determinant() > 1e-3 * scale * scale * scale) {
      // Quadratic convergence: a step that changes X by d leaves an error
      // of about d^2 / 2, so a change under 1e-7 ends at about 1e-14 (R's
      // norm is sqrt 3) without a further step to confirm it.
      // X^-T is the cofactor matrix over det X: one division per step.
      // Near convergence the scale g is 1 to within the change squared, so
      // it is dropped once the change is under 1e-2 (Higham's practice),
      // which keeps the quadratic convergence and saves two norms and two
      // square roots a step.
      Mat3<T> X = F;
      bool scaled = true;
      for (int it = 0; it < 20; ++it) {
        Mat3<T> cof;
        cof.col(0) = X.col(1).cross(X.col(2));
        cof.col(1) = X.col(2).cross(X.col(0));
        cof.col(2) = X.col(0).cross(X.col(1));
        const Mat3<T> Xinv_t = cof * (1.0 / X.col(0).dot(cof.col(0)));
        const double g =
            scaled ? std::sqrt(std::sqrt(Xinv_t.squaredNorm() / X.squaredNorm())) : 1.0;
        const Mat3<T> next = (0.5 * g) * X + (0.5 / g) * Xinv_t;
        const double change2 = (next - X).squaredNorm();
        X = next;
        if (change2 < 1e-14) break;
        if (change2 < 1e-4) scaled = false;
      }
      return X;
    }
  }
  Mat3<T> U, V;
  Vec3<T> sigma;
  svd3(F, U, sigma, V);
  return U * V.transpose();
}

namespace svd3_detail {
// Eight doubles, GCC's vector extension: one AVX-512 register, two AVX
// ones, four SSE ones. A loop over plain arrays with `omp simd` stayed
// scalar (GCC 12 did not vectorize its square roots and inner sums).
#if defined(__GNUC__)
typedef double PackD __attribute__((vector_size(64)));
// In place, and the lane maximum by reference: a 64-byte vector passed or
// returned by value changes the ABI where AVX-512 is off (GCC's -Wpsabi).
TRIAD_SVD3_INLINE void sqrtInPlace(PackD& x) {
#if defined(__AVX512F__)
  x = (PackD)_mm512_maskz_sqrt_pd(
      0xFF, (__m512d)x);  // maskz: _mm512_sqrt_pd warns (-Wmaybe-uninitialized)
#elif defined(__AVX__)
  __m256d h[2];
  std::memcpy(h, &x, sizeof(x));
  h[0] = _mm256_sqrt_pd(h[0]);
  h[1] = _mm256_sqrt_pd(h[1]);
  std::memcpy(&x, h, sizeof(x));
#else
  for (int l = 0; l < 8; ++l) x[l] = std::sqrt(x[l]);
#endif
}
TRIAD_SVD3_INLINE double laneMax(const PackD& a) {
  double m = a[0];
  for (int l = 1; l < 8; ++l) m = a[l] > m ? a[l] : m;
  return m;
}
#endif
}  // namespace svd3_detail

#if defined(__GNUC__)
// The polar rotation of N groups of up to eight double matrices already in
// vector lanes, f[n] (column-major, lanes from count[n] on copies of a real
// one) into r[n]. The groups' iterations run side by side: each step is a
// chain of dependent operations (cofactors, a determinant, a division, the
// next iterate), and one group alone left the vector units idle most of the
// time; two groups together take about two thirds of the time per matrix,
// four no less than two (bench/RESULTS.md). The groups step until all
// their lanes have converged, so a lane may take a step more than it would
// alone: R agrees to rounding, not bit for bit, with other groupings.
template <int N>
inline void polarRotationOfLaneGroups(const int (&count)[N], const svd3_detail::PackD (&f)[N][9],
                                      svd3_detail::PackD (&r)[N][9]) {
  using svd3_detail::PackD;
  constexpr int L = 8;
  PackD x[N][9];
  bool all_direct = true;
  bool direct[N][L];
  for (int n = 0; n < N; ++n) {
    // Lanes the iteration can take (det F > 1e-3 |F|^3); lanes past count
    // iterate from the identity, as the fallback's do.
    PackD c[9];
    svd3_detail::cofactorLanes(f[n], c);
    const PackD det = f[n][0] * c[0] + f[n][1] * c[1] + f[n][2] * c[2];
    PackD norm2 = f[n][0] * f[n][0];
    for (int e = 1; e < 9; ++e) norm2 += f[n][e] * f[n][e];
    alignas(64) double det_l[L], norm2_l[L], start[9][L];
    std::memcpy(det_l, &det, sizeof(det_l));
    std::memcpy(norm2_l, &norm2, sizeof(norm2_l));
    std::memcpy(start, f[n], sizeof(start));
    for (int l = 0; l < L; ++l) {
      const double scale = std::sqrt(norm2_l[l]);
      const bool pad = l >= count[n];
      direct[n][l] = pad || det_l[l] > 1e-3 * scale * scale * scale;
      all_direct &= direct[n][l];
      if (!direct[n][l] || pad)
        for (int e = 0; e < 9; ++e) start[e][l] = e % 4 == 0 ? 1.0 : 0.0;
    }
    std::memcpy(x[n], start, sizeof(x[n]));
  }
  bool scaled = true;
  for (int it = 0; it < 20; ++it) {
    PackD worst2 = PackD{};
    for (int n = 0; n < N; ++n) {
      PackD c[9];
      svd3_detail::cofactorLanes(x[n], c);
      const PackD inv_det = 1.0 / (x[n][0] * c[0] + x[n][1] * c[1] + x[n][2] * c[2]);
      for (int e = 0; e < 9; ++e) c[e] *= inv_det;
      PackD half_g = PackD{} + 0.5, half_inv_g = PackD{} + 0.5;
      if (scaled) {
        PackD xx = x[n][0] * x[n][0], cc = c[0] * c[0];
        for (int e = 1; e < 9; ++e) xx += x[n][e] * x[n][e], cc += c[e] * c[e];
        PackD g = cc / xx;
        svd3_detail::sqrtInPlace(g);
        svd3_detail::sqrtInPlace(g);
        half_g = 0.5 * g;
        half_inv_g = 0.5 / g;
      }
      PackD d2 = PackD{};
      for (int e = 0; e < 9; ++e) {
        const PackD next = half_g * x[n][e] + half_inv_g * c[e];
        d2 += (next - x[n][e]) * (next - x[n][e]);
        x[n][e] = next;
      }
      worst2 = n == 0 ? d2 : (worst2 > d2 ? worst2 : d2);
    }
    const double worst = svd3_detail::laneMax(worst2);
    if (worst < 1e-14) break;
    if (worst < 1e-4) scaled = false;
  }
  for (int n = 0; n < N; ++n) {
    if (!all_direct) {
      // The lanes the iteration could not take: the SVD's rotation.
      alignas(64) double in[9][L], out[9][L];
      std::memcpy(in, f[n], sizeof(in));
      std::memcpy(out, x[n], sizeof(out));
      for (int l = 0; l < count[n]; ++l) {
        if (direct[n][l]) continue;
        Mat3d A;
        for (int e = 0; e < 9; ++e) A.data()[e] = in[e][l];
        const Mat3d Rl = polarRotation(A);
        for (int e = 0; e < 9; ++e) out[e][l] = Rl.data()[e];
      }
      std::memcpy(x[n], out, sizeof(out));
    }
    std::memcpy(r[n], x[n], sizeof(x[n]));
  }
}

// The polar rotation of up to eight double matrices already in vector
// lanes, f (column-major, lanes from `count` on copies of a real one) into
// r: one group of polarRotationOfLaneGroups.
inline void polarRotationOfLanes(int count, const svd3_detail::PackD (&f)[9],
                                 svd3_detail::PackD (&r)[9]) {
  using svd3_detail::PackD;
  const int counts[1] = {count};
  polarRotationOfLaneGroups<1>(counts, reinterpret_cast<const PackD(&)[1][9]>(f),
                               reinterpret_cast<PackD(&)[1][9]>(r));
}

// The polar rotation of double F[0..n), eight matrices at a time across
// vector lanes, with the lanes handed on: for each pass over up to eight
// matrices from F[b], fn(b, count, f, r) receives F and R as nine lane
// vectors each, column-major (entry (i, j) at [3 j + i], as Eigen stores
// them), so that a caller's formula in F and R runs across the lanes too.
// The scaled Newton iteration of polarRotation, whose dependent chain
// (cofactors, a determinant, a division, the next iterate) left one
// matrix's core idle most of the time. A pass iterates until all its
// lanes have converged, so a lane may take a step more than it would
// alone: R agrees with polarRotation to rounding (about 1e-15), not bit
// for bit. Nearly singular or inverted F take the single call's SVD.
template <class Fn>
inline void polarRotationLanes(int n, const Mat3d* F, Fn&& fn) {
  using svd3_detail::PackD;
  constexpr int L = 8;
  for (int b = 0; b < n; b += L) {
    const int count = n - b < L ? n - b : L;
    alignas(64) double in[9][L];
    for (int l = 0; l < L; ++l) {
      const Mat3d& A = F[b + (l < count ? l : 0)];
      for (int e = 0; e < 9; ++e) in[e][l] = A.data()[e];
    }
    PackD f[9], x[9];
    std::memcpy(f, in, sizeof(f));
    polarRotationOfLanes(count, f, x);
    fn(b, count, f, x);
  }
}
#endif

// polarRotation<double> of F[0..n) into R[0..n) (may alias F), eight
// matrices at a time across vector lanes (polarRotationLanes).
inline void polarRotationBatch(int n, const Mat3d* F, Mat3d* R) {
#if defined(__GNUC__)
  polarRotationLanes(
      n, F, [&](int b, int count, const svd3_detail::PackD(&)[9], const svd3_detail::PackD(&r)[9]) {
        alignas(64) double out[9][8];
        std::memcpy(out, r, sizeof(out));
        for (int l = 0; l < count; ++l)
          for (int e = 0; e < 9; ++e) R[b + l].data()[e] = out[e][l];
      });
#else
  for (int k = 0; k < n; ++k) R[k] = polarRotation(F[k]);
#endif
}

// svd3<float> of F[0..n) into U[0..n), sigma[0..n), V[0..n): the same
// results as n calls (up to rounding), several times faster per matrix.
// The outputs may alias F.
inline void svd3Batch(int n, const Mat3f* F, Mat3f* U, Vec3f* sigma, Mat3f* V) {
  using svd3_detail::kLanes;
  for (int b = 0; b < n; b += kLanes) {
    svd3_detail::batchPass<true>(n - b < kLanes ? n - b : kLanes, F + b, U + b, sigma + b, V + b,
                                 nullptr);
  }
}

// polarRotation<float> of F[0..n) into R[0..n) (may alias F), batched like
// svd3Batch.
inline void polarRotationBatch(int n, const Mat3f* F, Mat3f* R) {
  using svd3_detail::kLanes;
  for (int b = 0; b < n; b += kLanes) {
    svd3_detail::batchPass<false>(n - b < kLanes ? n - b : kLanes, F + b, nullptr, nullptr, nullptr,
                                  R + b);
  }
}

// The polar rotation of F[0..n) with the lanes handed on: for each pass over
// up to kLanes matrices from F[b], fn(b, count, f, r) receives F and R as
// nine lane vectors each (entry (i, j) at [3 i + j]), so that a caller's
// formula in F and R runs across the lanes too instead of on one matrix at a
// time (svd3_detail::storeLanes writes results back). R comes from
// svd3_detail::newtonPolar, or from the SVD (U V^T) for a pass with an
// inverted or nearly singular F.
template <class Fn>
inline void polarRotationLanes(int n, const Mat3f* F, Fn&& fn) {
  using namespace svd3_detail;
  for (int b = 0; b < n; b += kLanes) {
    const int count = n - b < kLanes ? n - b : kLanes;
    Pack f[9], r[9];
    loadLanes(count, F + b, f);
    if (!newtonPolar(f, r)) {
      Pack u[9], s[3], v[9];
      svdKernel(f, u, s, v);
      rotationOf(u, v, r);
    }
    fn(b, count, f, r);
  }
}

// svd3Batch with the lanes handed on: for each pass over up to kLanes
// matrices from F[b], fn(b, count, f, u, sigma, v) receives F, U, sigma and V
// as lane vectors (matrix entry (i, j) at [3 i + j]), so that a caller's
// formula in them (a plastic return, a stress) runs across the lanes too.
template <class Fn>
inline void svdLanes(int n, const Mat3f* F, Fn&& fn) {
  using namespace svd3_detail;
  for (int b = 0; b < n; b += kLanes) {
    const int count = n - b < kLanes ? n - b : kLanes;
    Pack f[9], u[9], s[3], v[9];
    loadLanes(count, F + b, f);
    svdKernel(f, u, s, v);
    fn(b, count, f, u, s, v);
  }
}

}  // namespace triad

#undef TRIAD_SVD3_INLINE
