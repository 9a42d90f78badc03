#include "import/mesh_sampler.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "sim/errors.h"

namespace triad {

namespace {

Vec3d toVec(const Vec3Desc& a) { return Vec3d(a[0], a[1], a[2]); }

std::string exact(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%a", v);
  return buf;
}

std::string placementKey(const MeshDesc& m) {
  std::error_code ec;
  const std::string& given = m.resolved_path.empty() ? m.path : m.resolved_path;
  std::filesystem::path p = std::filesystem::weakly_canonical(given, ec);
  std::string key = (ec ? given : p.string());
  // The file's size and time stamp: a file rewritten in between is read again.
  std::error_code ec2;
  const auto size = std::filesystem::file_size(given, ec2);
  if (!ec2) key += "|" + std::to_string(size);
  const auto stamp = std::filesystem::last_write_time(given, ec2);
  if (!ec2) key += "|" + std::to_string(stamp.time_since_epoch().count());
  key += "|" + exact(m.scale);
  for (double v : m.rotate_deg) key += "|" + exact(v);
  for (double v : m.translate) key += "|" + exact(v);
  return key;
}

std::string fmt(const Vec3d& v) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "[%g, %g, %g]", v.x(), v.y(), v.z());
  return buf;
}

// Throws when the mesh's bounds and the domain do not overlap with positive volume.
void requireOverlap(const MeshAsset& a, const DomainDesc& domain) {
  Vec3d lo, hi;
  a.load.mesh.bounds(lo, hi);
  const Vec3d dlo = toVec(domain.min), dhi = toVec(domain.max);
  if ((hi.cwiseMin(dhi) - lo.cwiseMax(dlo)).minCoeff() <= 0.0)
    throw InputError(a.file, "the mesh lies entirely outside the domain: after scale, rotate_deg "
                             "and translate its bounds are " + fmt(lo) + " to " + fmt(hi) +
                                 ", the domain is " + fmt(dlo) + " to " + fmt(dhi));
}

// The distance field a solid's samples read: the domain's (voxel_ratio dx,
// shared with MPM objects of the same mesh) unless the samples are finer;
// then one at the sample spacing, with the samples on its voxel centres.
std::shared_ptr<const MeshAsset> solidAsset(MeshCache& cache, const MeshDesc& mesh,
                                            const DomainDesc& domain, double voxel_ratio,
                                            double h) {
  if (h >= voxel_ratio * domain.dx) return cache.get(mesh, domain, voxel_ratio);
  return cache.get(mesh, h, toVec(domain.min) + Vec3d::Constant(0.5 * h));
}

}  // namespace

std::shared_ptr<const MeshAsset> MeshCache::get(const MeshDesc& mesh, const DomainDesc& domain,
                                                double voxel_ratio) {
  const double h = voxel_ratio * domain.dx;
  return get(mesh, h, toVec(domain.min) + Vec3d::Constant(0.5 * h));
}

std::shared_ptr<const MeshAsset> MeshCache::get(const MeshDesc& mesh, double voxel_size,
                                                const Vec3d& origin) {
  const std::string pkey = placementKey(mesh);
  // Origins that differ by whole voxels give the same grid.
  std::string vkey = pkey + "|voxel " + exact(voxel_size);
  for (int d = 0; d < 3; ++d) {
    const double o = origin[d] - voxel_size * std::floor(origin[d] / voxel_size);
    vkey += "|" + exact(std::round(o / voxel_size * 1e9) / 1e9);
  }
  // One lock around load and voxelization: a run builds its world serially,
  // and this keeps the counts exact.
  std::lock_guard<std::mutex> lock(mutex_);
  if (auto it = assets_.find(vkey); it != assets_.end()) return it->second;
  std::shared_ptr<const MeshLoadResult>& loaded = loaded_[pkey];
  const std::string file = mesh.resolved_path.empty() ? mesh.path : mesh.resolved_path;
  if (!loaded) {
    try {
      loaded = std::make_shared<const MeshLoadResult>(loadMesh(mesh));
    } catch (...) {
      loaded_.erase(pkey);
      throw;
    }
    ++loads_;
    for (const std::string& w : loaded->warnings) warnings_.push_back({file, w});
  }
  auto asset = std::make_shared<MeshAsset>();
  asset->file = file;
  asset->load = *loaded;
  asset->volume = std::make_shared<const MeshVolume>(loaded->mesh, voxel_size, origin);
  ++voxelizations_;
  assets_[vkey] = asset;
  return asset;
}

size_t MeshCache::loads() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return loads_;
}
size_t MeshCache::voxelizations() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return voxelizations_;
}
std::vector<MeshWarning> MeshCache::warnings() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return warnings_;
}

MeshSampler makeMeshSampler(std::shared_ptr<MeshCache> cache, double voxel_ratio) {
  return [cache, voxel_ratio](const MeshDesc& mesh, const DomainDesc& domain, int ppc) {
    const auto asset = cache->get(mesh, domain, voxel_ratio);
    requireOverlap(*asset, domain);
    const MeshVolume& vol = *asset->volume;
    const Vec3d dmin = toVec(domain.min), dmax = toVec(domain.max);
    const double dx = domain.dx;
    const Vec3d lo = vol.boundsMin().cwiseMax(dmin), hi = vol.boundsMax().cwiseMin(dmax);
    Eigen::Vector3i c0, c1;
    for (int d = 0; d < 3; ++d) {
      c0[d] = static_cast<int>(std::floor((lo[d] - dmin[d]) / dx));
      c1[d] = static_cast<int>(std::ceil((hi[d] - dmin[d]) / dx));
    }
    const std::vector<Vec3d> offsets = cellSampleOffsets(ppc);
    const int nx = std::max(0, c1.x() - c0.x());
    // One x-slab of cells per task; slabs are concatenated in order, so the
    // result is the same as the serial loop (i, j, k, offset) of primitives.
    std::vector<std::vector<Vec3f>> slabs(nx);
#pragma omp parallel
    {
      std::vector<Vec3d> cand;
      std::vector<float> sd;
#pragma omp for schedule(dynamic, 1)
      for (int s = 0; s < nx; ++s) {
        const int i = c0.x() + s;
        cand.clear();
        for (int j = c0.y(); j < c1.y(); ++j)
          for (int k = c0.z(); k < c1.z(); ++k)
            for (const Vec3d& o : offsets) {
              const Vec3d p = dmin + dx * (Vec3d(i, j, k) + o);
              if ((p - dmin).minCoeff() < 0.0 || (dmax - p).minCoeff() <= 0.0) continue;
              cand.push_back(p);
            }
        sd.resize(cand.size());
        vol.signedDistances(cand.data(), cand.size(), sd.data());
        for (size_t q = 0; q < cand.size(); ++q)
          if (sd[q] < 0.0f) slabs[s].push_back(cand[q].cast<float>());
      }
    }
    std::vector<Vec3f> out;
    size_t total = 0;
    for (const auto& s : slabs) total += s.size();
    out.reserve(total);
    for (const auto& s : slabs) out.insert(out.end(), s.begin(), s.end());
    return out;
  };
}

CollisionSamples sampleCollision(const ShapeDesc& shape, const DomainDesc& domain, double density,
                                 MeshCache& cache, double voxel_ratio, double spacing) {
  const double h = spacing > 0.0 ? spacing : 0.5 * domain.dx;
  const Vec3d dmin = toVec(domain.min), dmax = toVec(domain.max);
  CollisionSamples out;
  out.spacing = h;
  out.volume_per_sample = static_cast<float>(h * h * h);
  out.mass_per_sample = static_cast<float>(density * h * h * h);

  Vec3d lo, hi;
  std::shared_ptr<const MeshAsset> asset;
  if (const auto* b = std::get_if<BoxDesc>(&shape)) {
    lo = toVec(b->min);
    hi = toVec(b->max);
  } else if (const auto* s = std::get_if<SphereDesc>(&shape)) {
    lo = toVec(s->center) - Vec3d::Constant(s->radius);
    hi = toVec(s->center) + Vec3d::Constant(s->radius);
  } else {
    asset = solidAsset(cache, std::get<MeshDesc>(shape), domain, voxel_ratio, h);
    requireOverlap(*asset, domain);
    lo = asset->volume->boundsMin();
    hi = asset->volume->boundsMax();
  }
  if (!asset && (hi.cwiseMin(dmax) - lo.cwiseMax(dmin)).minCoeff() <= 0.0)
    throw InputError("", "the shape lies entirely outside the domain");

  // Lattice points dmin + h (n + 1/2), n over the shape's bounds.
  Eigen::Vector3i n0, n1;
  for (int d = 0; d < 3; ++d) {
    n0[d] = static_cast<int>(std::floor((lo[d] - dmin[d]) / h - 0.5));
    n1[d] = static_cast<int>(std::ceil((hi[d] - dmin[d]) / h - 0.5)) + 1;
  }
  std::vector<Vec3d> cand;
  for (int i = n0.x(); i < n1.x(); ++i)
    for (int j = n0.y(); j < n1.y(); ++j)
      for (int k = n0.z(); k < n1.z(); ++k) cand.push_back(dmin + h * (Vec3d(i, j, k) + Vec3d::Constant(0.5)));

  if (asset) {
    const std::vector<float> sd = asset->volume->signedDistances(cand);
    std::vector<Vec3d> kept;
    for (size_t q = 0; q < cand.size(); ++q)
      if (sd[q] < 0.0f) kept.push_back(cand[q]);
    out.normal = asset->volume->gradients(kept);
    out.phi = asset->volume->signedDistances(kept);
    for (const Vec3d& p : kept) out.x.push_back(p.cast<float>());
    return out;
  }
  for (const Vec3d& p : cand) {
    Vec3d n;
    if (const auto* b = std::get_if<BoxDesc>(&shape)) {
      bool in = true;
      for (int d = 0; d < 3; ++d) in = in && p[d] >= b->min[d] && p[d] < b->max[d];
      if (!in) continue;
      out.phi.push_back(static_cast<float>(boxDistance(toVec(b->min), toVec(b->max), p, &n)));
    } else {
      const auto& s = std::get<SphereDesc>(shape);
      const Vec3d r = p - toVec(s.center);
      if (r.squaredNorm() >= s.radius * s.radius) continue;
      const double len = r.norm();
      n = len > 0 ? Vec3d(r / len) : Vec3d(0, 1, 0);
      out.phi.push_back(static_cast<float>(len - s.radius));
    }
    out.x.push_back(p.cast<float>());
    out.normal.push_back(n.cast<float>());
  }
  return out;
}

SolidSampler makeSolidSampler(std::shared_ptr<MeshCache> cache, double voxel_ratio) {
  return [cache, voxel_ratio](const ShapeDesc& shape, const DomainDesc& domain, double density,
                              double spacing) {
    SolidSamples out;
    out.samples = sampleCollision(shape, domain, density, *cache, voxel_ratio, spacing);
    if (const auto* m = std::get_if<MeshDesc>(&shape)) {
      // The same load the samples came from (cached).
      const TriangleMesh& mesh =
          solidAsset(*cache, *m, domain, voxel_ratio, out.samples.spacing)->load.mesh;
      for (const Vec3d& p : mesh.positions) out.surface.vertices.push_back(p.cast<float>());
      for (const auto& t : mesh.triangles)
        out.surface.triangles.push_back({uint32_t(t[0]), uint32_t(t[1]), uint32_t(t[2])});
    } else {
      out.surface = primitiveSurface(shape);
    }
    return out;
  };
}

MeshFrames loadMeshSequence(const MeshDesc& sequence, int frames) {
  MeshFrames out;
  out.first = sequence;
  out.first.sequence_digits = 0;
  out.first.resolved_path =
      sequenceFrame(sequence.resolved_path, sequence.sequence_digits, 0);
  out.first.path = sequenceFrame(sequence.path, sequence.sequence_digits, 0);
  for (int f = 0; f <= frames; ++f) {
    MeshDesc one = out.first;
    one.resolved_path = sequenceFrame(sequence.resolved_path, sequence.sequence_digits, f);
    const TriangleMesh mesh = loadMesh(one).mesh;  // InputError names the file
    if (f == 0)
      for (const auto& t : mesh.triangles)
        out.triangles.push_back({uint32_t(t[0]), uint32_t(t[1]), uint32_t(t[2])});
    bool same = mesh.triangles.size() == out.triangles.size() &&
                (f == 0 || mesh.positions.size() == out.positions[0].size());
    for (size_t t = 0; same && t < mesh.triangles.size(); ++t)
      for (int k = 0; k < 3; ++k) same = same && uint32_t(mesh.triangles[t][k]) == out.triangles[t][k];
    if (!same)
      throw InputError(one.resolved_path,
                       "a mesh sequence's frames must all have frame 0's vertices and triangles (" +
                           std::to_string(f == 0 ? 0 : out.positions[0].size()) + " and " +
                           std::to_string(out.triangles.size()) + " in " +
                           out.first.resolved_path + "), but frame " + std::to_string(f) +
                           " has " + std::to_string(mesh.positions.size()) + " vertices and " +
                           std::to_string(mesh.triangles.size()) +
                           " triangles (after merging coincident vertices), or others");
    std::vector<Vec3f> p;
    p.reserve(mesh.positions.size());
    for (const Vec3d& v : mesh.positions) p.push_back(v.cast<float>());
    out.positions.push_back(std::move(p));
  }
  return out;
}

World buildSceneWorld(const SceneDesc& scene, std::shared_ptr<MeshCache> cache,
                      ParticleShare* share) {
  if (!cache) cache = std::make_shared<MeshCache>();
  return buildWorld(scene, makeMeshSampler(cache), makeSolidSampler(cache), loadMeshSequence,
                    share);
}

}  // namespace triad
