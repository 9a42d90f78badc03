// End-to-end physics from scene files, each checked against a number.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "scene_fixture.h"
#include "sim/solver.h"

namespace triad {
namespace {

using nlohmann::json;
using test::box;

json jelly(double E = 1e5) {
  return {{"model", "fixed_corotated"}, {"density", 1000}, {"youngs_modulus", E},
          {"poisson_ratio", 0.3}};
}

json sand(double E = 1e5, double phi = 30) {
  return {{"model", "drucker_prager"}, {"density", 1600}, {"youngs_modulus", E},
          {"poisson_ratio", 0.3}, {"friction_angle_deg", phi}};
}

json mpmObject(const std::string& name, const std::string& mat, const json& shape,
               const std::array<double, 3>& v = {0, 0, 0}) {
  return {{"name", name}, {"kind", "mpm"}, {"material", mat}, {"shape", shape}, {"velocity", v}};
}

// A free-falling body follows y0 - g t^2/2. Symplectic Euler is first order:
// it follows the discrete recurrence exactly, and the parabola to g t dt / 2.
class FreeFall : public ::testing::TestWithParam<std::string> {};

TEST_P(FreeFall, FollowsParabola) {
  json j = test::baseScene("free_fall", {0.4, 2.0, 0.4}, 0.02);
  j["solver"] = {{"transfer", GetParam()}, {"max_dt", 2e-3}};
  j["materials"]["jelly"] = jelly();
  j["objects"].push_back(mpmObject("body", "jelly", box({0.15, 1.6, 0.15}, {0.25, 1.7, 0.25})));
  World w = test::loadWorld(test::tempDir("free_fall_" + GetParam()), j);
  Solver solver(w);
  const double g = 9.81, y0 = test::moments(w).centre.y();
  double v_discrete = 0.0, y_discrete = y0, dt_max = 0.0;
  const double t_end = 0.4;
  solver.advanceTo(t_end, [&](double dt) {
    v_discrete -= g * dt;
    y_discrete += v_discrete * dt;
    dt_max = std::max(dt_max, dt);
  });
  EXPECT_EQ(w.time, t_end);  // lands exactly on the requested time
  const test::Moments m = test::moments(w);
  EXPECT_NEAR(m.centre.y(), y_discrete, 2e-5);
  EXPECT_NEAR(m.centre.y(), y0 - 0.5 * g * t_end * t_end, 0.5 * g * t_end * dt_max + 2e-5);
  EXPECT_NEAR(m.momentum.y() / m.mass, -g * t_end, 1e-4);
  EXPECT_NEAR(m.centre.x(), 0.2, 1e-5);
  // A uniform motion deforms nothing.
  for (const ParticleSet& s : w.sets)
    for (size_t i = 0; i < s.size(); ++i) ASSERT_NEAR(s.v[i].y(), -g * t_end, 1e-4);
}

INSTANTIATE_TEST_SUITE_P(Transfers, FreeFall, ::testing::Values("apic", "pic", "flip"));

// A jelly cube spinning rigidly in free space (gravity off, no stress: the
// model is rotation invariant) tells the transfers apart, where a uniform
// translation cannot: APIC keeps the angular momentum (the particles' and
// their affine matrices' m (dx^2/4) axial(C^T - C)), PIC's round trip
// through the grid loses rotation every step, and FLIP's blend loses less
// the closer its ratio is to 1. Returns L_z after 0.2 s over L_z at start.
double spinKept(const std::string& transfer, double flip_ratio = 0.95) {
  const double dx = 0.02, omega = 5.0;
  json j = test::baseScene("spin_" + transfer, {0.4, 0.4, 0.4}, dx);
  j["gravity"] = {0, 0, 0};
  j["solver"] = {{"transfer", transfer}};
  if (transfer == "flip") j["solver"]["flip_ratio"] = flip_ratio;
  j["materials"]["jelly"] = jelly();
  j["objects"].push_back(mpmObject("cube", "jelly", box({0.15, 0.15, 0.15}, {0.25, 0.25, 0.25})));
  World w = test::loadWorld(test::tempDir("spin_" + transfer), j);
  const Vec3f c(0.2f, 0.2f, 0.2f);
  Mat3f spin;
  spin << 0, -float(omega), 0, float(omega), 0, 0, 0, 0, 0;  // v = omega z x r
  for (ParticleSet& s : w.sets)
    for (size_t i = 0; i < s.size(); ++i) {
      s.v[i] = spin * (s.x[i] - c);
      if (transfer != "pic") s.C[i] = spin;
    }
  const Vec3d o = c.cast<double>();
  auto lz = [&]() { return test::angularMomentum(w, o).z(); };
  const double l0 = lz();
  Solver solver(w);
  solver.advanceTo(0.2);
  return lz() / l0;
}

TEST(Transfers, SpinningCubeTellsThemApart) {
  const double apic = spinKept("apic"), pic = spinKept("pic");
  const double flip = spinKept("flip", 0.95), flip_half = spinKept("flip", 0.5);
  std::printf("angular momentum kept over 0.2 s: apic %.4f, pic %.4f, flip 0.95 %.4f, flip 0.5 %.4f\n",
              apic, pic, flip, flip_half);
  // Measured: apic 1.0000, pic 0.0000 (about 12% of it lost per step:
  // 2 dx^2/4 against the cube's mean r^2), flip 0.95 0.103, flip 0.5 0.000.
  EXPECT_NEAR(apic, 1.0, 2e-3);
  EXPECT_LT(pic, 0.02);
  EXPECT_GT(flip, 0.05);
  EXPECT_GT(flip, flip_half + 0.05) << "flip_ratio makes no difference";
}

// With gravity off and no walls touched, P2G and G2P conserve linear
// momentum exactly; only float round-off remains.
TEST(Momentum, ConservedInCollisionWithoutGravity) {
  json j = test::baseScene("momentum", {1, 1, 1}, 0.02);
  j["gravity"] = {0, 0, 0};
  j["materials"]["jelly"] = jelly();
  j["materials"]["sand"] = sand();
  j["materials"]["water"] = {{"model", "water"}, {"density", 1000}, {"bulk_modulus", 2e5},
                             {"viscosity", 0.01}};
  j["objects"].push_back(
      mpmObject("jelly", "jelly", box({0.2, 0.4, 0.4}, {0.4, 0.6, 0.6}), {2.0, 0.3, 0}));
  j["objects"].push_back(
      mpmObject("sand", "sand", box({0.45, 0.42, 0.38}, {0.6, 0.6, 0.6}), {-1.5, 0, 0.2}));
  j["objects"].push_back(
      mpmObject("water", "water", box({0.62, 0.4, 0.4}, {0.72, 0.5, 0.5}), {-2.0, 0.5, 0}));
  World w = test::loadWorld(test::tempDir("momentum"), j);
  Solver solver(w);
  const test::Moments before = test::moments(w);
  solver.advanceTo(0.1);
  const test::Moments after = test::moments(w);
  ASSERT_GT(solver.record().steps, 50);
  for (int d = 0; d < 3; ++d)
    EXPECT_NEAR(after.momentum[d], before.momentum[d], 2e-6 * before.abs_momentum) << "axis " << d;
  // The bodies did collide: kinetic energy was lost to deformation and plasticity.
  EXPECT_LT(after.kinetic, 0.9 * before.kinetic);
}

// A shear wave in viscous water decays as exp(-nu k^2 t): water filling a
// box between slip walls (gravity off) with v_x = A cos(pi y / H), which
// meets the walls' no-stress condition and carries no net flux, measured in
// the middle third along x, away from the end walls. Returns A(t)/A(0).
double shearWaveKept(double viscosity, double t) {
  const double H = 0.2, dx = 0.02;
  json j = test::baseScene("shear_wave", {0.6, H, 0.1}, dx);
  j["gravity"] = {0, 0, 0};
  j["materials"]["water"] = {{"model", "water"}, {"density", 1000}, {"bulk_modulus", 1e5},
                             {"viscosity", viscosity}};
  j["objects"].push_back(mpmObject("water", "water", box({0, 0, 0}, {0.6, H, 0.1})));
  World w = test::loadWorld(test::tempDir("shear_wave"), j);
  const double k = M_PI / H;
  for (ParticleSet& s : w.sets)
    for (size_t i = 0; i < s.size(); ++i) {
      const float c = float(std::cos(k * s.x[i].y()));
      s.v[i] = Vec3f(0.1f * c, 0, 0);
      if (!s.C.empty()) s.C[i] << 0, float(-0.1 * k * std::sin(k * s.x[i].y())), 0, 0, 0, 0, 0, 0, 0;
    }
  auto amplitude = [&]() {
    double a = 0, n = 0;
    for (const ParticleSet& s : w.sets)
      for (size_t i = 0; i < s.size(); ++i) {
        if (s.x[i].x() < 0.2 || s.x[i].x() > 0.4) continue;
        a += s.v[i].x() * std::cos(k * s.x[i].y());
        n += std::cos(k * s.x[i].y()) * std::cos(k * s.x[i].y());
      }
    return a / n;
  };
  const double a0 = amplitude();
  Solver solver(w);
  solver.advanceTo(t);
  return amplitude() / a0;
}

TEST(Water, ShearWaveDecaysAtTheViscousRate) {
  const double t = 0.3, mu = 10.0, k = M_PI / 0.2;
  const double viscous = shearWaveKept(mu, t), inviscid = shearWaveKept(0.0, t);
  const double expected = std::exp(-mu / 1000.0 * k * k * t);
  std::printf("shear wave kept over %.1f s: viscous %.3f (exp(-nu k^2 t) = %.3f), inviscid %.3f\n",
              t, viscous, expected, inviscid);
  // The grid's own loss (ten cells per half wavelength) is divided out:
  // measured inviscid 0.450 and viscous 0.189, a ratio of 0.42 against
  // exp(-nu k^2 t) = 0.477 (the effective viscosity 14% high); at dx = 0.01,
  // 0.924 and 0.398, ratio 0.43. Bounds: the ratio within 20% of the
  // analytic decay (no viscosity: 1; twice it: 0.23), the grid's own loss
  // no worse than measured with a margin.
  EXPECT_NEAR(viscous / inviscid, expected, 0.2 * expected);
  EXPECT_GT(inviscid, 0.35);
}

// A jelly cube dropped on the floor bounces, no higher than it fell, and
// stays finite.
TEST(Jelly, BouncesOnFloor) {
  json j = test::baseScene("jelly_bounce", {0.6, 0.8, 0.6}, 0.02);
  j["materials"]["jelly"] = jelly(5e4);
  j["objects"].push_back(mpmObject("cube", "jelly", box({0.2, 0.3, 0.2}, {0.4, 0.5, 0.4})));
  World w = test::loadWorld(test::tempDir("jelly_bounce"), j);
  Solver solver(w);
  double min_vy = 0.0, max_vy_after = -1e9, min_y = 1e9;
  bool hit = false;
  for (int k = 1; k <= 60; ++k) {
    solver.advanceTo(k * 0.01);
    const test::Moments m = test::moments(w);
    const double vy = m.momentum.y() / m.mass;
    min_vy = std::min(min_vy, vy);
    min_y = std::min(min_y, m.centre.y());
    if (vy > 0.0) hit = true;
    if (hit) max_vy_after = std::max(max_vy_after, vy);
    for (const ParticleSet& s : w.sets)
      for (size_t i = 0; i < s.size(); ++i) {
        ASSERT_TRUE(s.x[i].allFinite() && s.v[i].allFinite());
        ASSERT_GT(s.volumeRatio(i), 0.3f);
        ASSERT_LT(s.volumeRatio(i), 3.0f);
      }
  }
  // Impact speed from a 0.3 m fall (minus what the floor takes in the last steps).
  EXPECT_LT(min_vy, -0.8 * std::sqrt(2 * 9.81 * 0.3));
  ASSERT_TRUE(hit) << "the cube never moved up again";
  EXPECT_GT(max_vy_after, 0.5) << "the bounce is too weak";
  // And no stronger than the impact: the floor gives no energy back that
  // the fall did not bring (the elastic energy stored on impact returns at
  // most all of the kinetic energy). Measured: 2.34 m/s in, 1.97 out
  // (restitution 0.84).
  std::printf("jelly bounce: impact %.3f m/s, rebound %.3f m/s (restitution %.2f)\n", -min_vy,
              max_vy_after, max_vy_after / -min_vy);
  EXPECT_LT(max_vy_after, -min_vy) << "the bounce gained energy";
  // Tighter, from the measurement (deterministic at this dx) with 0.02 of
  // margin: a floor that throws material back 3% harder than it came
  // (restitution 0.87) fails here.
  EXPECT_LT(max_vy_after / -min_vy, 0.86);
  // It never sank into the floor: the centre stays above half the cube's height.
  EXPECT_GT(min_y, 0.05);
}

// A block sliding on a floor with Coulomb friction mu decelerates at mu g
// (measured: within 1% at dx = 0.02; finer grids add friction from contact
// stress waves, about 5% at dx = 0.01).
TEST(Walls, SlidingBlockDeceleratesAtMuG) {
  const double mu = 0.3, v0 = 2.0, g = 9.81;
  json j = test::baseScene("slide", {1.0, 0.3, 0.3}, 0.02);
  j["domain"]["boundary"] = {{"type", "slip"}, {"friction", mu}};
  j["materials"]["block"] = jelly(1e6);
  j["objects"].push_back(
      mpmObject("block", "block", box({0.1, 0.0, 0.1}, {0.2, 0.1, 0.2}), {v0, 0, 0}));
  World w = test::loadWorld(test::tempDir("slide"), j);
  Solver solver(w);
  solver.advanceTo(0.05);
  const double v1 = test::moments(w).momentum.x() / test::moments(w).mass;
  solver.advanceTo(0.45);
  const double v2 = test::moments(w).momentum.x() / test::moments(w).mass;
  EXPECT_NEAR((v1 - v2) / 0.4, mu * g, 0.05 * mu * g);
  // Frictionless walls would keep it at v0; sticky would stop it at once.
  EXPECT_GT(v2, 0.5);
}

// Profile slope of a granular heap: fit h(r) where the heap is between 20%
// and 80% of its height; returns the angle in degrees.
double heapAngle(const World& w, double cx, double cz, double dr) {
  std::vector<double> h(200, 0.0);
  for (const ParticleSet& s : w.sets)
    for (size_t i = 0; i < s.size(); ++i) {
      const double r = std::hypot(s.x[i].x() - cx, s.x[i].z() - cz);
      const size_t b = std::min<size_t>(h.size() - 1, size_t(r / dr));
      h[b] = std::max(h[b], double(s.x[i].y()));
    }
  const double top = *std::max_element(h.begin(), h.end());
  double sr = 0, sh = 0, srr = 0, srh = 0;
  int n = 0;
  for (size_t b = 0; b < h.size(); ++b) {
    if (h[b] < 0.2 * top || h[b] > 0.8 * top) continue;
    const double r = (b + 0.5) * dr;
    sr += r, sh += h[b], srr += r * r, srh += r * h[b], ++n;
  }
  if (n < 3) return 90.0;
  const double slope = (n * srh - sr * sh) / (n * srr - sr * sr);
  return std::atan(std::abs(slope)) * 180.0 / M_PI;
}

// A low sand column slumped into a heap after 0.75 s: the angle of its
// flanks, and the fastest particle's speed.
std::pair<double, double> heapOf(double phi) {
  json j = test::baseScene("sand_heap_" + std::to_string(int(phi)), {0.6, 0.3, 0.6}, 0.015);
  j["domain"]["boundary"] = {{"type", "slip"}, {"friction", 0.6}};
  j["materials"]["sand"] = sand(1e5, phi);
  j["objects"].push_back(mpmObject("column", "sand", box({0.2, 0.0, 0.2}, {0.4, 0.1, 0.4})));
  World w = test::loadWorld(test::tempDir("sand_heap_" + std::to_string(int(phi))), j);
  Solver solver(w);
  solver.advanceTo(0.75);
  double max_speed = 0.0;
  for (const ParticleSet& s : w.sets)
    for (size_t i = 0; i < s.size(); ++i) max_speed = std::max(max_speed, double(s.v[i].norm()));
  return {heapAngle(w, 0.3, 0.3, 0.015), max_speed};
}

// The heap's flanks come to rest no steeper than the friction angle, and
// steeper the higher the angle (a fluid would spread flat). MPM heaps stand
// below phi at this resolution, so each alone is bounded loosely (0.55 phi
// to phi + 1 degree); what pins the friction angle's effect is the
// difference between the two heaps, asserted at half the measured one.
// Measured: 20 degrees -> 17.8, 35 -> 23.2 (5.4 apart); with the model's
// angle fixed at 25 whatever the scene says, the two tie and this fails.
TEST(SandHeap, AngleFollowsTheFrictionAngle) {
  const auto [low, low_speed] = heapOf(20.0);
  const auto [high, high_speed] = heapOf(35.0);
  std::printf("heap angles: phi 20 -> %.1f deg, phi 35 -> %.1f deg\n", low, high);
  for (const auto& [phi, angle, speed] :
       {std::tuple{20.0, low, low_speed}, std::tuple{35.0, high, high_speed}}) {
    EXPECT_LT(speed, 0.02) << "the heap for phi " << phi << " has not come to rest";
    EXPECT_LE(angle, phi + 1.0);
    EXPECT_GE(angle, 0.55 * phi) << "sand flowed out like a fluid";
  }
  EXPECT_GT(high - low, 2.7) << "the heap's angle does not follow the friction angle";
}

// The largest displacement of any particle of the first set after `t`
// seconds from the world's start.
double largestDisplacement(World& w, double t) {
  const std::vector<Vec3f> x0 = w.sets[0].x;
  const std::vector<uint32_t> id0 = w.sets[0].id;
  Solver solver(w);
  solver.advanceTo(t);
  std::vector<Vec3f> start(id0.size());
  for (size_t i = 0; i < id0.size(); ++i) start[id0[i] - id0.front()] = x0[i];
  double most = 0;
  const ParticleSet& s = w.sets[0];
  for (size_t i = 0; i < s.size(); ++i)
    most = std::max(most, double((s.x[i] - start[s.id[i] - id0.front()]).norm()));
  return most;
}

// Sand of `model` and angle phi shaped by the mesh in `dir`, at rest on a
// rough fixed floor (friction 1) between frictionless domain walls.
World sandOnRoughFloor(const std::string& name, const std::filesystem::path& dir,
                       const std::string& model, double phi, const Vec3d& size, double dx) {
  json j = test::baseScene(name, {size.x(), size.y(), size.z()}, dx);
  j["domain"]["min"] = {0, -0.02, 0};
  j["domain"]["boundary"] = {{"type", "slip"}, {"friction", 0}};
  j["materials"]["sand"] = sand(1e5, phi);
  j["materials"]["sand"]["model"] = model;
  j["objects"].push_back({{"name", "floor"},
                          {"kind", "rigid"},
                          {"fixed", true},
                          {"density", 1000},
                          {"friction", 1.0},
                          {"shape", box({0, -0.02, 0}, {size.x(), 0, size.z()})}});
  j["objects"].push_back(
      mpmObject("heap", "sand", {{"mesh", {{"path", (dir / "heap.obj").string()}}}}));
  return test::loadWorld(dir, j);
}

// A plane-strain wedge of sand (a triangular prism 4 cells thick between
// frictionless walls, on a rough fixed floor) with flanks at slope beta,
// after 0.5 s: the largest displacement of any particle. Infinite-slope
// stability says cohesionless sand holds its flanks iff beta <= phi.
double wedgeDisplacement(const std::string& model, double phi, double beta) {
  const double dx = 0.01, b = 0.15, h = b * std::tan(beta * M_PI / 180), z = 4 * dx;
  const std::string name = "wedge_" + model + "_" + std::to_string(int(beta));
  const std::filesystem::path dir = test::tempDir(name);
  {
    std::ofstream obj(dir / "heap.obj");
    for (const double zz : {0.0, z})
      obj << "v " << 0.3 - b << " 0 " << zz << "\nv " << 0.3 + b << " 0 " << zz << "\nv 0.3 "
          << h << " " << zz << "\n";
    obj << "f 1 3 2\nf 4 5 6\nf 1 2 5\nf 1 5 4\nf 2 3 6\nf 2 6 5\nf 3 1 4\nf 3 4 6\n";
  }
  World w = sandOnRoughFloor(name, dir, model, phi, {0.6, 0.15, z}, dx);
  return largestDisplacement(w, 0.5);
}

// Mohr-Coulomb holds a plane-strain slope below its friction angle and lets
// one above it fail; Drucker-Prager's cone, fitted in triaxial compression,
// is stronger in plane strain and holds the steeper slope too. Measured
// (phi 30, dx 0.01) at 0.5 s: beta 26: 0.5 mm (MC); beta 34: 11.8 mm (MC),
// 1.3 mm (DP); at 1 s the MC wedge of 34 degrees has moved 15.7 mm and
// still moves, the DP one rests.
TEST(SandWedge, MohrCoulombHoldsItsFrictionAngleInPlaneStrain) {
  const double dx = 0.01;
  const double below = wedgeDisplacement("mohr_coulomb", 30, 26);
  const double above = wedgeDisplacement("mohr_coulomb", 30, 34);
  const double cone = wedgeDisplacement("drucker_prager", 30, 34);
  std::printf("wedge, largest displacement in 0.5 s: MC 26 deg %.4f m, MC 34 deg %.4f m, "
              "DP 34 deg %.4f m\n", below, above, cone);
  EXPECT_LT(below, 0.2 * dx);
  EXPECT_GT(above, 0.5 * dx);
  EXPECT_LT(cone, 0.3 * dx);
}

// The same in 3D: a cone of sand of base radius 0.15 m with flanks at
// slope beta, a quarter of it in the corner of frictionless walls (its
// planes of symmetry), after 0.5 s. Mohr-Coulomb's strength does not depend
// on the intermediate principal stress, so the hoop stress does not hold a
// cone steeper than phi: its flanks hold iff beta <= phi, as in plane strain.
// Measured (phi 30, dx 0.01) at 0.5 s, Mohr-Coulomb: beta 26 / 28 / 32 / 34:
// 0.5 / 0.9 / 2.8 / 7.5 mm (a slope just above phi fails slowly, from its
// surface); Drucker-Prager: 26: 0.5 mm, 34: 2.1 mm.
double coneDisplacement(const std::string& model, double phi, double beta) {
  const double dx = 0.01, b = 0.15, h = b * std::tan(beta * M_PI / 180);
  const std::string name = "cone_" + model + "_" + std::to_string(int(beta));
  const std::filesystem::path dir = test::tempDir(name);
  {
    std::ofstream obj(dir / "heap.obj");
    const int sides = 96;
    for (int k = 0; k < sides; ++k)
      obj << "v " << b * std::cos(2 * M_PI * k / sides) << " 0 "
          << b * std::sin(2 * M_PI * k / sides) << "\n";
    obj << "v 0 " << h << " 0\nv 0 0 0\n";
    for (int k = 0; k < sides; ++k) {
      const int i = k + 1, n = (k + 1) % sides + 1;
      obj << "f " << i << " " << sides + 1 << " " << n << "\nf " << i << " " << n << " "
          << sides + 2 << "\n";
    }
  }
  World w = sandOnRoughFloor(name, dir, model, phi, {0.25, 0.15, 0.25}, dx);
  return largestDisplacement(w, 0.5);
}

TEST(SandCone, MohrCoulombHoldsItsFrictionAngleIn3D) {
  const double dx = 0.01;
  const double below = coneDisplacement("mohr_coulomb", 30, 26);
  const double above = coneDisplacement("mohr_coulomb", 30, 34);
  std::printf("cone, largest displacement in 0.5 s: MC 26 deg %.4f m, MC 34 deg %.4f m\n", below,
              above);
  EXPECT_LT(below, 0.2 * dx);
  EXPECT_GT(above, 0.5 * dx);
}

// Snow compacts under load as Stomakhin et al.'s hardening says. A snow
// column 0.1 m high fills a box of frictionless walls under gravity 200 m/s^2
// (its bottom carries 8 kPa, twice the yield stress theta_c (2 mu + lambda) =
// 3.9 kPa of confined compression). Where the load sigma exceeds the yield
// stress the elastic stretch sits at 1 - theta_c and the moduli have hardened
// by exp(xi (1 - Jp)) = sigma / yield, so each layer's volume ratio is
//   J = (1 - theta_c) (1 - ln(sigma / yield) / xi),   else J = 1 - sigma / M.
// The column's mean height follows from integrating J over the load. The
// load arrives at once, so the column overshoots and keeps the plastic part
// of the overshoot: the measured mean height lies between the static answer
// for the load and for twice the load (a suddenly applied load reaches at
// most twice its static strain). Measured (PIC, dx 0.01 m, 1 s): xi 5:
// 0.04377 m in [0.03957, 0.04554]; xi 20: 0.04721 in [0.04647, 0.04802].
// Without hardening the column collapses to 0.032 m; a solver that ignored
// xi (always 10: 0.0458) fails both; a purely elastic one (at least 0.0466)
// fails xi 5.
class SnowColumn : public ::testing::TestWithParam<double> {};

double snowColumnMeanHeight(double xi, double load_factor) {
  constexpr double E = 1.4e5, nu = 0.2, rho = 400, H = 0.1, g = 200, theta_c = 0.025;
  const double mu = E / (2 * (1 + nu)), lambda = E * nu / ((1 + nu) * (1 - 2 * nu));
  const double M = 2 * mu + lambda, yield = theta_c * M;
  // Mean height = (1/H) integral over the reference depth s of (H - s) J(sigma(s)).
  const int n = 4000;
  double mean = 0;
  for (int i = 0; i < n; ++i) {
    const double s = (i + 0.5) / n * H, sigma = load_factor * rho * g * (H - s);
    const double J =
        sigma <= yield ? 1 - sigma / M : (1 - theta_c) * (1 - std::log(sigma / yield) / xi);
    mean += (H - s) * J * (H / n) / H;
  }
  return mean;
}

TEST_P(SnowColumn, CompactsAsHardeningSays) {
  const double xi = GetParam();
  json j = test::baseScene("snow_column", {0.1, 0.2, 0.1}, 0.01);
  j["gravity"] = {0, -200, 0};
  j["solver"] = {{"transfer", "pic"}};
  j["materials"]["snow"] = {{"model", "snow"}, {"density", 400}, {"youngs_modulus", 1.4e5},
                            {"poisson_ratio", 0.2}, {"hardening", xi}};
  j["objects"].push_back(mpmObject("snow", "snow", box({0, 0, 0}, {0.1, 0.1, 0.1})));
  World w = test::loadWorld(test::tempDir("snow_column"), j);
  Solver solver(w);
  solver.advanceTo(1.0);
  double mean = 0;
  size_t n = 0;
  for (const ParticleSet& set : w.sets)
    for (size_t i = 0; i < set.size(); ++i, ++n) mean += set.x[i].y();
  mean /= double(n);
  const double stat = snowColumnMeanHeight(xi, 1), twice = snowColumnMeanHeight(xi, 2);
  std::printf("snow xi %.0f: mean height %.5f m, static %.5f, static at twice the load %.5f\n", xi,
              mean, stat, twice);
  EXPECT_LT(mean, stat);
  EXPECT_GT(mean, twice);
}

INSTANTIATE_TEST_SUITE_P(Hardening, SnowColumn, ::testing::Values(5.0, 20.0));

}  // namespace
}  // namespace triad
