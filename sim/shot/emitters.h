#pragma once
// Sources and sinks (scene-format.md, "Directing a shot").
//
// A source is an MPM object with `emit`: from start to end its shape,
// moved by its animation, is kept full. Its sites are the particles its
// shape would get at t = 0 (the domain's lattice, particles_per_cell); a
// site whose neighbourhood holds none of the source's own particles gets a
// new one, with the object's velocity turned by the pose plus the pose's
// own velocity there. A site's neighbourhood is the points of the shape as
// written nearer to it than to any other site of its cell, so material
// flowing out through a face at speed v empties, and refills, one layer of
// sites every (lattice spacing) / v: rho A |v| kg/s through an open face A.
//
// A sink removes every MPM particle inside its shape (moved by its
// animation) at the end of each step.
#include <cstdint>
#include <string>
#include <unordered_map>
#include <vector>

#include "sim/math.h"
#include "sim/mpm/particles.h"
#include "sim/scene_desc.h"
#include "sim/shot/animation.h"

namespace triad {

// A shape's pose over time: points of the shape as written map to the
// world as pivot + T + R (p - pivot).
struct Placement {
  Animation animation;
  Vec3d pivot = Vec3d::Zero();
};

struct Source {
  int object = -1;  // index into SceneDesc::objects
  std::string name;
  size_t set = 0;   // index into World::sets of its material
  EmitDesc emit;
  Vec3d velocity = Vec3d::Zero();  // the object's velocity, in the shape's frame as written
  Placement placement;
  std::vector<Vec3f> sites;        // the shape as written, sampled like an MPM object
  std::vector<Vec3d> offsets;      // the in-cell sample offsets of the lattice (cells)
  int cube = 0;                    // k when the offsets are a k x k x k lattice, else 0
  // Sites by domain cell: cell key -> c, then sites cell_sites[c * offsets + j]
  // (-1 where offset j of the cell lies outside the shape).
  std::unordered_map<uint64_t, uint32_t> cell_of;
  std::vector<int32_t> cell_sites;
  double radius = 0.0;             // largest |site - pivot| plus a cell
  uint64_t emitted = 0;
  bool activeAt(double t) const { return t >= emit.start && t < emit.end; }
};

struct Sink {
  int object = -1;
  std::string name;
  ShapeDesc shape;  // box and sphere tested exactly
  // Mesh sinks: the cells of the domain lattice (spacing h) whose centres
  // lie inside the mesh as written.
  double h = 0.0;
  Vec3d lattice_lo = Vec3d::Zero();
  Eigen::Vector3i dims = Eigen::Vector3i::Zero();
  std::vector<uint8_t> inside;
  Placement placement;
  uint64_t removed = 0;
  // Whether world point p is inside at the pose whose rotation is R.
  bool contains(const Vec3d& p, const Pose& pose, const Mat3d& R) const;
};

// Builds a source from its sites (sampleShape of its shape as written).
Source makeSource(int object, const ObjectDesc& obj, size_t set, std::vector<Vec3f> sites,
                  const DomainDesc& domain, int ppc, const Vec3d& pivot);

// Fills the empty sites of every source active at t with new particles of
// consecutive ids from next_id. Returns the particles made. Throws
// SimulationError when ids would pass 2^32. Split over processes (`split`),
// every process finds the same empty sites from all processes' particles
// and makes the same particles, and keeps those in its own blocks.
class DomainExchange;
size_t emitFromSources(std::vector<Source>& sources, std::vector<ParticleSet>& sets,
                       const DomainDesc& domain, double t, uint32_t& next_id,
                       DomainExchange* split = nullptr);

// Removes the particles inside any sink at time t, keeping the others'
// order. Returns the particles removed.
size_t removeInSinks(std::vector<Sink>& sinks, std::vector<ParticleSet>& sets, double t);

// The fastest speed at which an active source emits or moves its material at
// time t (for the step's CFL limit).
double sourceSpeed(const std::vector<Source>& sources, double t);

}  // namespace triad
