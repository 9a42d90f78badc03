#pragma once
// Grid update: momentum to velocity, body forces and the domain walls.
#include <vector>

#include "sim/math.h"
#include "sim/scene_desc.h"
#include "sim/mpm/sparse_grid.h"

namespace triad {

// Domain walls in node indices: nodes at or below `lo` (at or above `hi`) on
// an axis lie on or beyond the wall.
struct WallConditions {
  Vec3i lo{0, 0, 0};
  Vec3i hi{0, 0, 0};
  BoundaryType type = BoundaryType::Slip;
  float friction = 0.0f;
};

// Apply one wall with inward normal n to a node velocity.
void applyWall(Vec3f& v, const Vec3f& n, BoundaryType type, float friction);

// Turn momenta into velocities, add gravity and apply the walls. With FLIP,
// `flip` holds each node's transfer momentum on entry and its velocity change
// over the step on exit.
void updateGrid(const GridLayout& layout, std::vector<GridNode>& grid, std::vector<GridNode>* flip,
                const Vec3f& gravity, float dt, const WallConditions& walls);

}  // namespace triad
