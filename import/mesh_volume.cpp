// The only translation unit of import/ that includes OpenVDB's tools
// (about 11 s and 0.9 GB to compile).
#include "import/mesh_volume.h"

#include <cmath>
#include <limits>
#include <mutex>

#include <openvdb/openvdb.h>
#include <openvdb/tools/Interpolation.h>
#include <openvdb/tools/MeshToVolume.h>

#include "import/mesh_loader.h"

namespace triad {

struct MeshVolume::Impl {
  openvdb::FloatGrid::Ptr grid;
};

namespace {

// Trilinear lookup in index space through an accessor.
template <class Accessor>
double lookup(const Accessor& acc, const openvdb::math::Transform& xf, const Vec3d& p) {
  const openvdb::Vec3d ijk = xf.worldToIndex(openvdb::Vec3d(p.x(), p.y(), p.z()));
  float v = 0.0f;
  openvdb::tools::BoxSampler::sample(acc, ijk, v);
  return v;
}

template <class Accessor>
Vec3d normalAt(const Accessor& acc, const openvdb::math::Transform& xf, double h, const Vec3d& p) {
  Vec3d g;
  for (int d = 0; d < 3; ++d) {
    Vec3d e = Vec3d::Zero();
    e[d] = h;
    g[d] = lookup(acc, xf, p + e) - lookup(acc, xf, p - e);
  }
  const double n = g.norm();
  return n > 0 ? Vec3d(g / n) : Vec3d(0, 1, 0);
}

}  // namespace

MeshVolume::MeshVolume(const TriangleMesh& mesh, double voxel_size, const Vec3d& origin,
                       double exterior_band)
    : impl_(std::make_unique<Impl>()), voxel_size_(voxel_size) {
  static std::once_flag once;
  std::call_once(once, [] { openvdb::initialize(); });
  mesh.bounds(lo_, hi_);
  auto xf = openvdb::math::Transform::createLinearTransform(voxel_size);
  xf->postTranslate(openvdb::Vec3d(origin.x(), origin.y(), origin.z()));
  // Single-precision index coordinates and the interrupter overload match
  // the instantiation that libopenvdb ships (declared extern in the header),
  // so this file does not instantiate the mesh-to-volume templates: 60 s of
  // compiling at -O2 and 160 s under the sanitizers. A float holds index
  // coordinates to 1e-4 voxels for meshes a thousand voxels across.
  std::vector<openvdb::Vec3s> pts;
  pts.reserve(mesh.positions.size());
  for (const Vec3d& p : mesh.positions) {
    const Vec3d q = (p - origin) / voxel_size;
    pts.emplace_back(float(q.x()), float(q.y()), float(q.z()));
  }
  std::vector<openvdb::Vec3I> tris;
  tris.reserve(mesh.triangles.size());
  for (const auto& t : mesh.triangles) tris.emplace_back(t[0], t[1], t[2]);
  openvdb::tools::QuadAndTriangleDataAdapter<openvdb::Vec3s, openvdb::Vec3I> adapter(pts, tris);
  openvdb::util::NullInterrupter interrupter;
  impl_->grid = openvdb::tools::meshToVolume<openvdb::FloatGrid>(
      interrupter, adapter, *xf, float(exterior_band), std::numeric_limits<float>::max(), 0,
      nullptr);
  impl_->grid->setGridClass(openvdb::GRID_LEVEL_SET);
  impl_->grid->setName("sdf");
}

MeshVolume::~MeshVolume() = default;

double MeshVolume::signedDistance(const Vec3d& p) const {
  auto acc = impl_->grid->getConstAccessor();
  return lookup(acc, impl_->grid->transform(), p);
}

Vec3d MeshVolume::gradient(const Vec3d& p) const {
  auto acc = impl_->grid->getConstAccessor();
  return normalAt(acc, impl_->grid->transform(), voxel_size_, p);
}

std::vector<float> MeshVolume::signedDistances(const std::vector<Vec3d>& points) const {
  std::vector<float> out(points.size());
  const long n = static_cast<long>(points.size());
#pragma omp parallel
  {
    auto acc = impl_->grid->getConstAccessor();
    const auto& xf = impl_->grid->transform();
#pragma omp for schedule(static, 4096)
    for (long i = 0; i < n; ++i) out[i] = static_cast<float>(lookup(acc, xf, points[i]));
  }
  return out;
}

void MeshVolume::signedDistances(const Vec3d* points, size_t n, float* out) const {
  auto acc = impl_->grid->getConstAccessor();
  const auto& xf = impl_->grid->transform();
  for (size_t i = 0; i < n; ++i) out[i] = static_cast<float>(lookup(acc, xf, points[i]));
}

std::vector<Vec3f> MeshVolume::gradients(const std::vector<Vec3d>& points) const {
  std::vector<Vec3f> out(points.size());
  const long n = static_cast<long>(points.size());
#pragma omp parallel
  {
    auto acc = impl_->grid->getConstAccessor();
    const auto& xf = impl_->grid->transform();
#pragma omp for schedule(static, 4096)
    for (long i = 0; i < n; ++i) out[i] = normalAt(acc, xf, voxel_size_, points[i]).cast<float>();
  }
  return out;
}

size_t MeshVolume::activeVoxels() const { return impl_->grid->activeVoxelCount(); }
size_t MeshVolume::memoryBytes() const { return impl_->grid->memUsage(); }
std::shared_ptr<void> MeshVolume::nativeGrid() const { return impl_->grid; }

}  // namespace triad
