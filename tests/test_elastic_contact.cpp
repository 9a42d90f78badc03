// Contacts of elastic solids (issue 5): for implicit solids the domain
// walls and rigid bodies act inside the backward Euler solve, so that a
// stiff solid taking steps far beyond its explicit limit lands without
// distorting; and elastic solids meet each other.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "scene_fixture.h"
#include "sim/solver.h"

namespace triad {
namespace {

using nlohmann::json;
using test::box;

struct Extent {
  Vec3d lo = Vec3d::Constant(1e9), hi = Vec3d::Constant(-1e9);
};

Extent extent(const FemBody& b) {
  Extent e;
  for (const Vec3d& x : b.x) e.lo = e.lo.cwiseMin(x), e.hi = e.hi.cwiseMax(x);
  return e;
}

// Largest change of any node's distance to the body's first node: zero for
// a rigid motion, so it measures distortion.
double distortion(const FemBody& b) {
  double worst = 0.0;
  for (size_t i = 1; i < b.nodes(); ++i)
    worst = std::max(worst, std::abs((b.x[i] - b.x[0]).norm() -
                                     (b.mesh.nodes[i] - b.mesh.nodes[0]).norm()));
  return worst;
}

// A stiff cube (E = 1e8 Pa: an explicit step of 5e-5 s) dropped at 2 m/s
// with 2 ms steps, onto the floor or onto a fixed rigid slab. Contacts in
// the solve stop it within a step as one body; acting after the solve, they
// would stop only its lowest nodes and let the rest run into them.
class ImplicitLanding : public ::testing::TestWithParam<std::string> {};

TEST_P(ImplicitLanding, StopsWithoutDistortingOrPenetrating) {
  const bool slab = GetParam() == "slab";
  json j = test::baseScene("implicit_landing_" + GetParam(), {0.3, 0.4, 0.3}, 0.05);
  j["solver"] = {{"max_dt", 2e-3}};
  j["materials"]["stiff"] = {{"model", "fixed_corotated"}, {"density", 1000},
                             {"youngs_modulus", 1e8}, {"poisson_ratio", 0.3}};
  const double floor = slab ? 0.1 : 0.0;
  if (slab)
    j["objects"].push_back({{"name", "slab"}, {"kind", "rigid"}, {"density", 1000},
                            {"fixed", true}, {"shape", box({0, 0, 0}, {0.3, 0.1, 0.3})}});
  j["objects"].push_back({{"name", "cube"}, {"kind", "elastic"}, {"material", "stiff"},
                          {"integrator", "implicit"},
                          {"shape", box({0.1, floor + 0.05, 0.1}, {0.2, floor + 0.15, 0.2})},
                          {"velocity", {0, -2, 0}}});
  World w = test::loadWorld(test::tempDir("implicit_landing_" + GetParam()), j);
  Solver solver(w);
  const FemBody& b = w.elastics[0].fem;
  ASSERT_LT(b.stableDt(1.0), 1e-4);
  double worst = 0.0, lowest = 1e9;
  for (int k = 1; k <= 20; ++k) {
    solver.advanceTo(0.02 * k);
    worst = std::max(worst, distortion(b));
    lowest = std::min(lowest, extent(b).lo.y());
  }
  const Extent e = extent(b);
  // Shape kept to 2% of its 0.1 m side throughout (the static strain under
  // its own weight is 5e-5).
  EXPECT_LT(worst, 2e-3) << GetParam();
  // Never more than 2.5 mm (a twentieth of a cell) into the floor, and
  // resting on it.
  EXPECT_GT(lowest, floor - 0.0025) << GetParam();
  EXPECT_NEAR(e.lo.y(), floor, 0.0025) << GetParam();
  double speed = 0.0;
  for (const Vec3d& v : b.v) speed = std::max(speed, v.norm());
  EXPECT_LT(speed, 0.05) << GetParam();
}

INSTANTIATE_TEST_SUITE_P(Obstacles, ImplicitLanding, ::testing::Values("floor", "slab"));

// A dynamic rigid ball laid on an implicit cube resting on the floor: the
// cube's contact with the ball is in its solve, the reaction holds the ball
// up, and the floor carries both.
TEST(ImplicitContact, RigidBallRestsOnImplicitCube) {
  json j = test::baseScene("implicit_ball_on_cube", {0.3, 0.5, 0.3}, 0.05);
  j["solver"] = {{"max_dt", 2e-3}};
  j["materials"]["stiff"] = {{"model", "fixed_corotated"}, {"density", 1000},
                             {"youngs_modulus", 1e6}, {"poisson_ratio", 0.3}};
  j["objects"].push_back({{"name", "cube"}, {"kind", "elastic"}, {"material", "stiff"},
                          {"integrator", "implicit"}, {"friction", 0.5},
                          {"shape", box({0.075, 0.0, 0.075}, {0.225, 0.15, 0.225})}});
  j["objects"].push_back({{"name", "ball"}, {"kind", "rigid"}, {"density", 2000}, {"friction", 0.5},
                          {"shape", {{"sphere", {{"center", {0.15, 0.2, 0.15}}, {"radius", 0.05}}}}}});
  World w = test::loadWorld(test::tempDir("implicit_ball_on_cube"), j);
  Solver solver(w);
  auto energy = [&w]() {
    const FemBody& c = w.elastics[0].fem;
    const RigidBody& r = w.bodies[0];
    double e = c.kineticEnergy() + c.elasticEnergy() + r.kineticEnergy() + 9.81 * r.mass * r.state.x.y();
    for (size_t i = 0; i < c.nodes(); ++i) e += 9.81 * c.mass[i] * c.x[i].y();
    return e;
  };
  const double e0 = energy();
  double highest = e0;
  for (int k = 1; k <= 25; ++k) {
    solver.advanceTo(0.02 * k);
    highest = std::max(highest, energy());
  }
  // No energy gained from the staggered reaction: at most a fifth of the
  // ball's m g R, 0.1 J, in the elastic energy of a contact's first step (one
  // staggered pass, or the reaction applied at the node rather than on the
  // normal's line, gains 0.8 J and sets the ball spinning).
  EXPECT_LT(highest, e0 + 0.1);
  const FemBody& b = w.elastics[0].fem;
  const RigidBody& ball = w.bodies[0];
  const Extent e = extent(b);
  // The ball sits on the cube's top (within half a cell), not in it.
  EXPECT_NEAR(ball.state.x.y() - 0.05, e.hi.y(), 0.025);
  EXPECT_LT(ball.state.v.norm(), 0.1);
  EXPECT_NEAR(e.lo.y(), 0.0, 0.0025);
  // The cube is pressed by the ball, but not crushed.
  EXPECT_GT(e.hi.y(), 0.14);
}

// A jelly slab (E 1e5 Pa, density 1000, friction 0.5, explicit) between lo
// and hi, in a 0.4 m box at dx 0.02: the first object.
json jellySlabScene(const std::string& name, const std::array<double, 3>& lo,
                    const std::array<double, 3>& hi) {
  json j = test::baseScene(name, {0.4, 0.4, 0.4}, 0.02);
  j["materials"]["jelly"] = {{"model", "fixed_corotated"},
                             {"density", 1000},
                             {"youngs_modulus", 1e5},
                             {"poisson_ratio", 0.3}};
  j["objects"].push_back({{"name", "slab"},
                          {"kind", "elastic"},
                          {"material", "jelly"},
                          {"friction", 0.5},
                          {"shape", box(lo, hi)}});
  return j;
}

// A rigid ball (radius 4 cm) dropped 5 mm onto an explicit jelly slab
// (E 1e5 Pa, 8 cm thick, undamped) on the floor, one as dense as the jelly
// and one a hundredth of it: neither may rise above where it was dropped
// from, both stay on the slab, and neither rolls off along a diagonal.
// Measured over 0.5 s: after landing the dense ball bounces on the ringing
// jelly to 0.4 mm under its start, the light one to 1.0 mm under it;
// they move sideways at 5 and 0 mm/s at 0.5 s. Faults this catches, each
// measured:
// - The nodes under a ball were found only once inside a cell that holds
//   one of its samples, up to a cell deep, and thrown out at that depth
//   over one step, the ball taking their whole change: the light ball was
//   thrown 23 cm up and off the slab (the dense one bounced 16 mm above
//   its start, spinning at 15 rad/s, in the same scene run at 24 frames a
//   second; stepped to this test's frame times it stayed under).
// - With the envelope sample's own normal, the four samples round the
//   ball's lowest point, tilted along the diagonals, nearly tie, and the
//   one that won by rounding pushed the ball along its diagonal: the light
//   ball rolled at 13 cm/s by 0.5 s, the dense one at 2 cm/s.
// The same with the slab implicit and sampled at dx (its nodes then
// outweigh the light ball): after landing the balls bounce to 4.0 and 4.2
// mm under their start and do not roll. The plain block Gauss-Seidel of
// the implicit solve against the ball gave the light ball, in each step's
// last pass, more than the nodes' whole approach: it bounced 2.3 mm above
// its start and rolled at 2.8 cm/s at 0.5 s.
struct JellyCase {
  double ball_density;
  bool implicit;
  double sample_spacing;  // the slab's, m
};

class BallOnJelly : public ::testing::TestWithParam<JellyCase> {};

TEST_P(BallOnJelly, BouncesNoHigherThanItFell) {
  const JellyCase c = GetParam();
  const double density = c.ball_density, r = 0.04;
  const std::string name =
      "ball_on_jelly_" + std::to_string(int(density)) + (c.implicit ? "_implicit" : "_explicit");
  json j = jellySlabScene(name, {0.1, 0, 0.1}, {0.3, 0.08, 0.3});
  j["objects"][0]["integrator"] = c.implicit ? "implicit" : "explicit";
  j["objects"][0]["sample_spacing"] = c.sample_spacing;
  World w = test::loadWorld(test::tempDir(name), j);
  const double top = extent(w.elastics[0].fem).hi.y(), start = top + r + 0.005;
  j["objects"].push_back({{"name", "ball"},
                          {"kind", "rigid"},
                          {"density", density},
                          {"friction", 0.5},
                          {"shape", {{"sphere", {{"center", {0.2, start, 0.2}}, {"radius", r}}}}}});
  w = test::loadWorld(test::tempDir(name), j);
  const RigidBody& ball = w.bodies[0];
  Solver solver(w);
  double highest = -1.0;
  bool landed = false;
  for (int k = 1; k <= 100; ++k) {
    solver.advanceTo(0.005 * k);
    landed = landed || ball.state.v.y() > 0.0;
    if (landed) highest = std::max(highest, ball.state.x.y());
  }
  std::printf(
      "ball of density %.0f on a jelly: highest after landing %+.2f mm from its start, "
      "at 0.5 s %.4f m, rolling at %.3f m/s\n",
      density, 1e3 * (highest - start), ball.state.x.y(),
      std::hypot(ball.state.v.x(), ball.state.v.z()));
  ASSERT_TRUE(landed);
  EXPECT_LT(highest, start);
  EXPECT_GT(ball.state.x.y(), top);  // on the slab, not through it or off it
  EXPECT_LT(std::hypot(ball.state.v.x(), ball.state.v.z()), 0.02);
}

INSTANTIATE_TEST_SUITE_P(Cases, BallOnJelly,
                         ::testing::Values(JellyCase{1000.0, false, 0.01},
                                           JellyCase{10.0, false, 0.01},
                                           JellyCase{1000.0, true, 0.02},
                                           JellyCase{10.0, true, 0.02}),
                         [](const ::testing::TestParamInfo<JellyCase>& p) {
                           return std::string(p.param.implicit ? "Implicit" : "Explicit") +
                                  (p.param.ball_density < 100.0 ? "LightBall" : "DenseBall");
                         });

// A light rigid cube (8 cm, density 10: 5 g) dropped flat at 1 m/s onto
// an explicit jelly slab meets the nodes under its face together: it
// lands level and is not thrown sideways. Measured at 0.04 s (frames 5 ms
// apart): 5 mm/s sideways, turning at 0.13 rad/s. Pushed one node at a
// time in node order, each against the velocity the nodes before it left,
// the first nodes took the cube's whole approach on one side: it left at
// 0.10 m/s sideways, turning at 1.8 rad/s. (The landing is sensitive to
// the steps: stepped straight to 0.04 s, the old pushes happened to land
// it level, 3 mm/s and 0.3 rad/s.)
TEST(ElasticContact, LightCubeLandsFlatOnAJelly) {
  json j = jellySlabScene("cube_on_jelly", {0.06, 0, 0.06}, {0.34, 0.08, 0.34});
  j["objects"].push_back({{"name", "cube"},
                          {"kind", "rigid"},
                          {"density", 10},
                          {"friction", 0.5},
                          {"velocity", {0, -1, 0}},
                          {"shape", box({0.16, 0.085, 0.16}, {0.24, 0.165, 0.24})}});
  World w = test::loadWorld(test::tempDir("cube_on_jelly"), j);
  const RigidBody& cube = w.bodies[0];
  Solver solver(w);
  for (int k = 1; k <= 8; ++k) solver.advanceTo(0.005 * k);
  const double sideways = std::hypot(cube.state.v.x(), cube.state.v.z());
  std::printf("light cube on a jelly at 0.04 s: %.4f m/s sideways, turning at %.3f rad/s\n",
              sideways, cube.omega().norm());
  EXPECT_GT(cube.state.x.y(), 0.08);  // landed on the slab, not through it
  EXPECT_LT(sideways, 0.02);
  EXPECT_LT(cube.omega().norm(), 0.5);
}

json jelly() {
  return {{"model", "fixed_corotated"}, {"density", 1000}, {"youngs_modulus", 2e4},
          {"poisson_ratio", 0.3}};
}

json cube(const std::string& name, const std::array<double, 3>& lo, double side,
          const std::array<double, 3>& v) {
  return {{"name", name}, {"kind", "elastic"}, {"material", "jelly"}, {"friction", 0.3},
          {"shape", box(lo, {lo[0] + side, lo[1] + side, lo[2] + side})}, {"velocity", v}};
}

// Points well inside q's tetrahedra: all barycentric weights above 0.05,
// more than a twentieth of an element deep.
int deepPoints(const std::vector<Vec3d>& points, const FemBody& q) {
  int count = 0;
  for (const Vec3d& x : points)
    for (const auto& n : q.mesh.tets) {
      const std::array<double, 4> w = barycentric(q.x, n, x);
      if (*std::min_element(w.begin(), w.end()) > 0.05) {
        ++count;
        break;
      }
    }
  return count;
}

// A stiff implicit cube (E = 1e7: explicit step 6e-5 s), 10 cm, its bottom
// at `bottom` and falling at `speed`, on a bed of sand 0.1 m deep (dx 0.05
// m), coupled through the three grids at the MPM's steps (0.83-1 ms)
// with `passes` elastic contact passes. Its lowest node every 0.05 s to
// 0.05 * frames, its largest distortion, and the most sand particles found
// deep inside it at any of those times.
struct StiffCubeRun {
  std::vector<double> lo;
  double distortion = 0.0;
  int deep = 0;
};
StiffCubeRun stiffCubeOnSand(double bottom, double speed, int passes, int frames) {
  json j = test::baseScene("implicit_on_sand", {0.3, 0.4, 0.3}, 0.05);
  j["solver"] = {{"elastic_contact_passes", passes}};
  j["materials"]["sand"] = {{"model", "drucker_prager"}, {"density", 1600},
                            {"youngs_modulus", 3.5e5}, {"poisson_ratio", 0.3},
                            {"friction_angle_deg", 30}};
  j["materials"]["stiff"] = {{"model", "fixed_corotated"}, {"density", 1000},
                             {"youngs_modulus", 1e7}, {"poisson_ratio", 0.3}};
  j["objects"].push_back({{"name", "sand"}, {"kind", "mpm"}, {"material", "sand"},
                          {"shape", box({0, 0, 0}, {0.3, 0.1, 0.3})}});
  j["objects"].push_back({{"name", "cube"},
                          {"kind", "elastic"},
                          {"material", "stiff"},
                          {"integrator", "implicit"},
                          {"friction", 0.5},
                          {"shape", box({0.1, bottom, 0.1}, {0.2, bottom + 0.1, 0.2})},
                          {"velocity", {0, -speed, 0}}});
  World w = test::loadWorld(test::tempDir("implicit_on_sand"), j);
  Solver solver(w);
  const FemBody& b = w.elastics[0].fem;
  StiffCubeRun run;
  for (int k = 1; k <= frames; ++k) {
    solver.advanceTo(0.05 * k);
    run.distortion = std::max(run.distortion, distortion(b));
    std::vector<Vec3d> sand;
    for (const ParticleSet& s : w.sets)
      for (size_t i = 0; i < s.size(); ++i) sand.push_back(s.x[i].cast<double>());
    run.deep = std::max(run.deep, deepPoints(sand, b));
    run.lo.push_back(extent(b).lo.y());
  }
  return run;
}

// Dropped at 2 m/s: no sand ends up inside it (particles found in its mesh
// are moved out through the face they entered by; without that, grains end
// deep inside and the cube sinks to 0.047 m), it keeps its shape, and it
// comes to rest on the surface (measured: its lowest node at 0.1004-0.1006
// m from 0.2 s to 0.5 s). With the contract's one pass
// (elastic_contact_passes 0) it does not rest: its lowest node sinks from
// 0.0940 to 0.0849 m over 0.25-0.5 s, because the points at its face read
// back only part of each node's collision (bench/RESULTS.md, "Why a stiff
// elastic solid creeps into sand").
TEST(ImplicitContact, StiffCubeOnSandKeepsSandOut) {
  const StiffCubeRun run = stiffCubeOnSand(0.2, 2.0, 8, 10);
  EXPECT_EQ(run.deep, 0);
  EXPECT_LT(run.distortion, 2e-3);  // 2% of its side: near rigid, as E = 1e7 is
  std::printf("stiff implicit cube dropped on sand: lowest node %.4f m at 0.25 s, %.4f at 0.5 s\n",
              run.lo[4], run.lo[9]);
  EXPECT_NEAR(run.lo[9], run.lo[4], 0.001);  // at rest
  EXPECT_NEAR(run.lo[9], 0.1, 0.25 * 0.05);  // on the surface, within 0.25 dx
}

// Placed 5 mm over the sand, the resting case: it settles on the
// surface and stays there, within 0.25 dx. Measured: its bottom at 0.0998 m
// at 0.1 s and 0.1006 at 0.5 s (the sand's top particles' centres lie
// half a particle spacing under the surface, at 0.0875 m). With the
// contract's one pass it creeps in at 14 mm/s: 0.0977 m at 0.1 s, 0.0920
// at 0.5 s.
TEST(ImplicitContact, StiffCubePlacedOnSandRests) {
  const StiffCubeRun run = stiffCubeOnSand(0.105, 0.0, 8, 10);
  const StiffCubeRun one = stiffCubeOnSand(0.105, 0.0, 0, 10);
  std::printf(
      "stiff implicit cube placed on sand: bottom %.4f m at 0.1 s, %.4f at 0.5 s; "
      "with one pass %.4f and %.4f\n",
      run.lo[1], run.lo[9], one.lo[1], one.lo[9]);
  EXPECT_NEAR(run.lo[9], 0.1, 0.25 * 0.05);
  EXPECT_NEAR(run.lo[9], run.lo[1], 0.0015);
  EXPECT_EQ(run.deep, 0);
  // The shortfall the passes remove.
  EXPECT_LT(one.lo[9], one.lo[1] - 0.004);
}

// Nodes of p well inside q's tetrahedra.
int deepNodes(const FemBody& p, const FemBody& q) { return deepPoints(p.x, q); }

// Without gravity two jelly cubes meet head on at 1 m/s each: they do not
// pass through each other (without the contact they would, entirely), they
// turn back, and the pair's momentum is kept.
TEST(ElasticPair, HeadOnCollisionKeepsMomentum) {
  json j = test::baseScene("elastic_head_on", {0.6, 0.3, 0.3}, 0.05);
  j["gravity"] = {0, 0, 0};
  j["materials"]["jelly"] = jelly();
  j["objects"].push_back(cube("left", {0.1, 0.1, 0.1}, 0.1, {1, 0, 0}));
  // Sampled finer, so that its nodes do not lie on the other's element
  // faces (as two lattices of one spacing would: a node exactly on a face
  // is neither in nor out).
  json right = cube("right", {0.4, 0.1, 0.1}, 0.1, {-1, 0, 0});
  right["sample_spacing"] = 0.05 / 3;
  j["objects"].push_back(right);
  World w = test::loadWorld(test::tempDir("elastic_head_on"), j);
  Solver solver(w);
  auto momentum = [&w]() {
    Vec3d p = Vec3d::Zero();
    for (const ElasticSolid& e : w.elastics)
      for (size_t i = 0; i < e.fem.nodes(); ++i) p += e.fem.mass[i] * e.fem.v[i];
    return p;
  };
  auto inside = [&w]() {
    return deepNodes(w.elastics[0].fem, w.elastics[1].fem) +
           deepNodes(w.elastics[1].fem, w.elastics[0].fem);
  };
  const double scale = (w.elastics[0].fem.totalMass() + w.elastics[1].fem.totalMass()) * 1.0;
  int worst = 0;
  for (int k = 1; k <= 30; ++k) {
    solver.advanceTo(0.01 * k);
    worst = std::max(worst, inside());
  }
  EXPECT_LT(momentum().norm(), 1e-9 * scale);
  // None of either cube's nodes deep in the other (passing through, most
  // are at some frame).
  EXPECT_EQ(worst, 0);
  // They have met and turned back (or at least stopped).
  EXPECT_LT(w.elastics[0].fem.v[0].x() - w.elastics[1].fem.v[0].x(), 0.2);
}

// A jelly cube slides at 1 m/s over a stiff elastic slab that rests on a
// floor of friction 1: with friction 0.3 on both it stops after v^2 / (2 mu g)
// = 0.170 m, frictionless it keeps its speed. Measured: 0.1694 m (-0.3%;
// -3.5% while nodes lying on one of the other's side planes were held by
// that side); frictionless 0.2000 m in 0.2 s. Before a node barely inside the other
// solid left through its nearest face, the slab's surface nodes that the
// cube's leading face swept over were stopped as at a wall: the cube went
// 0.080 m with friction, and frictionless it stopped and slid back (-0.011 m).
double elasticSlide(double mu, double seconds) {
  json j = test::baseScene("elastic_slide", {0.45, 0.3, 0.3}, 0.05);
  j["domain"]["boundary"] = {{"type", "slip"}, {"friction", 1.0}};
  j["materials"]["stiff"] = {{"model", "fixed_corotated"}, {"density", 1000},
                             {"youngs_modulus", 1e6}, {"poisson_ratio", 0.3}};
  j["materials"]["jelly"] = {{"model", "fixed_corotated"}, {"density", 1000},
                             {"youngs_modulus", 1e5}, {"poisson_ratio", 0.3}};
  j["objects"].push_back({{"name", "slab"}, {"kind", "elastic"}, {"material", "stiff"},
                          {"friction", mu}, {"integrator", "implicit"},
                          {"shape", box({0, 0, 0.05}, {0.45, 0.05, 0.25})}});
  j["objects"].push_back({{"name", "cube"}, {"kind", "elastic"}, {"material", "jelly"},
                          {"friction", mu}, {"shape", box({0.05, 0.05, 0.1}, {0.15, 0.15, 0.2})},
                          {"velocity", {1, 0, 0}}});
  World w = test::loadWorld(test::tempDir("elastic_slide"), j);
  auto centre = [&]() {
    Vec3d c = Vec3d::Zero();
    for (const Vec3d& x : w.elastics[1].fem.x) c += x;
    return Vec3d(c / double(w.elastics[1].fem.nodes()));
  };
  const Vec3d c0 = centre();
  Solver solver(w);
  solver.advanceTo(seconds);
  const Vec3d d = centre() - c0;
  EXPECT_LT(std::abs(d.z()), 0.005) << "mu " << mu << ": the cube veered";
  EXPECT_LT(std::abs(d.y()), 0.005) << "mu " << mu << ": the cube left the slab's surface";
  return d.x();
}

TEST(ElasticPair, SlidingStopsAtTheCoulombDistance) {
  const double expected = 1.0 / (2 * 0.3 * 9.81);
  const double with = elasticSlide(0.3, 0.5), without = elasticSlide(0.0, 0.2);
  std::printf("jelly cube sliding on an elastic slab at 1 m/s: mu 0.3 %.4f m (v^2/(2 mu g) %.4f), "
              "frictionless %.4f m in 0.2 s\n", with, expected, without);
  EXPECT_NEAR(with, expected, 0.02 * expected);
  EXPECT_NEAR(without, 0.2, 0.01 * 0.2);
}

// A jelly cube placed on another on a frictional floor (10 cm cubes, dx =
// 0.05 m, 5 x 5 nodes on each face that meets the other). Faults this
// catches, each measured:
// - Kuhn's split of every voxel along the same diagonal made the mesh
//   chiral, and each ring of the pair pushed the upper cube along (-1, 0,
//   -1): 9.2 mm in 2 s explicit, 0.77 mm implicit. The split is mirrored
//   in alternate voxels now.
// - The upper's nodes along its bottom edges lie on the lower's side
//   planes; held by their nearest face, they were held by nothing and sank
//   down the lower's sides, the faces overlapping by 3.5 mm on average
//   (8 mm at the edges). Now by the face turned against their own: 0.2 mm.
// Undamped, the explicit pair bounces (the upper's centre between 0 and 16
// mm down) and rocks on the lower chaotically, 1-7 mm sideways over 2 s
// depending on rounding; backward Euler damps the ringing and the upper
// cube stays put, and so does the explicit pair with a little Kelvin-Voigt
// damping (20 Pa s, a damping ratio of about 0.04 in the pair's bounce):
// 0.000 mm. The bound, 0.5 mm, holds for both.
class ElasticStack : public ::testing::TestWithParam<std::string> {};

TEST_P(ElasticStack, UpperCubeStaysOverTheLower) {
  const bool implicit = GetParam() == "implicit", damped = GetParam() == "damped";
  json j = test::baseScene("elastic_stack_" + GetParam(), {0.4, 0.4, 0.4}, 0.05);
  j["domain"]["boundary"] = {{"type", "slip"}, {"friction", 0.5}};
  j["materials"]["jelly"] = jelly();
  for (int k = 0; k < 2; ++k) {
    json o = {{"name", k ? "upper" : "lower"}, {"kind", "elastic"}, {"material", "jelly"},
              {"friction", 0.5},
              {"shape", box({0.15, 0.1 * k, 0.15}, {0.25, 0.1 * (k + 1), 0.25})}};
    if (implicit) o["integrator"] = "implicit";
    if (damped) o["damping"] = 20.0;
    j["objects"].push_back(o);
  }
  World w = test::loadWorld(test::tempDir("elastic_stack_" + GetParam()), j);
  Solver solver(w);
  auto centre = [](const FemBody& b) {
    Vec3d m = Vec3d::Zero();
    for (const Vec3d& x : b.x) m += x;
    return Vec3d(m / double(b.nodes()));
  };
  const FemBody& lower = w.elastics[0].fem;
  const FemBody& upper = w.elastics[1].fem;
  // The faces that meet: the lower's top nodes and the upper's bottom ones
  // above them at rest.
  std::vector<std::pair<size_t, size_t>> face;
  for (size_t a = 0; a < lower.nodes(); ++a)
    for (size_t b = 0; b < upper.nodes(); ++b)
      if (std::abs(lower.mesh.nodes[a].y() - 0.1) < 1e-6 &&
          (upper.mesh.nodes[b] - lower.mesh.nodes[a]).norm() < 1e-6)
        face.emplace_back(a, b);
  ASSERT_EQ(face.size(), 25u);
  const Vec3d start = centre(upper);
  double worst = 0.0, overlap = 0.0;
  for (int k = 1; k <= 40; ++k) {
    solver.advanceTo(0.05 * k);
    const Vec3d d = centre(upper) - start;
    worst = std::max(worst, std::hypot(d.x(), d.z()));
    // Mean overlap of the faces over the second second.
    if (k > 20)
      for (const auto& [a, b] : face) overlap += (lower.x[a].y() - upper.x[b].y()) / (20.0 * 25.0);
  }
  std::printf("%s: upper cube's largest sideways offset over 2 s %.3f mm, faces' mean overlap "
              "%.2f mm\n", GetParam().c_str(), 1e3 * worst, 1e3 * overlap);
  EXPECT_LT(worst, implicit || damped ? 0.5e-3 : 7.5e-3);
  EXPECT_LT(std::abs(overlap), 1e-3);
  // It rests on the lower cube: down by the pair's sag (about 9 mm at rest)
  // and no more than twice that while ringing, not fallen in.
  EXPECT_GT(centre(upper).y() - start.y(), -0.02);
}

INSTANTIATE_TEST_SUITE_P(Integrators, ElasticStack,
                         ::testing::Values("explicit", "implicit", "damped"));

}  // namespace
}  // namespace triad
