#include "export/particle_level_set.h"

#include <openvdb/io/Stream.h>
#include <openvdb/tools/FastSweeping.h>
#include <openvdb/tools/ParticlesToLevelSet.h>
#include <openvdb/tools/Prune.h>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
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

SurfaceSampling combinedSampling(const std::vector<SurfaceSampling>& each) {
  SurfaceSampling s;
  for (const SurfaceSampling& e : each) {
    if (!(e.radius > 0.0)) continue;
    const bool first = !(s.radius > 0.0);
    s.radius = std::max(s.radius, e.radius);
    s.voxel_size = first ? e.voxel_size : std::min(s.voxel_size, e.voxel_size);
    s.erosion = first ? e.erosion : std::min(s.erosion, e.erosion);
  }
  if (!(s.radius > 0.0) && !each.empty()) s.voxel_size = each.front().voxel_size;
  return s;
}

namespace {

// The spheres of `world`'s particles of `material` rasterised by
// ParticlesToLevelSet: distances to the nearest sphere near the spheres'
// surfaces, not yet pruned.
openvdb::FloatGrid::Ptr rasterOfSpheres(const World& world, const SurfaceSampling& s, int material,
                                        double half_width) {
  openvdb::FloatGrid::Ptr ls =
      openvdb::createLevelSet<openvdb::FloatGrid>(s.voxel_size, half_width);
  const ParticleSpheres spheres(world, material);
  if (spheres.size() == 0) return ls;
  openvdb::tools::ParticlesToLevelSet<openvdb::FloatGrid> raster(*ls);
  raster.setRmin(1.5);
  raster.rasterizeSpheres(spheres);
  return ls;
}

// From the union's raster (pruned as a level set), the true distance from
// its zero crossing over its active voxels (inside the union they hold
// distances to the nearest sphere only), by fast sweeping, cut to the band.
// levelSetRebuild gives the same band through a mesh five times slower
// (11.6 s against 2.2 s on a splashing 216k dam break).
openvdb::FloatGrid::Ptr bandOfRaster(const openvdb::FloatGrid& raster, const SurfaceSampling& s,
                                     double half_width) {
  openvdb::FloatGrid::Ptr sdf = openvdb::tools::sdfToSdf(raster, 0.0f, /*nIter=*/1);
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

// Adds raster b into raster a as ParticlesToLevelSet would have drawn b's
// spheres into a: a voxel inside any sphere's inner band is inactive at
// -background; any other voxel a sphere reached holds the least distance,
// active. Both are unpruned rasters (leaf voxels only). OpenVDB's csgUnion
// gives the same values but other active states inside, and so other bytes
// than one process drawing every sphere.
void uniteRasters(openvdb::FloatTree& a, const openvdb::FloatTree& b) {
  for (auto leaf = b.cbeginLeaf(); leaf; ++leaf) {
    openvdb::FloatTree::LeafNodeType* into = a.touchLeaf(leaf->origin());
    for (openvdb::Index n = 0; n < openvdb::FloatTree::LeafNodeType::SIZE; ++n) {
      const float bv = leaf->getValue(n), av = into->getValue(n);
      const bool b_on = leaf->isValueOn(n), a_on = into->isValueOn(n);
      if (!b_on && bv < 0.0f) {
        into->setValueOff(n, bv);  // inside b's spheres
      } else if (b_on && (a_on || av >= 0.0f) && (!a_on || bv < av)) {
        into->setValueOn(n, bv);  // nearer than a's, and not inside a's spheres
      }
    }
  }
}

}  // namespace

openvdb::FloatGrid::Ptr particleLevelSet(const World& world, const SurfaceSampling& s, int material,
                                         double half_width) {
  openvdb::FloatGrid::Ptr raster = rasterOfSpheres(world, s, material, half_width);
  if (ParticleSpheres(world, material).size() == 0) return raster;
  openvdb::tools::pruneLevelSet(raster->tree());
  return bandOfRaster(*raster, s, half_width);
}

std::string sphereUnionPart(const World& world, const SurfaceSampling& s, int material,
                            double half_width) {
  openvdb::initialize();
  std::ostringstream out(std::ios::binary);
  openvdb::io::Stream(out).write({rasterOfSpheres(world, s, material, half_width)});
  return out.str();
}

openvdb::FloatGrid::Ptr particleLevelSet(const SphereUnionParts& parts, double half_width) {
  openvdb::initialize();
  openvdb::FloatGrid::Ptr raster;
  for (const std::string& part : parts.parts) {
    std::istringstream in(part, std::ios::binary);
    openvdb::io::Stream stream(in);
    openvdb::FloatGrid::Ptr grid =
        openvdb::gridPtrCast<openvdb::FloatGrid>(stream.getGrids()->at(0));
    if (!grid) throw std::runtime_error("a process's part of a surface is not a float grid");
    if (!raster)
      raster = grid;
    else
      uniteRasters(raster->tree(), grid->tree());
  }
  // No particle anywhere: the empty level set of one process without any.
  if (!raster || !(parts.sampling.radius > 0.0))
    return openvdb::createLevelSet<openvdb::FloatGrid>(parts.sampling.voxel_size, half_width);
  openvdb::tools::pruneLevelSet(raster->tree());
  return bandOfRaster(*raster, parts.sampling, half_width);
}

}  // namespace triad
