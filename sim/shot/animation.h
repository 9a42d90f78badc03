#pragma once
// Prescribed motion of colliders, sources and sinks (scene-format.md,
// "Directing a shot"): a pose at every time, and its exact time derivative,
// from keyed translations and rotations.
//
// A pose moves a point p of the shape as written to
//   x(t) = pivot + T(t) + R(t) (p - pivot),
// with pivot the centroid of the shape's volume as written. Its velocity is
//   x'(t) = T'(t) + omega(t) x (R(t) (p - pivot)),
// omega the world angular velocity (R' R^T = [omega]x).
//
// Linear: T piecewise linear, R by slerp (the shorter way between keys).
// Smooth: C1 in time. T is a cubic Hermite with Catmull-Rom tangents; R is
// exp(phi(s)) R_k on each segment with phi a cubic Hermite in rotation
// vectors, its end tangents mapped through the SO(3) Jacobian so that the
// angular velocity is continuous at the keys. The first and last keys have
// zero tangents: motion eases in from the held first pose and out into the
// held last one.
#include <vector>

#include "sim/math.h"
#include "sim/scene_desc.h"

namespace triad {

// XYZ Euler angles in degrees about the fixed world axes, X first:
// R = Rz(c) Ry(b) Rx(a) (right-handed; a > 0 turns +y towards +z).
Mat3d eulerXYZDegrees(const Vec3Desc& rotate_deg);

struct Pose {
  Vec3d translate = Vec3d::Zero();
  Quatd rotation = Quatd::Identity();
  Vec3d velocity = Vec3d::Zero();  // T'
  Vec3d omega = Vec3d::Zero();     // world angular velocity, rad/s
};

class Animation {
 public:
  Animation() = default;  // the identity at all times
  explicit Animation(const AnimationDesc& desc);

  Pose at(double t) const;
  bool empty() const { return times_.empty(); }

 private:
  Interpolation interpolation_ = Interpolation::Linear;
  std::vector<double> times_;
  std::vector<Vec3d> translate_;
  std::vector<Quatd> rotation_;
  std::vector<Vec3d> turn_;     // per segment k: rotation vector of R_{k+1} R_k^T
  std::vector<Vec3d> t_slope_;  // per key: translation tangent dT/dt
  std::vector<Vec3d> w_key_;    // per key: angular velocity
};

// Rotation vector (axis times angle, angle in [0, pi]) of a rotation, and back.
Vec3d rotationLog(const Quatd& q);
Quatd rotationExp(const Vec3d& phi);
// Left Jacobian of SO(3) at phi: d/dt exp(phi) exp(phi)^T = [J(phi) phi']x.
Mat3d leftJacobian(const Vec3d& phi);
Mat3d leftJacobianInverse(const Vec3d& phi);

}  // namespace triad
