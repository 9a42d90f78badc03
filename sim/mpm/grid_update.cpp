#include "sim/mpm/grid_update.h"

#include <algorithm>

namespace triad {

void applyWall(Vec3f& v, const Vec3f& n, BoundaryType type, float friction) {
  if (type == BoundaryType::Sticky) {
    v.setZero();
    return;
  }
  const float vn = v.dot(n);
  // Material may leave a separating wall freely; a slip wall holds it.
  if (type == BoundaryType::Separate && vn >= 0.0f) return;
  Vec3f vt = v - vn * n;
  if (vn < 0.0f && friction > 0.0f) {
    // Coulomb friction: the normal impulse bounds the tangential one; it can
    // stop sliding but never reverse it.
    const float speed = vt.norm();
    const float reduced = std::max(0.0f, speed + friction * vn);
    vt *= speed > 0.0f ? reduced / speed : 0.0f;
  }
  v = vt;
}

void updateGrid(const GridLayout& layout, std::vector<GridNode>& grid,
                std::vector<GridNode>* flip, const Vec3f& gravity, float dt,
                const WallConditions& walls) {
  const Vec3f dv_gravity = dt * gravity;
  // A few blocks update faster than the other threads wake.
#pragma omp parallel for schedule(static) if (layout.gridBlocks() > 64)
  for (int64_t gb = 0; gb < static_cast<int64_t>(layout.gridBlocks()); ++gb) {
    const Vec3i origin = unpackBlock(layout.grid_keys[gb]) * kBlockSize;
    // Blocks away from every wall skip the per-node wall tests.
    bool near_wall = false;
    for (int d = 0; d < 3; ++d)
      near_wall = near_wall || origin[d] <= walls.lo[d] || origin[d] + kBlockSize - 1 >= walls.hi[d];
    for (int k = 0; k < kBlockNodes; ++k) {
      GridNode& g = grid[gb * kBlockNodes + k];
      if (g.m <= 0.0f) continue;
      const float inv_m = 1.0f / g.m;
      Vec3f v(g.v[0] * inv_m, g.v[1] * inv_m, g.v[2] * inv_m);
      v += dv_gravity;
      if (near_wall) {
        const Vec3i node = origin + Vec3i(k >> (2 * kBlockBits), (k >> kBlockBits) & (kBlockSize - 1),
                                          k & (kBlockSize - 1));
        for (int d = 0; d < 3; ++d) {
          if (node[d] <= walls.lo[d]) applyWall(v, Vec3f::Unit(d), walls.type, walls.friction);
          if (node[d] >= walls.hi[d]) applyWall(v, -Vec3f::Unit(d), walls.type, walls.friction);
        }
      }
      g.v[0] = v.x();
      g.v[1] = v.y();
      g.v[2] = v.z();
      if (flip) {
        GridNode& f = (*flip)[gb * kBlockNodes + k];
        for (int d = 0; d < 3; ++d) f.v[d] = v[d] - f.v[d] * inv_m;
      }
    }
  }
}

}  // namespace triad
