#include "sim/shot/emitters.h"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "sim/errors.h"
#include "sim/mpm/domain.h"
#include "sim/mpm/sampling.h"

namespace triad {

namespace {

Vec3d toVec(const Vec3Desc& a) { return Vec3d(a[0], a[1], a[2]); }

uint64_t cellKey(const Eigen::Vector3i& c) {
  constexpr uint64_t m = (1u << 21) - 1;
  return ((uint64_t(c.x()) & m) << 42) | ((uint64_t(c.y()) & m) << 21) | (uint64_t(c.z()) & m);
}

// World point x in the frame of the shape as written.
Vec3d asWritten(const Placement& pl, const Pose& pose, const Mat3d& R, const Vec3d& x) {
  return pl.pivot + R.transpose() * (x - pl.pivot - pose.translate);
}

}  // namespace

bool Sink::contains(const Vec3d& p, const Pose& pose, const Mat3d& R) const {
  const Vec3d q = asWritten(placement, pose, R, p);
  if (const auto* b = std::get_if<BoxDesc>(&shape)) {
    for (int d = 0; d < 3; ++d)
      if (q[d] < b->min[d] || q[d] > b->max[d]) return false;
    return true;
  }
  if (const auto* s = std::get_if<SphereDesc>(&shape))
    return (q - toVec(s->center)).squaredNorm() <= s->radius * s->radius;
  Eigen::Vector3i c;
  for (int d = 0; d < 3; ++d) {
    c[d] = int(std::lround((q[d] - lattice_lo[d]) / h));
    if (c[d] < 0 || c[d] >= dims[d]) return false;
  }
  return inside[(size_t(c.x()) * dims.y() + c.y()) * dims.z() + c.z()] != 0;
}

Source makeSource(int object, const ObjectDesc& obj, size_t set, std::vector<Vec3f> sites,
                  const DomainDesc& domain, int ppc, const Vec3d& pivot) {
  Source s;
  s.object = object;
  s.name = obj.name;
  s.set = set;
  s.emit = *obj.emit;
  s.velocity = toVec(obj.velocity);
  if (obj.animation) s.placement.animation = Animation(*obj.animation);
  s.placement.pivot = pivot;
  s.offsets = cellSampleOffsets(ppc);
  const int k = int(std::lround(std::cbrt(double(ppc))));
  s.cube = k * k * k == ppc ? k : 0;
  const Vec3d dmin = toVec(domain.min);
  for (size_t q = 0; q < sites.size(); ++q) {
    const Vec3d g = (sites[q].cast<double>() - dmin) / domain.dx;
    const Eigen::Vector3i cell(int(std::floor(g.x())), int(std::floor(g.y())), int(std::floor(g.z())));
    const Vec3d f = g - cell.cast<double>();
    int j = 0;
    double best = 1e30;
    for (size_t o = 0; o < s.offsets.size(); ++o) {
      const double d = (f - s.offsets[o]).squaredNorm();
      if (d < best) best = d, j = int(o);
    }
    auto [it, fresh] = s.cell_of.try_emplace(cellKey(cell), uint32_t(s.cell_of.size()));
    if (fresh) s.cell_sites.resize(s.cell_sites.size() + s.offsets.size(), -1);
    s.cell_sites[size_t(it->second) * s.offsets.size() + size_t(j)] = int32_t(q);
    s.radius = std::max(s.radius, (sites[q].cast<double>() - pivot).norm());
  }
  s.radius += std::sqrt(3.0) * domain.dx;
  s.sites = std::move(sites);
  return s;
}

// The site whose lattice cube (in cells of the domain) holds g, or -1.
int32_t siteAt(const Source& s, const Vec3d& g) {
  const Eigen::Vector3i cell(int(std::floor(g.x())), int(std::floor(g.y())), int(std::floor(g.z())));
  const auto it = s.cell_of.find(cellKey(cell));
  if (it == s.cell_of.end()) return -1;
  const Vec3d f = g - cell.cast<double>();
  const size_t per_cell = s.offsets.size();
  int j = 0;
  if (s.cube > 0) {
    // A k x k x k lattice: the sub-cell, in the offsets' order (x, y, z).
    Eigen::Vector3i a;
    for (int d = 0; d < 3; ++d) a[d] = std::clamp(int(f[d] * s.cube), 0, s.cube - 1);
    j = (a.x() * s.cube + a.y()) * s.cube + a.z();
  } else {
    double best = 1e30;
    for (size_t o = 0; o < per_cell; ++o) {
      const double d = (f - s.offsets[o]).squaredNorm();
      if (d < best) best = d, j = int(o);
    }
  }
  return s.cell_sites[size_t(it->second) * per_cell + size_t(j)];
}

size_t emitFromSources(std::vector<Source>& sources, std::vector<ParticleSet>& sets,
                       const DomainDesc& domain, double t, uint32_t& next_id,
                       DomainExchange* split) {
  size_t made = 0;
  const Vec3d dmin = toVec(domain.min);
  const double dx = domain.dx;
  for (Source& s : sources) {
    if (!s.activeAt(t)) continue;
    const Pose pose = s.placement.animation.at(t);
    const Mat3d R = pose.rotation.toRotationMatrix();
    const Vec3d centre = s.placement.pivot + pose.translate;
    ParticleSet& set = sets[s.set];
    const double h = dx / std::cbrt(double(s.offsets.size()));
    // A site's region is the lattice cube just downstream of it (shifted half
    // a spacing along the emission velocity's main axis): a particle seeded
    // at the site holds it until it has moved a whole spacing, so the
    // material leaves as dense as it was seeded.
    Vec3d shift = Vec3d::Zero();
    if (s.velocity.squaredNorm() > 0.0) shift = (0.5 * h) * s.velocity / s.velocity.cwiseAbs().maxCoeff();
    // The source's own particles near it (in parallel: most of a set is elsewhere).
    std::vector<uint8_t> near(set.size(), 0);
#pragma omp parallel for schedule(static) if (set.size() > 16384)
    for (int64_t i = 0; i < int64_t(set.size()); ++i)
      near[i] = set.object[i] == s.object &&
                (set.x[i].cast<double>() - centre).squaredNorm() <= s.radius * s.radius;
    // Which sites hold one, and where in its region (the one of lowest id:
    // the same whatever the particles' order).
    std::vector<uint32_t> holder(s.sites.size(), std::numeric_limits<uint32_t>::max());
    std::vector<Vec3d> offset(s.sites.size(), Vec3d::Zero());
    size_t inside = 0;  // the source's own particles in its sites' regions
    for (size_t i = 0; i < set.size(); ++i) {
      if (!near[i]) continue;
      const Vec3d p = asWritten(s.placement, pose, R, set.x[i].cast<double>());
      const int32_t q = siteAt(s, (p - shift - dmin) / dx);
      if (q < 0) continue;
      ++inside;
      if (set.id[i] >= holder[size_t(q)]) continue;
      holder[size_t(q)] = set.id[i];
      offset[size_t(q)] = p - s.sites[size_t(q)].cast<double>();
    }
    if (split) {
      // Every process's survey, in process order: the holder of lowest id
      // wins, whichever process has it.
      struct Held {
        uint32_t id;
        Vec3d offset;
      };
      std::vector<Held> mine(s.sites.size());
      for (size_t q = 0; q < mine.size(); ++q) mine[q] = {holder[q], offset[q]};
      const std::vector<Held> all = allGatherValues(*split, mine);
      const std::vector<uint64_t> counts = allGatherValues(*split, std::vector<uint64_t>{inside});
      inside = 0;
      for (uint64_t c : counts) inside += size_t(c);
      std::fill(holder.begin(), holder.end(), std::numeric_limits<uint32_t>::max());
      for (size_t k = 0; k < all.size(); ++k) {
        const size_t q = k % mine.size();
        if (all[k].id >= holder[q]) continue;
        holder[q] = all[k].id;
        offset[q] = all[k].offset;
      }
    }
    // The shape holds at most as many particles as it has sites: where the
    // flow bunches them (material accelerating under gravity meets the new,
    // slower particles on the grid), empty sites are refilled only up to
    // that count, the most upstream first (where the flow leaves gaps).
    std::vector<uint32_t> empty;
    for (uint32_t q = 0; q < s.sites.size(); ++q)
      if (holder[q] == std::numeric_limits<uint32_t>::max()) empty.push_back(q);
    const size_t room = s.sites.size() > inside ? s.sites.size() - inside : 0;
    if (empty.size() > room) {
      const Vec3d up = -s.velocity;
      std::stable_sort(empty.begin(), empty.end(), [&](uint32_t a, uint32_t b) {
        return s.sites[a].cast<double>().dot(up) > s.sites[b].cast<double>().dot(up);
      });
      empty.resize(room);
      std::sort(empty.begin(), empty.end());
    }
    // New particles at those sites, in site order. A site emptied by flow
    // is seeded where its upstream neighbour would now be: a spacing behind
    // the particle that left it (held by the site downstream), so the
    // spacing stays exact whatever the step.
    const Vec3d v_emit = R * s.velocity;
    const Vec3d step = shift.isZero() ? Vec3d::Zero() : Vec3d(2.0 * shift);
    for (const uint32_t q : empty) {
      if (next_id == std::numeric_limits<uint32_t>::max())
        throw SimulationError("source '" + s.name + "' at t = " + std::to_string(t) +
                              " s: particle ids would pass 2^32");
      Vec3d at = s.sites[q].cast<double>();
      if (!step.isZero()) {
        const int32_t down = siteAt(s, (at + step - dmin) / dx);
        if (down >= 0 && holder[size_t(down)] != std::numeric_limits<uint32_t>::max()) {
          const Vec3d o = offset[size_t(down)];
          // Only along the flow, and well inside the site's own region (at its
          // far edge it would count for the site downstream).
          const double along = std::clamp(o.dot(step) / step.squaredNorm(), 0.0, 0.5);
          at += along * step;
        }
      }
      const Vec3d r = R * (at - s.placement.pivot);
      const Vec3d x = centre + r;
      const Vec3d v = v_emit + pose.velocity + pose.omega.cross(r);
      if (!split || split->ownsPoint(x.cast<float>()))
        set.push(x.cast<float>(), v.cast<float>(), next_id, uint16_t(s.object));
      ++next_id;
      ++s.emitted;
      ++made;
    }
  }
  return made;
}

size_t removeInSinks(std::vector<Sink>& sinks, std::vector<ParticleSet>& sets, double t) {
  if (sinks.empty()) return 0;
  std::vector<Pose> poses;
  std::vector<Mat3d> rotations;
  for (const Sink& k : sinks) {
    poses.push_back(k.placement.animation.at(t));
    rotations.push_back(poses.back().rotation.toRotationMatrix());
  }
  size_t removed = 0;
  for (ParticleSet& set : sets) {
    // Per particle, 1 + the first sink that holds it, or 0.
    std::vector<uint16_t> by(set.size(), 0);
#pragma omp parallel for schedule(static) if (set.size() > 16384)
    for (int64_t i = 0; i < int64_t(set.size()); ++i)
      for (size_t k = 0; k < sinks.size(); ++k)
        if (sinks[k].contains(set.x[i].cast<double>(), poses[k], rotations[k])) {
          by[i] = uint16_t(k + 1);
          break;
        }
    std::vector<uint8_t> gone(set.size(), 0);
    size_t n = 0;
    for (size_t i = 0; i < set.size(); ++i)
      if (by[i]) {
        gone[i] = 1;
        ++sinks[by[i] - 1].removed;
        ++n;
      }
    if (n == 0) continue;
    set.removeFlagged(gone);
    // Give the memory back once most of it is unused.
    if (set.x.capacity() > 2 * set.size() + 256) set.shrinkToFit();
    removed += n;
  }
  return removed;
}

double sourceSpeed(const std::vector<Source>& sources, double t) {
  double s = 0.0;
  for (const Source& src : sources) {
    if (!src.activeAt(t)) continue;
    const Pose p = src.placement.animation.at(t);
    s = std::max(s, src.velocity.norm() + p.velocity.norm() + p.omega.norm() * src.radius);
  }
  return s;
}

}  // namespace triad
