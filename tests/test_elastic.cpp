// Volumetric elastic solids from scene files (issue 5): FEM coupled to MPM
// through its nodes as collision particles, contacts with rigid bodies and
// the domain walls.
#include <gtest/gtest.h>

#include <cmath>

#include "cli_fixture.h"
#include "scene_fixture.h"
#include "sim/solver.h"

namespace triad {
namespace {

using nlohmann::json;
using test::box;

json jelly(double E, double nu = 0.3) {
  return {{"model", "fixed_corotated"}, {"density", 1000}, {"youngs_modulus", E},
          {"poisson_ratio", nu}};
}

json elastic(const std::string& name, const json& shape, const std::array<double, 3>& v = {0, 0, 0}) {
  return {{"name", name}, {"kind", "elastic"}, {"material", "jelly"}, {"friction", 0.5},
          {"shape", shape}, {"velocity", v}};
}

bool finite(const FemBody& b) {
  for (size_t i = 0; i < b.nodes(); ++i)
    if (!std::isfinite(b.x[i].sum() + b.v[i].sum())) return false;
  return true;
}

double height(const FemBody& b) {
  double lo = 1e9, hi = -1e9;
  for (const Vec3d& x : b.x) lo = std::min(lo, x.y()), hi = std::max(hi, x.y());
  return hi - lo;
}

// A jelly cube dropped at 2 m/s on a sand bed squashes on impact, comes to
// rest on the sand, and no sand ends up inside it; with either integrator.
class JellyOnSand : public ::testing::TestWithParam<std::string> {};

TEST_P(JellyOnSand, SquashesAndRests) {
  json j = test::baseScene("jelly_on_sand", {0.4, 0.5, 0.4}, 0.025);
  j["materials"]["sand"] = {{"model", "drucker_prager"}, {"density", 1600},
                            {"youngs_modulus", 3.5e5}, {"poisson_ratio", 0.3},
                            {"friction_angle_deg", 30}};
  j["materials"]["jelly"] = jelly(3e4);
  j["objects"].push_back({{"name", "sand"}, {"kind", "mpm"}, {"material", "sand"},
                          {"shape", box({0, 0, 0}, {0.4, 0.1, 0.4})}});
  json obj = elastic("cube", box({0.12, 0.2, 0.12}, {0.28, 0.36, 0.28}), {0, -2, 0});
  obj["integrator"] = GetParam();
  j["objects"].push_back(obj);
  World w = test::loadWorld(test::tempDir("jelly_on_sand_" + GetParam()), j);
  ASSERT_EQ(w.elastics.size(), 1u);
  const FemBody& cube = w.elastics[0].fem;
  const double h0 = height(cube);
  Solver solver(w);
  double h_min = h0;
  for (int k = 1; k <= 25; ++k) {
    solver.advanceTo(0.02 * k);
    h_min = std::min(h_min, height(cube));
  }
  ASSERT_TRUE(finite(cube));
  EXPECT_LT(h_min, 0.97 * h0);  // it squashed
  double lo = 1e9;
  for (const Vec3d& x : cube.x) lo = std::min(lo, x.y());
  // Resting on the sand's surface (0.1 m), within two cells, not in it.
  EXPECT_GT(lo, 0.1 - 0.05);
  EXPECT_LT(lo, 0.1 + 0.05);
  // At rest as a whole (it still wobbles: jelly has no damping).
  Vec3d p = Vec3d::Zero();
  for (size_t i = 0; i < cube.nodes(); ++i) p += cube.mass[i] * cube.v[i];
  EXPECT_LT((p / cube.totalMass()).norm(), 0.1);
  size_t inside = 0;
  for (const ParticleSet& s : w.sets)
    for (size_t i = 0; i < s.size(); ++i)
      if (s.x[i].y() > lo + 0.025) ++inside;  // above the cube's bottom: on or in it
  EXPECT_EQ(inside, 0u);
}

// Implicit is tested on its own (tests/test_fem.cpp): here, at the MPM's
// step, its sparse factorisation per Newton iteration costs minutes.
INSTANTIATE_TEST_SUITE_P(Integrators, JellyOnSand, ::testing::Values("explicit"));

// integrator: implicit from a scene: a small, stiff cube in free fall takes
// steps limited by its speed only (explicit would need 1e-5 s), falls as a
// body should and keeps its shape. (Contacts act outside the Newton solve
// for now, which at such steps lets a stiff implicit solid distort against
// a wall: not yet tested, see the note.)
TEST(Elastic, ImplicitCubeFromSceneFallsFreely) {
  json j = test::baseScene("implicit_cube", {0.3, 0.6, 0.3}, 0.025);
  j["solver"] = {{"max_dt", 2e-3}};
  j["materials"]["jelly"] = jelly(1e7);
  json obj = elastic("cube", box({0.125, 0.45, 0.125}, {0.175, 0.5, 0.175}), {0, -1, 0});
  obj["integrator"] = "implicit";
  j["objects"].push_back(obj);
  World w = test::loadWorld(test::tempDir("implicit_cube"), j);
  ASSERT_TRUE(w.elastics[0].implicit);
  Solver solver(w);
  EXPECT_GT(solver.stableDt(), 1e-3);  // not the explicit element limit
  const FemBody& b = w.elastics[0].fem;
  auto centre = [&]() {
    double y = 0.0;
    for (size_t i = 0; i < b.nodes(); ++i) y += b.mass[i] * b.x[i].y();
    return y / b.totalMass();
  };
  const double y0 = centre(), t = 0.2;
  solver.advanceTo(t);
  ASSERT_TRUE(finite(b));
  // Backward Euler's gravity lands one step late: within g t dt.
  EXPECT_NEAR(centre(), y0 - 1.0 * t - 0.5 * 9.81 * t * t, 9.81 * t * 2e-3 + 1e-4);
  EXPECT_NEAR(height(b), 0.05, 1e-4);
}

// Very stiff and very soft cubes dropped on the floor stay finite.
TEST(Elastic, StiffAndSoftStayFinite) {
  for (double E : {1e3, 1e9}) {
    json j = test::baseScene("extreme_elastic", {0.3, 0.3, 0.3}, 0.025);
    j["materials"]["jelly"] = jelly(E);
    j["objects"].push_back(elastic("cube", box({0.1, 0.05, 0.1}, {0.2, 0.15, 0.2}), {0, -1, 0}));
    World w = test::loadWorld(test::tempDir("extreme_elastic"), j);
    Solver solver(w);
    solver.advanceTo(E > 1e6 ? 0.01 : 0.3);
    ASSERT_TRUE(finite(w.elastics[0].fem)) << "E = " << E;
    for (const Vec3d& x : w.elastics[0].fem.x) {
      ASSERT_GT(x.y(), -1e-9) << "E = " << E;
      ASSERT_LT(x.y(), 0.3) << "E = " << E;
    }
  }
}

}  // namespace
}  // namespace triad

namespace triad {
namespace {

// A soft column (nu = 0) standing on a fixed rigid slab shortens under its
// own weight by rho g H^2 / (2 E). Nothing damps it, so it oscillates about
// that: the time average over whole periods is the static value.
TEST(Elastic, ColumnOnSlabSagsByRhoGHSquaredOverTwoE) {
  const double E = 5e4, H = 0.2, rho = 1000, g = 9.81;
  json j = test::baseScene("sag", {0.2, 0.4, 0.2}, 0.025);
  j["materials"]["jelly"] = jelly(E, 0.0);
  j["objects"].push_back({{"name", "slab"}, {"kind", "rigid"}, {"density", 2000}, {"fixed", true},
                          {"shape", box({0, 0, 0}, {0.2, 0.05, 0.2})}});
  j["objects"].push_back(elastic("column", box({0.075, 0.05, 0.075}, {0.125, 0.25, 0.125})));
  World w = test::loadWorld(test::tempDir("sag"), j);
  const FemBody& col = w.elastics[0].fem;
  std::vector<size_t> top, bottom;
  for (size_t i = 0; i < col.nodes(); ++i) {
    if (std::abs(col.mesh.nodes[i].y() - 0.25) < 1e-6) top.push_back(i);
    if (std::abs(col.mesh.nodes[i].y() - 0.05) < 1e-6) bottom.push_back(i);
  }
  auto length = [&]() {
    double t = 0.0, b = 0.0;
    for (size_t i : top) t += col.x[i].y() / top.size();
    for (size_t i : bottom) b += col.x[i].y() / bottom.size();
    return t - b;
  };
  Solver solver(w);
  // Period of the first mode 4 H / c = 0.11 s; average over 0.1..0.54 s.
  solver.advanceTo(0.1);
  double sum = 0.0, time = 0.0;
  solver.advanceTo(0.54, [&](double dt) {
    sum += length() * dt;
    time += dt;
  });
  const double sag = H - sum / time;
  const double expect = rho * g * H * H / (2 * E);  // 3.9 mm
  std::printf("column sag %.2f mm, expected %.2f mm\n", sag * 1e3, expect * 1e3);
  EXPECT_NEAR(sag, expect, 0.1 * expect);
}

}  // namespace
}  // namespace triad

namespace triad {
namespace {

// A run killed mid-way (a blow-up injected at a step) and resumed writes the
// same deformed surface, byte for byte, as one that ran through: the
// checkpoint holds the solid's nodes exactly.
TEST(Elastic, ResumedRunWritesTheSameSurface) {
  const auto dir = test::tempDir("elastic_resume");
  json j = test::baseScene("elastic_resume", {0.3, 0.3, 0.3}, 0.025);
  j["frames"] = {{"count", 4}, {"fps", 24}};
  j["materials"]["jelly"] = jelly(3e4);
  j["materials"]["sand"] = {{"model", "drucker_prager"}, {"density", 1600},
                            {"youngs_modulus", 3.5e5}, {"poisson_ratio", 0.3}};
  j["objects"].push_back({{"name", "sand"}, {"kind", "mpm"}, {"material", "sand"},
                          {"shape", box({0, 0, 0}, {0.3, 0.05, 0.3})}});
  j["objects"].push_back(elastic("cube", box({0.1, 0.08, 0.1}, {0.2, 0.18, 0.2}), {0, -1, 0}));
  j["output"] = {{"vdb", false}, {"png", false}};
  const std::string scene = test::writeScene(dir, j);
  auto run = [&](const std::string& out, const std::string& extra, const std::string& env) {
    return test::runTriad(dir, "run " + scene + " --out " + (dir / out).string() +
                                   " --quiet --threads 1 " + extra, env);
  };
  ASSERT_EQ(run("whole", "", "").status, 0);
  // Fail in the last frame (75 steps a frame), then resume from frame 3.
  EXPECT_EQ(run("resumed", "", "TRIAD_FAULT_STEP=250").status, 1);
  ASSERT_EQ(run("resumed", "--resume", "").status, 0);
  for (const char* f : {"bodies/cube.0004.ply", "particles/particles.0004.ply"}) {
    const std::string a = test::slurp(dir / "whole" / f), b = test::slurp(dir / "resumed" / f);
    ASSERT_GT(a.size(), 100u) << f;
    EXPECT_TRUE(a == b) << f << " differs after resuming";
  }
}

}  // namespace
}  // namespace triad
