#include "sim/shot/deforming.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace triad {

namespace {

// The triangle's frame: columns edge ab, in-plane perpendicular, normal.
Mat3d triangleFrame(const Vec3d& a, const Vec3d& b, const Vec3d& c) {
  Vec3d e1 = b - a;
  Vec3d n = e1.cross(c - a);
  Mat3d f = Mat3d::Identity();
  if (e1.norm() == 0.0 || n.norm() == 0.0) return f;  // degenerate: no rotation
  e1.normalize();
  n.normalize();
  f.col(0) = e1;
  f.col(1) = n.cross(e1);
  f.col(2) = n;
  return f;
}

// Buckets of triangles by cubic cell, for nearest-triangle queries.
struct TriangleBuckets {
  double cell;
  std::vector<std::pair<uint64_t, uint32_t>> entries;  // (cell key, triangle), sorted

  static uint64_t key(const Eigen::Vector3i& c) {
    constexpr uint64_t m = (1u << 21) - 1;
    return ((uint64_t(c.x()) & m) << 42) | ((uint64_t(c.y()) & m) << 21) | (uint64_t(c.z()) & m);
  }
  Eigen::Vector3i cellOf(const Vec3d& p) const {
    return Eigen::Vector3i(int(std::floor(p.x() / cell)), int(std::floor(p.y() / cell)),
                           int(std::floor(p.z() / cell)));
  }
};

}  // namespace

Vec3d closestOnTriangle(const Vec3d& p, const Vec3d& a, const Vec3d& b, const Vec3d& c) {
  // Ericson, Real-Time Collision Detection, 5.1.5: by Voronoi region.
  const Vec3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return Vec3d(1, 0, 0);
  const Vec3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return Vec3d(0, 1, 0);
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double v = d1 / (d1 - d3);
    return Vec3d(1 - v, v, 0);
  }
  const Vec3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return Vec3d(0, 0, 1);
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const double w = d2 / (d2 - d6);
    return Vec3d(1 - w, 0, w);
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return Vec3d(0, 1 - w, w);
  }
  const double denom = 1.0 / (va + vb + vc);
  const double v = vb * denom, w = vc * denom;
  if (!std::isfinite(v + w)) return Vec3d(1, 0, 0);  // degenerate triangle
  return Vec3d(1 - v - w, v, w);
}

DeformingSurface::DeformingSurface(std::vector<std::vector<Vec3f>> frames,
                                   std::vector<std::array<uint32_t, 3>> triangles, double fps,
                                   const std::vector<Vec3f>& x, const std::vector<Vec3f>& n,
                                   double reach)
    : frames_(std::move(frames)), triangles_(std::move(triangles)), fps_(fps) {
  for (size_t k = 0; k + 1 < frames_.size(); ++k) {
    double m = 0.0;
    for (size_t i = 0; i < frames_[k].size(); ++i)
      m = std::max(m, double((frames_[k + 1][i] - frames_[k][i]).norm()) * fps_);
    max_speed_.push_back(m);
  }
  const std::vector<Vec3f>& v0 = frames_.front();
  auto vert = [&](uint32_t i) { return v0[i].cast<double>(); };
  // Every triangle in each cell its box, grown by the reach, overlaps: a
  // sample's nearest triangle (within the reach) is in the sample's cell.
  TriangleBuckets buckets;
  buckets.cell = std::max(reach, 1e-9);
  for (uint32_t t = 0; t < triangles_.size(); ++t) {
    Vec3d lo = vert(triangles_[t][0]), hi = lo;
    for (int k = 1; k < 3; ++k) {
      lo = lo.cwiseMin(vert(triangles_[t][k]));
      hi = hi.cwiseMax(vert(triangles_[t][k]));
    }
    const Eigen::Vector3i c0 = buckets.cellOf(lo - Vec3d::Constant(reach));
    const Eigen::Vector3i c1 = buckets.cellOf(hi + Vec3d::Constant(reach));
    for (int i = c0.x(); i <= c1.x(); ++i)
      for (int j = c0.y(); j <= c1.y(); ++j)
        for (int k = c0.z(); k <= c1.z(); ++k)
          buckets.entries.emplace_back(TriangleBuckets::key({i, j, k}), t);
  }
  std::sort(buckets.entries.begin(), buckets.entries.end());

  const size_t ns = x.size();
  tri_.assign(ns, 0);
  bary_.assign(ns, Vec3f(1, 0, 0));
  offset_.assign(ns, Vec3f::Zero());
  normal_.assign(ns, Vec3f(0, 0, 1));
#pragma omp parallel for schedule(dynamic, 256) if (ns > 4096)
  for (int64_t q = 0; q < int64_t(ns); ++q) {
    const Vec3d p = x[q].cast<double>();
    const uint64_t k = TriangleBuckets::key(buckets.cellOf(p));
    auto it = std::lower_bound(buckets.entries.begin(), buckets.entries.end(),
                               std::make_pair(k, uint32_t(0)));
    double best = std::numeric_limits<double>::infinity();
    uint32_t best_t = 0;
    Vec3d best_b(1, 0, 0);
    for (; it != buckets.entries.end() && it->first == k; ++it) {
      const auto& tr = triangles_[it->second];
      const Vec3d a = vert(tr[0]), b = vert(tr[1]), c = vert(tr[2]);
      const Vec3d w = closestOnTriangle(p, a, b, c);
      const double d = (p - (w.x() * a + w.y() * b + w.z() * c)).squaredNorm();
      if (d < best) best = d, best_t = it->second, best_b = w;
    }
    // Beyond the reach of every triangle (should not happen): it stays put
    // relative to the first triangle's frame.
    const auto& tr = triangles_[best_t];
    const Vec3d a = vert(tr[0]), b = vert(tr[1]), c = vert(tr[2]);
    const Mat3d f = triangleFrame(a, b, c);
    const Vec3d closest = best_b.x() * a + best_b.y() * b + best_b.z() * c;
    tri_[q] = best_t;
    bary_[q] = best_b.cast<float>();
    offset_[q] = (f.transpose() * (p - closest)).cast<float>();
    normal_[q] = (f.transpose() * n[q].cast<double>()).cast<float>();
  }
}

void DeformingSurface::vertices(double t, std::vector<Vec3d>& x, std::vector<Vec3d>& v) const {
  const size_t nv = frames_.front().size();
  x.resize(nv);
  v.resize(nv);
  const double f = std::max(0.0, t * fps_);
  const int last = int(frames_.size()) - 1;
  const int k = std::min(int(std::floor(f)), last);
  if (k >= last) {
    for (size_t i = 0; i < nv; ++i) x[i] = frames_[size_t(last)][i].cast<double>();
    std::fill(v.begin(), v.end(), Vec3d::Zero());
    return;
  }
  const double s = f - k;
  const std::vector<Vec3f>& a = frames_[size_t(k)];
  const std::vector<Vec3f>& b = frames_[size_t(k) + 1];
  for (size_t i = 0; i < nv; ++i) {
    const Vec3d pa = a[i].cast<double>(), pb = b[i].cast<double>();
    x[i] = pa + s * (pb - pa);
    v[i] = (pb - pa) * fps_;
  }
}

void DeformingSurface::placeAll(double t, const Mat3d& A, const Vec3d& pivot, const Vec3d& centre,
                                const Vec3d& lin, const Vec3d& omega, std::vector<Vec3f>& pos,
                                std::vector<Vec3f>& vel, std::vector<Vec3f>& nrm,
                                size_t first) const {
  std::vector<Vec3d> x, v;
  vertices(t, x, v);
  // Each triangle's frame now and a moment later (vertices move linearly
  // within a frame): the samples' velocities are that difference.
  const double eps = 1e-4 / fps_;
  const int64_t nt = int64_t(triangles_.size());
  std::vector<Mat3d> f0(static_cast<size_t>(nt)), f1(static_cast<size_t>(nt));
#pragma omp parallel for schedule(static) if (nt > 4096)
  for (int64_t k = 0; k < nt; ++k) {
    const auto& tr = triangles_[size_t(k)];
    f0[size_t(k)] = triangleFrame(x[tr[0]], x[tr[1]], x[tr[2]]);
    f1[size_t(k)] = triangleFrame(x[tr[0]] + eps * v[tr[0]], x[tr[1]] + eps * v[tr[1]],
                                  x[tr[2]] + eps * v[tr[2]]);
  }
  const int64_t ns = int64_t(tri_.size());
#pragma omp parallel for schedule(static) if (ns > 8192)
  for (int64_t q = 0; q < ns; ++q) {
    const uint32_t k = tri_[size_t(q)];
    const auto& tr = triangles_[k];
    const Vec3d w = bary_[size_t(q)].cast<double>(), o = offset_[size_t(q)].cast<double>();
    const Vec3d c = w.x() * x[tr[0]] + w.y() * x[tr[1]] + w.z() * x[tr[2]];
    const Vec3d cv = w.x() * v[tr[0]] + w.y() * v[tr[1]] + w.z() * v[tr[2]];
    const Vec3d p = c + f0[k] * o;
    const Vec3d pv = cv + (f1[k] - f0[k]) * o / eps;
    const Vec3d r = A * (p - pivot);
    pos[first + size_t(q)] = (centre + r).cast<float>();
    vel[first + size_t(q)] = (A * pv + lin + omega.cross(r)).cast<float>();
    nrm[first + size_t(q)] = (A * (f0[k] * normal_[size_t(q)].cast<double>())).cast<float>();
  }
}

double DeformingSurface::maxSpeed(double t) const {
  const int k = int(std::floor(std::max(0.0, t * fps_)));
  return k < int(max_speed_.size()) ? max_speed_[size_t(k)] : 0.0;
}

double DeformingSurface::bindingError(const std::vector<Vec3f>& x) const {
  std::vector<Vec3f> pos(tri_.size()), vel(tri_.size()), nrm(tri_.size());
  placeAll(0.0, Mat3d::Identity(), Vec3d::Zero(), Vec3d::Zero(), Vec3d::Zero(), Vec3d::Zero(), pos,
           vel, nrm, 0);
  double e = 0.0;
  for (size_t q = 0; q < tri_.size(); ++q) e += double((pos[q] - x[q]).norm());
  return tri_.empty() ? 0.0 : e / double(tri_.size());
}

void PlacedSamples::index(float h, const std::vector<float>& phi, float deepest) {
  if (x.empty()) {
    cells_.clear();
    return;
  }
  Vec3f lo = x[0], hi = x[0];
  for (const Vec3f& p : x) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  // The grid keeps its allocation while the samples stay inside it: its
  // box is snapped to 8 cells with 4 to spare on each side, so a collider
  // that moves or deforms a little refills it without clearing it whole.
  const double snap = 8.0 * h;
  bool fits = h == h_ && !cells_.empty();
  for (int d = 0; d < 3 && fits; ++d)
    fits = lo[d] >= origin_[d] + 0.5 * h && hi[d] <= origin_[d] + double(h) * (dims_[d] - 1.5);
  if (!fits) {
    h_ = h;
    for (int d = 0; d < 3; ++d) {
      origin_[d] = std::floor(lo[d] / snap) * snap - 4.0 * h;
      dims_[d] = int(std::ceil((double(hi[d]) - origin_[d]) / snap) * 8.0) + 8;
    }
    cells_.assign(size_t(dims_.x()) * size_t(dims_.y()) * size_t(dims_.z()), -1);
    filled_.clear();
  }
  for (uint32_t i : filled_) cells_[i] = -1;
  filled_.clear();
  // Each cell keeps its first sample: the same lookup for any order of work.
  const float inv_h = 1.0f / h;
  const Vec3f o = origin_.cast<float>();
  for (size_t q = 0; q < x.size(); ++q) {
    if (phi[q] <= deepest) continue;
    const Vec3f c = ((x[q] - o) * inv_h).array().round();
    const uint32_t i = uint32_t((size_t(c.x()) * size_t(dims_.y()) + size_t(c.y())) * size_t(dims_.z()) +
                                size_t(c.z()));
    if (cells_[i] >= 0) continue;
    cells_[i] = int32_t(q);
    filled_.push_back(i);
  }
}

Eigen::Vector3i PlacedSamples::cellOf(const Vec3d& p) const {
  const Vec3d c = (p - origin_) / double(h_);
  return {int(std::lround(c.x())), int(std::lround(c.y())), int(std::lround(c.z()))};
}

int PlacedSamples::kept(const Eigen::Vector3i& c) const {
  for (int d = 0; d < 3; ++d)
    if (c[d] < 0 || c[d] >= dims_[d]) return -1;
  return cells_[(size_t(c.x()) * size_t(dims_.y()) + size_t(c.y())) * size_t(dims_.z()) + size_t(c.z())];
}

int PlacedSamples::at(const Vec3d& p) const { return cells_.empty() ? -1 : kept(cellOf(p)); }

float PlacedSamples::radiusAbout(const Vec3d& c) const {
  double r = 0.0;
  for (const Vec3f& p : x) r = std::max(r, (p.cast<double>() - c).squaredNorm());
  return float(std::sqrt(r)) + h_;
}

}  // namespace triad
