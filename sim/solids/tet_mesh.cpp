#include "sim/solids/tet_mesh.h"

#include <cmath>
#include <limits>
#include <unordered_map>

#include "sim/mpm/sparse_grid.h"

namespace triad {

std::array<double, 4> barycentric(const std::vector<Vec3d>& x, const std::array<int, 4>& tet,
                                  const Vec3d& p) {
  Mat3d D;
  for (int k = 0; k < 3; ++k) D.col(k) = x[size_t(tet[k + 1])] - x[size_t(tet[0])];
  const Vec3d b = D.inverse() * (p - x[size_t(tet[0])]);
  return {1.0 - b.sum(), b.x(), b.y(), b.z()};
}

double TetMesh::restVolume(size_t t) const {
  const auto& n = tets[t];
  Mat3d D;
  for (int k = 0; k < 3; ++k) D.col(k) = nodes[n[k + 1]] - nodes[n[0]];
  return D.determinant() / 6.0;
}

TetMesh tetsFromVoxels(const std::vector<Vec3d>& centres, double h) {
  TetMesh m;
  m.spacing = h;
  m.cells = centres;
  if (centres.empty()) return m;
  // Corners on the lattice of cell corners: origin at the first cell's
  // lower corner, integer coordinates from there.
  const Vec3d origin = centres[0] - Vec3d::Constant(0.5 * h);
  std::unordered_map<uint64_t, int> corner_index;
  auto corner = [&](const Eigen::Vector3i& c) {
    auto [it, fresh] = corner_index.try_emplace(packBlock(c), int(m.nodes.size()));
    if (fresh) m.nodes.push_back(origin + h * c.cast<double>());
    return it->second;
  };
  // Kuhn's six tetrahedra: one per order of the axes, along the path
  // 000 -> e_a -> e_a + e_b -> 111.
  static const int kOrders[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2},
                                    {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (const Vec3d& c : centres) {
    const Vec3d rel = (c - origin) / h - Vec3d::Constant(0.5);
    const Eigen::Vector3i base(int(std::lround(rel.x())), int(std::lround(rel.y())),
                               int(std::lround(rel.z())));
    // Mirrored along each axis whose index is odd: neighbours share their
    // faces' diagonals (the mesh stays conforming), and the split's
    // diagonal direction alternates instead of running one way.
    Eigen::Vector3i start = base, step = Eigen::Vector3i::Ones();
    for (int a = 0; a < 3; ++a)
      if (base[a] & 1) start[a] += 1, step[a] = -1;
    for (const auto& order : kOrders) {
      Eigen::Vector3i p = start;
      std::array<int, 4> tet;
      tet[0] = corner(p);
      for (int k = 0; k < 3; ++k) {
        p[order[k]] += step[order[k]];
        tet[k + 1] = corner(p);
      }
      m.tets.push_back(tet);
      if (m.restVolume(m.tets.size() - 1) < 0) std::swap(m.tets.back()[2], m.tets.back()[3]);
    }
  }
  return m;
}

std::vector<Embedding> embed(const TetMesh& m, const std::vector<Vec3d>& points) {
  std::vector<Embedding> out(points.size());
  if (m.cells.empty()) return out;
  const double h = m.spacing;
  const Vec3d origin = m.cells[0];
  std::unordered_map<uint64_t, int> cell_index;
  for (size_t c = 0; c < m.cells.size(); ++c) {
    const Vec3d rel = (m.cells[c] - origin) / h;
    cell_index.emplace(packBlock(Eigen::Vector3i(int(std::lround(rel.x())),
                                                  int(std::lround(rel.y())),
                                                  int(std::lround(rel.z())))),
                       int(c));
  }
  for (size_t i = 0; i < points.size(); ++i) {
    const Vec3d rel = (points[i] - origin) / h;
    int cell = -1;
    auto it = cell_index.find(packBlock(Eigen::Vector3i(
        int(std::lround(rel.x())), int(std::lround(rel.y())), int(std::lround(rel.z())))));
    if (it != cell_index.end()) {
      cell = it->second;
    } else {
      double best = std::numeric_limits<double>::max();
      for (size_t c = 0; c < m.cells.size(); ++c) {
        const double d = (m.cells[c] - points[i]).squaredNorm();
        if (d < best) best = d, cell = int(c);
      }
    }
    // The cell's tetrahedron with the least negative weight holds it (or
    // is nearest to it).
    double best_min = -std::numeric_limits<double>::max();
    for (int k = 0; k < 6; ++k) {
      const size_t t = size_t(cell) * 6 + k;
      const auto w = barycentric(m.nodes, m.tets[t], points[i]);
      const double lo = std::min(std::min(w[0], w[1]), std::min(w[2], w[3]));
      if (lo > best_min) {
        best_min = lo;
        out[i].tet = int(t);
        out[i].w = w;
      }
    }
  }
  return out;
}

Vec3d embeddedPosition(const TetMesh& m, const std::vector<Vec3d>& x, const Embedding& e) {
  const auto& n = m.tets[e.tet];
  return e.w[0] * x[n[0]] + e.w[1] * x[n[1]] + e.w[2] * x[n[2]] + e.w[3] * x[n[3]];
}

}  // namespace triad
