#pragma once
// A UV sphere of nu segments around and nv from pole to pole (2 nu (nv - 1)
// triangles), outward wound: the benchmarks' mesh of chosen size.
#include <cmath>

#include "import/mesh_loader.h"

namespace triad {

inline TriangleMesh uvSphere(const Vec3d& c, double r, int nu, int nv) {
  TriangleMesh m;
  m.positions.push_back(c + Vec3d(0, r, 0));
  for (int j = 1; j < nv; ++j)
    for (int i = 0; i < nu; ++i) {
      const double th = M_PI * j / nv, ph = 2 * M_PI * i / nu;
      m.positions.push_back(c + r * Vec3d(std::sin(th) * std::cos(ph), std::cos(th), std::sin(th) * std::sin(ph)));
    }
  m.positions.push_back(c - Vec3d(0, r, 0));
  const int south = int(m.positions.size()) - 1;
  auto ring = [&](int j, int i) { return 1 + (j - 1) * nu + (i % nu); };
  for (int i = 0; i < nu; ++i) {
    m.triangles.push_back({0, ring(1, i + 1), ring(1, i)});
    m.triangles.push_back({south, ring(nv - 1, i), ring(nv - 1, i + 1)});
    for (int j = 1; j < nv - 1; ++j) {
      m.triangles.push_back({ring(j, i), ring(j, i + 1), ring(j + 1, i + 1)});
      m.triangles.push_back({ring(j, i), ring(j + 1, i + 1), ring(j + 1, i)});
    }
  }
  return m;
}

}  // namespace triad
