#pragma once
// VTK XML PolyData (.vtp) caches for ParaView and VTK, and the .pvd
// collection that gives them their times:
//   vtk/particles.FFFF.vtp        every MPM particle as a vertex cell, with
//                                 point data `velocity` (m/s), `id`,
//                                 `object` and `J`, in increasing id
//   vtk/bodies/NAME.FFFF.vtp      a solid's world-space surface (triangles)
//   vtk/surfaces/MATERIAL.FFFF.vtp  a material's surface mesh
//   vtk/cache.pvd                 every file above with its frame's time, one
//                                 part per series (ParaView opens it as one
//                                 multiblock dataset over time)
// The files are VTK's XML format version 1.0, raw appended binary data with
// 64-bit headers and offsets (what vtkXMLPolyDataWriter writes without
// compression), written by hand: the format is a few lines of XML, and
// linking VTK's C++ libraries for it would add hundreds of megabytes to the
// build.
#include <string>
#include <vector>

#include "sim/solids/collision_particles.h"
#include "sim/world.h"

namespace triad {

// Each throws std::runtime_error naming the file; each writes atomically.
void writeParticlesVtp(const std::string& path, const World& world);
void writeSurfaceVtp(const std::string& path, const TriSurface& surface);

// One entry of a .pvd collection: the file (relative to the .pvd), its time,
// and the series it belongs to (its part; `name` labels the part's block).
struct PvdEntry {
  double time = 0.0;
  int part = 0;
  std::string name;
  std::string file;
};
void writePvd(const std::string& path, const std::vector<PvdEntry>& entries);

}  // namespace triad
