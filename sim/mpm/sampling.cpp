#include "sim/mpm/sampling.h"

#include <algorithm>
#include <cmath>

#include "sim/errors.h"

namespace triad {

namespace {

Vec3d toVec(const Vec3Desc& a) { return Vec3d(a[0], a[1], a[2]); }

struct Bounds {
  Vec3d lo, hi;
};

bool inside(const BoxDesc& b, const Vec3d& p) {
  for (int d = 0; d < 3; ++d)
    if (p[d] < b.min[d] || p[d] >= b.max[d]) return false;
  return true;
}

bool inside(const SphereDesc& s, const Vec3d& p) {
  return (p - toVec(s.center)).squaredNorm() < s.radius * s.radius;
}

Bounds boundsOf(const BoxDesc& b) { return {toVec(b.min), toVec(b.max)}; }
Bounds boundsOf(const SphereDesc& s) {
  const Vec3d r = Vec3d::Constant(s.radius);
  return {toVec(s.center) - r, toVec(s.center) + r};
}

template <class Shape>
std::vector<Vec3f> sampleImplicit(const Shape& shape, const DomainDesc& domain, int ppc) {
  const Vec3d dmin = toVec(domain.min), dmax = toVec(domain.max);
  const double dx = domain.dx;
  Bounds b = boundsOf(shape);
  b.lo = b.lo.cwiseMax(dmin);
  b.hi = b.hi.cwiseMin(dmax);
  const std::vector<Vec3d> offsets = cellSampleOffsets(ppc);
  std::vector<Vec3f> out;
  if ((b.hi - b.lo).minCoeff() <= 0.0) return out;
  // Cells of the domain lattice that overlap the shape's bounds.
  Eigen::Vector3i c0, c1;
  for (int d = 0; d < 3; ++d) {
    c0[d] = static_cast<int>(std::floor((b.lo[d] - dmin[d]) / dx));
    c1[d] = static_cast<int>(std::ceil((b.hi[d] - dmin[d]) / dx));
  }
  for (int i = c0.x(); i < c1.x(); ++i)
    for (int j = c0.y(); j < c1.y(); ++j)
      for (int k = c0.z(); k < c1.z(); ++k)
        for (const Vec3d& o : offsets) {
          const Vec3d p = dmin + dx * (Vec3d(i, j, k) + o);
          if (!inside(shape, p)) continue;
          if ((p - dmin).minCoeff() < 0.0 || (dmax - p).minCoeff() <= 0.0) continue;
          out.push_back(p.cast<float>());
        }
  return out;
}

}  // namespace

std::vector<Vec3d> cellSampleOffsets(int ppc) {
  std::vector<Vec3d> offsets;
  const int k = static_cast<int>(std::lround(std::cbrt(static_cast<double>(ppc))));
  if (k * k * k == ppc) {
    for (int a = 0; a < k; ++a)
      for (int b = 0; b < k; ++b)
        for (int c = 0; c < k; ++c) offsets.emplace_back((a + 0.5) / k, (b + 0.5) / k, (c + 0.5) / k);
    return offsets;
  }
  // Roberts' R3 sequence: the inverse powers of the plastic number's 3D
  // analogue give an evenly spread, deterministic point set.
  const double g = 1.22074408460575947536;
  const Vec3d alpha(1.0 / g, 1.0 / (g * g), 1.0 / (g * g * g));
  for (int n = 0; n < ppc; ++n) {
    Vec3d p = Vec3d::Constant(0.5) + (n + 1) * alpha;
    for (int d = 0; d < 3; ++d) p[d] -= std::floor(p[d]);
    offsets.push_back(p);
  }
  return offsets;
}

std::vector<Vec3f> sampleShape(const ShapeDesc& shape, const DomainDesc& domain, int ppc,
                               const MeshSampler& mesh_sampler) {
  if (const auto* box = std::get_if<BoxDesc>(&shape)) return sampleImplicit(*box, domain, ppc);
  if (const auto* sphere = std::get_if<SphereDesc>(&shape))
    return sampleImplicit(*sphere, domain, ppc);
  if (!mesh_sampler) throw InputError("", "mesh shapes need a mesh importer (none was given)");
  return mesh_sampler(std::get<MeshDesc>(shape), domain, ppc);
}

}  // namespace triad
