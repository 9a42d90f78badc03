#include "sim/solids/collision_particles.h"

#include <algorithm>
#include <cmath>
#include <map>

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

namespace triad {

namespace {

TriSurface boxSurface(const BoxDesc& b) {
  TriSurface s;
  for (int i = 0; i < 8; ++i)
    s.vertices.emplace_back(float(i & 4 ? b.max[0] : b.min[0]), float(i & 2 ? b.max[1] : b.min[1]),
                            float(i & 1 ? b.max[2] : b.min[2]));
  // Two outward triangles per face; corner index = 4x + 2y + z.
  const uint32_t faces[6][4] = {{0, 1, 3, 2}, {4, 6, 7, 5}, {0, 4, 5, 1},
                                {2, 3, 7, 6}, {0, 2, 6, 4}, {1, 5, 7, 3}};
  for (const auto& f : faces) {
    s.triangles.push_back({f[0], f[1], f[2]});
    s.triangles.push_back({f[0], f[2], f[3]});
  }
  return s;
}

TriSurface sphereSurface(const SphereDesc& sd) {
  // Icosahedron, subdivided three times, vertices pushed onto the sphere.
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<Vec3d> v = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0},
                          {0, -1, t}, {0, 1, t}, {0, -1, -t}, {0, 1, -t},
                          {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  for (Vec3d& p : v) p.normalize();
  std::vector<std::array<uint32_t, 3>> tris = {
      {0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
      {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
      {3, 8, 9},  {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  for (int level = 0; level < 3; ++level) {
    std::map<std::pair<uint32_t, uint32_t>, uint32_t> mid;
    auto midpoint = [&](uint32_t a, uint32_t b) {
      const auto key = std::minmax(a, b);
      auto [it, fresh] = mid.try_emplace({key.first, key.second}, uint32_t(v.size()));
      if (fresh) v.push_back((v[a] + v[b]).normalized());
      return it->second;
    };
    std::vector<std::array<uint32_t, 3>> next;
    for (const auto& f : tris) {
      const uint32_t a = midpoint(f[0], f[1]), b = midpoint(f[1], f[2]), c = midpoint(f[2], f[0]);
      next.push_back({f[0], a, c});
      next.push_back({f[1], b, a});
      next.push_back({f[2], c, b});
      next.push_back({a, b, c});
    }
    tris = std::move(next);
  }
  TriSurface s;
  const Vec3d c(sd.center[0], sd.center[1], sd.center[2]);
  for (const Vec3d& p : v) s.vertices.push_back((c + sd.radius * p).cast<float>());
  s.triangles = std::move(tris);
  return s;
}

}  // namespace

double boxDistance(const Vec3d& lo, const Vec3d& hi, const Vec3d& p, Vec3d* normal) {
  const Vec3d c = 0.5 * (lo + hi), half = 0.5 * (hi - lo);
  const Vec3d q = (p - c).cwiseAbs() - half;
  const Vec3d outside = q.cwiseMax(0.0);
  if (outside.squaredNorm() > 0) {
    if (normal) {
      Vec3d n = outside;
      for (int d = 0; d < 3; ++d) n[d] *= p[d] < c[d] ? -1.0 : 1.0;
      *normal = n.normalized();
    }
    return outside.norm();
  }
  int axis = 0;
  q.maxCoeff(&axis);
  if (normal) {
    *normal = Vec3d::Zero();
    (*normal)[axis] = p[axis] < c[axis] ? -1.0 : 1.0;
  }
  return q[axis];
}

TriSurface primitiveSurface(const ShapeDesc& shape) {
  if (const auto* b = std::get_if<BoxDesc>(&shape)) return boxSurface(*b);
  if (const auto* s = std::get_if<SphereDesc>(&shape)) return sphereSurface(*s);
  return {};
}

Vec3d volumeCentroid(const TriSurface& surface) {
  // Signed tetrahedra from the origin: volume det/6, centroid at the
  // mean of their four corners.
  double volume = 0.0;
  Vec3d moment = Vec3d::Zero(), mean = Vec3d::Zero();
  for (const auto& t : surface.triangles) {
    const Vec3d a = surface.vertices[t[0]].cast<double>(), b = surface.vertices[t[1]].cast<double>(),
                c = surface.vertices[t[2]].cast<double>();
    const double v = a.dot(b.cross(c)) / 6.0;
    volume += v;
    moment += v * (a + b + c) / 4.0;
  }
  for (const Vec3f& v : surface.vertices) mean += v.cast<double>();
  if (!surface.vertices.empty()) mean /= double(surface.vertices.size());
  double extent = 0.0;
  for (const Vec3f& v : surface.vertices) extent = std::max(extent, (v.cast<double>() - mean).norm());
  if (std::abs(volume) <= 1e-12 * std::pow(extent, 3)) return mean;
  return moment / volume;
}

}  // namespace triad
