#pragma once
// Natural logarithm and exponential across the SVD's vector lanes
// (svd3_detail::Pack), for the plastic return mappings that work in log
// strain: a call of libm's logf or expf per singular value cost as much
// as the rest of a sand particle's return. The polynomials are Cephes'
// (S. Moshier), as SIMD libraries carry them: within 2 ulp of libm over
// normal positive arguments (log) and [-87, 88] (exp).
#include <cmath>
#include <cstdint>

#include "sim/svd3.h"

namespace triad::svd3_detail {

inline float logv(float x) {
  return std::log(x);
}
inline float expv(float x) {
  return std::exp(x);
}

#if defined(__GNUC__) && defined(__SSE2__)
// e^x; arguments beyond [-87.3, 88.4] are clamped to that range.
inline Pack expv(Pack x) {
  typedef std::int32_t Bits __attribute__((vector_size(sizeof(Pack))));
  x = x > 88.3762626647949f ? splat<Pack>(88.3762626647949f) : x;
  x = x < -87.3365478515625f ? splat<Pack>(-87.3365478515625f) : x;
  // x = n ln 2 + r, |r| <= ln 2 / 2, ln 2 split in two for an exact n ln 2.
  const Pack fx = x * 1.44269504088896341f + 0.5f;
  Bits n = __builtin_convertvector(fx, Bits);
  n -= (__builtin_convertvector(n, Pack) > fx) ? 1 : 0;  // floor
  const Pack fn = __builtin_convertvector(n, Pack);
  const Pack r = x - fn * 0.693359375f + fn * 2.12194440e-4f;
  Pack y = 1.9875691500e-4f * r + 1.3981999507e-3f;
  y = y * r + 8.3334519073e-3f;
  y = y * r + 4.1665795894e-2f;
  y = y * r + 1.6666665459e-1f;
  y = y * r + 5.0000001201e-1f;
  y = y * (r * r) + r + 1.0f;
  // 2^n from its exponent bits (n >= -126 after the clamp: a normal float).
  return y * (Pack)((n + 127) << 23);
}

// ln x for positive normal x (smaller x read as the smallest normal float).
inline Pack logv(Pack x) {
  typedef std::int32_t Bits __attribute__((vector_size(sizeof(Pack))));
  x = x < 1.17549435e-38f ? splat<Pack>(1.17549435e-38f) : x;
  // x = m 2^e with m in [0.5, 1), then m in [sqrt(1/2), sqrt(2)).
  const Bits bits = (Bits)x;
  Pack e = __builtin_convertvector((bits >> 23) - 126, Pack);
  Pack m = (Pack)((bits & 0x007fffff) | 0x3f000000);
  const auto small = m < 0.707106781186547524f;
  e -= small ? 1.0f : 0.0f;
  m = (small ? m + m : m) - 1.0f;
  const Pack z = m * m;
  Pack y = 7.0376836292e-2f * m - 1.1514610310e-1f;
  y = y * m + 1.1676998740e-1f;
  y = y * m - 1.2420140846e-1f;
  y = y * m + 1.4249322787e-1f;
  y = y * m - 1.6668057665e-1f;
  y = y * m + 2.0000714765e-1f;
  y = y * m - 2.4999993993e-1f;
  y = y * m + 3.3333331174e-1f;
  y = y * m * z;
  y += e * -2.12194440e-4f;
  y -= 0.5f * z;
  return m + y + e * 0.693359375f;
}
#endif

}  // namespace triad::svd3_detail
