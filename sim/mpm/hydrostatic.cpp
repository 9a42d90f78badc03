#include "sim/mpm/hydrostatic.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <variant>

#include "sim/world.h"

namespace triad {

WaterLevels::WaterLevels(const DomainDesc& domain, const Vec3d& gravity, double spacing)
    : dx_(domain.dx), half_spacing_(0.5 * spacing) {
  g_ = gravity.norm();
  if (g_ > 0.0) up_ = -gravity / g_;
  origin_ = Vec3d(domain.min[0], domain.min[1], domain.min[2]);
}

WaterLevels::Cell WaterLevels::cellOf(const Vec3f& x) const {
  Cell c;
  for (int d = 0; d < 3; ++d) c[size_t(d)] = int32_t(std::floor((double(x[d]) - origin_[d]) / dx_));
  return c;
}

void WaterLevels::add(const Vec3f& x) {
  const auto [it, inserted] = index_.try_emplace(cellOf(x), uint32_t(highest_.size()));
  const float h = float(heightOf(x));
  if (inserted)
    highest_.push_back(h);
  else
    highest_[it->second] = std::max(highest_[it->second], h);
}

void WaterLevels::finish() {
  // Union-find over the cells, joined across faces.
  std::vector<uint32_t> parent(highest_.size());
  std::iota(parent.begin(), parent.end(), 0u);
  const auto root = [&](uint32_t i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  };
  for (const auto& [cell, i] : index_)
    for (int d = 0; d < 3; ++d) {
      Cell next = cell;
      ++next[size_t(d)];
      const auto it = index_.find(next);
      if (it == index_.end()) continue;
      const uint32_t a = root(i), b = root(it->second);
      if (a != b) parent[std::max(a, b)] = std::min(a, b);
    }
  // Each body's level: its highest particle, and half a spacing.
  std::vector<float> level(highest_.size(), -std::numeric_limits<float>::max());
  for (uint32_t i = 0; i < highest_.size(); ++i)
    level[root(i)] = std::max(level[root(i)], highest_[i]);
  for (uint32_t i = 0; i < highest_.size(); ++i)
    highest_[i] = level[root(i)] + float(half_spacing_);
}

double WaterLevels::depth(const Vec3f& x) const {
  const auto it = index_.find(cellOf(x));
  if (it == index_.end()) return 0.0;
  return std::max(0.0, double(highest_[it->second]) - heightOf(x));
}

void startHydrostatic(World& world, const WaterLevels& levels) {
  const SceneDesc& scene = world.scene;
  for (ParticleSet& set : world.sets) {
    const auto* water = std::get_if<Water<float>>(&set.model);
    if (!water) continue;
    const double rho = scene.materials[size_t(set.material)].density;
    for (size_t i = 0; i < set.size(); ++i) {
      const ObjectDesc& o = scene.objects[set.object[i]];
      if (o.initial_pressure != InitialPressure::Hydrostatic) continue;
      set.J[i] = water->jAtPressure(float(rho * levels.gravity() * levels.depth(set.x[i])));
    }
  }
}

}  // namespace triad
