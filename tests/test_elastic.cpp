// Volumetric elastic solids from scene files (issue 5): FEM coupled to MPM
// through its nodes as collision particles, contacts with rigid bodies and
// the domain walls.
#include <gtest/gtest.h>

#include <cmath>

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
// rest on the sand, and no sand ends up inside it.
TEST(Elastic, JellyCubeDroppedOnSand) {
  json j = test::baseScene("jelly_on_sand", {0.4, 0.5, 0.4}, 0.025);
  j["materials"]["sand"] = {{"model", "drucker_prager"}, {"density", 1600},
                            {"youngs_modulus", 3.5e5}, {"poisson_ratio", 0.3},
                            {"friction_angle_deg", 30}};
  j["materials"]["jelly"] = jelly(3e4);
  j["objects"].push_back({{"name", "sand"}, {"kind", "mpm"}, {"material", "sand"},
                          {"shape", box({0, 0, 0}, {0.4, 0.1, 0.4})}});
  j["objects"].push_back(elastic("cube", box({0.12, 0.2, 0.12}, {0.28, 0.36, 0.28}), {0, -2, 0}));
  World w = test::loadWorld(test::tempDir("jelly_on_sand"), j);
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
