#include "sim/shot/animation.h"

#include <algorithm>
#include <cmath>

namespace triad {

namespace {

Mat3d axisRotation(int axis, double deg) {
  const double a = deg * M_PI / 180.0, c = std::cos(a), s = std::sin(a);
  Mat3d r = Mat3d::Identity();
  const int i = (axis + 1) % 3, j = (axis + 2) % 3;  // x: (y,z); y: (z,x); z: (x,y)
  r(i, i) = c;
  r(i, j) = -s;
  r(j, i) = s;
  r(j, j) = c;
  return r;
}

Mat3d cross(const Vec3d& a) {
  Mat3d m;
  m << 0, -a.z(), a.y(), a.z(), 0, -a.x(), -a.y(), a.x(), 0;
  return m;
}

Vec3d toVec(const Vec3Desc& a) { return Vec3d(a[0], a[1], a[2]); }

// Cubic Hermite basis on s in [0, 1] and its derivative.
struct Hermite {
  double h00, h10, h01, h11, d00, d10, d01, d11;
  explicit Hermite(double s) {
    const double s2 = s * s, s3 = s2 * s;
    h00 = 2 * s3 - 3 * s2 + 1;
    h10 = s3 - 2 * s2 + s;
    h01 = -2 * s3 + 3 * s2;
    h11 = s3 - s2;
    d00 = 6 * s2 - 6 * s;
    d10 = 3 * s2 - 4 * s + 1;
    d01 = -6 * s2 + 6 * s;
    d11 = 3 * s2 - 2 * s;
  }
};

}  // namespace

Mat3d eulerXYZDegrees(const Vec3Desc& r) {
  return axisRotation(2, r[2]) * axisRotation(1, r[1]) * axisRotation(0, r[0]);
}

Vec3d rotationLog(const Quatd& q_in) {
  Quatd q = q_in.normalized();
  if (q.w() < 0) q.coeffs() = -q.coeffs();  // the shorter way: angle in [0, pi]
  const Vec3d v = q.vec();
  const double s = v.norm();
  if (s < 1e-12) return 2.0 * v;
  return (2.0 * std::atan2(s, q.w()) / s) * v;
}

Quatd rotationExp(const Vec3d& phi) {
  const double a = phi.norm();
  if (a < 1e-12) return Quatd(1.0, 0.5 * phi.x(), 0.5 * phi.y(), 0.5 * phi.z()).normalized();
  return Quatd(Eigen::AngleAxisd(a, phi / a));
}

Mat3d leftJacobian(const Vec3d& phi) {
  const double a = phi.norm();
  const Mat3d K = cross(phi);
  if (a < 1e-6) return Mat3d::Identity() + 0.5 * K + K * K / 6.0;
  return Mat3d::Identity() + ((1 - std::cos(a)) / (a * a)) * K +
         ((a - std::sin(a)) / (a * a * a)) * K * K;
}

Mat3d leftJacobianInverse(const Vec3d& phi) {
  const double a = phi.norm();
  const Mat3d K = cross(phi);
  // 1/a^2 - cot(a/2) / (2a), which tends to 1/12 at a = 0.
  const double c = a < 1e-4 ? 1.0 / 12.0 + a * a / 720.0
                            : 1.0 / (a * a) - 1.0 / (2.0 * a * std::tan(0.5 * a));
  return Mat3d::Identity() - 0.5 * K + c * K * K;
}

Animation::Animation(const AnimationDesc& desc) : interpolation_(desc.interpolation) {
  for (const AnimationKeyDesc& k : desc.keys) {
    times_.push_back(k.time);
    translate_.push_back(toVec(k.translate));
    rotation_.push_back(Quatd(eulerXYZDegrees(k.rotate_deg)).normalized());
  }
  const size_t n = times_.size();
  for (size_t k = 0; k + 1 < n; ++k)
    turn_.push_back(rotationLog(rotation_[k + 1] * rotation_[k].conjugate()));
  // Catmull-Rom tangents at interior keys, zero at the ends. The rotation's
  // is the two neighbouring segments' turns over their time, which, unlike
  // the log of R_{k+1} R_{k-1}^T, stays right when they add up past pi.
  t_slope_.assign(n, Vec3d::Zero());
  w_key_.assign(n, Vec3d::Zero());
  for (size_t k = 1; k + 1 < n; ++k) {
    const double span = times_[k + 1] - times_[k - 1];
    t_slope_[k] = (translate_[k + 1] - translate_[k - 1]) / span;
    w_key_[k] = (turn_[k - 1] + turn_[k]) / span;
  }
}

Pose Animation::at(double t) const {
  Pose p;
  const size_t n = times_.size();
  if (n == 0) return p;
  // Held before the first key and after the last.
  if (t <= times_.front() || n == 1) {
    p.translate = translate_.front();
    p.rotation = rotation_.front();
    return p;
  }
  if (t >= times_.back()) {
    p.translate = translate_.back();
    p.rotation = rotation_.back();
    return p;
  }
  // The segment [t_k, t_k+1) holding t.
  const size_t k = size_t(std::upper_bound(times_.begin(), times_.end(), t) - times_.begin()) - 1;
  const double span = times_[k + 1] - times_[k];
  const double s = (t - times_[k]) / span;
  if (interpolation_ == Interpolation::Linear) {
    p.translate = translate_[k] + s * (translate_[k + 1] - translate_[k]);
    p.velocity = (translate_[k + 1] - translate_[k]) / span;
    p.rotation = (rotationExp(s * turn_[k]) * rotation_[k]).normalized();
    p.omega = turn_[k] / span;
    return p;
  }
  const Hermite h(s);
  p.translate = h.h00 * translate_[k] + h.h10 * span * t_slope_[k] + h.h01 * translate_[k + 1] +
                h.h11 * span * t_slope_[k + 1];
  p.velocity = (h.d00 * translate_[k] + h.d10 * span * t_slope_[k] + h.d01 * translate_[k + 1] +
                h.d11 * span * t_slope_[k + 1]) /
               span;
  // phi(0) = 0, phi(1) = turn, phi'(0) = span w_k, and at s = 1 the
  // angular velocity J(turn) phi'(1) / span equals w_k+1.
  const Vec3d m0 = span * w_key_[k];
  const Vec3d m1 = span * (leftJacobianInverse(turn_[k]) * w_key_[k + 1]);
  const Vec3d phi = h.h10 * m0 + h.h01 * turn_[k] + h.h11 * m1;
  const Vec3d dphi = h.d10 * m0 + h.d01 * turn_[k] + h.d11 * m1;
  p.rotation = (rotationExp(phi) * rotation_[k]).normalized();
  p.omega = leftJacobian(phi) * dphi / span;
  return p;
}

}  // namespace triad
