#pragma once
// Reads a triangle mesh back from a cache's `bodies/NAME.FFFF.ply` (binary
// little-endian PLY: a vertex element with float x y z, then a face element
// with one list of vertex indices, as export/body_writer.cpp writes it).
// Other scalar properties are skipped; polygons are split into fans.
#include <string>

#include "render/preview_renderer.h"

namespace triad::render {

// Fills mesh.xyz and mesh.triangles (mesh.object is left as it is). Throws
// triad::InputError naming the file for anything that is not such a PLY:
// bad header, other elements, truncated data, an index out of range.
void readMeshPly(const std::string& path, PreviewMesh& mesh);

}  // namespace triad::render
