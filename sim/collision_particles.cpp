#include "sim/collision_particles.h"

namespace triad {

MassProperties computeMassProperties(const CollisionSamples& s) {
  MassProperties mp;
  const size_t n = s.x.size();
  if (n == 0) return mp;
  const double m = s.mass_per_sample;
  // Centre first, then second moments about it (two passes: no cancellation
  // between large |x|^2 and the parallel-axis correction).
  Vec3d sum = Vec3d::Zero();
  for (const Vec3f& p : s.x) sum += p.cast<double>();
  mp.mass = m * double(n);
  mp.centre = sum / double(n);
  Mat3d second = Mat3d::Zero();  // sum of r r^T
  for (const Vec3f& p : s.x) {
    const Vec3d r = p.cast<double>() - mp.centre;
    second += r * r.transpose();
  }
  mp.inertia = m * (second.trace() * Mat3d::Identity() - second) +
               mp.mass * s.spacing * s.spacing / 6.0 * Mat3d::Identity();
  return mp;
}

}  // namespace triad
