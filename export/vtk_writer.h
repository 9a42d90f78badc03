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
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "export/ply_writer.h"
#include "sim/solids/collision_particles.h"
#include "sim/world.h"

namespace triad {

// Each throws std::runtime_error naming the file; each writes atomically.
void writeParticlesVtp(const std::string& path, const World& world);
void writeSurfaceVtp(const std::string& path, const TriSurface& surface);

// Where writeParticlesVtp's file of n particles keeps what, for writers
// that fill its arrays in parts (each MPI process its run of ids): the
// bytes that do not depend on the particles' values (the XML before the
// appended data, each array's byte count, the closing XML), by file
// offset, and where each array's first value lies. Entry k of an array is
// at values[array] + k * entry[array], in increasing id: Float32 velocity,
// UInt32 id, Int32 object, Float32 J, Float32 points, Int64 connectivity
// (k itself) and Int64 offsets (k + 1).
struct ParticlesVtpLayout {
  enum Array { Velocity, Id, Object, J, Points, Connectivity, Offsets, kArrays };
  std::vector<std::pair<uint64_t, std::string>> fixed;
  uint64_t values[kArrays] = {};
  uint64_t entry[kArrays] = {};
  uint64_t bytes = 0;  // the whole file
};
ParticlesVtpLayout particlesVtpLayout(size_t n);
// Array a's entries for `count` particles in id order, whose first is the
// file's entry `first`, into out (count * entry[a] bytes).
void packParticlesVtp(ParticlesVtpLayout::Array a, const PlyParticle* particles, size_t count,
                      uint64_t first, unsigned char* out);

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
