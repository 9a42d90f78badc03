#pragma once
// Coupling of MPM material with solids through collocated grids
// (../shared/specs/coupling.md). The MPM grid is the solver's own; the
// volumetric grid lives here, on the nodes of the MPM grid's blocks that
// solids reach: a node without MPM mass takes no part in any collision, so
// the volumetric grid never needs nodes the MPM grid lacks. The combined
// grid is never stored: each shared node forms it on the fly.
#include <algorithm>
#include <array>
#include <cstdint>
#include <vector>

#include "sim/math.h"
#include "sim/mpm/domain.h"
#include "sim/mpm/sparse_grid.h"
#include "sim/mpm/transfer.h"
#include "sim/scene_desc.h"

namespace triad {

// How a solid moves: by the coupling (a rigid body, an elastic solid), not
// at all (scattered once), or as prescribed (an animated collider: infinite
// mass, scattered every step with its own velocity).
enum class SolidKind : uint8_t { Moving = 0, Static = 1, Driven = 2 };

// The collision particles of every solid for one step, world space.
// Points of solid s are [begin[s], begin[s+1]), the last solid's up to size().
struct SolidPoints {
  std::vector<Vec3f> x;   // position at the start of the step
  std::vector<Vec3f> v;   // velocity v_q* from the solid's own solver
  std::vector<Vec3f> n;   // outward unit normal
  std::vector<float> phi;  // signed distance to the solid's surface (negative inside)
  std::vector<Vec3f> dv;  // out (gather): velocity change the grid gave the point
  std::vector<float> point_mass;  // mass of each point, kg
  std::vector<size_t> begin;
  std::vector<float> mass;      // per solid: mass per point if uniform (rigid), kg
  std::vector<float> friction;  // per solid: Coulomb coefficient against MPM material
  std::vector<SolidKind> kind;  // per solid; Static and Driven have infinite mass
  // Per solid: the mass that moves as one with each of its nodes. A rigid
  // body's node carries the whole body (its total mass); 0 for solids whose
  // nodes move on their own (their node mass is all there is).
  std::vector<double> body_mass;
  // Per solid, for rigid bodies: centre of mass, inverse mass and world
  // inverse inertia, so that the collision can feed back the body's response.
  std::vector<Vec3f> centre;
  std::vector<float> inv_mass;
  std::vector<Mat3f> inv_inertia;
  std::vector<Vec3f> velocity;  // v and omega as predicted, for the body's
  std::vector<Vec3f> spin;      // velocity at each of its nodes

  size_t size() const { return x.size(); }
  size_t solids() const { return mass.size(); }
  void clear();
  // Starts the points of a new solid; returns its index.
  size_t addSolid(float uniform_mass, float mu, SolidKind how, double whole_mass);
};

// What a coupling step did, for tests and the run record.
struct CouplingStats {
  size_t active_points = 0;  // collision particles whose stencil met the MPM grid
  size_t shared_nodes = 0;   // nodes with both MPM and solid mass
  size_t collisions = 0;     // shared nodes that were approaching (three grids)
  int passes = 0;            // Jacobi passes until converged (the most a body took)
};

class GridCoupling {
 public:
  explicit GridCoupling(const SolverDesc& solver) : solver_(solver) {}

  // Split over processes (sim/mpm/domain.h): each node's collision is its
  // owner's, and every process solves the collision of all of them, so the
  // bodies take the same impulses everywhere.
  void setDomain(DomainExchange* domain) { domain_ = domain; }

  // Contract steps 1 and 4: scatter the points' mass, momentum and normals
  // (and their solids' friction and fixedness) onto the MPM grid's nodes.
  // Call after the MPM P2G (step 2), before the grid update.
  void scatter(const SolidPoints& points, const GridLayout& layout, const TransferParams& p);

  // Remembers the MPM velocities before the grid update where the chosen
  // variant needs them (contact_velocity before_update, solid_velocity combined).
  void keepPreUpdate(const std::vector<GridNode>& grid);

  // Step 6 with three grids: an inelastic, frictional collision on every
  // shared node whose MPM material approaches the solid. With a single grid
  // both sides take the mass-weighted velocity instead (they stick).
  // `grid` holds MPM velocities after the grid update; it is changed in place.
  // With FLIP, `flip` holds each node's velocity change over the step, which
  // the particles add to their own: it takes the collision's change too.
  void collide(std::vector<GridNode>& grid, const SolidPoints& points, const TransferParams& p,
               std::vector<GridNode>* flip = nullptr);

  // With `gaps`, the gap between the MPM material and the solids at every node: the
  // smallest clearance (distance to the solids' surface less half a
  // particle spacing, never negative) of the particles whose stencils
  // reach the node, their distance interpolated from the nodes' own.
  //
  // With `fronts`, the same pass prepares two fields on moving solids'
  // nodes (sim/coupling/front_fields.cpp): each node's sums of the
  // material in front of its face and of all of it, summed across
  // processes in colour order where the run is split.
  void measureNearSolids(const std::vector<ParticleSet>& sets, const GridLayout& layout,
                         const TransferParams& p, bool gaps, bool fronts);
  // After collide(): each field's velocity; after the MPM gather,
  // correctFronts() gives each particle near a moving solid its own field's
  // velocity where a node has two.
  void finishFronts(const std::vector<GridNode>& grid);
  void correctFronts(std::vector<ParticleSet>& sets, const GridLayout& layout,
                     const TransferParams& p) const;
  bool frontsOn() const { return !front_.empty(); }

  // Step 8: each point's velocity change from the grid (points.dv), either
  // the opposite of the impulses the MPM side got (momentum conserving) or
  // the combined grid's velocity minus the solid's own (as the note writes).
  void gather(SolidPoints& points, const TransferParams& p) const;

  const CouplingStats& stats() const { return stats_; }
  // Per solid, the impulse the last collide() gave it at its own nodes, and
  // its moment about the world origin, each node's at the node, where the
  // material took the opposite: for fixed solids, and for moving rigid
  // bodies with the momentum-conserving read-back (their nodes then leave
  // nothing for gather(), so angular momentum is kept exactly). Nodes that
  // several solids share, and elastic solids, read back through gather().
  const std::vector<Vec3d>& nodeImpulse() const { return node_impulse_; }
  const std::vector<Vec3d>& nodeMoment() const { return node_moment_; }
  // Whether fixed solids have been scattered once for good: their points
  // are no longer needed.
  bool fixedBuilt() const { return fixed_built_; }
  size_t bytes() const;

  // Solid data on one node: sums of w m, w m v, w n, w m mu, and of w m
  // and w m v over solids of infinite mass; which moving solid it holds and
  // which fixed one (solid + 1; 0 none yet; -1 several). Three rows of
  // eight 4-byte lanes, 32-byte aligned: the scatter adds each row of sums
  // in one vector (a row written by narrower stores would stall the next
  // point's wide load of it).
  struct alignas(32) SolidNode {
    float m, p[3], n[3], mu;
    float fixed_m, fixed_p[3];
    // Outside the solid: the samples' normals weighted by how far outside
    // their own planes the node lies, w_iq max(0, phi_q + n_q . (x_i - x_q)),
    // summed. Beside a face only that face's samples count; around an edge
    // or a corner both faces do, in proportion to the node's distance from
    // each: the direction from the closest point, as the exact distance has.
    float on[3];
    float unused = 0.0f;
    // Signed distance to the solids' surface, extrapolated from each sample
    // along its normal (phi_q + n_q . (x_i - x_q)) and the largest taken: a
    // body's own distance inside it and across its nearest face, exact for
    // plane faces however thin the body, where summed normals cancel.
    float phi;
    // The normal of the sample that gave phi: inside the body, the normal of
    // its nearest face (zero where no sample has a distance).
    float dn[3];
    int32_t solid, fixed_solid;
    int32_t owner;  // the one solid of any kind it holds (solid + 1; 0 none; -1 several)
    int32_t unused_tag = 0;
  };
  static_assert(sizeof(SolidNode) == 96, "three rows of eight lanes");
  // After scatter(): the solids' record of MPM grid node `node` (its block's
  // index in the layout times 64 plus its place in the block), or nullptr
  // where no solid reaches that block.
  const SolidNode* solidNode(size_t node) const;

 private:
  // A node with both MPM and solid mass, during the collision.
  struct Shared {
    uint32_t i, g;        // slot node, grid node
    int32_t solid;        // the one moving solid it holds, or -1
    int32_t fixed_solid;  // the one fixed solid it holds, or -1
    bool fixed;
    float m_mpm, m_vol, mu;
    float m_all;  // the node's whole MPM mass (m_mpm is its front field's where fields split)
    Vec3f v_mpm, v_cmp, v_vol, n, x;  // x: world position
    Vec3f v_pre;                      // the MPM velocity before the grid update, where kept
    Vec3f P = Vec3f::Zero(), T = Vec3f::Zero(), dP = Vec3f::Zero();
    float lambda = 0.0f;  // accumulated normal impulse
    float close = 0.0f;   // approach speed the gap allows: gap / dt
    float gap = 1e30f;    // the material's clearance from the solid (m), where measured
    bool elastic = false;  // a node of one elastic solid
    // One relaxation: the material's velocity relative to the solid u (un
    // its normal part, less what the gap allows) is stopped through the
    // reduced mass, the normal impulse never pulling and the tangential one
    // within Coulomb's cone (it can stop sliding, never reverse it); dP is
    // the change.
    void relaxWith(const Vec3f& u, float un, float reduced) {
      const float next = std::max(0.0f, lambda - reduced * un);
      const Vec3f ut = u - un * n;
      Vec3f t = T - reduced * ut;
      const float limit = mu * next, len = t.norm();
      if (len > limit) t *= limit / len;
      dP = (next - lambda) * n + (t - T);
      lambda = next;
      T = t;
      P += dP;
    }
  };
  // A base block of active points: its points and the slots of the eight
  // grid blocks its stencils reach (-1: not in the MPM grid).
  struct PointBlock {
    uint64_t key;
    uint32_t first, last;  // range in order_
    std::array<int32_t, 8> slot;
  };

  SolverDesc solver_;
  std::vector<SolidNode> nodes_;       // per slot * 64 + node
  std::vector<Vec3f> delta_;           // per slot node: velocity change felt by the solids
  std::vector<uint8_t> slot_moving_;   // per slot: a moving or driven solid reaches it
  // Whether slot s's nodes take the contact gap: a moving solid's do, a
  // fixed solid's with solver.contact_gap_fixed.
  bool takesGap(size_t s) const { return slot_moving_[s] || solver_.contact_gap_fixed; }
  std::vector<float> gap_;            // per slot node: the material's clearance (measureNearSolids)
  std::vector<std::vector<float>> gap_threads_;  // each thread's gaps, without fronts
  std::vector<Vec3f> pre_;             // per slot node: MPM velocity before the update
  std::vector<uint32_t> slot_block_;   // per slot: grid block index
  std::vector<int32_t> block_slot_;    // per grid block: slot or -1
  std::vector<uint32_t> order_;        // active points grouped by base block
  std::vector<PointBlock> blocks_;
  // Per slot, by colour: 8 k + d for the base block blocks_[k] whose
  // neighbour d it is, or -1.
  std::vector<std::array<int32_t, 8>> slot_sources_;
  std::vector<Stencil> stencils_;      // per point (active ones only)
  std::vector<SolidNode> halos_;       // per base block: its points' sums, 6x6x6 nodes
  // Per base block: the halo nodes its points reach, lo x, y, z and hi
  // (inclusive) x, y, z.
  std::vector<std::array<int8_t, 6>> halo_box_;
  std::vector<int32_t> slot_fixed_;    // per slot: its block in fixed_keys_, or -1
  // Per base block: the points of the blocks before it; one more at the end.
  std::vector<uint64_t> block_points_;
  std::vector<uint64_t> point_key_;    // per point: base block key
  void buildFixed(const SolidPoints& points, const TransferParams& p);
  // The least clearance of particle block pb's particles at each moving
  // solid's node their stencils reach, into `gap` (per slot node).
  void gapsOfBlock(uint32_t pb, const std::vector<ParticleSet>& sets, const GridLayout& layout,
                   const TransferParams& p, float* gap) const;
  // measureNearSolids' pass over this process's particles.
  void scanNearSolids(const std::vector<ParticleSet>& sets, const GridLayout& layout,
                      const TransferParams& p, bool gaps, bool fronts);
  void addNodeLoad(int32_t solid, const Shared& c, const Vec3f& impulse);
  // Passes over elastic solids' nodes until the collision holds for what
  // their points read back (elastic_response.cpp).
  void settleElasticNodes(const SolidPoints& points, const TransferParams& p);
  // settleElasticNodes' lists, kept from step to step: made afresh, its
  // arrays of half a megabyte for a slab on water cost more in page faults
  // than in use (most of the collision's time).
  struct ElasticScratch {
    struct Link {
      uint32_t to;  // a point's entry: its node; a node's entry: its point
      float w;
    };
    std::vector<uint32_t> sel, cand, first, node_first, next;
    std::vector<Vec3i> at;
    std::vector<Link> slots, entries, back;
    std::vector<float> s_q, row, inv_m;
    std::vector<Vec3f> dv, change, per_mass;
    std::vector<int32_t> table_block, table_index;
    size_t bytes() const;
  };
  ElasticScratch elastic_scratch_;
  // The velocity change shared_[k] gives the solid points that gather it;
  // called in shared_'s order.
  void setChange(size_t k, const Vec3f& dv);
  // The normal impulses at moving rigid bodies' nodes (moving_), solved
  // for each body's velocity change (dV, dW) by Newton's method; returns
  // the largest number of iterations a body took.
  int solveBodyNormals(const SolidPoints& points, int max_iterations, std::vector<Vec3f>& dV,
                       std::vector<Vec3f>& dW);
  // The Jacobi passes over the moving bodies' nodes (moving_), from pass
  // `pass` to at most `passes`, each body taking the opposite of its nodes'
  // impulses between passes and stopping once its own nodes converge;
  // returns the most passes a body took.
  int relaxMoving(const SolidPoints& points, const std::vector<float>& share, int pass, int passes,
                  std::vector<Vec3f>& dV, std::vector<Vec3f>& dW);
  // relaxMoving's nodes, a body's after another, in vector lanes: one array
  // of each quantity (kMovingFields of them, field by field), each body's
  // run padded to whole lanes with nodes that take no impulse.
  std::vector<float> moving_lanes_;
  std::vector<uint32_t> moving_start_;  // per body: its first lane; one more at the end

  // Split over processes: shared_ becomes every process's owned shared
  // nodes, in process order, each mapped to this process's copy of its
  // node where it has one (kNotHere otherwise).
  void shareAcrossProcesses();
  // Split over processes: gather() from every shared node's change (the
  // collision every process solved alike), not only this process's nodes.
  void gatherEverywhere(SolidPoints& points, const TransferParams& p) const;
  static constexpr uint32_t kNotHere = 0xffffffffu;
  DomainExchange* domain_ = nullptr;
  std::vector<std::pair<uint64_t, uint32_t>> shared_at_;  // per shared node: block key, node
  std::vector<uint64_t> change_keys_;  // grid blocks with a shared node's change, sorted
  std::vector<Vec3f> change_;          // their nodes' changes, 64 per block

  std::vector<Shared> shared_;
  struct FrontSums {
    float mf = 0.0f, pf[3] = {0, 0, 0}, ma = 0.0f, pa[3] = {0, 0, 0};
  };
  struct FrontParticle {
    uint32_t set, index, block, mask;  // mask: bit k set where stencil node k is in front
    Vec3f x;                           // position the gather used
  };
  std::vector<FrontSums> front_;           // per slot node
  std::vector<Vec3f> front_dv_, rest_dv_;  // per slot node: field velocity less the grid's
  std::vector<uint64_t> split_;            // per slot: bit k, node k holds two fields
  std::vector<std::vector<FrontParticle>> front_lists_;  // per thread of the scan
  void correctFront(std::vector<ParticleSet>& sets, const GridLayout& layout,
                    const TransferParams& p, float c_scale, const FrontParticle& fp) const;
  // A particle block's halo: the 6^3 nodes its particles' stencils reach.
  static constexpr int kHaloSize = kBlockSize + 2, kHaloNodes = kHaloSize * kHaloSize * kHaloSize;
  static int haloNode(int x, int y, int z) { return (x * kHaloSize + y) * kHaloSize + z; }
  // Adds particle block pb's halo of field sums (then zeroes it) to its
  // nodes, or to the layers of colour `colour` where the run is split.
  void addFrontHalo(uint32_t pb, int colour, const GridLayout& layout, FrontSums* halo);
  // Split over processes: the fields' sums of the grid blocks on the cut,
  // added by their owners in colour order and returned whole.
  void sumFrontsAcrossProcesses(const GridLayout& layout);
  std::array<std::vector<GridNode>, 2> front_layers_;  // front and whole field, per layer node
  std::vector<uint32_t> moving_;  // shared nodes of one moving rigid body
  bool fixed_built_ = false;
  std::vector<uint64_t> fixed_keys_;     // grid blocks fixed solids reach, sorted
  std::vector<SolidNode> fixed_nodes_;   // their node sums, 64 per block
  const std::vector<uint64_t>* layout_keys_ = nullptr;  // the grid's block keys
  CouplingStats stats_;
  std::vector<Vec3d> node_impulse_, node_moment_;
};

}  // namespace triad
