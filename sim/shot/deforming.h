#pragma once
// Deforming colliders: a mesh sequence (one file per frame, the same
// vertices and triangles in each) whose vertices move linearly between
// frame times. The collider is sampled once, at frame 0; each sample rides
// on its nearest triangle from then on: its closest point keeps its
// barycentric coordinates, and its offset from that point and its normal
// keep their coordinates in the triangle's own frame (edge, in-plane
// perpendicular, face normal). No voxelization after the first frame: a
// step costs one pass over the vertices and one over the samples.
#include <array>
#include <cstdint>
#include <functional>
#include <vector>

#include "sim/math.h"
#include "sim/scene_desc.h"

namespace triad {

class DeformingSurface {
 public:
  // `frames[k]`: vertex positions at t = k / fps (world, before any
  // animation); `triangles` index them. Binds the samples x (with outward
  // normals n, at frame 0) to their nearest triangles, searching within
  // `reach` of each sample (at least its distance to the surface).
  DeformingSurface(std::vector<std::vector<Vec3f>> frames,
                   std::vector<std::array<uint32_t, 3>> triangles, double fps,
                   const std::vector<Vec3f>& x, const std::vector<Vec3f>& n, double reach);

  // Vertex positions and velocities at time t (held after the last frame).
  void vertices(double t, std::vector<Vec3d>& x, std::vector<Vec3d>& v) const;
  // Every sample at time t, then moved by a rigid motion: world position
  // centre + A (p - pivot), velocity A v + lin + omega x (A (p - pivot)),
  // normal A n; written to pos, vel, nrm from index `first` on. Each
  // triangle's frame is formed once for all its samples.
  void placeAll(double t, const Mat3d& A, const Vec3d& pivot, const Vec3d& centre,
                const Vec3d& lin, const Vec3d& omega, std::vector<Vec3f>& pos,
                std::vector<Vec3f>& vel, std::vector<Vec3f>& nrm, size_t first) const;

  // The fastest vertex speed at time t (for the step's CFL limit).
  double maxSpeed(double t) const;
  size_t samples() const { return tri_.size(); }
  const std::vector<std::array<uint32_t, 3>>& triangles() const { return triangles_; }
  int frameCount() const { return int(frames_.size()); }
  // Mean distance (m) from a sample as bound to where it was sampled: 0 up
  // to round-off; for tests.
  double bindingError(const std::vector<Vec3f>& x) const;

 private:
  std::vector<std::vector<Vec3f>> frames_;
  std::vector<std::array<uint32_t, 3>> triangles_;
  double fps_;
  std::vector<double> max_speed_;  // per frame interval
  std::vector<uint32_t> tri_;     // per sample: its triangle
  std::vector<Vec3f> bary_;       // per sample: barycentric coordinates of its closest point
  std::vector<Vec3f> offset_;     // per sample: x - closest point, in the triangle's frame
  std::vector<Vec3f> normal_;     // per sample: its normal, in the triangle's frame
};

// A deforming collider's samples as placed now (world): positions,
// velocities, normals, and a lookup of them by the cell of a regular grid
// of the sample spacing over their bounding box (each cell keeps its first
// sample). What bodies, elastic solids and particles that
// touch the collider query: its frame-0 lattice no longer matches it.
struct PlacedSamples {
  double time = -1.0;  // the time they were placed for
  std::vector<Vec3f> x, v, n;

  // Rebuilds the lookup from the samples of x whose distance phi is above
  // `deepest` (contacts and the push-out need the surface layer only), in
  // cells of size h.
  void index(float h, const std::vector<float>& phi, float deepest);
  // The sample kept in the cell that holds p, or -1 (none, or outside).
  int at(const Vec3d& p) const;
  // Calls f(q) for the sample kept in each of the 27 cells around p's.
  template <class F>
  void around(const Vec3d& p, F&& f) const {
    if (cells_.empty()) return;
    const Eigen::Vector3i c = cellOf(p);
    for (int i = -1; i <= 1; ++i)
      for (int j = -1; j <= 1; ++j)
        for (int k = -1; k <= 1; ++k) {
          const int q = kept(c + Eigen::Vector3i(i, j, k));
          if (q >= 0) f(q);
        }
  }
  // Largest distance of any sample from c, plus h: a bounding sphere.
  float radiusAbout(const Vec3d& c) const;

 private:
  Eigen::Vector3i cellOf(const Vec3d& p) const;
  int kept(const Eigen::Vector3i& c) const;
  Vec3d origin_ = Vec3d::Zero();  // centre of cell (0, 0, 0)
  float h_ = 1.0f;
  Eigen::Vector3i dims_ = Eigen::Vector3i::Zero();
  std::vector<int32_t> cells_;
  std::vector<uint32_t> filled_;  // cells holding a sample, cleared at the next index()
};

// A mesh sequence as loaded: the shape of its frame 0 (one file, to
// sample), and every frame's vertex positions (placed: scale, rotation,
// translation) over one set of triangles.
struct MeshFrames {
  MeshDesc first;
  std::vector<std::vector<Vec3f>> positions;  // frames 0..count
  std::vector<std::array<uint32_t, 3>> triangles;
};

// Loads frames 0..frames of a sequence (sequence_digits > 0). Provided by
// import/; throws InputError naming the first file that is missing,
// unreadable or of other vertices or triangles than frame 0's.
using SequenceLoader = std::function<MeshFrames(const MeshDesc& sequence, int frames)>;

// Closest point to p on triangle (a, b, c), as barycentric coordinates.
Vec3d closestOnTriangle(const Vec3d& p, const Vec3d& a, const Vec3d& b, const Vec3d& c);

}  // namespace triad
