#pragma once
// Tetrahedral meshes of voxelized solids (issue 5): the voxel cells centred
// on a solid's collision particle lattice, each split into six tetrahedra
// along its main diagonal (Kuhn / Freudenthal). Every cell is split the
// same way, so neighbouring cells share faces exactly: the mesh conforms.
#include <array>
#include <vector>

#include "sim/math.h"

namespace triad {

struct TetMesh {
  std::vector<Vec3d> nodes;               // rest positions (cell corners)
  std::vector<std::array<int, 4>> tets;   // positively oriented; cell c owns [6c, 6c + 6)
  double spacing = 0.0;                   // cell size h
  std::vector<Vec3d> cells;               // cell centres

  // Rest volume of tetrahedron t (positive).
  double restVolume(size_t t) const;
};

// Cells of side h centred on `centres` (lattice points, spacing h), six
// positively oriented tetrahedra each, corners shared between cells.
TetMesh tetsFromVoxels(const std::vector<Vec3d>& centres, double h);

// Barycentric weights of p in tetrahedron `tet` of node positions x (sum 1;
// all >= 0 inside).
std::array<double, 4> barycentric(const std::vector<Vec3d>& x, const std::array<int, 4>& tet,
                                  const Vec3d& p);

// Where a point sits in a mesh at rest: a tetrahedron and barycentric
// weights (summing to 1; all >= 0 inside). Points outside every
// tetrahedron get the nearest one by barycentric distance, so that a
// surface mesh slightly outside the voxels still follows the deformation.
struct Embedding {
  int tet = -1;
  std::array<double, 4> w{0, 0, 0, 0};
};

// Embeds each point in the mesh (a point of a cell's cube goes to that
// cell's tetrahedra; points outside all cells to the nearest cell's).
std::vector<Embedding> embed(const TetMesh& mesh, const std::vector<Vec3d>& points);

// The embedded points moved with the mesh's deformed node positions x.
Vec3d embeddedPosition(const TetMesh& mesh, const std::vector<Vec3d>& x, const Embedding& e);

}  // namespace triad
