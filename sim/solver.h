#pragma once
// The MLS-MPM time stepper. One step reads like the algorithm:
// bin particles, P2G with the stresses, grid update, G2P.
#include <functional>
#include <memory>
#include <vector>

#include "sim/coupling/coupling.h"
#include "sim/mpm/domain.h"
#include "sim/mpm/grid_update.h"
#include "sim/mpm/sleep.h"
#include "sim/mpm/sparse_grid.h"
#include "sim/mpm/transfer.h"
#include "sim/solids/rigid_contact.h"
#include "sim/world.h"

namespace triad {

// The solids phase by part, wall-clock seconds: what a scene with solids
// spends where (they sum to PhaseTimes::solids).
struct SolidsTimes {
  double elastic_forces = 0;  // elastic solids' FEM forces or implicit solves
  double poses = 0;           // collision particles placed, elastic node normals
  double scatter = 0;         // solids' sums onto the solid grid (steps 1, 3, 4)
  double gaps = 0;            // material's gaps to solids near them
  double collide = 0;         // the shared nodes' collision (step 6)
  double fronts = 0;          // particles' own fields (solver.front_fields)
  double push_out = 0;        // particles found inside solids moved out
  double gather = 0;          // collision particles read back (step 8)
  double bodies = 0;          // rigid bodies' read-back, contacts and motion
  double elastic = 0;         // elastic nodes' read-back, walls, contacts, motion
  // (name, seconds) in the order of the step, for records.
  std::vector<std::pair<const char*, double>> parts() const {
    return {{"elastic_forces", elastic_forces},
            {"poses", poses},
            {"scatter", scatter},
            {"gaps", gaps},
            {"collide", collide},
            {"fronts", fronts},
            {"push_out", push_out},
            {"gather", gather},
            {"bodies", bodies},
            {"elastic", elastic}};
  }
};

// Wall-clock seconds spent in each phase of the step.
struct PhaseTimes {
  double bin = 0, p2g = 0, grid = 0, g2p = 0;  // p2g includes the stress
  double solids = 0;  // coupling transfers, contacts and rigid integration
  double shot = 0;    // sources' emission and sinks' removal
  SolidsTimes solid_parts;
  double total() const { return bin + p2g + grid + g2p + solids + shot; }
};

// What MPM material and elastic solids did to one rigid body since the
// last reset: the impulse and its moment about the body's centre of mass,
// summed over substeps, and the time they cover.
struct BodyLoad {
  Vec3d impulse = Vec3d::Zero();  // N s
  Vec3d moment = Vec3d::Zero();   // N m s
  double time = 0.0;              // s
  Vec3d force() const { return time > 0.0 ? Vec3d(impulse / time) : Vec3d::Zero(); }
  Vec3d torque() const { return time > 0.0 ? Vec3d(moment / time) : Vec3d::Zero(); }
};

struct StepRecord {
  int64_t steps = 0;
  double dt_min = 0.0, dt_max = 0.0;
  uint64_t particle_steps = 0;  // particles times substeps
  uint64_t sleeping_steps = 0;  // of those, particles asleep (solver.sleep)
};

// What the next step depends on beyond the World: checkpoints save it so
// that a resumed run takes exactly the steps an uninterrupted one takes.
struct SolverState {
  float max_speed = 0.0f;            // CFL speed from the last G2P
  float max_stiffness_scale = 1.0f;  // snow hardening from the last P2G's stresses
  SleepState sleep;                  // how long each block has been still
};

// The transfers' constants for a scene's grid (the dt is set each step).
TransferParams transferParamsFor(const SceneDesc& scene);

class Solver {
 public:
  explicit Solver(World& world);

  // Largest stable step now: the CFL limit on material and solid speed plus
  // the materials' wave speed, capped by solver.max_dt.
  double stableDt() const;

  // One substep of length dt.
  void step(double dt);

  // Step until world.time equals t exactly. Steps are shortened so that the
  // last one lands on t (and the one before is split evenly, so no tiny step
  // remains). `on_step` is called after every substep.
  void advanceTo(double t, const std::function<void(double dt)>& on_step = {});

  // Testing aid: make one particle's velocity NaN during substep `step`
  // (counted from the start of the world), to exercise the failure path.
  void injectFaultAtStep(int64_t step) { fault_step_ = step; }

  // Runs this world's particles as one part of a simulation split over
  // several processes (sim/mpm/domain.h); the world must already hold only
  // the particles this process owns. Solids and sources are whole on every
  // process. The first step's speed becomes the largest over the processes.
  void setDomain(DomainExchange* domain);
  const TransferParams& transferParams() const { return params_; }

  // Split over processes: gathers what state() must hold of every process
  // (the sleeping blocks' still times). Collective; call before state()
  // goes into a checkpoint.
  void gatherState();
  SolverState state() const {
    return {max_speed_, max_stiffness_scale_, sleep_ ? sleep_->state() : SleepState{}};
  }
  void restore(const SolverState& s) {
    max_speed_ = s.max_speed;
    max_stiffness_scale_ = s.max_stiffness_scale;
    if (sleep_) sleep_->restore(s.sleep);
  }

  const PhaseTimes& phaseTimes() const { return times_; }
  // The last step's coupling and contact counts (zero without solids).
  const CouplingStats& couplingStats() const;
  const ContactStats& contactStats() const { return contact_stats_; }
  size_t particlesPushedOut() const { return pushed_out_; }
  // Per rigid body (scene order), the loads since the last resetLoads():
  // bodies/forces.csv's mean force and torque over a frame.
  const std::vector<BodyLoad>& bodyLoads() const { return loads_; }
  void resetLoads();
  const StepRecord& record() const { return record_; }
  // Bytes held by grids and binning buffers (capacity).
  size_t bytes() const;

 private:
  void binParticles();
  // Settled material: which blocks sleep this step (and still their
  // particles), from the blocks' still times and the moving solids.
  void classifySleep();
  // Whether rigid body b is beyond the reach of every particle block of
  // the last binning, this step included.
  bool farFromMaterial(const RigidBody& b, double dt) const;
  // World position of particle block `key`'s centre.
  Vec3d blockCentre(uint64_t key) const;
  void wakeMovingSleepers();
  // Rigid bodies at rest among calm material sleep with it: held still,
  // they neither fall nor keep the material around them awake.
  void sleepBodies();
  void updateBodyStillness(double dt);
  double wakeMargin() const;  // beyond a moving solid's bounds, metres
  WakeBox wakeBox(const RigidBody& b) const;
  WakeBox elasticBox(const ElasticSolid& e) const;
  void particlesToGrid(float dt);
  void updateGrid(float dt);
  void gridToParticles(float dt);
  void emitSources();
  void drainSinks(double dt);
  void predictSolids(double dt);
  // An elastic solid's velocities before the grid: its forces over the
  // step, explicit or solved implicitly against walls and rigid bodies.
  void predictElastic(ElasticSolid& e, double dt, const Vec3d& g);
  // An implicit solid's solve against the walls and the rigid bodies it
  // touches, the moving ones taking the contacts' reaction.
  void solveAgainstBodies(ElasticSolid& e, double dt, const Vec3d& g, FemContacts& contacts);
  void scatterSolids();
  void collideSolids();
  void advanceSolids(double dt);
  void correctFronts();
  void pushOutOfSolids(double dt);
  // Elastic nodes after the grid: velocities constrained by the walls and
  // rigid bodies (then by each other), then moved.
  void constrainElastic(ElasticSolid& e, size_t first, double dt);
  void moveElastic(ElasticSolid& e, double dt);
  // Walls and rigid surfaces an implicit solid's solve keeps its nodes out of.
  FemContacts elasticContacts(const ElasticSolid& e, double dt);
  double wallFriction() const;  // Coulomb coefficient of the walls (sticky: huge)
  double solidSpeed() const;
  [[noreturn]] void reportNonFinite() const;

  World& world_;
  TransferParams params_;
  WallConditions walls_;
  Vec3f gravity_;
  std::vector<float> wave_speed_;  // per set, at rest
  bool flip_ = false;
  bool has_particles_ = false;  // no MPM material: only solids move
  DomainExchange* domain_ = nullptr;  // split over processes, or not
  int64_t fault_step_ = -1;

  Binner binner_;
  GridLayout layout_;
  std::vector<GridNode> grid_;
  std::vector<GridNode> flip_grid_;
  // Split over processes: the sums of blocks that cross processes, a layer
  // per colour (particlesToGrid).
  std::vector<GridNode> layers_, flip_layers_;
  std::unique_ptr<SleepTracker> sleep_;  // only when the scene lets material sleep
  SleepHalos sleep_halos_;               // sleeping blocks' sums at rest
  std::vector<uint8_t> moving_blocks_;   // sleeping blocks whose particles would move
  std::vector<float> block_speed2_;      // per particle block, from the gather
  size_t sleeping_ = 0;                  // particles asleep this step
  std::vector<uint8_t> body_asleep_;     // per rigid body, this step

  // Solids: only built when the scene has any.
  std::unique_ptr<GridCoupling> coupling_;
  SolidPoints points_;
  ContactSettings contact_;
  ContactStats contact_stats_;
  size_t pushed_out_ = 0;
  std::vector<BodyLoad> loads_;
  // Adds impulse j applied at world point x to rigid body b's load.
  void addLoad(size_t b, const Vec3d& j, const Vec3d& x);
  std::vector<Vec3d> fem_force_;
  std::vector<std::pair<size_t, size_t>> contact_bodies_;  // (plane, rigid body) of elasticContacts
  std::vector<Vec3d> contact_surface_;                     // per such plane, the surface point
  // Implicit solves per step against moving bodies, at most, and the
  // residual at which a body and the solid agree, as a part of the change
  // the contacts made to the body's velocity.
  static constexpr int kMaxContactPasses = 8;
  static constexpr double kContactAgreement = 0.01;
  // Most Gauss-Seidel sweeps over an explicit solid's nodes pushed by a rigid body.
  static constexpr int kMaxElasticContactSweeps = 20;
  static constexpr double kMaxElementCfl = 0.5;  // explicit FEM step, fraction of h / c
  bool binned_ = false;  // the layout holds a binning of this run's particles
  bool shrunk_ = false;  // particles moved out of bodies in the last step

  float max_speed_ = 0.0f;
  float max_stiffness_scale_ = 1.0f;
  PhaseTimes times_;
  StepRecord record_;
};

}  // namespace triad
