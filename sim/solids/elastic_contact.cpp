#include "sim/solids/elastic_contact.h"

#include <omp.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <optional>

#include "sim/mpm/domain.h"
#include "sim/mpm/particles.h"
#include "sim/mpm/sparse_grid.h"
#include "sim/solids/fem.h"

namespace triad {

namespace {

// Axis-aligned bounds. Default-constructed they are left unset, so that a
// new vector of them is not written before it is filled.
struct Bounds {
  Bounds() {}  // user-provided: a resized vector is not zeroed either
  Bounds(const Vec3d& l, const Vec3d& h) : lo(l), hi(h) {}
  Vec3d lo, hi;
  bool contains(const Vec3d& p) const {
    return (p.array() >= lo.array()).all() && (p.array() <= hi.array()).all();
  }
  bool overlaps(const Bounds& b) const {
    return (lo.array() <= b.hi.array()).all() && (b.lo.array() <= hi.array()).all();
  }
};

// Bounds that start empty and grow by the points added.
struct Box : Bounds {
  Box() : Bounds(Vec3d::Constant(1e300), Vec3d::Constant(-1e300)) {}
  void add(const Vec3d& p) { lo = lo.cwiseMin(p), hi = hi.cwiseMax(p); }
};

// A solid's voxels binned by the bounding boxes of their deformed corners on
// a uniform grid of twice its spacing (a voxel's box then meets about 3
// cells rather than 8, and the bins are rebuilt every step while the
// queries are few): a point's candidate tetrahedra are the
// six of each voxel of its bin whose box holds it. Binning the voxels, not
// their tetrahedra, makes a sixth of the boxes and bin entries (the bins
// are rebuilt most steps: the solid moves); the candidates come in
// tetrahedron index order, the voxels' boxes holding every tetrahedron
// that holds the point.
class TetBins {
 public:
  // The voxels of the whole bounding box `all` of y, per cell, in one array
  // (counted, then filled: no allocation per bin; a cell lists its voxels
  // in index order).
  TetBins(const std::vector<Vec3d>& y, const Box& all, const TetMesh& mesh)
      : h_(2.0 * mesh.spacing) {
    if (y.empty() || !all.lo.allFinite() || !all.hi.allFinite()) return;  // a blow-up: reported after
    // A solid stretched across a large domain: coarser cells, at most 2^24.
    for (;;) {
      lo_ = cell(all.lo);
      dims_ = cell(all.hi) - lo_ + Eigen::Vector3i::Ones();
      if (dims_.cast<double>().prod() <= double(1 << 24)) break;
      h_ *= 2.0;
    }
    const size_t nvox = mesh.tets.size() / kTetsPerVoxel;
    boxes_.resize(nvox);  // (left unset: each thread sets its voxels')
    const size_t cells = size_t(dims_.prod());
    start_.assign(cells + 1, 0);
    // A counting sort in one parallel region: each thread takes a run of
    // voxels, counts their cells, then places its entries after those of
    // the threads before it, so that a cell lists its voxels in index order
    // on any number of threads. (Built serially it took half of the push-out
    // on two threads, and the other thread fell asleep meanwhile.)
    std::vector<uint32_t> counts;
#pragma omp parallel if (nvox > 1024)
    {
      const int threads = omp_get_num_threads(), me = omp_get_thread_num();
      const size_t v0 = nvox * size_t(me) / size_t(threads);
      const size_t v1 = nvox * size_t(me + 1) / size_t(threads);
#pragma omp single
      counts.assign(cells * size_t(threads), 0);
      uint32_t* mine = counts.data() + cells * size_t(me);
      // A voxel's box: the corners of its Kuhn tetrahedra 0, 3 and 4 (axis
      // orders xyz, yzx, zxy) are its eight corners.
      for (size_t v = v0; v < v1; ++v) {
        Box b;
        for (const size_t t : {0, 3, 4})
          for (int k = 0; k < 4; ++k) b.add(y[size_t(mesh.tets[kTetsPerVoxel * v + t][k])]);
        boxes_[v] = b;
        forCells(cell(b.lo) - lo_, cell(b.hi) - lo_, [&](size_t c) { ++mine[c]; });
      }
#pragma omp barrier
#pragma omp single
      {
        // Each thread's first entry per cell, cell by cell, thread by thread.
        uint32_t total = 0;
        for (size_t c = 0; c < cells; ++c) {
          start_[c] = total;
          for (int t = 0; t < threads; ++t) {
            const uint32_t k = counts[cells * size_t(t) + c];
            counts[cells * size_t(t) + c] = total;
            total += k;
          }
        }
        start_[cells] = total;
        voxels_.resize(total);
      }
      for (size_t v = v0; v < v1; ++v)
        forCells(cell(boxes_[v].lo) - lo_, cell(boxes_[v].hi) - lo_,
                 [&](size_t c) { voxels_[mine[c]++] = uint32_t(v); });
    }
  }
  // Calls f(t) for the candidate tetrahedra of p in index order until f
  // returns true (none outside the box).
  template <class F>
  bool find(const Vec3d& p, F&& f) const {
    const Eigen::Vector3i c = cell(p) - lo_;
    if ((c.array() < 0).any() || (c.array() >= dims_.array()).any()) return false;
    const size_t i = index(c);
    for (uint32_t k = start_[i]; k < start_[i + 1]; ++k) {
      const uint32_t v = voxels_[k];
      if (!boxes_[v].contains(p)) continue;
      for (int t = int(kTetsPerVoxel * v); t < int(kTetsPerVoxel * (v + 1)); ++t)
        if (f(t)) return true;
    }
    return false;
  }

 private:
  static constexpr size_t kTetsPerVoxel = 6;  // TetMesh: cell c owns [6c, 6c + 6)
  Eigen::Vector3i cell(const Vec3d& p) const {
    return (p / h_).array().floor().cast<int>();
  }
  size_t index(const Eigen::Vector3i& c) const {
    return (size_t(c.x()) * size_t(dims_.y()) + size_t(c.y())) * size_t(dims_.z()) + size_t(c.z());
  }
  template <class F>
  void forCells(const Eigen::Vector3i& a, const Eigen::Vector3i& b, F&& f) const {
    for (int i = a.x(); i <= b.x(); ++i)
      for (int j = a.y(); j <= b.y(); ++j)
        for (int k = a.z(); k <= b.z(); ++k) f(index({i, j, k}));
  }
  double h_;
  Eigen::Vector3i lo_ = Eigen::Vector3i::Zero(), dims_ = Eigen::Vector3i::Zero();
  std::vector<uint32_t> start_;  // per cell: first entry; one more at the end
  std::vector<uint32_t> voxels_;
  std::vector<Bounds> boxes_;  // per voxel: its deformed corners' box (unset until filled)
};

constexpr double kPushOut = 0.2;  // share of a penetration undone per step

// A face of b's voxels at rest: the cell inside it, the axis and the side
// (+1 or -1) the face looks to.
struct Face {
  Eigen::Vector3i cell;
  int axis = 0, side = 1;
};

// Distances from a rest point inside b's voxels to their boundary along
// each axis both ways, and the boundary faces reached, nearest first.
struct FaceDistance {
  double dist = 0.0;
  Face face;
};
std::array<FaceDistance, 6> restFaces(const ElasticSolid& b, const Vec3d& rest) {
  constexpr int kMaxWalk = 64;
  const double h = b.fem.mesh.spacing;
  const Eigen::Vector3i c = b.cellIndex(rest);
  const Vec3d centre = b.fem.mesh.cells[0] + h * c.cast<double>();
  std::array<FaceDistance, 6> out;
  for (int d = 0; d < 3; ++d)
    for (int s = -1; s <= 1; s += 2) {
      int k = 1;
      while (k < kMaxWalk && b.hasCell(c + s * k * Eigen::Vector3i::Unit(d))) ++k;
      FaceDistance& f = out[size_t(2 * d + (s + 1) / 2)];
      f.dist = s * (centre[d] + s * (0.5 * h + (k - 1) * h) - rest[d]);
      f.face = {c + s * (k - 1) * Eigen::Vector3i::Unit(d), d, s};
    }
  std::stable_sort(out.begin(), out.end(),
                   [](const FaceDistance& p, const FaceDistance& q) { return p.dist < q.dist; });
  return out;
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

// How deep, in sample spacings, a point must be before the face it crossed
// in the step, rather than its nearest face, is the one it leaves through.
constexpr double kShallow = 0.25;
// How much more (in the cosine with the node's own normal) another shallow
// face must be turned against the node than its nearest face to hold it.
constexpr double kTurned = 0.5;
// How near, in sample spacings, the nearest face must be for a point to lie
// on its plane (and another face to be the one that holds it).
constexpr double kOnPlane = 0.05;

double inverseMass(const FemBody& b, int node) {
  return b.pinned[size_t(node)] ? 0.0 : 1.0 / b.mass[size_t(node)];
}

// A solid at the end of the step: node positions x + dt v, their bounding
// box, and its tetrahedra binned for point queries (binned only when a
// query may fall inside the box: most steps of most solids have none).
struct EndOfStep {
  const FemBody& body;
  std::vector<Vec3d> y;
  Box box;
  std::optional<TetBins> bins;
  EndOfStep(const FemBody& f, double dt) : body(f), y(f.nodes()) {
    for (size_t i = 0; i < f.nodes(); ++i) {
      y[i] = f.x[i] + dt * f.v[i];
      box.add(y[i]);
    }
  }
  void bin() {
    if (!bins) bins.emplace(y, box, body.mesh);
  }
};

// A point found inside a solid: its tetrahedron and barycentric weights, the
// solid's velocity there, and the boundary face it is pushed out through
// (outward unit normal, signed distance: negative inside).
struct Penetration {
  int tet = -1;
  std::array<double, 4> w{};
  Vec3d vb = Vec3d::Zero(), normal = Vec3d::Zero();
  double depth = 0.0;
};

// Whether point x (moving at v over the step) ends inside solid b. The
// face it is pushed out through is, deep inside, the one it crossed in
// this step (walking back along its motion relative to b, in rest space),
// which at an edge need not be the nearest one; near the surface the
// nearest one, or the shallow face turned against `own` (the outward
// normal of the surface the point belongs to; zero for a particle). Depth
// and normal are those of the face deformed (the plane of its four nodes),
// so that the split of the voxels into tetrahedra does not tilt them.
bool findPenetration(const ElasticSolid& b, const EndOfStep& end, const Vec3d& x, const Vec3d& v,
                     const Vec3d& own, double dt, Penetration& out) {
  const FemBody& fb = b.fem;
  if (!end.box.contains(x)) return false;
  bool found = false;
  end.bins->find(x, [&](int t) {
    const auto& n = fb.mesh.tets[size_t(t)];
    const std::array<double, 4> w = barycentric(end.y, n, x);
    if (*std::min_element(w.begin(), w.end()) < -1e-9) return false;  // not this one
    // The first tetrahedron that holds x decides.
    Vec3d rest = Vec3d::Zero(), vb = Vec3d::Zero();
    for (int k = 0; k < 4; ++k) {
      rest += w[size_t(k)] * fb.mesh.nodes[size_t(n[k])];
      vb += w[size_t(k)] * fb.v[size_t(n[k])];
    }
    const Mat3d F = edges(end.y, n) * fb.dm_inv[size_t(t)];
    const std::array<FaceDistance, 6> faces = restFaces(b, rest);
    Face face = faces[0].face;
    const double nearest = faces[0].dist, h = fb.mesh.spacing;
    if (nearest <= 0.0) return true;
    // A point barely inside leaves through its nearest face: a node of a
    // surface sliding along this one, which the other's leading face sweeps
    // over, is a bump to ride over, not a wall to stop at. But a node of a
    // solid's surface (outward normal `own`) whose face lies on this one
    // is held by the face turned against its own, when that face is also
    // shallow: the nodes along the bottom edge of a cube stacked face to
    // face on another lie on the lower's side planes, and through those,
    // nearest at a depth of nothing, nothing held them up.
    Face entry;
    if (nearest > kShallow * h) {
      // Walked back along its motion relative to b, at rest.
      if (entryDepth(b, rest, -dt * (F.inverse() * (v - vb)), entry) >= 0.0) face = entry;
    } else if (nearest < kOnPlane * h && own.squaredNorm() > 0.0) {
      const Mat3d G = F.inverse().transpose();
      auto facing = [&](const Face& f) {
        return own.dot((G * (f.side * Vec3d::Unit(f.axis))).normalized());
      };
      double best = facing(face);
      for (size_t k = 1; k < faces.size() && faces[k].dist <= kShallow * h; ++k) {
        const double c = facing(faces[k].face);
        if (c < best - kTurned) best = c, face = faces[k].face;
      }
    }
    Vec3d centroid, normal;
    if (!deformedFace(b, end.y, face, centroid, normal)) return true;
    const double depth = normal.dot(x - centroid);
    if (depth >= 0.0) return true;
    out = {t, w, vb, normal, depth};
    found = true;
    return true;
  });
  return found;
}

// Nodes of `a` stopped at the surface of `b`.
size_t pushOut(ElasticSolid& a, ElasticSolid& b, double dt) {
  FemBody& fa = a.fem;
  FemBody& fb = b.fem;
  Box ba;
  for (size_t i = 0; i < fa.nodes(); ++i) ba.add(fa.x[i] + dt * fa.v[i]);
  EndOfStep end(fb, dt);
  if (!ba.overlaps(end.box)) return 0;
  end.bin();
  const double mu = std::sqrt(double(a.friction) * double(b.friction));
  size_t contacts = 0;
  for (size_t i = 0; i < fa.nodes(); ++i) {
    const double inv_a = inverseMass(fa, int(i));
    Penetration pen;
    if (inv_a == 0.0 ||
        !findPenetration(b, end, fa.x[i] + dt * fa.v[i], fa.v[i], a.normal(i), dt, pen))
      continue;
    const auto& n = fb.mesh.tets[size_t(pen.tet)];
    // Separate the node and b's material point under it by the depth
    // within the step: the impulse over the pair's reduced mass.
    double inv_b = 0.0;
    for (int k = 0; k < 4; ++k) inv_b += pen.w[size_t(k)] * pen.w[size_t(k)] * inverseMass(fb, n[k]);
    const double inv_pair = inv_a + inv_b;
    // Separation speed to gain: enough to stop the approach, and to undo
    // a fifth of the penetration per step beyond it, so that a node found
    // deep inside is eased out rather than thrown.
    const Vec3d rel = fa.v[i] - pen.vb;
    const double approach = std::max(0.0, -pen.normal.dot(rel));
    const double dvn = std::min(-pen.depth / dt, approach + kPushOut * -pen.depth / dt);
    Vec3d impulse = (dvn / inv_pair) * pen.normal;
    // Coulomb friction on the relative sliding, bounded by that impulse.
    const Vec3d vt = rel - pen.normal.dot(rel) * pen.normal;
    const double slide = vt.norm();
    if (slide > 0.0) impulse -= std::min(slide, mu * dvn) / inv_pair / slide * vt;
    fa.v[i] += inv_a * impulse;
    for (int k = 0; k < 4; ++k)
      fb.v[size_t(n[k])] -= pen.w[size_t(k)] * inverseMass(fb, n[k]) * impulse;
    ++contacts;
  }
  return contacts;
}

}  // namespace

size_t pushParticlesOut(ElasticSolid& b, std::vector<ParticleSet>& sets, double dt,
                        const ParticleBlocks& blocks, DomainExchange* domain) {
  FemBody& fb = b.fem;
  EndOfStep end(fb, dt);
  // The blocks whose particles may end inside: those whose sphere meets
  // the solid's box.
  std::vector<uint32_t> near;
  for (size_t pb = 0; pb < blocks.centre.size(); ++pb) {
    const Vec3d& c = blocks.centre[pb];
    const Vec3d out = (end.box.lo - c).cwiseMax(c - end.box.hi).cwiseMax(0.0);
    if (out.squaredNorm() <= blocks.radius * blocks.radius) near.push_back(uint32_t(pb));
  }
  // Split over processes, every process takes part in the exchange below.
  if (near.empty() && !domain) return 0;
  if (!near.empty()) end.bin();
  size_t moved = 0;
  for (size_t s = 0; s < sets.size(); ++s) {
    ParticleSet& set = sets[s];
    const double mp = double(set.mass);
    // Found in parallel (each particle on its own, against the solid's
    // velocities before this pass), then applied in the order of the
    // particles' ids, each against the velocities the ones before it left:
    // the solid's nodes take the same sums on any number of threads or
    // processes.
    // Pieces of at most a fixed size, dealt out as threads come free: the
    // particles near a solid lie together in the sorted order, so equal
    // shares per thread left one thread with all of them.
    constexpr uint32_t kPiece = 2048;
    const std::vector<uint32_t>& off = (*blocks.offsets)[s];
    std::vector<std::pair<uint32_t, uint32_t>> pieces;
    for (const uint32_t pb : near)
      for (uint32_t p = off[pb]; p < off[pb + 1]; p += kPiece) {
        const uint32_t e = std::min(off[pb + 1], p + kPiece);
        if (!pieces.empty() && pieces.back().second == p && e - pieces.back().first <= kPiece)
          pieces.back().second = e;  // a run of small blocks in one piece
        else
          pieces.emplace_back(p, e);
      }
    std::vector<std::vector<std::pair<uint32_t, Penetration>>> part(pieces.size());
#pragma omp parallel for schedule(dynamic, 1) if (pieces.size() > 1)
    for (int64_t c = 0; c < int64_t(pieces.size()); ++c)
      for (uint32_t p = pieces[size_t(c)].first; p < pieces[size_t(c)].second; ++p) {
        Penetration pen;
        if (findPenetration(b, end, set.x[p].cast<double>(), set.v[p].cast<double>(), Vec3d::Zero(),
                            dt, pen))
          part[size_t(c)].emplace_back(p, pen);
      }
    // Every hit with the particle's state: split over processes, every
    // process's.
    struct Hit {
      int32_t process;
      uint32_t p, id;
      Penetration pen;
      Vec3d x, v;
    };
    const int32_t me = domain ? domain->process() : 0;
    std::vector<Hit> hits;
    for (const auto& chunk : part)
      for (const auto& [p, pen] : chunk)
        hits.push_back({me, p, set.id[p], pen, set.x[p].cast<double>(), set.v[p].cast<double>()});
    if (domain) hits = allGatherValues(*domain, hits);
    // In the order of the particles' ids: the same sequence however the
    // particles are stored, or split between processes.
    std::sort(hits.begin(), hits.end(), [](const Hit& l, const Hit& r) { return l.id < r.id; });
    for (const Hit& h : hits) {
      const bool own = h.process == me;
      const Penetration& pen = h.pen;
      // Onto the face, and the approach stopped by an inelastic impulse
      // between the particle and the solid's point under it (the pair's
      // reduced mass, the nodes' share by barycentric weight). A particle
      // may outweigh the nodes it meets (water on a light solid's corner
      // node, 30 to 1): handing them its whole approach momentum threw
      // them off at many times its speed, and backward Euler let those
      // kicks grow until the run blew up.
      if (own) set.x[h.p] = (h.x - pen.depth * pen.normal).cast<float>();
      const auto& n = fb.mesh.tets[size_t(pen.tet)];
      Vec3d vb = Vec3d::Zero();
      double inv_b = 0.0;
      for (int k = 0; k < 4; ++k) {
        vb += pen.w[size_t(k)] * fb.v[size_t(n[k])];
        inv_b += pen.w[size_t(k)] * pen.w[size_t(k)] * inverseMass(fb, n[k]);
      }
      const double vn = pen.normal.dot(h.v - vb);
      if (vn < 0.0) {
        const double j = -vn / (1.0 / mp + inv_b);  // along the normal, onto the particle
        if (own) set.v[h.p] = (h.v + (j / mp) * pen.normal).cast<float>();
        for (int k = 0; k < 4; ++k)
          fb.v[size_t(n[k])] -= (pen.w[size_t(k)] * j * inverseMass(fb, n[k])) * pen.normal;
      }
      moved += own ? 1 : 0;
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
