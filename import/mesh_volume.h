#pragma once
// A signed distance field of a triangle mesh (an OpenVDB FloatGrid level
// set behind a pimpl: OpenVDB headers stay in mesh_volume.cpp, the one
// translation unit of import/ that includes OpenVDB's tools).
//
// Inside/outside: OpenVDB's mesh-to-volume conversion classifies voxels by a
// flood fill from the outside through voxels the surface does not cross, so
// the sign does not depend on triangle winding and tolerates
// self-intersections, overlapping shells and unmerged vertices (the
// triangles still meet). It needs a closed surface: loadMesh closes holes
// first (repairMesh). The interior is filled completely with distances (not
// only a narrow band), so interior samples get normals from the gradient.
#include <memory>
#include <vector>

#include "sim/math.h"

namespace triad {

struct TriangleMesh;

class MeshVolume {
 public:
  // `voxel_size` in metres; voxel centres at `origin` + voxel_size * n
  // (n integer); `exterior_band` voxels of distance outside the surface
  // (beyond: +exterior_band * voxel_size). The interior is full.
  //
  // Align the voxel centres with the points you sample: there the value is
  // OpenVDB's distance to the nearest triangle, exact in the narrow band.
  // Between centres, trilinear interpolation rounds convex edges and
  // corners off by up to ~0.3 voxel, which loses samples near box edges.
  MeshVolume(const TriangleMesh& mesh, double voxel_size, const Vec3d& origin = Vec3d::Zero(),
             double exterior_band = 3.0);
  ~MeshVolume();
  MeshVolume(const MeshVolume&) = delete;
  MeshVolume& operator=(const MeshVolume&) = delete;

  // Trilinear interpolation of the distance field (negative inside).
  double signedDistance(const Vec3d& p) const;
  // Outward unit normal: normalized central-difference gradient of the
  // interpolated field (step: one voxel). (0, 1, 0) where it vanishes.
  Vec3d gradient(const Vec3d& p) const;
  // Batch versions, parallel (OpenMP), each thread with its own accessor.
  std::vector<float> signedDistances(const std::vector<Vec3d>& points) const;
  std::vector<Vec3f> gradients(const std::vector<Vec3d>& points) const;
  // Serial batch on the calling thread (one accessor): for callers that
  // parallelize themselves.
  void signedDistances(const Vec3d* points, size_t n, float* out) const;

  double voxelSize() const { return voxel_size_; }
  // Bounds of the mesh's vertices (the zero level set lies within).
  const Vec3d& boundsMin() const { return lo_; }
  const Vec3d& boundsMax() const { return hi_; }
  size_t activeVoxels() const;
  size_t memoryBytes() const;
  // The underlying openvdb::FloatGrid::Ptr, type-erased, for code that
  // includes OpenVDB itself (e.g. a VDB exporter): cast with
  // std::static_pointer_cast<openvdb::FloatGrid>.
  std::shared_ptr<void> nativeGrid() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  double voxel_size_;
  Vec3d lo_, hi_;
};

}  // namespace triad
