#include "export/particle_level_set.h"

#include <openvdb/tools/FastSweeping.h>
#include <openvdb/tools/ParticlesToLevelSet.h>
#include <openvdb/tools/Prune.h>

#include <algorithm>
#include <cmath>
#include <vector>

namespace triad {

namespace {

bool wanted(const ParticleSet& set, int material) {
  return set.size() > 0 && (material < 0 || set.material == material);
}

// The mean height of the spheres' union over a face of lattice-sampled
// material, in sampling spacings: spheres of radius sqrt(3)/2 centred half a
// spacing inside the face rise 0 to 0.366 above it, 0.261 on average
// (integrated over the lattice's cell). Eroding by the mean, not the peak,
// keeps a smoothed surface's volume the material's.
constexpr double kFaceBump = 0.261;

double setRadius(const ParticleSet& set) {
  return std::cbrt(double(set.volume)) * std::sqrt(3.0) * 0.5;
}

// Particles as ParticlesToLevelSet reads them: positions and per-set radius.
class ParticleSpheres {
 public:
  using PosType = openvdb::Vec3R;
  ParticleSpheres(const World& world, int material) {
    for (const ParticleSet& set : world.sets) {
      if (!wanted(set, material)) continue;
      sets_.push_back(&set);
      radius_.push_back(setRadius(set));
      start_.push_back(size_);
      size_ += set.size();
    }
  }
  size_t size() const { return size_; }
  void getPos(size_t n, openvdb::Vec3R& xyz) const {
    const size_t s = setOf(n);
    const Vec3f& x = sets_[s]->x[n - start_[s]];
    xyz = openvdb::Vec3R(x.x(), x.y(), x.z());
  }
  void getPosRad(size_t n, openvdb::Vec3R& xyz, openvdb::Real& r) const {
    getPos(n, xyz);
    r = radius_[setOf(n)];
  }

 private:
  size_t setOf(size_t n) const {
    return size_t(std::upper_bound(start_.begin(), start_.end(), n) - start_.begin()) - 1;
  }
  std::vector<const ParticleSet*> sets_;
  std::vector<size_t> start_;
  std::vector<double> radius_;
  size_t size_ = 0;
};

}  // namespace

SurfaceSampling surfaceSampling(const World& world, double density_voxel_size, int material) {
  SurfaceSampling s;
  double r_min = 0.0, erosion = 0.0;
  for (const ParticleSet& set : world.sets) {
    if (!wanted(set, material)) continue;
    const double r = setRadius(set), e = kFaceBump * std::cbrt(double(set.volume));
    s.radius = std::max(s.radius, r);
    r_min = r_min > 0.0 ? std::min(r_min, r) : r;
    erosion = erosion > 0.0 ? std::min(erosion, e) : e;
  }
  s.voxel_size = r_min > 0.0 ? std::min(density_voxel_size, 0.5 * r_min) : density_voxel_size;
  s.erosion = erosion;
  return s;
}

openvdb::FloatGrid::Ptr particleLevelSet(const World& world, const SurfaceSampling& s, int material,
                                         double half_width) {
  openvdb::FloatGrid::Ptr ls =
      openvdb::createLevelSet<openvdb::FloatGrid>(s.voxel_size, half_width);
  const ParticleSpheres spheres(world, material);
  if (spheres.size() == 0) return ls;

  // Rasterise the spheres' union, then solve for the true distance from its
  // zero crossing over the union's active voxels (inside the union they hold
  // distances to the nearest sphere only) by fast sweeping, and keep the
  // band. levelSetRebuild gives the same band through a mesh five times
  // slower (11.6 s against 2.2 s on a splashing 216k dam break).
  openvdb::tools::ParticlesToLevelSet<openvdb::FloatGrid> raster(*ls);
  raster.setRmin(1.5);
  raster.rasterizeSpheres(spheres);
  raster.finalize(/*prune=*/true);
  openvdb::FloatGrid::Ptr sdf = openvdb::tools::sdfToSdf(*ls, 0.0f, /*nIter=*/1);
  const float band = float(half_width * s.voxel_size);
  for (auto it = sdf->tree().beginValueOn(); it; ++it) {
    if (*it < -band) {
      it.setValue(-band);
      it.setValueOff();
    } else if (*it > band) {
      it.setValue(band);
      it.setValueOff();
    }
  }
  sdf->tree().root().setBackground(band, /*updateChildNodes=*/true);
  openvdb::tools::pruneLevelSet(sdf->tree());
  sdf->setGridClass(openvdb::GRID_LEVEL_SET);
  return sdf;
}

}  // namespace triad
