#pragma once
// Reading triangle meshes (any format assimp reads: OBJ, STL ascii/binary,
// PLY, glTF 2 .gltf/.glb, ascii FBX) into one world-space triangle soup, and
// repairing what a voxelizer needs repaired. No assimp type leaks from here.
#include <array>
#include <string>
#include <vector>

#include "sim/math.h"
#include "sim/scene_desc.h"
#include "sim/shot/animation.h"

namespace triad {

// One triangle soup in double precision. Triangles index `positions`.
struct TriangleMesh {
  std::vector<Vec3d> positions;
  std::vector<std::array<int, 3>> triangles;

  // Axis-aligned bounds of the positions (lo > hi when empty).
  void bounds(Vec3d& lo, Vec3d& hi) const;
  // Sum of signed tetrahedron volumes: the enclosed volume of a closed,
  // outward-oriented mesh.
  double signedVolume() const;
};

// What the loader found and did, besides the mesh.
struct MeshLoadResult {
  TriangleMesh mesh;                  // world space, repaired (see loadMesh)
  std::vector<std::string> warnings;  // repairs, one line each, without the file name
  size_t input_triangles = 0;         // triangles read, before repairs
  int shells = 0;                     // edge-connected components
  int boundary_edges = 0;             // open edges found (before hole filling)
};

// The rotation of a mesh shape's `rotate_deg` is eulerXYZDegrees
// (sim/shot/animation.h), the same as an animation key's.

// The full placement of a mesh shape: p_world = translate + R (scale p).
Vec3d placePoint(const MeshDesc& desc, const Vec3d& p);

// Loads `path` (desc.resolved_path when called with a MeshDesc), merges all
// meshes of the file with their node transforms into one triangle soup,
// applies the shape's scale, rotation and translation, then repairs it:
//  - vertices at identical positions are merged (across meshes too),
//  - degenerate triangles (a repeated vertex) are dropped,
//  - winding is made consistent within every shell (edge-connected
//    component) and every closed shell is turned outward,
//  - holes (loops of open boundary edges) are closed by a fan around the
//    loop's centroid, so the inside/outside test sees a closed surface.
// Each repair adds a warning. Throws InputError(path, reason) for a missing
// or unreadable file, a file assimp cannot parse, no triangles (only points
// or lines), out-of-range indices or non-finite coordinates.
MeshLoadResult loadMesh(const MeshDesc& desc);
MeshLoadResult loadMeshFile(const std::string& path);  // identity placement

// The repair step on its own (for meshes built in memory).
void repairMesh(TriangleMesh& mesh, MeshLoadResult& report);

// A UV sphere of nu segments around and nv from pole to pole (2 nu (nv - 1)
// triangles), outward wound: a closed mesh of chosen size, for tests and
// benchmarks.
TriangleMesh uvSphere(const Vec3d& centre, double radius, int nu, int nv);

// Writes `mesh` with assimp's exporter. `format` is an assimp export id:
// "obj", "stl" (ascii), "stlb" (binary), "ply", "plyb", "gltf2", "glb2",
// "fbxa". When `node_transform` is given (row-major 4x4, column-vector
// convention), the mesh hangs under a child node with that transform and
// the vertices are written untransformed. For tests and benchmarks.
void saveMesh(const TriangleMesh& mesh, const std::string& path, const std::string& format,
              const std::array<double, 16>* node_transform = nullptr);

}  // namespace triad
