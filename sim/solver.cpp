#include "sim/solver.h"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>
#include <sstream>

#include "sim/errors.h"
#include "sim/phase_timer.h"
#include "sim/solids/elastic_contact.h"

namespace triad {

namespace {

// Below this step the simulation has blown up rather than become stiff.
constexpr double kMinDt = 1e-10;

}  // namespace

TransferParams transferParamsFor(const SceneDesc& scene) {
  const DomainDesc& domain = scene.domain;
  TransferParams p;
  for (int d = 0; d < 3; ++d) {
    p.shifted_origin[d] = static_cast<float>(domain.min[d] + 0.5 * domain.dx);
    p.domain_lo[d] = static_cast<float>(domain.min[d]);
    p.domain_hi[d] = static_cast<float>(domain.max[d]);
  }
  p.dx = static_cast<float>(domain.dx);
  p.inv_dx = 1.0f / p.dx;
  p.scheme = scene.solver.transfer;
  p.flip_ratio = static_cast<float>(scene.solver.flip_ratio);
  return p;
}

Solver::Solver(World& world) : world_(world), params_(transferParamsFor(world.scene)) {
  const SceneDesc& scene = world.scene;
  const DomainDesc& domain = scene.domain;
  for (int d = 0; d < 3; ++d) {
    walls_.hi[d] = static_cast<int>(std::lround((domain.max[d] - domain.min[d]) / domain.dx));
    gravity_[d] = static_cast<float>(scene.gravity[d]);
  }
  flip_ = scene.solver.transfer == TransferScheme::Flip;
  walls_.type = domain.boundary.type;
  walls_.friction = static_cast<float>(domain.boundary.friction);
  for (const ParticleSet& set : world.sets)
    wave_speed_.push_back(waveSpeed(scene.materials[set.material]));
  for (const ParticleSet& set : world.sets)
    for (const Vec3f& v : set.v) max_speed_ = std::max(max_speed_, v.norm());
  has_particles_ = world.particleCount() > 0;
  if (scene.solver.sleep.enabled) sleep_ = std::make_unique<SleepTracker>(scene.solver.sleep);
  if (!world.bodies.empty() || !world.elastics.empty()) {
    coupling_ = std::make_unique<GridCoupling>(scene.solver);
    for (int d = 0; d < 3; ++d) {
      contact_.lo[d] = domain.min[d];
      contact_.hi[d] = domain.max[d];
    }
    contact_.wall_type = domain.boundary.type;
    contact_.wall_friction = domain.boundary.friction;
    contact_.iterations = scene.solver.contact_iterations;
    contact_.gravity = Vec3d(scene.gravity[0], scene.gravity[1], scene.gravity[2]).norm();
  }
  resetLoads();
}

void Solver::setDomain(DomainExchange* domain) {
  domain_ = domain;
  if (coupling_) coupling_->setDomain(domain);
  // Each process built only its share: the first step's speed is every
  // share's largest.
  if (domain_) {
    std::vector<double> m{double(max_speed_)};
    domain_->maxOverProcesses(m);
    max_speed_ = float(m[0]);
  }
}

void Solver::resetLoads() { loads_.assign(world_.bodies.size(), BodyLoad{}); }

void Solver::addLoad(size_t b, const Vec3d& j, const Vec3d& x) {
  loads_[b].impulse += j;
  loads_[b].moment += (x - world_.bodies[b].state.x).cross(j);
}

const CouplingStats& Solver::couplingStats() const {
  static const CouplingStats none;
  return coupling_ ? coupling_->stats() : none;
}

double Solver::solidSpeed() const {
  double s = 0.0;
  for (const RigidBody& b : world_.bodies)
    if (!b.fixed || b.animated)
      s = std::max(s, b.state.v.norm() + b.omega().norm() * b.radius +
                          (b.deform ? b.deform->maxSpeed(world_.time) : 0.0));
  return s;
}

double Solver::stableDt() const {
  float c = 0.0f;
  for (float w : wave_speed_) c = std::max(c, w);
  // Hardened snow is stiffer: its wave speed grows with the square root.
  c *= std::sqrt(max_stiffness_scale_);
  const double speed =
      double(c) + std::max({double(max_speed_), solidSpeed(), sourceSpeed(world_.sources, world_.time)});
  const SolverDesc& s = world_.scene.solver;
  double dt = s.max_dt;
  if (speed > 0.0) dt = std::min(dt, s.cfl * world_.scene.domain.dx / speed);
  // Elastic solids: their explicit step's limit (element height over wave
  // speed), and their nodes' speed against the grid.
  for (const ElasticSolid& e : world_.elastics) {
    // Symplectic Euler on these elements is stable to 0.76-0.9 of h / c
    // (bench/RESULTS.md): a cfl above 0.5 buys no more there.
    if (!e.implicit) dt = std::min(dt, e.fem.stableDt(std::min(s.cfl, kMaxElementCfl)));
    double vmax = 0.0;
    for (const Vec3d& v : e.fem.v) vmax = std::max(vmax, v.norm());
    if (vmax > 0.0) dt = std::min(dt, s.cfl * world_.scene.domain.dx / vmax);
  }
  return dt;
}

void Solver::step(double dt) {
  const float fdt = static_cast<float>(dt);
  const bool solids = coupling_ != nullptr;
  if (!world_.sources.empty()) emitSources();  // refill the sources' shapes
  // A process of a split run takes part in every exchange, with or without
  // particles of its own.
  has_particles_ = domain_ != nullptr || world_.particleCount() > 0;
  if (sleep_ && solids) sleepBodies();  // bodies resting in calm material
  if (solids) predictSolids(dt);  // solids' own step: v_q* of every collision particle
  if (has_particles_) {
    binParticles();
    if (sleep_) classifySleep();    // settled blocks skip the rest
    if (domain_) domain_->extendLayout(layout_);  // blocks others scatter into
    particlesToGrid(fdt);                         // contract step 2, the stress folded in
    if (domain_) {                  // partial sums to their owners
      domain_->sumGhosts(layout_, grid_, layers_);
      if (flip_) domain_->sumGhosts(layout_, flip_grid_, flip_layers_);
    }
    if (solids) scatterSolids();    // steps 1, 3, 4
    updateGrid(fdt);                // step 5
    if (domain_) {                  // owners' velocities back
      domain_->returnHalo(layout_, grid_);
      if (flip_) domain_->returnHalo(layout_, flip_grid_);
    }
    if (solids) collideSolids();    // step 6
    if (sleep_) wakeMovingSleepers();  // sleepers that would move gather too
    gridToParticles(fdt);           // step 7
    if (solids && coupling_->frontsOn()) correctFronts();  // each particle its own field
    if (solids) pushOutOfSolids(dt);            // no particle stays inside a body
    if (!world_.sinks.empty()) drainSinks(dt);  // remove what the sinks hold
    if (domain_) domain_->migrate(world_.sets);  // particles to their blocks' owners
  }
  if (solids) advanceSolids(dt);    // step 8, then contacts and rigid motion
  if (sleep_ && solids) updateBodyStillness(dt);
  for (BodyLoad& l : loads_) l.time += dt;

  world_.steps++;
  record_.steps++;
  record_.particle_steps += world_.particleCount();
  record_.sleeping_steps += has_particles_ ? sleeping_ : 0;
  record_.dt_min = record_.steps == 1 ? dt : std::min(record_.dt_min, dt);
  record_.dt_max = std::max(record_.dt_max, dt);
}

void Solver::advanceTo(double t, const std::function<void(double)>& on_step) {
  while (world_.time < t) {
    double dt = stableDt();
    if (domain_) {
      // Split over processes, every process takes the same step, whatever
      // each holds, so that their exchanges always meet.
      std::vector<double> m{-dt};
      domain_->maxOverProcesses(m);
      dt = -m[0];
    }
    if (dt < kMinDt) {
      std::ostringstream msg;
      msg << "step " << world_.steps << " at t = " << world_.time
          << " s: the stable time step collapsed to " << dt << " s (particle speed "
          << max_speed_ << " m/s): the simulation is blowing up";
      throw SimulationError(msg.str());
    }
    const double remaining = t - world_.time;
    bool last = false;
    if (dt >= remaining) {
      dt = remaining;
      last = true;
    } else if (2.0 * dt > remaining) {
      dt = 0.5 * remaining;
    }
    step(dt);
    world_.time = last ? t : world_.time + dt;
    if (on_step) on_step(dt);
  }
}

void Solver::emitSources() {
  PhaseTimer timer(times_.shot);
  const size_t made = emitFromSources(world_.sources, world_.sets, world_.scene.domain, world_.time,
                                      world_.next_id, domain_);
  // New particles move at their source's speed from this step on.
  if (made > 0)
    max_speed_ = std::max(max_speed_, float(sourceSpeed(world_.sources, world_.time)));
}

void Solver::drainSinks(double dt) {
  PhaseTimer timer(times_.shot);
  removeInSinks(world_.sinks, world_.sets, world_.time + dt);
}

void Solver::binParticles() {
  PhaseTimer timer(times_.bin);
  binned_ = true;
  binner_.bin(world_.sets, params_.shifted_origin, params_.inv_dx, layout_, &grid_,
              domain_ ? domain_->binOrder() : nullptr);
}

double Solver::wakeMargin() const {
  // Solids move less than a cell a step: two blocks of margin wake the
  // material before they reach it.
  return 2.0 * kBlockSize * world_.scene.domain.dx;
}

void Solver::gatherState() {
  if (sleep_ && domain_) sleep_->gatherState(*domain_);
}

WakeBox Solver::wakeBox(const RigidBody& b) const {
  const double margin = wakeMargin();
  const Vec3d r = Vec3d::Constant(double(b.radius) + margin);
  return {b.state.x - r, b.state.x + r};
}

void Solver::sleepBodies() {
  std::vector<double>& still = sleep_->bodyStill();
  still.resize(world_.bodies.size(), 0.0);
  body_asleep_.assign(world_.bodies.size(), 0);
  auto overlaps = [](const WakeBox& a, const WakeBox& b) {
    return (a.lo.array() <= b.hi.array()).all() && (b.lo.array() <= a.hi.array()).all();
  };
  std::vector<WakeBox> others;  // moving things that may be about to touch a body
  for (const RigidBody& b : world_.bodies)
    if (b.animated || b.deform) others.push_back(wakeBox(b));
  for (const ElasticSolid& e : world_.elastics) others.push_back(elasticBox(e));
  // Whether the material round each body is calm: split over processes,
  // each knows its own blocks, and a body is calm where all are.
  std::vector<double> unrest(world_.bodies.size(), 0.0);
  bool any = false;
  for (size_t k = 0; k < world_.bodies.size(); ++k) {
    const RigidBody& b = world_.bodies[k];
    if (b.fixed || still[k] < sleep_->delay()) continue;
    any = true;
    unrest[k] = sleep_->calmWithin(wakeBox(b), params_.shifted_origin, params_.inv_dx) ? 0.0 : 1.0;
  }
  if (domain_ && any) domain_->maxOverProcesses(unrest);
  for (size_t k = 0; k < world_.bodies.size(); ++k) {
    const RigidBody& b = world_.bodies[k];
    if (b.fixed || still[k] < sleep_->delay()) continue;
    const WakeBox box = wakeBox(b);
    if (unrest[k] > 0.0) continue;
    bool alone = true;
    for (const WakeBox& o : others) alone = alone && !overlaps(box, o);
    for (size_t j = 0; j < world_.bodies.size() && alone; ++j) {
      const RigidBody& o = world_.bodies[j];
      if (j != k && !o.fixed && still[j] < sleep_->delay()) alone = !overlaps(box, wakeBox(o));
    }
    body_asleep_[k] = alone;
  }
}

void Solver::updateBodyStillness(double dt) {
  std::vector<double>& still = sleep_->bodyStill();
  const double limit = sleep_->speed();
  for (size_t k = 0; k < world_.bodies.size(); ++k) {
    const RigidBody& b = world_.bodies[k];
    const double speed = b.state.v.norm() + b.omega().norm() * double(b.radius);
    still[k] = speed < limit ? std::min(still[k] + dt, 1e30) : 0.0;
  }
}

WakeBox Solver::elasticBox(const ElasticSolid& e) const {
  const double margin = wakeMargin();
  WakeBox w{Vec3d::Constant(std::numeric_limits<double>::max()),
            Vec3d::Constant(std::numeric_limits<double>::lowest())};
  for (const Vec3d& x : e.fem.x) {
    w.lo = w.lo.cwiseMin(x);
    w.hi = w.hi.cwiseMax(x);
  }
  w.lo.array() -= margin;
  w.hi.array() += margin;
  return w;
}

void Solver::classifySleep() {
  PhaseTimer timer(times_.bin);
  // Solids moving faster than the speed keep the material near them awake.
  // One slower than that (at rest in material that still creeps, or asleep)
  // leaves the material to its own test: sleeping material scatters its
  // mass and stress, so the collision still meets it and wakes it when the
  // solid pushes it faster than the speed.
  std::vector<WakeBox> wake;
  const double still = sleep_->speed();
  for (size_t k = 0; k < world_.bodies.size(); ++k) {
    const RigidBody& b = world_.bodies[k];
    if (b.fixed && !b.animated && !b.deform) continue;
    if (k < body_asleep_.size() && body_asleep_[k]) continue;
    const double speed = b.state.v.norm() + b.omega().norm() * double(b.radius);
    if (!b.deform && speed < still) continue;
    wake.push_back(wakeBox(b));
  }
  for (const ElasticSolid& e : world_.elastics) {
    double fastest = 0.0;
    for (const Vec3d& v : e.fem.v) fastest = std::max(fastest, v.norm());
    if (fastest >= still) wake.push_back(elasticBox(e));
  }
  sleeping_ = sleep_->classify(layout_, wake, params_.shifted_origin, params_.inv_dx, domain_);
  sleep_halos_.prepare(layout_);
  stillSleepingParticles(layout_, world_.sets);
}

void Solver::particlesToGrid(float dt) {
  PhaseTimer timer(times_.p2g);
  params_.dt = dt;
  max_stiffness_scale_ = triad::particlesToGrid(
      world_.sets, layout_, params_, grid_, flip_ ? &flip_grid_ : nullptr,
      domain_ ? &layers_ : nullptr, domain_ && flip_ ? &flip_layers_ : nullptr,
      sleep_ ? &sleep_halos_ : nullptr);
}

void Solver::updateGrid(float dt) {
  PhaseTimer timer(times_.grid);
  triad::updateGrid(layout_, grid_, flip_ ? &flip_grid_ : nullptr, gravity_, dt, walls_);
}

void Solver::wakeMovingSleepers() {
  PhaseTimer timer(times_.g2p);
  triad::sleepersThatWouldMove(world_.sets, layout_, params_, grid_, float(sleep_->speed()),
                               moving_blocks_);
  sleeping_ -= sleep_->wakeMoving(layout_, moving_blocks_, sleep_halos_);
}

void Solver::gridToParticles(float dt) {
  PhaseTimer timer(times_.g2p);
  params_.dt = dt;
  G2PStats st = triad::gridToParticles(world_.sets, layout_, params_, grid_,
                                       flip_ ? &flip_grid_ : nullptr,
                                       sleep_ ? &block_speed2_ : nullptr);
  if (sleep_) sleep_->update(layout_, block_speed2_, params_.dt, domain_);
  if (world_.steps + 1 == fault_step_ && !world_.sets.empty() && world_.sets[0].size() > 0) {
    world_.sets[0].v[0].x() = std::numeric_limits<float>::quiet_NaN();
    st.finite = false;
  }
  if (!st.finite) reportNonFinite();
  max_speed_ = st.max_speed;
  if (domain_) {
    // The next step's length is the same on every process.
    std::vector<double> m{double(max_speed_), double(max_stiffness_scale_)};
    domain_->maxOverProcesses(m);
    max_speed_ = float(m[0]);
    max_stiffness_scale_ = float(m[1]);
  }
}

void Solver::predictSolids(double dt) {
  PhaseTimer timer(times_.solids);
  points_.clear();
  // Once fixed bodies are scattered for good, their points are gone: give
  // back the memory they took in the first step.
  if (coupling_->fixedBuilt() && !shrunk_) {
    shrunk_ = true;
    for (auto* a : {&points_.x, &points_.v, &points_.n, &points_.dv}) a->shrink_to_fit();
    points_.phi.shrink_to_fit();
  }
  const Vec3d g(world_.scene.gravity[0], world_.scene.gravity[1], world_.scene.gravity[2]);
  SolidsTimes& parts = times_.solid_parts;
  for (size_t k = 0; k < world_.bodies.size(); ++k) {
    PhaseTimer part(parts.poses);
    RigidBody& b = world_.bodies[k];
    if (k < body_asleep_.size() && body_asleep_[k]) {
      b.state.v.setZero();  // held by the sleeping material around it
      b.state.L.setZero();
    } else if (!b.fixed) {
      b.state.v += dt * g;
    }
    // Fixed bodies that do not move are scattered once and for all
    // (GridCoupling::buildFixed); animated colliders every step, at their
    // pose now and with its exact velocity.
    const SolidKind kind = !b.fixed ? SolidKind::Moving
                           : b.animated ? SolidKind::Driven
                                        : SolidKind::Static;
    const size_t id = points_.addSolid(b.sample_mass, b.friction, kind, b.fixed ? 0.0 : b.mass);
    if (kind == SolidKind::Static && coupling_->fixedBuilt()) continue;
    // A body far from all material flies (or is driven) on its own: no node
    // of its would meet material, so the grid would give it nothing back.
    if (kind != SolidKind::Static && !b.deform && farFromMaterial(b, dt)) {
      if (b.animated) b.poseAt(world_.time);
      continue;
    }
    // From the clock alone, so that a resumed run poses it the same.
    if (b.animated) b.poseAt(world_.time);
    if (!b.fixed) {
      const Mat3d R = b.rotation();
      points_.centre[id] = b.state.x.cast<float>();
      points_.inv_mass[id] = float(1.0 / b.mass);
      points_.velocity[id] = b.state.v.cast<float>();
      points_.spin[id] = b.omega().cast<float>();
      points_.inv_inertia[id] =
          (R * b.moments.cwiseInverse().asDiagonal() * R.transpose()).cast<float>();
    }
    const size_t first = points_.size(), n = b.r.size();
    points_.x.resize(first + n);
    points_.v.resize(first + n);
    points_.n.resize(first + n);
    points_.phi.insert(points_.phi.end(), b.phi.begin(), b.phi.end());
    points_.point_mass.resize(first + n, b.sample_mass);
    if (b.deform) {
      // Placed by poseAt: the sequence's surface now, then the animation's pose.
      std::copy(b.placed->x.begin(), b.placed->x.end(), points_.x.begin() + std::ptrdiff_t(first));
      std::copy(b.placed->v.begin(), b.placed->v.end(), points_.v.begin() + std::ptrdiff_t(first));
      std::copy(b.placed->n.begin(), b.placed->n.end(), points_.n.begin() + std::ptrdiff_t(first));
      continue;
    }
    const Mat3f R = b.rotation().cast<float>();
    const Vec3f c = b.state.x.cast<float>(), v = b.state.v.cast<float>();
    const Vec3f w = b.omega().cast<float>();
    // Split from a few thousand points: the last step's scatter left these
    // arrays in every core's cache, and one thread alone rewriting them
    // waits on each line.
#pragma omp parallel for schedule(static) if (n > 2048)
    for (int64_t q = 0; q < int64_t(n); ++q) {
      const Vec3f r = R * b.r[q];
      points_.x[first + q] = c + r;
      points_.v[first + q] = v + w.cross(r);
      points_.n[first + q] = R * b.n[q];
    }
  }
  // Elastic solids: the explicit FEM step's velocities are their v_q*.
  for (ElasticSolid& e : world_.elastics) predictElastic(e, dt, g);
}

bool Solver::farFromMaterial(const RigidBody& b, double dt) const {
  // The blocks that held particles at the last binning (a split run's
  // process sees only its own: it scatters every body). Since then the
  // material moved less than a cell, the body by its speed over the step.
  if (!binned_ || domain_ || !world_.sources.empty()) return false;
  const double reach = double(b.radius) + b.state.v.norm() * dt + wakeMargin() +
                       std::sqrt(3.0) * 0.5 * kBlockSize * world_.scene.domain.dx;
  for (const uint64_t key : layout_.particle_keys)
    if ((blockCentre(key) - b.state.x).squaredNorm() < reach * reach) return false;
  return true;
}

Vec3d Solver::blockCentre(uint64_t key) const {
  // A particle block holds the particles whose stencil's base node is one
  // of its nodes: they lie in the block's cells shifted by half a cell.
  return params_.shifted_origin.cast<double>() +
         (unpackBlock(key).cast<double>() + Vec3d::Constant(0.5)) * kBlockSize *
             world_.scene.domain.dx;
}

void Solver::scatterSolids() {
  PhaseTimer timer(times_.solids), part(times_.solid_parts.scatter);
  coupling_->scatter(points_, layout_, params_);
  coupling_->keepPreUpdate(grid_);
}

void Solver::collideSolids() {
  PhaseTimer timer(times_.solids);
  const SolverDesc& s = world_.scene.solver;
  const bool three = s.coupling == CouplingScheme::ThreeGrid;
  {
    PhaseTimer part(times_.solid_parts.gaps);
    coupling_->measureNearSolids(world_.sets, layout_, params_, three && s.contact_gap,
                                 three && s.front_fields);
  }
  PhaseTimer part(times_.solid_parts.collide);
  coupling_->collide(grid_, points_, params_, flip_ ? &flip_grid_ : nullptr);
  coupling_->finishFronts(grid_);
  for (size_t b = 0; b < world_.bodies.size(); ++b) {
    if (!world_.bodies[b].fixed) continue;
    const Vec3d j = coupling_->nodeImpulse()[b];
    loads_[b].impulse += j;
    loads_[b].moment += coupling_->nodeMoment()[b] - world_.bodies[b].state.x.cross(j);
  }
}

void Solver::correctFronts() {
  PhaseTimer timer(times_.solids), part(times_.solid_parts.fronts);
  coupling_->correctFronts(world_.sets, layout_, params_);
}

void Solver::pushOutOfSolids(double dt) {
  PhaseTimer timer(times_.solids), part(times_.solid_parts.push_out);
  // The grid collision stops material approaching a body at shared nodes,
  // but interpolation lets particles at the surface creep in, slowly.
  // Particles found inside a body move back to its surface and lose their
  // approach velocity; the body takes that momentum, so nothing is lost.
  const size_t nb = world_.bodies.size();
  const double dx = world_.scene.domain.dx;
  std::vector<Mat3d> rot;
  std::vector<LatticeBox> boxes;
  for (const RigidBody& b : world_.bodies) {
    rot.push_back(b.rotation());
    boxes.push_back(b.latticeBox());
  }
  // Impulses summed per particle block, then over the blocks in the order
  // of their keys: the same sums for any thread count, and for any split
  // over processes (their blocks, in process order, are in that order).
  struct Push {
    uint64_t key = 0, body = 0;
    Vec3d p = Vec3d::Zero(), l = Vec3d::Zero();
  };
  size_t moved = 0;
  const double block_reach = (std::sqrt(3.0) * 0.5 * kBlockSize + 1.0) * dx;
  float shifted = 0.0f;  // the farthest a particle was moved here
  for (size_t si = 0; si < world_.sets.size() && nb > 0; ++si) {
    ParticleSet& set = world_.sets[si];
    const std::vector<uint32_t>& off = layout_.offsets[si];
    std::vector<Push> partial;
#pragma omp parallel reduction(+ : moved) reduction(max : shifted)
    {
      std::vector<Push> mine, acc(nb);
      std::vector<uint8_t> touched(nb), near(nb);
#pragma omp for schedule(dynamic, 16) nowait
      for (int64_t pb = 0; pb < int64_t(layout_.particleBlocks()); ++pb) {
        if (off[pb] == off[pb + 1]) continue;
        std::fill(touched.begin(), touched.end(), 0);
        // Only bodies that the block's sphere meets (its particles lie
        // within half a cell of its cells).
        const Vec3d centre = blockCentre(layout_.particle_keys[size_t(pb)]);
        bool any = false;
        for (size_t bi = 0; bi < nb; ++bi) {
          near[bi] = boxes[bi].mayReach(centre, block_reach);
          any = any || near[bi];
        }
        if (!any) continue;
        for (int64_t i = off[pb]; i < int64_t(off[pb + 1]); ++i) {
          const Vec3f start = set.x[i];
          for (size_t bi = 0; bi < nb; ++bi) {
            if (!near[bi]) continue;
            const RigidBody& b = world_.bodies[bi];
            const Vec3d x = set.x[i].cast<double>();
            if (!boxes[bi].mayReach(x, 0.0)) continue;  // most particles near a body
            double phi;
            Vec3d n, vb;
            if (!b.surfaceAt(x, rot[bi], phi, n, vb) || phi >= 0.0) continue;
            const Vec3d v = set.v[i].cast<double>();
            const Vec3d v_rel = v - vb;
            Vec3d out = x - phi * n, normal = n;
            // (Not through a deforming collider: its placed samples leave
            // holes where its surface stretched, which this search would take
            // for the far side.)
            if (v_rel.dot(n) > 0.0 && !b.placed) {
              // Moving out through the nearest face: in a part thinner than a
              // few samples it came in through the opposite one (a plate one
              // cell thick). Send it back there, not through. The search
              // reaches a cell whatever the body's sample spacing.
              const double h = b.spacing;
              const int steps = std::clamp(int(std::ceil(2.0 * std::max(2.0 * h, dx) / h)), 4, 32);
              for (int step = 1; step <= steps; ++step) {
                const Vec3d back = x - (step * 0.5 * h) * n;
                if (b.sampleAt(back) == -1) {
                  out = back;
                  normal = -n;
                  break;
                }
              }
            }
            set.x[i] = out.cast<float>();
            const double vn = v_rel.dot(normal);
            if (vn < 0.0) {
              set.v[i] = (v - vn * normal).cast<float>();
              const Vec3d j = double(set.mass) * vn * normal;  // what the body takes
              if (!touched[bi]) acc[bi] = Push{layout_.particle_keys[size_t(pb)], bi};
              touched[bi] = 1;
              acc[bi].p += j;
              acc[bi].l += (x - b.state.x).cross(j);
            }
            ++moved;
          }
          shifted = std::max(shifted, (set.x[i] - start).norm());
        }
        for (size_t bi = 0; bi < nb; ++bi)
          if (touched[bi]) mine.push_back(acc[bi]);
      }
#pragma omp critical
      partial.insert(partial.end(), mine.begin(), mine.end());
    }
    std::sort(partial.begin(), partial.end(), [](const Push& a, const Push& b) {
      return a.key != b.key ? a.key < b.key : a.body < b.body;
    });
    // Split over processes: every process's blocks, in process order, so
    // that the bodies change alike everywhere.
    if (domain_) partial = allGatherValues(*domain_, partial);
    for (const Push& acc : partial) {
      RigidBody& b = world_.bodies[size_t(acc.body)];
      loads_[acc.body].impulse += acc.p;
      loads_[acc.body].moment += acc.l;
      if (b.fixed) continue;
      b.state.v += acc.p / b.mass;
      b.state.L += acc.l;
    }
  }
  // Elastic solids: particles inside their deformed meshes.
  if (!world_.elastics.empty()) {
    // The blocks' spheres grow by the farthest the bodies' push-out just
    // moved a particle (back through a thin part: a cell or two).
    ParticleBlocks blocks;
    blocks.offsets = &layout_.offsets;
    blocks.radius = block_reach + double(shifted);
    for (const uint64_t key : layout_.particle_keys) blocks.centre.push_back(blockCentre(key));
    for (ElasticSolid& e : world_.elastics)
      moved += pushParticlesOut(e, world_.sets, dt, blocks, domain_);
  }
  pushed_out_ = moved;
}

void Solver::advanceSolids(double dt) {
  PhaseTimer timer(times_.solids);
  std::optional<PhaseTimer> part(std::in_place, times_.solid_parts.gather);
  coupling_->gather(points_, params_);
  part.emplace(times_.solid_parts.bodies);
  // Each body takes the momentum and angular momentum its collision
  // particles gained. Only the change is read back: a body that touches no
  // material keeps its motion exactly, instead of losing spin to the
  // smoothing of a round trip through the grid.
  for (size_t s = 0; s < world_.bodies.size(); ++s) {
    RigidBody& b = world_.bodies[s];
    if (b.fixed) continue;
    if (s < body_asleep_.size() && body_asleep_[s]) {
      // Held by the sleeping material: it bears the body's weight.
      const Vec3d g(world_.scene.gravity[0], world_.scene.gravity[1], world_.scene.gravity[2]);
      loads_[s].impulse += -b.mass * dt * g;
      continue;
    }
    const size_t first = points_.begin[s];
    const size_t last = s + 1 < points_.begin.size() ? points_.begin[s + 1] : points_.size();
    Vec3d dp = Vec3d::Zero(), dl = Vec3d::Zero();
    for (size_t q = first; q < last; ++q) {
      const Vec3d dv = points_.dv[q].cast<double>();
      if (dv.isZero()) continue;
      dp += dv;
      dl += (points_.x[q].cast<double>() - b.state.x).cross(dv);
    }
    // Plus what this step's collision gave the body directly, node by node
    // (no collision runs without MPM particles).
    const bool collided = has_particles_ && s < coupling_->nodeImpulse().size();
    const Vec3d j = collided ? coupling_->nodeImpulse()[s] : Vec3d::Zero();
    const Vec3d m = collided ? Vec3d(coupling_->nodeMoment()[s] - b.state.x.cross(j)) : Vec3d::Zero();
    dp = dp * double(b.sample_mass) + j;
    dl = dl * double(b.sample_mass) + m;
    b.state.v += dp / b.mass;
    b.state.L += dl;
    loads_[s].impulse += dp;
    loads_[s].moment += dl;
  }
  contact_stats_ = resolveContacts(world_.bodies, contact_, dt);
  // A sleeping body stays where it rests.
  for (size_t s = 0; s < body_asleep_.size(); ++s) {
    if (!body_asleep_[s]) continue;
    world_.bodies[s].state.v.setZero();
    world_.bodies[s].state.L.setZero();
  }
  for (RigidBody& b : world_.bodies) {
    if (b.animated) b.poseAt(world_.time + dt);
    b.advance(dt);
    if (!std::isfinite(b.state.x.sum() + b.state.v.sum() + b.state.L.sum() +
                       b.state.q_principal.coeffs().sum())) {
      std::ostringstream msg;
      msg << "step " << world_.steps + 1 << " at t = " << world_.time << " s: rigid object '"
          << b.name << "' became non-finite: centre (" << b.state.x.transpose() << "), velocity ("
          << b.state.v.transpose() << ")";
      throw SimulationError(msg.str());
    }
  }
  part.emplace(times_.solid_parts.elastic);
  for (size_t k = 0; k < world_.elastics.size(); ++k)
    constrainElastic(world_.elastics[k], points_.begin[world_.bodies.size() + k], dt);
  if (world_.elastics.size() > 1) resolveElasticContacts(world_.elastics, dt);
  for (ElasticSolid& e : world_.elastics) moveElastic(e, dt);
}

void Solver::reportNonFinite() const {
  const SceneDesc& scene = world_.scene;
  for (const ParticleSet& set : world_.sets) {
    for (size_t i = 0; i < set.size(); ++i) {
      if (std::isfinite(set.x[i].sum() + set.v[i].sum() + set.C[i].sum())) continue;
      std::ostringstream msg;
      msg << "step " << world_.steps + 1 << " at t = " << world_.time << " s: particle "
          << set.id[i] << " of object '" << scene.objects[set.object[i]].name
          << "' (material '" << scene.materials[set.material].name
          << "') became non-finite: position (" << set.x[i].transpose() << "), velocity ("
          << set.v[i].transpose() << ")";
      throw SimulationError(msg.str());
    }
  }
  throw SimulationError("step " + std::to_string(world_.steps + 1) +
                        ": a particle became non-finite");
}

size_t Solver::bytes() const {
  size_t solids = 0;
  if (coupling_)
    solids = coupling_->bytes() + (points_.x.capacity() + points_.v.capacity() +
                                   points_.n.capacity() + points_.dv.capacity()) * sizeof(Vec3f);
  return grid_.capacity() * sizeof(GridNode) + flip_grid_.capacity() * sizeof(GridNode) +
         layout_.bytes() + binner_.bytes() + sleep_halos_.bytes() + solids;
}

}  // namespace triad
