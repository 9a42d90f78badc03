// Where users push the solver: every case either runs finite and plausible
// or stops with a clear SimulationError, never a NaN state or a crash, and
// each asserts what its extreme must do beyond that: no energy from nowhere
// (all), a soft cube slumps and a stiff one keeps its shape, a nearly
// incompressible one keeps its volume, a huge max_dt changes nothing, a
// light ball bounces off sand and a heavy one ploughs through, a domain 100
// times larger gives the same run. Small scenes: the file runs in seconds.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "scene_fixture.h"
#include "sim/errors.h"
#include "sim/solver.h"

namespace triad {
namespace {

using nlohmann::json;
using test::box;

json jelly(double E, double nu = 0.3, double density = 1000) {
  return {{"model", "fixed_corotated"}, {"density", density}, {"youngs_modulus", E},
          {"poisson_ratio", nu}};
}

json mpm(const json& shape, const std::array<double, 3>& v = {0, 0, 0}) {
  return {{"name", "body"}, {"kind", "mpm"}, {"material", "m"}, {"shape", shape}, {"velocity", v}};
}

// Kinetic plus potential energy of everything that moves: MPM particles
// (their velocities; APIC's affine part would only add) and rigid bodies
// (translation and spin).
double mechanicalEnergy(const World& w) {
  const Vec3d g(w.scene.gravity[0], w.scene.gravity[1], w.scene.gravity[2]);
  double e = 0.0;
  for (const ParticleSet& s : w.sets)
    for (size_t i = 0; i < s.size(); ++i)
      e += double(s.mass) * (0.5 * s.v[i].cast<double>().squaredNorm() - g.dot(s.x[i].cast<double>()));
  for (const RigidBody& b : w.bodies)
    if (!b.fixed)
      e += 0.5 * b.mass * b.state.v.squaredNorm() + 0.5 * b.omega().dot(b.state.L) -
           b.mass * g.dot(b.state.x);
  return e;
}

// Everything finite, inside the domain (the transfer clamps positions, so
// this guards the clamp only), and no energy from nowhere: kinetic plus
// potential energy no more than at the start (e0, with no elastic energy
// stored then; stored elastic energy and dissipation only lower it), to 1%
// of the start's kinetic energy and the potential energy's scale.
void expectSane(const World& w, const std::string& tag, double e0, double scale) {
  const Vec3f lo(float(w.scene.domain.min[0]), float(w.scene.domain.min[1]),
                 float(w.scene.domain.min[2]));
  const Vec3f hi(float(w.scene.domain.max[0]), float(w.scene.domain.max[1]),
                 float(w.scene.domain.max[2]));
  for (const ParticleSet& s : w.sets)
    for (size_t i = 0; i < s.size(); ++i) {
      ASSERT_TRUE(std::isfinite(s.x[i].sum() + s.v[i].sum() + s.C[i].sum())) << tag;
      ASSERT_TRUE((s.x[i].array() >= lo.array()).all() && (s.x[i].array() <= hi.array()).all())
          << tag;
    }
  for (const RigidBody& b : w.bodies)
    ASSERT_TRUE(std::isfinite(b.state.x.sum() + b.state.v.sum() + b.state.L.sum())) << tag;
  const double e = mechanicalEnergy(w);
  std::printf("%s: mechanical energy %.4g J, at the start %.4g J\n", tag.c_str(), e, e0);
  EXPECT_LT(e, e0 + 0.01 * scale) << tag << ": energy from nowhere";
}

// The energy scale of a world: its kinetic energy plus its weight times the
// domain's height.
double energyScale(const World& w) {
  const Vec3d g(w.scene.gravity[0], w.scene.gravity[1], w.scene.gravity[2]);
  const double h = w.scene.domain.max[1] - w.scene.domain.min[1];
  double m = 0.0, k = 0.0;
  for (const ParticleSet& s : w.sets)
    for (size_t i = 0; i < s.size(); ++i) {
      m += s.mass;
      k += 0.5 * double(s.mass) * s.v[i].cast<double>().squaredNorm();
    }
  for (const RigidBody& b : w.bodies)
    if (!b.fixed) {
      m += b.mass;
      k += 0.5 * b.mass * b.state.v.squaredNorm();
    }
  return k + m * g.norm() * h;
}

// What a run left: the material's centre of mass, its extent in y, the
// mean and largest |J - 1| of its particles, and the steps taken.
struct Outcome {
  Vec3d centre = Vec3d::Zero();
  double height = 0.0, mean_dj = 0.0, max_dj = 0.0;
  size_t steps = 0;
};

Outcome outcome(const World& w) {
  Outcome o;
  o.centre = test::moments(w).centre;
  double lo = 1e30, hi = -1e30;
  size_t n = 0;
  for (const ParticleSet& s : w.sets)
    for (size_t i = 0; i < s.size(); ++i) {
      lo = std::min(lo, double(s.x[i].y()));
      hi = std::max(hi, double(s.x[i].y()));
      const double dj = std::abs(double(s.volumeRatio(i)) - 1.0);
      o.mean_dj += dj;
      o.max_dj = std::max(o.max_dj, dj);
      ++n;
    }
  o.height = hi - lo;
  o.mean_dj /= double(std::max<size_t>(n, 1));
  o.steps = w.steps;
  return o;
}

// A jelly cube (0.12 m, 6 cells, from 0.1 m up at 1 m/s down) dropped on
// the floor, for a given material.
Outcome dropCube(const json& material, double t_end, const std::string& tag,
                 const json& solver = json::object(), double size = 0.4) {
  json j = test::baseScene("extreme", {size, size, size}, 0.02);
  j["materials"]["m"] = material;
  j["solver"] = solver;
  j["objects"].push_back(mpm(box({0.14, 0.1, 0.14}, {0.26, 0.22, 0.26}), {0, -1, 0}));
  World w = test::loadWorld(test::tempDir("extreme"), j);
  const double e0 = mechanicalEnergy(w), scale = energyScale(w);
  Solver solver_(w);
  solver_.advanceTo(t_end);
  expectSane(w, tag, e0, scale);
  // No energy from nowhere: the centre stays below where the drop's energy
  // (start 0.16 m, 1 m/s down) could lift it.
  EXPECT_LT(test::moments(w).centre.y(), 0.16 + 1.0 / (2 * 9.81) + 0.005) << tag;
  const Outcome o = outcome(w);
  std::printf("%s: centre y %.5f, height %.5f, |J-1| mean %.2e largest %.2e, %zu steps\n",
              tag.c_str(), o.centre.y(), o.height, o.mean_dj, o.max_dj, o.steps);
  return o;
}

TEST(Extremes, YoungsModulusFrom1e2To1e10) {
  // Very soft (a 100 Pa jelly flattens) to steel-stiff (dt shrinks to 1e-7
  // s: keep the time short).
  const Outcome soft = dropCube(jelly(1e2), 0.2, "E = 1e2");
  const Outcome mid = dropCube(jelly(1e6), 0.1, "E = 1e6");
  const Outcome stiff = dropCube(jelly(1e10), 0.002, "E = 1e10");
  // 100 Pa cannot hold 0.12 m of jelly up (rho g h = 1200 Pa): it slumps to
  // under half its height. The 1e6 Pa cube bounces and keeps its shape
  // within its elastic strain; the 1e10 Pa one, 2 mm into its fall, keeps it
  // exactly (the particles' extent: 0.12 m less a cell's spacing of them).
  EXPECT_LT(soft.height, 0.5 * mid.height);
  EXPECT_NEAR(mid.height, stiff.height, 0.05 * stiff.height);
  EXPECT_NEAR(stiff.height, 0.12 - 0.01, 1e-4);
  EXPECT_LT(stiff.max_dj, 1e-4);
}

TEST(Extremes, NearlyIncompressible) {
  // At nu = 0.49 (bulk modulus 1.7e6 Pa against shear 3.4e4; at 0.3, 8.3e4)
  // the cube squashes at nearly constant volume: its particles' J stays
  // near 1 while it deforms. Measured: mean |J - 1| 1.3e-3 for both models
  // against 5.9e-3 at nu = 0.3.
  const Outcome c = dropCube(jelly(1e5, 0.3), 0.2, "nu = 0.3");
  const Outcome fc = dropCube(jelly(1e5, 0.49), 0.2, "nu = 0.49");
  json nh = jelly(1e5, 0.49);
  nh["model"] = "neo_hookean";
  const Outcome nhc = dropCube(nh, 0.2, "neo-Hookean nu = 0.49");
  for (const Outcome* o : {&fc, &nhc}) EXPECT_LT(o->mean_dj, 0.3 * c.mean_dj);
}

TEST(Extremes, HugeMaxDtIsCappedByStability) {
  // The step is the stable one whatever max_dt allows: the run is the one
  // with the default max_dt (1 ms), not one of 10 s steps.
  const Outcome huge = dropCube(jelly(1e5), 0.2, "max_dt = 10", {{"max_dt", 10.0}});
  const Outcome ref = dropCube(jelly(1e5), 0.2, "max_dt default");
  EXPECT_GT(huge.steps, 100u);
  EXPECT_NEAR(huge.centre.y(), ref.centre.y(), 1e-6);
  EXPECT_NEAR(huge.height, ref.height, 1e-6);
}

// At 100 m/s into the floor: the walls and the position clamp keep the
// material in the domain; the step shrinks with the speed.
TEST(Extremes, HundredMetresPerSecondImpact) {
  json j = test::baseScene("impact", {0.4, 0.4, 0.4}, 0.02);
  j["materials"]["m"] = {{"model", "drucker_prager"}, {"density", 1600}, {"youngs_modulus", 3.5e5},
                         {"poisson_ratio", 0.3}, {"friction_angle_deg", 30}};
  j["objects"].push_back(mpm(box({0.14, 0.2, 0.14}, {0.26, 0.3, 0.26}), {30, -100, 10}));
  World w = test::loadWorld(test::tempDir("impact100"), j);
  const double e0 = mechanicalEnergy(w), scale = energyScale(w);
  Solver solver(w);
  solver.advanceTo(0.02);
  expectSane(w, "100 m/s", e0, scale);
}

// Rigid balls at 100 m/s into sand, 1:1000 and 1000:1 in density: finite,
// in the domain, not through the floor.
TEST(Extremes, RigidBallsAtHundredMetresPerSecond) {
  for (double ratio : {1e-3, 1e3}) {
    json j = test::baseScene("rigid100", {0.4, 0.4, 0.4}, 0.02);
    j["materials"]["m"] = {{"model", "drucker_prager"}, {"density", 1600},
                           {"youngs_modulus", 3.5e5}, {"poisson_ratio", 0.3},
                           {"friction_angle_deg", 30}};
    j["objects"].push_back(mpm(box({0, 0, 0}, {0.4, 0.1, 0.4})));
    j["objects"].push_back({{"name", "ball"}, {"kind", "rigid"}, {"density", 1600 * ratio},
                            {"friction", 0.5}, {"velocity", {20, -100, 0}},
                            {"shape", {{"sphere", {{"center", {0.2, 0.3, 0.2}}, {"radius", 0.04}}}}}});
    World w = test::loadWorld(test::tempDir("rigid100"), j);
    const double e0 = mechanicalEnergy(w), scale = energyScale(w);
    Solver solver(w);
    solver.advanceTo(0.02);
    const std::string tag = "density ratio " + std::to_string(ratio);
    expectSane(w, tag, e0, scale);
    const Vec3d c = w.bodies[0].state.x;
    std::printf("%s: ball at (%.4f, %.4f), velocity (%.3f, %.3f) m/s\n", tag.c_str(), c.x(), c.y(),
                w.bodies[0].state.v.x(), w.bodies[0].state.v.y());
    EXPECT_GT(c.y(), 0.04 - 0.5 * 0.02) << tag;
    EXPECT_LT(c.x(), 0.4 - 0.04 + 0.5 * 0.02) << tag;
    // The light ball (0.43 g) is stopped by the sand's surface (0.1 m) and
    // thrown back off it (measured: centre 0.227 m, rising at 3.7 m/s); the
    // heavy one (430 kg) ploughs through the bed to the floor (0.040 m).
    if (ratio < 1)
      EXPECT_GT(c.y(), 0.1 + 0.04) << tag;
    else
      EXPECT_LT(c.y(), 0.04 + 0.01) << tag;
  }
}

// Material heading out of the domain at speed stays in, against the wall
// (a separating wall lets it leave the wall, not the domain). At twice the
// water's sound speed it is squeezed against the wall and springs back
// (its centre at 0.145 m after 0.1 s), losing 96% of its energy.
TEST(Extremes, MaterialLeavingTheDomainStaysIn) {
  json j = test::baseScene("leave", {0.4, 0.4, 0.4}, 0.02);
  j["domain"]["boundary"] = {{"type", "separate"}};
  j["materials"]["m"] = {{"model", "water"}, {"density", 1000}, {"bulk_modulus", 1e5}};
  j["objects"].push_back(mpm(box({0.25, 0.1, 0.1}, {0.35, 0.2, 0.2}), {20, 5, 0}));
  World w = test::loadWorld(test::tempDir("leave"), j);
  const double e0 = mechanicalEnergy(w), scale = energyScale(w);
  Solver solver(w);
  solver.advanceTo(0.1);
  expectSane(w, "leaving", e0, scale);

}

// A domain of 4 cells and one of 2000 cells per axis (sparse: only the
// material's blocks exist), relative to dx.
TEST(Extremes, TinyAndHugeDomainsRelativeToDx) {
  auto run = [](const std::string& name, double size, double E, const json& shape, double t) {
    json j = test::baseScene(name, {size, size, size}, 0.02);
    j["materials"]["m"] = jelly(E);
    j["objects"].push_back(mpm(shape));
    World w = test::loadWorld(test::tempDir(name), j);
    const double e0 = mechanicalEnergy(w), scale = energyScale(w);
    Solver solver(w);
    solver.advanceTo(t);
    expectSane(w, name, e0, scale);
  };
  run("tiny", 0.08, 1e4, box({0.02, 0.02, 0.02}, {0.06, 0.06, 0.06}), 0.1);
  run("huge", 40, 1e5, box({0.14, 0.1, 0.14}, {0.26, 0.22, 0.26}), 0.05);
  // A domain 100 times larger is the same simulation where the material
  // does not reach the far walls: the sparse grid holds only its blocks.
  const Outcome small = dropCube(jelly(1e5), 0.05, "in 0.4 m");
  const Outcome large = dropCube(jelly(1e5), 0.05, "in 40 m", json::object(), 40.0);
  EXPECT_NEAR(large.centre.y(), small.centre.y(), 1e-6);
  EXPECT_NEAR(large.height, small.height, 1e-6);
  EXPECT_NEAR(large.mean_dj, small.mean_dj, 1e-6);
}

}  // namespace
}  // namespace triad
