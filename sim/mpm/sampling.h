#pragma once
// Deterministic sampling of primitive shapes into MPM particles.
#include <functional>
#include <vector>

#include "sim/math.h"
#include "sim/scene_desc.h"

namespace triad {

// In-cell sample offsets (in cell units, in [0,1)^3) for `ppc` particles per
// cell: a regular k x k x k lattice when ppc = k^3, else a low-discrepancy
// (R3 sequence) pattern. The same for every cell, so sampling is
// deterministic and the sampled volume converges with dx.
std::vector<Vec3d> cellSampleOffsets(int ppc);

// Samples the interior of a mesh shape on the same lattice as the
// primitives (cellSampleOffsets). Provided by import/, since sim/ reads no
// files; throws InputError naming the mesh file when it cannot.
using MeshSampler =
    std::function<std::vector<Vec3f>(const MeshDesc& mesh, const DomainDesc& domain, int ppc)>;

// Particles of the domain's cell lattice that fall inside the shape (and the
// domain). Boxes are half-open [min, max) so that abutting boxes never
// sample a point twice. Mesh shapes go to `mesh_sampler` (an InputError when
// none is given).
std::vector<Vec3f> sampleShape(const ShapeDesc& shape, const DomainDesc& domain, int ppc,
                               const MeshSampler& mesh_sampler = {});

}  // namespace triad
