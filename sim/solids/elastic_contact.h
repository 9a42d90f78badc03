#pragma once
// Contact between elastic solids: a node of one solid that would end the
// step inside another's deformed tetrahedra is stopped at that solid's
// boundary. The node's barycentric position in the containing tetrahedron
// maps it to a rest point; a face of the other solid's voxels gives the
// depth and the rest normal (the voxels are the solid: its tetrahedra fill
// them), and the element's deformation turns them (F^-T N). The face is
// the nearest one along the axes, unless another face within a quarter of
// a spacing is turned against the node's own surface normal: along an edge
// of two cubes stacked face to face, the upper's nodes lie on the lower's
// side planes, and the nearest face would hold them with no depth at all.
// A cell's own sample normal would not do: at edges and corners it points
// to whichever face was nearest the cell's centre, not the point's. The
// impulse stops the approach and removes a fifth of the rest of the
// penetration per step; it is shared between the node and the
// tetrahedron's four nodes by mass and barycentric weight, so momentum is
// kept, with Coulomb friction at the pair's geometric-mean coefficient.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "sim/solids/elastic_solid.h"

namespace triad {

struct ElasticContactStats {
  size_t contacts = 0;  // nodes stopped at another solid's surface this step
};

// Changes the velocities of the solids' nodes (positions x + dt v at the
// end of the step) so that none ends inside another solid. Every ordered
// pair is visited once, in order: the result does not depend on threads.
ElasticContactStats resolveElasticContacts(std::vector<ElasticSolid>& solids, double dt);

// MPM particles (positions at the end of the step) found inside the
// solid's mesh at the end of the step are moved onto its boundary, through
// the face they came in by (else the nearest), and lose their approach
// velocity, which the solid's nodes under them take. Returns how many moved.
// Split over processes (`domain`), every process applies every process's
// hits in process order, so that the solid changes alike everywhere.
struct ParticleSet;
class DomainExchange;
// Where the particles lie: the binning's blocks (per set, offsets into the
// sorted particles, block b holding [offsets[s][b], offsets[s][b + 1])) and
// a sphere about each block that holds its particles now.
struct ParticleBlocks {
  const std::vector<std::vector<uint32_t>>* offsets = nullptr;
  std::vector<Vec3d> centre;
  double radius = 0.0;
};
size_t pushParticlesOut(ElasticSolid& solid, std::vector<ParticleSet>& sets, double dt,
                        const ParticleBlocks& blocks, DomainExchange* domain = nullptr);

}  // namespace triad
