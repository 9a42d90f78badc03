#include "sim/elastic_contact.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <unordered_map>

#include "sim/particles.h"

namespace triad {

namespace {

struct Box {
  Vec3d lo = Vec3d::Constant(1e300), hi = Vec3d::Constant(-1e300);
  void add(const Vec3d& p) { lo = lo.cwiseMin(p), hi = hi.cwiseMax(p); }
  bool contains(const Vec3d& p) const {
    return (p.array() >= lo.array()).all() && (p.array() <= hi.array()).all();
  }
  bool overlaps(const Box& b) const {
    return (lo.array() <= b.hi.array()).all() && (b.lo.array() <= hi.array()).all();
  }
};

// A solid's tetrahedra binned by their bounding boxes on a uniform grid of
// its own spacing: a point's candidate tetrahedra are those of its bin.
class TetBins {
 public:
  TetBins(const std::vector<Vec3d>& y, const TetMesh& mesh) : h_(mesh.spacing) {
    for (size_t t = 0; t < mesh.tets.size(); ++t) {
      Box b;
      for (int k = 0; k < 4; ++k) b.add(y[size_t(mesh.tets[t][k])]);
      const Eigen::Vector3i lo = cell(b.lo), hi = cell(b.hi);
      for (int i = lo.x(); i <= hi.x(); ++i)
        for (int j = lo.y(); j <= hi.y(); ++j)
          for (int k = lo.z(); k <= hi.z(); ++k) bins_[key({i, j, k})].push_back(int(t));
    }
  }
  const std::vector<int>* at(const Vec3d& p) const {
    const auto it = bins_.find(key(cell(p)));
    return it == bins_.end() ? nullptr : &it->second;
  }

 private:
  Eigen::Vector3i cell(const Vec3d& p) const {
    return (p / h_).array().floor().cast<int>();
  }
  static int64_t key(const Eigen::Vector3i& c) {
    constexpr int64_t kBias = 1 << 20;
    return ((int64_t(c.x()) + kBias) << 42) | ((int64_t(c.y()) + kBias) << 21) |
           (int64_t(c.z()) + kBias);
  }
  double h_;
  std::unordered_map<int64_t, std::vector<int>> bins_;
};

// Barycentric weights of p in the tetrahedron n of positions y.
std::array<double, 4> barycentric(const std::vector<Vec3d>& y, const std::array<int, 4>& n,
                                  const Vec3d& p) {
  Mat3d D;
  for (int k = 0; k < 3; ++k) D.col(k) = y[size_t(n[k + 1])] - y[size_t(n[0])];
  const Vec3d w = D.inverse() * (p - y[size_t(n[0])]);
  return {1.0 - w.sum(), w.x(), w.y(), w.z()};
}

constexpr double kPushOut = 0.2;  // share of a penetration undone per step

// A face of b's voxels at rest: the cell inside it, the axis and the side
// (+1 or -1) the face looks to.
struct Face {
  Eigen::Vector3i cell;
  int axis = 0, side = 1;
};

// Distance from a rest point inside b's voxels to their boundary, along the
// axes, and the boundary face reached.
double restDepth(const ElasticSolid& b, const Vec3d& rest, Face& face) {
  constexpr int kMaxWalk = 64;
  const double h = b.fem.mesh.spacing;
  const Eigen::Vector3i c = b.cellIndex(rest);
  const Vec3d centre = b.fem.mesh.cells[0] + h * c.cast<double>();
  double best = 1e300;
  for (int d = 0; d < 3; ++d)
    for (int s = -1; s <= 1; s += 2) {
      int k = 1;
      while (k < kMaxWalk && b.hasCell(c + s * k * Eigen::Vector3i::Unit(d))) ++k;
      const double dist = s * (centre[d] + s * (0.5 * h + (k - 1) * h) - rest[d]);
      if (dist < best) {
        best = dist;
        face = {c + s * (k - 1) * Eigen::Vector3i::Unit(d), d, s};
      }
    }
  return best;
}

// The face deformed: the plane through its four corner nodes (centroid and
// outward unit normal), from the positions y. False when a corner is not a
// node of the mesh (it always is for a face of b's voxels).
bool deformedFace(const ElasticSolid& b, const std::vector<Vec3d>& y, const Face& f,
                  Vec3d& centroid, Vec3d& normal) {
  const int u = (f.axis + 1) % 3, v = (f.axis + 2) % 3;
  // Corners in order around the face, as offsets (0 or 1) of the cell's
  // lowest corner.
  const int ring[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  Vec3d p[4];
  for (int k = 0; k < 4; ++k) {
    Eigen::Vector3i corner = f.cell;
    corner[f.axis] += f.side > 0 ? 1 : 0;
    corner[u] += ring[k][0];
    corner[v] += ring[k][1];
    const int node = b.nodeAt(corner);
    if (node < 0) return false;
    p[k] = y[size_t(node)];
  }
  centroid = 0.25 * (p[0] + p[1] + p[2] + p[3]);
  // (u, v, axis) is right-handed: the diagonals' cross product looks along
  // +axis; flip it for the -axis side.
  const Vec3d m = f.side * (p[2] - p[0]).cross(p[3] - p[1]);
  const double len = m.norm();
  if (!(len > 0.0) || !std::isfinite(len)) return false;
  normal = m / len;
  return true;
}

// Where the segment from a rest point inside b's voxels to rest + back
// leaves them: the distance along it and the face it leaves through; -1
// when the whole segment is inside (the point was inside already at the
// start of the step).
double entryDepth(const ElasticSolid& b, const Vec3d& rest, const Vec3d& back, Face& face) {
  const double len = back.norm();
  if (!(len > 0.0) || !std::isfinite(len)) return -1.0;
  const Vec3d dir = back / len;
  const double h = b.fem.mesh.spacing;
  const int steps = std::clamp(int(std::ceil(16.0 * len / h)), 1, 256);
  Eigen::Vector3i c = b.cellIndex(rest);
  for (int k = 1; k <= steps; ++k) {
    const Eigen::Vector3i next = b.cellIndex(rest + (len * k / steps) * dir);
    if (!b.hasCell(next)) {
      // The axis along which the walk stepped out (the largest change).
      const Eigen::Vector3i jump = next - c;
      int d = 0;
      for (int a = 1; a < 3; ++a)
        if (std::abs(jump[a]) > std::abs(jump[d])) d = a;
      face = {c, d, jump[d] > 0 ? 1 : -1};
      return len * k / steps;
    }
    c = next;
  }
  return -1.0;
}

double inverseMass(const FemBody& b, int node) {
  return b.pinned[size_t(node)] ? 0.0 : 1.0 / b.mass[size_t(node)];
}

// Nodes of `a` stopped at the surface of `b`.
size_t pushOut(ElasticSolid& a, ElasticSolid& b, double dt) {
  FemBody& fa = a.fem;
  FemBody& fb = b.fem;
  std::vector<Vec3d> ya(fa.nodes()), yb(fb.nodes());
  Box ba, bb;
  for (size_t i = 0; i < fa.nodes(); ++i) ba.add(ya[i] = fa.x[i] + dt * fa.v[i]);
  for (size_t i = 0; i < fb.nodes(); ++i) bb.add(yb[i] = fb.x[i] + dt * fb.v[i]);
  if (!ba.overlaps(bb)) return 0;
  const TetBins bins(yb, fb.mesh);
  const double mu = std::sqrt(double(a.friction) * double(b.friction));
  size_t contacts = 0;
  for (size_t i = 0; i < fa.nodes(); ++i) {
    const double inv_a = inverseMass(fa, int(i));
    if (!bb.contains(ya[i]) || inv_a == 0.0) continue;
    const std::vector<int>* candidates = bins.at(ya[i]);
    if (!candidates) continue;
    for (int t : *candidates) {
      const auto& n = fb.mesh.tets[size_t(t)];
      const std::array<double, 4> w = barycentric(yb, n, ya[i]);
      if (*std::min_element(w.begin(), w.end()) < -1e-9) continue;
      // Depth at the node's rest point in b: the nearest face of b's voxels
      // along the six axes (its boundary at rest), and that face's normal
      // turned by the element's deformation, F^-T N, whose length also
      // turns rest into deformed distance.
      Vec3d rest = Vec3d::Zero(), vb = Vec3d::Zero();
      for (int k = 0; k < 4; ++k) {
        rest += w[size_t(k)] * fb.mesh.nodes[size_t(n[k])];
        vb += w[size_t(k)] * fb.v[size_t(n[k])];
      }
      Mat3d D;
      for (int k = 0; k < 3; ++k) D.col(k) = yb[size_t(n[k + 1])] - yb[size_t(n[0])];
      const Mat3d F = D * fb.dm_inv[size_t(t)];
      // The boundary face of b the node is pushed out through: the one it
      // crossed in this step (walking back along its motion relative to b,
      // in rest space), which at an edge need not be the nearest one, else
      // the nearest one. Depth and normal are those of the face deformed
      // (the plane of its four nodes), so that the split of the voxels
      // into tetrahedra does not tilt them.
      Face face;
      if (restDepth(b, rest, face) <= 0.0) break;
      const Vec3d rel = fa.v[i] - vb;
      Face entry;
      if (entryDepth(b, rest, -dt * (F.inverse() * rel), entry) >= 0.0) face = entry;
      Vec3d centroid, normal;
      if (!deformedFace(b, yb, face, centroid, normal)) break;
      const double depth = normal.dot(ya[i] - centroid);
      if (depth >= 0.0) break;
      // Separate the node and b's material point under it by the depth
      // within the step: the impulse over the pair's reduced mass.
      double inv_b = 0.0;
      for (int k = 0; k < 4; ++k) inv_b += w[size_t(k)] * w[size_t(k)] * inverseMass(fb, n[k]);
      const double inv_pair = inv_a + inv_b;
      // Separation speed to gain: enough to stop the approach, and to undo
      // a fifth of the penetration per step beyond it, so that a node found
      // deep inside is eased out rather than thrown.
      const double approach = std::max(0.0, -normal.dot(fa.v[i] - vb));
      const double dvn = std::min(-depth / dt, approach + kPushOut * -depth / dt);
      Vec3d impulse = (dvn / inv_pair) * normal;
      // Coulomb friction on the relative sliding, bounded by that impulse.
      Vec3d vt = fa.v[i] - vb;
      vt -= normal.dot(vt) * normal;
      const double slide = vt.norm();
      if (slide > 0.0) impulse -= std::min(slide, mu * dvn) / inv_pair / slide * vt;
      fa.v[i] += inv_a * impulse;
      for (int k = 0; k < 4; ++k) fb.v[size_t(n[k])] -= w[size_t(k)] * inverseMass(fb, n[k]) * impulse;
      ++contacts;
      break;
    }
  }
  return contacts;
}

}  // namespace

size_t pushParticlesOut(ElasticSolid& b, std::vector<ParticleSet>& sets, double dt) {
  FemBody& fb = b.fem;
  std::vector<Vec3d> yb(fb.nodes());
  Box bb;
  for (size_t i = 0; i < fb.nodes(); ++i) bb.add(yb[i] = fb.x[i] + dt * fb.v[i]);
  const TetBins bins(yb, fb.mesh);
  size_t moved = 0;
  for (ParticleSet& set : sets) {
    const double mp = double(set.mass);
    for (size_t p = 0; p < set.size(); ++p) {
      const Vec3d x = set.x[p].cast<double>();
      if (!bb.contains(x)) continue;
      const std::vector<int>* candidates = bins.at(x);
      if (!candidates) continue;
      for (int t : *candidates) {
        const auto& n = fb.mesh.tets[size_t(t)];
        const std::array<double, 4> w = barycentric(yb, n, x);
        if (*std::min_element(w.begin(), w.end()) < -1e-9) continue;
        Vec3d rest = Vec3d::Zero(), vb = Vec3d::Zero();
        for (int k = 0; k < 4; ++k) {
          rest += w[size_t(k)] * fb.mesh.nodes[size_t(n[k])];
          vb += w[size_t(k)] * fb.v[size_t(n[k])];
        }
        Mat3d D;
        for (int k = 0; k < 3; ++k) D.col(k) = yb[size_t(n[k + 1])] - yb[size_t(n[0])];
        const Mat3d F = D * fb.dm_inv[size_t(t)];
        // Out through the face it came in by, else the nearest (as nodes).
        Face face;
        if (restDepth(b, rest, face) <= 0.0) break;
        const Vec3d v = set.v[p].cast<double>();
        Face entry;
        if (entryDepth(b, rest, -dt * (F.inverse() * (v - vb)), entry) >= 0.0) face = entry;
        Vec3d centroid, normal;
        if (!deformedFace(b, yb, face, centroid, normal)) break;
        const double depth = normal.dot(x - centroid);
        if (depth >= 0.0) break;
        // Onto the face; the approach velocity goes to the solid's nodes
        // under the particle, by barycentric weight.
        set.x[p] = (x - depth * normal).cast<float>();
        const double vn = normal.dot(v - vb);
        if (vn < 0.0) {
          set.v[p] = (v - vn * normal).cast<float>();
          for (int k = 0; k < 4; ++k)
            if (!fb.pinned[size_t(n[k])])
              fb.v[size_t(n[k])] += (w[size_t(k)] * mp * vn / fb.mass[size_t(n[k])]) * normal;
        }
        ++moved;
        break;
      }
    }
  }
  return moved;
}

ElasticContactStats resolveElasticContacts(std::vector<ElasticSolid>& solids, double dt) {
  ElasticContactStats s;
  for (size_t a = 0; a < solids.size(); ++a)
    for (size_t b = 0; b < solids.size(); ++b)
      if (a != b) s.contacts += pushOut(solids[a], solids[b], dt);
  return s;
}

}  // namespace triad
