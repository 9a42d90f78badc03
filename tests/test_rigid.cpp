// Rigid bodies on their own: mass properties, free rotation, contacts with
// the domain walls and with each other.
#include <gtest/gtest.h>

#include <cmath>

#include "scene_fixture.h"
#include "sim/solver.h"

namespace triad {
namespace {

using nlohmann::json;
using test::box;

json rigid(const std::string& name, const json& shape, double density = 500,
           const std::array<double, 3>& v = {0, 0, 0}, const std::array<double, 3>& w = {0, 0, 0}) {
  return {{"name", name}, {"kind", "rigid"}, {"density", density}, {"shape", shape},
          {"velocity", v}, {"angular_velocity", w}};
}

json sphere(const std::array<double, 3>& c, double r) {
  return {{"sphere", {{"center", c}, {"radius", r}}}};
}

// A box's mass and inertia are exact when its faces lie on sample cells.
TEST(RigidBody, BoxMassProperties) {
  json j = test::baseScene("props", {1, 1, 1}, 0.05);
  j["objects"].push_back(rigid("b", box({0.2, 0.3, 0.4}, {0.6, 0.5, 0.5}), 800));
  const World w = test::loadWorld(test::tempDir("rigid_props"), j);
  ASSERT_EQ(w.bodies.size(), 1u);
  const RigidBody& b = w.bodies[0];
  const double a = 0.4, h = 0.2, c = 0.1, m = 800 * a * h * c;
  EXPECT_NEAR(b.mass, m, 1e-6 * m);
  EXPECT_NEAR((b.state.x - Vec3d(0.4, 0.4, 0.45)).norm(), 0.0, 1e-6);
  // Principal moments, sorted: m (h^2 + c^2)/12 etc.
  Vec3d expect(m * (h * h + c * c) / 12, m * (a * a + c * c) / 12, m * (a * a + h * h) / 12);
  Vec3d got = b.moments;
  std::sort(expect.data(), expect.data() + 3);
  std::sort(got.data(), got.data() + 3);
  EXPECT_NEAR((got - expect).norm() / expect.norm(), 0.0, 1e-4);
  EXPECT_TRUE(b.orientation().isApprox(Quatd::Identity(), 1e-9));
}

// Torque-free rotation of an asymmetric body, about its unstable middle axis
// (the tumbling "Dzhanibekov" case, the hardest for an integrator): angular
// momentum is kept exactly and the energy to a bounded error.
TEST(RigidBody, FreeSpinKeepsMomentumAndEnergy) {
  json j = test::baseScene("spin", {2, 2, 2}, 0.05);
  j["gravity"] = {0, 0, 0};
  j["solver"] = {{"max_dt", 2e-3}};
  j["objects"].push_back(
      rigid("b", box({0.7, 0.9, 0.95}, {1.3, 1.1, 1.05}), 500, {0, 0, 0}, {0.1, 8.0, 0.2}));
  World w = test::loadWorld(test::tempDir("rigid_spin"), j);
  RigidBody& b = w.bodies[0];
  const Vec3d L0 = b.state.L, x0 = b.state.x;
  const double E0 = b.kineticEnergy();
  Solver solver(w);
  double e_min = E0, e_max = E0;
  Vec3d w_min = b.omega(), w_max = b.omega();
  for (int k = 0; k < 40; ++k) {
    solver.advanceTo(0.1 * (k + 1));
    const double e = b.kineticEnergy();
    e_min = std::min(e_min, e);
    e_max = std::max(e_max, e);
    // Angular velocity in the body's own (rest) axes.
    const Vec3d wb = b.orientation().conjugate() * b.omega();
    w_min = w_min.cwiseMin(wb);
    w_max = w_max.cwiseMax(wb);
  }
  EXPECT_LT((b.state.L - L0).norm(), 1e-12 * L0.norm());
  EXPECT_LT((e_max - e_min) / E0, 2e-3);
  // It really tumbles: seen from the body, the spin flips over (the
  // intermediate axis theorem)...
  EXPECT_LT(w_min.y(), -4.0);
  // ...and the centre stays put.
  EXPECT_LT((b.state.x - x0).norm(), 1e-12);
}

// A falling box lands on the floor and rests on it: one spacing of slack.
TEST(RigidBody, FallsAndRestsOnTheFloor) {
  json j = test::baseScene("floor", {1, 1, 1}, 0.05);
  j["objects"].push_back(
      rigid("b", box({0.3, 0.5, 0.3}, {0.7, 0.6, 0.7}), 500, {0, 0, 0}, {0.0, 0.0, 0.0}));
  World w = test::loadWorld(test::tempDir("rigid_floor"), j);
  Solver solver(w);
  solver.advanceTo(0.4);  // it lands at t = 0.32 s
  const RigidBody& b = w.bodies[0];
  // Resting: the centre half the height above the floor, still to within a
  // small fraction of a cell (speculative contacts let it settle into the
  // last gap at most).
  double lo = 1e9, hi = -1e9;
  for (int k = 1; k <= 30; ++k) {
    solver.advanceTo(0.4 + 0.02 * k);
    lo = std::min(lo, b.state.x.y());
    hi = std::max(hi, b.state.x.y());
  }
  EXPECT_GT(lo, 0.05 - 0.05 * 0.02);
  EXPECT_LT(hi, 0.05 + 0.05 * 0.05);
  EXPECT_LT(b.omega().norm(), 1e-3);
  EXPECT_NEAR(b.state.x.x(), 0.5, 1e-6);
}

// A box sliding at 1 m/s on a frictional surface stops after v^2 / (2 mu g)
// (0.170 m at mu = 0.3), without turning: on the domain's floor (wall
// friction) and on a fixed rigid slab (the pair's coefficient, the geometric
// mean of theirs). Returns the distance slid in 0.6 s.
double slideDistance(bool on_slab, double mu) {
  const std::string name = on_slab ? "slide_slab" : "slide_floor";
  json j = test::baseScene(name, {1, 0.5, 0.4}, 0.025);
  double floor = 0.0;
  if (on_slab) {
    floor = 0.1;
    json slab = rigid("slab", box({0, 0, 0}, {1, 0.1, 0.4}), 2000);
    slab["fixed"] = true;
    slab["friction"] = mu;
    j["objects"].push_back(slab);
  } else {
    j["domain"]["boundary"] = {{"type", "slip"}, {"friction", mu}};
  }
  json b = rigid("box", box({0.1, floor, 0.15}, {0.2, floor + 0.1, 0.25}), 500, {1, 0, 0});
  b["friction"] = 0.3;
  j["objects"].push_back(b);
  World w = test::loadWorld(test::tempDir(name), j);
  const RigidBody& box = w.bodies.back();
  const double x0 = box.state.x.x();
  Solver solver(w);
  double spin = 0.0, sink = 0.0, bob = 0.0;
  for (int k = 1; k <= 30; ++k) {
    solver.advanceTo(0.02 * k);
    spin = std::max(spin, box.omega().norm());
    sink = std::max(sink, std::abs(box.state.x.y() - floor - 0.05));
    bob = std::max(bob, std::abs(box.state.v.y()));
  }
  EXPECT_LT(spin, 0.05) << name << ": the box turned";
  // It rides on the surface. On the slab it rode up to 6 mm low, bobbing at
  // up to 0.24 m/s, while the slab's distance answered only inside it.
  EXPECT_LT(sink, 0.001) << name;
  EXPECT_LT(bob, 0.01) << name;
  if (mu > 0.0) {
    EXPECT_LT(std::abs(box.state.v.x()), 0.01) << name << ": it did not stop";
  }
  return box.state.x.x() - x0;
}

TEST(RigidBody, SlidingStopsAtTheCoulombDistance) {
  const double expected = 1.0 / (2 * 0.3 * 9.81);
  const double floor = slideDistance(false, 0.3), slab = slideDistance(true, 0.3);
  const double free_slab = slideDistance(true, 0.0);
  std::printf("sliding 1 m/s at mu 0.3: floor %.4f m, slab %.4f m (v^2/(2 mu g) %.4f); "
              "frictionless slab %.4f m in 0.6 s\n", floor, slab, expected, free_slab);
  // Measured: 0.1694 (-0.3%), 0.1694, 0.6000. Before the pair contacts
  // required facing normals, the box on the slab spun up to 2.5 rad/s, even
  // frictionless (1.7 rad/s), and slid 0.284 m; before the slab's distance
  // answered just outside it (the envelope of its sample planes), the box
  // rode into it and slid 0.1827 m (+7.5%).
  EXPECT_NEAR(floor, expected, 0.02 * expected);
  EXPECT_NEAR(slab, expected, 0.02 * expected);
  EXPECT_NEAR(free_slab, 0.6, 0.01 * 0.6);
}

// At 20 m/s towards a wall, with steps limited only by max_dt, the body
// stops at the wall: speculative contacts close exactly the gap.
TEST(RigidBody, FastImpactStopsAtTheWall) {
  json j = test::baseScene("impact", {1, 1, 1}, 0.05);
  j["gravity"] = {0, 0, 0};
  j["objects"].push_back(
      rigid("b", sphere({0.5, 0.5, 0.5}, 0.1), 500, {20, 0, 0}, {0, 0, 0}));
  World w = test::loadWorld(test::tempDir("rigid_impact"), j);
  Solver solver(w);
  for (int k = 1; k <= 20; ++k) {
    solver.advanceTo(0.005 * k);
    ASSERT_LT(w.bodies[0].state.x.x(), 1.0 - 0.1 + 0.02) << "through the wall at step " << k;
  }
  EXPECT_NEAR(w.bodies[0].state.x.x(), 0.9, 0.03);
  EXPECT_LT(w.bodies[0].state.v.x(), 0.1);  // inelastic: it stopped
}

// Two boxes thrown at each other do not pass through each other; the
// collision is inelastic and conserves momentum.
TEST(RigidBody, BodiesDoNotPassThroughEachOther) {
  json j = test::baseScene("pair", {2, 1, 1}, 0.05);
  j["gravity"] = {0, 0, 0};
  j["objects"].push_back(rigid("a", box({0.5, 0.4, 0.4}, {0.7, 0.6, 0.6}), 500, {3, 0, 0}));
  j["objects"].push_back(rigid("b", box({1.3, 0.45, 0.45}, {1.4, 0.55, 0.55}), 2000, {-3, 0, 0}));
  World w = test::loadWorld(test::tempDir("rigid_pair"), j);
  const Vec3d p0 = w.bodies[0].mass * w.bodies[0].state.v + w.bodies[1].mass * w.bodies[1].state.v;
  Solver solver(w);
  double min_gap = 1e9;
  for (int k = 1; k <= 60; ++k) {
    solver.advanceTo(0.005 * k);
    const RigidBody& a = w.bodies[0];
    const RigidBody& b = w.bodies[1];
    // Face of a at x + 0.1, face of b at x - 0.05.
    min_gap = std::min(min_gap, (b.state.x.x() - 0.05) - (a.state.x.x() + 0.1));
  }
  const RigidBody& a = w.bodies[0];
  const RigidBody& b = w.bodies[1];
  const Vec3d p1 = a.mass * a.state.v + b.mass * b.state.v;
  EXPECT_GT(min_gap, -0.5 * 0.05 / 2) << "penetrated more than half a sample spacing";
  EXPECT_LT((p1 - p0).norm(), 1e-6 * (a.mass + b.mass) * 3);
  // After the inelastic hit they move together at the momentum's speed.
  const double v_common = p0.x() / (a.mass + b.mass);
  EXPECT_NEAR(a.state.v.x(), v_common, 0.05 * 3);
  EXPECT_NEAR(b.state.v.x(), v_common, 0.05 * 3);
}

// A ball (radius 4 cm, samples at dx/2 = 1 cm) dropped 5 mm onto a fixed
// slab comes to rest on its top, wherever it lies against the lattices:
// the ball's lowest samples sit up to 9 mm above its bottom, and they must
// meet the slab before they reach it. The slab's distance was asked only
// in cells holding one of its samples, inside it, so the ball sank until
// those samples did: 9.2, 8.2 and 5.5 mm into the slab (0.27-0.46 dx) at
// the three placements here. Through the envelope of the slab's sample
// planes, which answers in the cells just outside it too: 0.4, 1.3 and
// 0.2 mm.
class BallOnSlab : public ::testing::TestWithParam<std::array<double, 2>> {};

TEST_P(BallOnSlab, RestsOnTheTopNotInIt) {
  const auto [across, up] = GetParam();
  const double dx = 0.02, r = 0.04, top = 0.08;
  json j = test::baseScene("ball_on_slab", {0.4, 0.4, 0.4}, dx);
  json slab = rigid("slab", box({0.06, 0, 0.06}, {0.34, top, 0.34}), 2500);
  slab["fixed"] = true;
  j["objects"].push_back(slab);
  const double start = top + 0.005 + up + r;
  j["objects"].push_back(rigid("ball", sphere({0.2 + across, start, 0.2 + across}, r), 1000));
  World w = test::loadWorld(test::tempDir("ball_on_slab"), j);
  const RigidBody& ball = w.bodies[1];
  Solver solver(w);
  solver.advanceTo(1.0);
  const double bottom = ball.state.x.y() - r;
  std::printf("ball placed %.4f m across, %.4f m up: its bottom rests %+.2f mm from the top\n",
              across, up, 1e3 * (bottom - top));
  EXPECT_NEAR(bottom, top, 0.1 * dx);
  EXPECT_LT(ball.state.v.norm(), 0.01);
  EXPECT_LT(std::hypot(ball.state.x.x() - 0.2 - across, ball.state.x.z() - 0.2 - across), 0.001);
}

INSTANTIATE_TEST_SUITE_P(Placements, BallOnSlab,
                         ::testing::Values(std::array<double, 2>{0.0, 0.0},
                                           std::array<double, 2>{0.005, 0.0025},
                                           std::array<double, 2>{0.0025, 0.0025}));

// The push-out skips particles outside a body's lattice box: the box must
// hold every point where the body's distance answers (turned and moved as
// the body is), and be much tighter than the bounding sphere for a wall.
TEST(RigidBody, LatticeBoxHoldsEveryPointTheDistanceAnswers) {
  json j = test::baseScene("lattice_box", {1, 1, 1}, 0.02);
  j["objects"].push_back(rigid("wall", box({0.2, 0.47, 0.4}, {0.8, 0.53, 0.6}), 800));
  World w = test::loadWorld(test::tempDir("rigid_lattice_box"), j);
  RigidBody& b = w.bodies[0];
  b.state.q_principal =
      (Quatd(Eigen::AngleAxisd(0.7, Vec3d(1, 2, 3).normalized())) * b.state.q_principal)
          .normalized();
  b.state.x += Vec3d(0.013, -0.021, 0.008);
  const Mat3d R = b.rotation();
  const LatticeBox lattice = b.latticeBox();
  uint64_t seed = 12345;
  auto uniform = [&] {
    seed = seed * 6364136223846793005ull + 1442695040888963407ull;
    return double(seed >> 11) * 0x1.0p-53 * 2.0 - 1.0;
  };
  int answered = 0, in_sphere = 0, culled = 0;
  for (int k = 0; k < 200000; ++k) {
    const Vec3d p = b.state.x + double(b.radius) * Vec3d(uniform(), uniform(), uniform());
    if ((p - b.state.x).norm() > b.radius) continue;
    ++in_sphere;
    double phi;
    Vec3d n;
    const bool reach = lattice.mayReach(p, 0.0);
    culled += reach ? 0 : 1;
    if (!b.distanceAt(p, R, phi, n)) continue;
    ++answered;
    ASSERT_TRUE(reach) << "a point with a distance outside the box: " << p.transpose();
  }
  EXPECT_GT(answered, 1000);
  // The wall (0.6 x 0.06 x 0.2 m) fills a small part of its sphere.
  EXPECT_GT(culled, in_sphere * 8 / 10) << culled << " of " << in_sphere;
  // A sphere about a point misses the box only when no point of it is in.
  const Vec3d beside = b.state.x + R * (b.principal.conjugate() * Vec3d(0, 0.03 + 0.05, 0));
  EXPECT_TRUE(lattice.mayReach(beside, 0.06));
}

}  // namespace
}  // namespace triad
