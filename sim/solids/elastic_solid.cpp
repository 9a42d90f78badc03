#include "sim/solids/elastic_solid.h"

#include <algorithm>
#include <cmath>

#include "sim/mpm/sparse_grid.h"

namespace triad {

Eigen::Vector3i ElasticSolid::cellIndex(const Vec3d& rest) const {
  const TetMesh& m = fem.mesh;
  return ((rest - m.cells[0]) / m.spacing).array().round().cast<int>();
}

bool ElasticSolid::hasCell(const Eigen::Vector3i& ijk) const {
  return cell_keys.count(packBlock(ijk)) > 0;
}

int ElasticSolid::nodeAt(const Eigen::Vector3i& ijk) const {
  const auto it = node_keys.find(packBlock(ijk));
  return it == node_keys.end() ? -1 : it->second;
}

Vec3d ElasticSolid::normal(size_t i) const {
  const size_t t = size_t(node_tet[i]);
  const Mat3d F = edges(fem.x, fem.mesh.tets[t]) * fem.dm_inv[t];
  return turned(i, F.inverse().transpose());
}

Vec3d ElasticSolid::normalAfterForces(size_t i) const {
  const Mat3d* kept = fem.keptInverseTranspose(size_t(node_tet[i]));
  return kept ? turned(i, *kept) : normal(i);
}

Vec3d ElasticSolid::turned(size_t i, const Mat3d& inv_t) const {
  const Vec3d m = inv_t * normal0[i];
  const double len = m.norm();
  return len > 0 && std::isfinite(len) ? Vec3d(m / len) : normal0[i];
}

TriSurface ElasticSolid::worldSurface() const {
  TriSurface s;
  s.triangles = surface.triangles;
  s.vertices.reserve(embedding.size());
  for (const Embedding& e : embedding)
    s.vertices.push_back(embeddedPosition(fem.mesh, fem.x, e).cast<float>());
  return s;
}

ElasticSolid makeElasticSolid(int object, const std::string& name, const CollisionSamples& samples,
                              TriSurface surface, const MaterialDesc& material, double friction,
                              const Vec3d& velocity, const SpannedWalls& walls) {
  ElasticSolid e;
  e.object = object;
  e.name = name;
  e.friction = static_cast<float>(friction);
  std::vector<Vec3d> centres;
  centres.reserve(samples.size());
  for (const Vec3f& p : samples.x) centres.push_back(p.cast<double>());
  e.fem = makeFemBody(tetsFromVoxels(centres, samples.spacing), material);
  for (Vec3d& v : e.fem.v) v = velocity;
  // Node normals: each cell gives its sample's normal to its corners.
  const TetMesh& m = e.fem.mesh;
  e.normal0.assign(m.nodes.size(), Vec3d::Zero());
  e.node_tet.assign(m.nodes.size(), 0);
  for (size_t t = 0; t < m.tets.size(); ++t) {
    const Vec3d n = samples.normal[t / 6].cast<double>();
    for (int k = 0; k < 4; ++k) {
      e.normal0[size_t(m.tets[t][k])] += n;
      e.node_tet[size_t(m.tets[t][k])] = int(t);
    }
  }
  for (Vec3d& n : e.normal0) {
    const double len = n.norm();
    n = len > 0 ? Vec3d(n / len) : Vec3d(0, 1, 0);
  }
  e.fem.keepInverseTransposes(e.node_tet);
  // Node distances: a node with fewer than eight cells around it lies on
  // the boundary. A cell's six tetrahedra are consecutive.
  std::vector<int> cells(m.nodes.size(), 0), last(m.nodes.size(), -1);
  std::vector<double> sum(m.nodes.size(), 0.0);
  for (size_t t = 0; t < m.tets.size(); ++t)
    for (int k = 0; k < 4; ++k) {
      const size_t i = size_t(m.tets[t][k]);
      if (last[i] == int(t / 6)) continue;
      last[i] = int(t / 6);
      cells[i]++;
      sum[i] += samples.phi[t / 6];
    }
  for (const Vec3d& c : m.cells) e.cell_keys.insert(packBlock(e.cellIndex(c)));
  // A node whose only missing cells lie beyond walls the solid spans is
  // inside it too: its distance is the mean of the cells it has.
  auto inside = [&](size_t i) {
    if (cells[i] == 8) return true;
    if (cells[i] == 0) return false;
    const double h = m.spacing;
    for (int k = 0; k < 8; ++k) {
      const Vec3d c = m.nodes[i] + 0.5 * h * Vec3d(k & 1 ? 1 : -1, k & 2 ? 1 : -1, k & 4 ? 1 : -1);
      if (e.hasCell(e.cellIndex(c))) continue;
      bool beyond = false;
      for (int d = 0; d < 3; ++d)
        beyond = beyond || (walls.axis[size_t(d)] && (c[d] < walls.min[d] || c[d] > walls.max[d]));
      if (!beyond) return false;
    }
    return true;
  };
  e.phi0.assign(m.nodes.size(), 0.0f);
  for (size_t i = 0; i < m.nodes.size(); ++i)
    if (inside(i)) e.phi0[i] = float(std::min(0.0, sum[i] / cells[i]));
  // A corner's lattice index is that of the cell whose lowest corner it is.
  for (size_t i = 0; i < m.nodes.size(); ++i)
    e.node_keys[packBlock(e.cellIndex(m.nodes[i] + Vec3d::Constant(0.5 * m.spacing)))] = int(i);
  std::vector<Vec3d> verts;
  for (const Vec3f& v : surface.vertices) verts.push_back(v.cast<double>());
  e.embedding = embed(m, verts);
  e.surface = std::move(surface);
  return e;
}

}  // namespace triad
