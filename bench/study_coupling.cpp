// The open choices of the coupling contract (../shared/specs/coupling.md),
// measured on small scenes, as a markdown table for bench/RESULTS.md:
//   study_coupling [--quick]
// 1. contact_velocity after_update / before_update: how deep a resting sand
//    pile sinks into a fixed rigid floor.
// 2. solid_readback momentum_conserving / combined: momentum drift when sand
//    hits a free box with gravity off, and how much a box is held back by
//    sand it leaves.
// 3. rigid_node_mass node / body_share and coupling_iterations: a floating
//    slab's draft against Archimedes.
#include <omp.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <nlohmann/json.hpp>
#include <string>

#include "import/mesh_sampler.h"
#include "import/scene_loader.h"
#include "sim/solver.h"

namespace {

using nlohmann::json;
using triad::Vec3d;

json baseScene(const std::array<double, 3>& max, double dx) {
  return {{"version", 1},
          {"name", "study"},
          {"domain", {{"min", {0, 0, 0}}, {"max", max}, {"dx", dx}}},
          {"materials", json::object()},
          {"objects", json::array()}};
}

json box(const std::array<double, 3>& lo, const std::array<double, 3>& hi) {
  return {{"box", {{"min", lo}, {"max", hi}}}};
}

json sand() {
  return {{"model", "drucker_prager"}, {"density", 1600}, {"youngs_modulus", 3.5e5},
          {"poisson_ratio", 0.3}, {"friction_angle_deg", 30}};
}

triad::World build(const json& j) {
  return triad::buildSceneWorld(triad::parseScene(j, "study_coupling.json"));
}

Vec3d mpmMomentum(const triad::World& w) {
  Vec3d p = Vec3d::Zero();
  for (const triad::ParticleSet& s : w.sets)
    for (size_t i = 0; i < s.size(); ++i) p += s.mass * s.v[i].cast<double>();
  return p;
}

// A sand pile resting on a fixed slab whose top is at y = 0.1: mean and
// deepest penetration of particles below the top, in cells.
void restingPile(const std::string& velocity) {
  const double dx = 0.02;
  json j = baseScene({0.6, 0.5, 0.6}, dx);
  j["solver"] = {{"contact_velocity", velocity}};
  j["materials"]["sand"] = sand();
  j["objects"].push_back({{"name", "floor"}, {"kind", "rigid"}, {"density", 2000},
                          {"fixed", true}, {"friction", 0.5},
                          {"shape", box({0, 0, 0}, {0.6, 0.1, 0.6})}});
  j["objects"].push_back({{"name", "pile"}, {"kind", "mpm"}, {"material", "sand"},
                          {"shape", box({0.2, 0.12, 0.2}, {0.4, 0.32, 0.4})}});
  triad::World w = build(j);
  triad::Solver solver(w);
  solver.advanceTo(1.0);
  double lowest = 1e9, sum_low = 0.0;
  size_t n_low = 0;
  for (const triad::ParticleSet& s : w.sets)
    for (size_t i = 0; i < s.size(); ++i) {
      lowest = std::min(lowest, double(s.x[i].y()));
      // The bottom layer: particles within a cell of the slab.
      if (s.x[i].y() < 0.1 + dx) {
        sum_low += s.x[i].y();
        ++n_low;
      }
    }
  std::printf("| contact_velocity %s | resting pile on a fixed slab, 1 s | lowest particle %+.2f dx, "
              "bottom layer mean %+.2f dx above the slab top |\n",
              velocity.c_str(), (lowest - 0.1) / dx, n_low ? (sum_low / n_low - 0.1) / dx : 0.0);
}

// Gravity off: a sand block at 3 m/s hits a free box of density 800.
void sandHitsBox(const std::string& readback) {
  json j = baseScene({1.0, 0.4, 0.4}, 0.025);
  j["gravity"] = {0, 0, 0};
  j["solver"] = {{"solid_readback", readback}};
  j["materials"]["sand"] = sand();
  j["objects"].push_back({{"name", "sand"}, {"kind", "mpm"}, {"material", "sand"},
                          {"velocity", {3, 0, 0}},
                          {"shape", box({0.1, 0.125, 0.125}, {0.3, 0.275, 0.275})}});
  j["objects"].push_back({{"name", "box"}, {"kind", "rigid"}, {"density", 800}, {"friction", 0.3},
                          {"shape", box({0.4, 0.1, 0.1}, {0.55, 0.3, 0.3})}});
  triad::World w = build(j);
  auto total = [&]() { return Vec3d(mpmMomentum(w) + w.bodies[0].mass * w.bodies[0].state.v); };
  const Vec3d p0 = total();
  triad::Solver solver(w);
  solver.advanceTo(0.15);
  std::printf("| solid_readback %s | sand at 3 m/s hits a free box, gravity off, 0.15 s | "
              "momentum drift %.2e, box speed %.3f m/s |\n",
              readback.c_str(), (total() - p0).norm() / p0.norm(), w.bodies[0].state.v.x());
}

// Gravity off: a box starts at 1 m/s away from sand it touches. Held back
// means it slows down although nothing pulls.
void boxLeavesSand(const std::string& readback) {
  json j = baseScene({1.0, 0.4, 0.4}, 0.025);
  j["gravity"] = {0, 0, 0};
  j["solver"] = {{"solid_readback", readback}};
  j["materials"]["sand"] = sand();
  j["objects"].push_back({{"name", "sand"}, {"kind", "mpm"}, {"material", "sand"},
                          {"shape", box({0.1, 0.1, 0.1}, {0.4, 0.3, 0.3})}});
  j["objects"].push_back({{"name", "box"}, {"kind", "rigid"}, {"density", 800}, {"friction", 0.3},
                          {"velocity", {1, 0, 0}},
                          {"shape", box({0.4, 0.1, 0.1}, {0.55, 0.3, 0.3})}});
  triad::World w = build(j);
  triad::Solver solver(w);
  solver.advanceTo(0.1);
  std::printf("| solid_readback %s | box leaves sand it touches at 1 m/s, gravity off, 0.1 s | "
              "box speed %.3f m/s |\n",
              readback.c_str(), w.bodies[0].state.v.x());
}

// A slab of density 500 on water; draft (level - bottom) vs Archimedes.
void floatingSlab(const std::string& node_mass, int iterations) {
  const double dx = 0.025;
  json j = baseScene({0.4, 0.5, 0.4}, dx);
  j["solver"] = {{"rigid_node_mass", node_mass}, {"coupling_iterations", iterations}};
  j["materials"]["water"] = {{"model", "water"}, {"density", 1000}, {"bulk_modulus", 1e5},
                             {"viscosity", 1.0}};
  j["objects"].push_back({{"name", "water"}, {"kind", "mpm"}, {"material", "water"},
                          {"shape", box({0, 0, 0}, {0.4, 0.25, 0.4})}});
  j["objects"].push_back({{"name", "slab"}, {"kind", "rigid"}, {"density", 500},
                          {"shape", box({0.08, 0.26, 0.08}, {0.32, 0.38, 0.32})}});
  triad::World w = build(j);
  triad::Solver solver(w);
  double draft[3];
  const double squeeze = 1.0 - 1000 * 9.81 * 0.27 / (2 * 1e5);
  const double level = (0.4 * 0.4 * 0.25 * squeeze + w.bodies[0].mass / 1000.0) / (0.4 * 0.4);
  const double expect = w.bodies[0].mass / 1000.0 / (0.24 * 0.24);
  for (int k = 0; k < 3; ++k) {
    solver.advanceTo(1.0 + k);
    draft[k] = level - (w.bodies[0].state.x.y() - 0.06);
  }
  std::printf("| rigid_node_mass %s, coupling_iterations %d | slab (500 kg/m3) on water | draft at "
              "1, 2, 3 s: %.1f, %.1f, %.1f mm; Archimedes %.1f mm |\n",
              node_mass.c_str(), iterations, draft[0] * 1e3, draft[1] * 1e3, draft[2] * 1e3, expect * 1e3);
}

}  // namespace

int main() {
  std::printf("| option | scene | measured |\n|---|---|---|\n");
  for (const char* v : {"after_update", "before_update"}) restingPile(v);
  for (const char* r : {"momentum_conserving", "combined"}) sandHitsBox(r);
  for (const char* r : {"momentum_conserving", "combined"}) boxLeavesSand(r);
  for (const char* m : {"node", "body_share"})
    for (int it : {1, 4, 30}) floatingSlab(m, it);
  return 0;
}
