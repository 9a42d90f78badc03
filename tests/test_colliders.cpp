// Colliders: solids moved exactly by their animation, never by anything
// else. Material meets them through the three-grid contact with the
// collider's own velocity, so friction carries material along a moving
// surface; rigid bodies meet them as an immovable body that moves; and
// what the material does to them is measured like a rigid body's load.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <algorithm>
#include <cstring>
#include <fstream>
#include <functional>
#include <map>

#include "cli_fixture.h"
#include "scene_fixture.h"
#include "sim/solids/collision_particles.h"
#include "sim/solver.h"

namespace triad {
namespace {

using nlohmann::json;
using test::box;

json linearMove(double t1, const std::array<double, 3>& translate) {
  return {{"interpolation", "linear"},
          {"keys", json::array({{{"time", 0.0}}, {{"time", t1}, {"translate", translate}}})}};
}

// A collider plate sliding at 0.5 m/s under a jelly block resting on it
// (friction 1) carries the block up to its speed: mu g = 9.8 m/s^2 gets
// it there in 0.05 s, and static friction keeps it there.
TEST(Collider, MovingPlateCarriesAJellyBlockAtItsSpeed) {
  json j = test::baseScene("plate_carries_jelly", {1.2, 0.4, 0.4}, 0.02);
  j["materials"]["jelly"] = {{"model", "fixed_corotated"}, {"density", 1000},
                             {"youngs_modulus", 5e4}, {"poisson_ratio", 0.3}};
  j["objects"].push_back({{"name", "block"}, {"kind", "mpm"}, {"material", "jelly"},
                          {"shape", box({0.15, 0.1, 0.15}, {0.25, 0.2, 0.25})}});
  j["objects"].push_back({{"name", "plate"}, {"kind", "collider"}, {"friction", 1.0},
                          {"shape", box({0.05, 0.04, 0.05}, {0.45, 0.1, 0.35})},
                          {"animation", linearMove(2.0, {1.0, 0, 0})}});
  World w = test::loadWorld(test::tempDir("plate_carries_jelly"), j);
  ASSERT_EQ(w.bodies.size(), 1u);
  EXPECT_TRUE(w.bodies[0].collider && w.bodies[0].animated);
  Solver solver(w);
  solver.advanceTo(0.3);
  double vx = 0;
  const int n = 5;
  for (int k = 1; k <= n; ++k) {
    solver.advanceTo(0.3 + 0.04 * k);
    vx += test::moments(w, 0).momentum.x() / test::moments(w, 0).mass / n;
  }
  const double plate_x = w.bodies[0].state.x.x();
  std::printf("block at %.4f m/s (plate 0.5), plate centre x %.4f m\n", vx, plate_x);
  EXPECT_NEAR(plate_x, 0.25 + 0.5 * 0.5, 1e-6);  // where the animation says
  EXPECT_NEAR(vx, 0.5, 0.025);
  // The block rides on the plate, not sunk into it.
  EXPECT_GT(test::moments(w, 0).centre.y(), 0.14);
}

// A frictionless moving plate slides under the block and leaves it at rest.
TEST(Collider, FrictionlessPlateLeavesTheBlockBehind) {
  json j = test::baseScene("plate_frictionless", {1.2, 0.4, 0.4}, 0.02);
  j["materials"]["jelly"] = {{"model", "fixed_corotated"}, {"density", 1000},
                             {"youngs_modulus", 5e4}, {"poisson_ratio", 0.3}};
  j["objects"].push_back({{"name", "block"}, {"kind", "mpm"}, {"material", "jelly"},
                          {"shape", box({0.15, 0.1, 0.15}, {0.25, 0.2, 0.25})}});
  j["objects"].push_back({{"name", "plate"}, {"kind", "collider"},
                          {"shape", box({0.05, 0.04, 0.05}, {0.65, 0.1, 0.35})},
                          {"animation", linearMove(2.0, {0.6, 0, 0})}});
  World w = test::loadWorld(test::tempDir("plate_frictionless"), j);
  Solver solver(w);
  solver.advanceTo(0.4);
  const double vx = test::moments(w, 0).momentum.x() / test::moments(w, 0).mass;
  std::printf("frictionless: block at %.4f m/s (plate 0.3)\n", vx);
  EXPECT_LT(std::abs(vx), 0.03);
}

// A paddle spun about y inside a ball of water (gravity off, nothing else
// touching it) sets the water turning its way; the torque the water exerts
// on the paddle, summed over the steps, is the opposite of the water's
// angular momentum change about the paddle's centre.
TEST(Collider, SpinningPaddleTurnsWaterAndFeelsTheOppositeTorque) {
  json j = test::baseScene("paddle_in_water", {0.6, 0.6, 0.6}, 0.02);
  j["gravity"] = {0, 0, 0};
  j["materials"]["water"] = {{"model", "water"}, {"density", 1000}, {"bulk_modulus", 1e5}};
  j["objects"].push_back({{"name", "ball"}, {"kind", "mpm"}, {"material", "water"},
                          {"shape", {{"sphere", {{"center", {0.3, 0.3, 0.3}}, {"radius", 0.2}}}}}});
  json keys = json::array();
  for (int k = 0; k <= 8; ++k)  // a quarter turn every 0.1 s: 2.5 turns a second
    keys.push_back({{"time", 0.1 * k}, {"rotate_deg", {0, 90 * k, 0}}});
  j["objects"].push_back({{"name", "paddle"}, {"kind", "collider"}, {"friction", 0.5},
                          {"shape", box({0.2, 0.22, 0.28}, {0.4, 0.38, 0.32})},
                          {"animation", {{"interpolation", "linear"}, {"keys", keys}}}});
  World w = test::loadWorld(test::tempDir("paddle_in_water"), j);
  const Vec3d o(0.3, 0.3, 0.3);
  EXPECT_TRUE(w.bodies[0].state.x.isApprox(o, 1e-6));  // the box's centroid
  const Vec3d l0 = test::angularMomentum(w, o);
  Solver solver(w);
  solver.advanceTo(0.3);
  const Vec3d dl = test::angularMomentum(w, o) - l0;
  const Vec3d moment = solver.bodyLoads()[0].moment;  // what the water did to the paddle
  std::printf("water dL %.5f %.5f %.5f N m s; paddle took %.5f %.5f %.5f\n", dl.x(), dl.y(),
              dl.z(), moment.x(), moment.y(), moment.z());
  EXPECT_GT(dl.y(), 0.0);      // turning the paddle's way (+y)
  EXPECT_LT(moment.y(), 0.0);  // the water resists it
  EXPECT_NEAR(-moment.y(), dl.y(), 0.1 * dl.y());
  EXPECT_GT(dl.y(), 1e-3);  // a real stir, not noise
}

// A collider floor moving at 0.3 m/s carries a rigid box on it (friction
// 0.5 each) up to its speed; a collider wall then stops a sliding box.
TEST(Collider, MovingFloorCarriesARigidBox) {
  json j = test::baseScene("floor_carries_box", {1.2, 0.4, 0.4}, 0.02);
  j["objects"].push_back({{"name", "box"}, {"kind", "rigid"}, {"density", 500},
                          {"friction", 0.5}, {"shape", box({0.14, 0.102, 0.14}, {0.26, 0.2, 0.26})}});
  j["objects"].push_back({{"name", "floor"}, {"kind", "collider"}, {"friction", 0.5},
                          {"shape", box({0.04, 0.04, 0.04}, {0.5, 0.1, 0.36})},
                          {"animation", linearMove(2.0, {0.6, 0, 0})}});
  World w = test::loadWorld(test::tempDir("floor_carries_box"), j);
  Solver solver(w);
  solver.advanceTo(0.5);
  const RigidBody& b = w.bodies[0];
  std::printf("box at %.4f m/s (floor 0.3), bottom at %.4f m\n", b.state.v.x(),
              b.state.x.y() - 0.049);
  EXPECT_NEAR(b.state.v.x(), 0.3, 0.015);
  EXPECT_NEAR(b.state.x.y(), 0.1 + 0.049, 0.01);  // resting on the floor
}

// A collider floor at 0.3 m/s carries an (explicit) elastic jelly cube
// resting on it (friction 0.5 each) up to its speed: the nodes stopped at
// its surface take Coulomb friction (frictionless, they would stay behind).
TEST(Collider, MovingFloorCarriesAnElasticSolid) {
  json j = test::baseScene("floor_carries_jelly", {1.2, 0.4, 0.4}, 0.02);
  j["materials"]["jelly"] = {{"model", "fixed_corotated"}, {"density", 1000},
                             {"youngs_modulus", 5e4}, {"poisson_ratio", 0.3}};
  j["objects"].push_back({{"name", "cube"}, {"kind", "elastic"}, {"material", "jelly"},
                          {"friction", 0.5}, {"shape", box({0.14, 0.1, 0.14}, {0.24, 0.2, 0.24})}});
  j["objects"].push_back({{"name", "floor"}, {"kind", "collider"}, {"friction", 0.5},
                          {"shape", box({0.04, 0.04, 0.04}, {0.5, 0.1, 0.36})},
                          {"animation", linearMove(2.0, {0.6, 0, 0})}});
  World w = test::loadWorld(test::tempDir("floor_carries_jelly"), j);
  Solver solver(w);
  // The soft cube sways as it is carried (its shear mode rings): its mean
  // speed over 0.4-0.8 s is its centre's travel over that time.
  auto centre = [&](double& ymin) {
    const FemBody& fem = w.elastics[0].fem;
    double mass = 0, x = 0;
    ymin = 1;
    for (size_t i = 0; i < fem.nodes(); ++i) {
      mass += fem.mass[i];
      x += fem.mass[i] * fem.x[i].x();
      ymin = std::min(ymin, fem.x[i].y());
    }
    return x / mass;
  };
  double ymin;
  solver.advanceTo(0.4);
  const double x0 = centre(ymin);
  solver.advanceTo(0.8);
  const double speed = (centre(ymin) - x0) / 0.4;
  std::printf("jelly at %.4f m/s (floor 0.3), lowest node %.4f m\n", speed, ymin);
  EXPECT_NEAR(speed, 0.3, 0.015);
  EXPECT_GT(ymin, 0.1 - 0.005);  // on the floor, not in it
}

// From the command line: the collider's surface in bodies/ each frame where
// its animation puts it, a forces.csv row for it each frame, its pose in
// rigid_states.csv, the source's and sink's counts in run.json; and a run
// killed mid-way and resumed, or run on two threads, writes the same bytes.
TEST(Collider, CacheFollowsTheAnimationAndResumesByteForByte) {
  const std::filesystem::path dir = test::tempDir("collider_cli");
  json j = test::baseScene("collider_cli", {0.6, 0.4, 0.4}, 0.025);
  j["frames"] = {{"count", 4}, {"fps", 20}};
  j["materials"]["sand"] = {{"model", "drucker_prager"}, {"density", 1600},
                            {"youngs_modulus", 3e5}, {"poisson_ratio", 0.3}};
  j["objects"].push_back({{"name", "pile"}, {"kind", "mpm"}, {"material", "sand"},
                          {"shape", box({0.0, 0.0, 0.0}, {0.6, 0.1, 0.4})}});
  j["objects"].push_back(
      {{"name", "blade"}, {"kind", "collider"}, {"friction", 0.3},
       {"shape", box({0.05, 0.05, 0.1}, {0.1, 0.2, 0.3})},
       {"animation",
        {{"interpolation", "smooth"},
         {"keys", json::array({{{"time", 0.0}},
                               {{"time", 0.2}, {"translate", {0.2, 0, 0}}, {"rotate_deg", {0, 0, -20}}}})}}}});
  // A hopper pouring sand in, and a drain at the far end taking it out.
  j["objects"].push_back({{"name", "hopper"}, {"kind", "mpm"}, {"material", "sand"},
                          {"velocity", {0, -1, 0}},
                          {"shape", box({0.4, 0.25, 0.15}, {0.5, 0.3, 0.25})},
                          {"emit", {{"start", 0.05}, {"end", 0.15}}}});
  j["objects"].push_back({{"name", "drain"}, {"kind", "sink"},
                          {"shape", box({0.45, 0.0, 0.0}, {0.6, 0.15, 0.4})}});
  j["output"] = {{"vdb", false}, {"png", false}};
  const std::string scene = test::writeScene(dir, j);
  const auto out = dir / "out", ref = dir / "ref";
  const auto run = [&](const std::filesystem::path& o, const std::string& extra,
                       const std::string& env) {
    return test::runTriad(dir, "run " + scene + " --out " + o.string() + " --quiet " + extra, env);
  };
  test::CliResult r = run(ref, "--threads 1", "");
  ASSERT_EQ(r.status, 0) << r.err;
  // The blade's mesh at frame 4 (t = 0.2, the last key): moved 0.2 m along x.
  const std::string ply = test::slurp(ref / "bodies" / "blade.0004.ply");
  ASSERT_FALSE(ply.empty());
  const std::string states = test::slurp(ref / "bodies" / "rigid_states.csv");
  const std::string last = states.substr(states.rfind("\n4,"));
  double px, py, pz, qw, qx, qy, qz;
  ASSERT_EQ(std::sscanf(last.c_str(), "\n4,%*[^,],blade,%lf,%lf,%lf,%lf,%lf,%lf,%lf", &px, &py, &pz,
                        &qw, &qx, &qy, &qz),
            7)
      << last;
  EXPECT_NEAR(px, 0.275, 1e-6);
  EXPECT_NEAR(py, 0.125, 1e-6);
  EXPECT_NEAR(2 * std::acos(qw) * 180 / M_PI, 20.0, 1e-6);
  EXPECT_NEAR(qz, -std::sin(10 * M_PI / 180), 1e-9);
  // The blade ploughs the sand: the sand pushes back against its motion (-x).
  const std::string forces = test::slurp(ref / "bodies" / "forces.csv");
  double fx_sum = 0;
  int rows = 0;
  for (size_t at = forces.find("\n"); at != std::string::npos && at + 1 < forces.size();
       at = forces.find("\n", at + 1)) {
    double fx;
    if (std::sscanf(forces.c_str() + at + 1, "%*d,%*[^,],blade,%lf", &fx) == 1) fx_sum += fx, ++rows;
  }
  EXPECT_EQ(rows, 4);
  EXPECT_LT(fx_sum, 0.0);

  // Particles in increasing id in every frame, though the hopper's new ones
  // and the drain's removals interleave them (the id is the last of nine
  // 4-byte properties).
  for (int f = 0; f <= 4; ++f) {
    char name[32];
    std::snprintf(name, sizeof name, "particles.%04d.ply", f);
    const std::string bytes = test::slurp(ref / "particles" / name);
    const size_t body = bytes.find("end_header\n") + 11;
    ASSERT_EQ((bytes.size() - body) % 36, 0u);
    int32_t previous = -1;
    for (size_t at = body; at < bytes.size(); at += 36) {
      int32_t id;
      std::memcpy(&id, bytes.data() + at + 32, 4);
      ASSERT_GT(id, previous) << name;
      previous = id;
    }
  }
  // run.json counts what the hopper made and the drain took.
  const json rec = json::parse(test::slurp(ref / "run.json"));
  const uint64_t emitted = rec["particles"]["emitted"]["hopper"].get<uint64_t>();
  const uint64_t removed = rec["particles"]["removed"]["drain"].get<uint64_t>();
  EXPECT_GT(emitted, 500u);
  EXPECT_GT(removed, 500u);
  EXPECT_EQ(rec["particles"]["total"].get<uint64_t>(),
            rec["particles"]["per_object"]["pile"].get<uint64_t>() + emitted - removed);

  // Killed in frame 3, resumed; and on two threads.
  const int64_t steps = json::parse(test::slurp(ref / "run.json"))["steps"].get<int64_t>();
  r = run(out, "--threads 1", "TRIAD_FAULT_STEP=" + std::to_string(steps * 6 / 10));
  ASSERT_EQ(r.status, 1) << r.err;
  r = run(out, "--threads 1 --resume", "");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find("resuming after frame"), std::string::npos) << r.err;
  const auto two = dir / "two";
  ASSERT_EQ(run(two, "--threads 2", "").status, 0);
  for (const auto& o : {out, two}) {
    const json other = json::parse(test::slurp(o / "run.json"));
    EXPECT_EQ(other["particles"]["emitted"], rec["particles"]["emitted"]) << o;
    EXPECT_EQ(other["particles"]["removed"], rec["particles"]["removed"]) << o;
    EXPECT_TRUE(test::slurp(o / "bodies" / "forces.csv") == forces) << o;
    EXPECT_TRUE(test::slurp(o / "bodies" / "rigid_states.csv") == states) << o;
    for (int f = 0; f <= 4; ++f) {
      char name[32];
      std::snprintf(name, sizeof name, "particles.%04d.ply", f);
      EXPECT_TRUE(test::slurp(o / "particles" / name) == test::slurp(ref / "particles" / name))
          << o << " frame " << f;
    }
  }
}

// Writes an icosphere of radius r(frame) at `centre` as dir/NAME.FFFF.obj
// for frames 0..count: one topology, vertices moving.
void writeSphereSequence(const std::filesystem::path& dir, const std::string& name, int count,
                         const std::array<double, 3>& centre,
                         const std::function<double(int)>& radius) {
  const TriSurface unit = primitiveSurface(SphereDesc{{0, 0, 0}, 1.0});
  for (int f = 0; f <= count; ++f) {
    char file[64];
    std::snprintf(file, sizeof file, "%s.%04d.obj", name.c_str(), f);
    std::ofstream out(dir / file);
    const double r = radius(f);
    for (const Vec3f& v : unit.vertices)
      out << "v " << centre[0] + r * v.x() << " " << centre[1] + r * v.y() << " "
          << centre[2] + r * v.z() << "\n";
    for (const auto& t : unit.triangles)
      out << "f " << t[0] + 1 << " " << t[1] + 1 << " " << t[2] + 1 << "\n";
  }
}

// The water's surface height: the mean over every column of cells of its
// highest particle. Sloshing moves water between columns but keeps this
// mean, so it reads the volume below the surface (water, a submerged solid
// and any void the water leaves) whatever the waves do; the tank's corners
// alone swing by 5 cm here.
double meanLevel(const World& w, double dx) {
  std::map<std::pair<int, int>, float> top;
  for (const ParticleSet& s : w.sets)
    for (const Vec3f& x : s.x) {
      auto& t = top[{int(x.x() / dx), int(x.z() / dx)}];
      t = std::max(t, x.y());
    }
  double sum = 0;
  for (const auto& [c, y] : top) sum += y;
  return top.empty() ? 0.0 : sum / double(top.size());
}

// A collider sphere growing inside a closed tank of water (a mesh
// sequence, radius 0.06 -> 0.12 m between 0.3 and 0.8 s) raises the water
// level by the volume it gains over the tank's area (39.6 mm).
TEST(DeformingCollider, GrowingSphereRaisesTheWaterByTheVolumeItGains) {
  const std::filesystem::path dir = test::tempDir("growing_sphere");
  const int frames = 20;
  const double fps = 20, r0 = 0.06, r1 = 0.12;
  writeSphereSequence(dir, "ball", frames, {0.2, 0.14, 0.2}, [&](int f) {
    const double s = std::clamp((f - 6) / 10.0, 0.0, 1.0);
    return r0 + s * (r1 - r0);
  });
  json j = test::baseScene("growing_sphere", {0.4, 0.5, 0.4}, 0.02);
  j["frames"] = {{"count", frames}, {"fps", fps}};
  j["materials"]["water"] = {{"model", "water"}, {"density", 1000}, {"bulk_modulus", 1e5}};
  j["objects"].push_back({{"name", "water"}, {"kind", "mpm"}, {"material", "water"},
                          {"shape", box({0, 0, 0}, {0.4, 0.3, 0.4})}});
  j["objects"].push_back(
      {{"name", "ball"}, {"kind", "collider"}, {"shape", {{"mesh", {{"path", "ball.####.obj"}}}}}});
  World w = test::loadWorld(dir, j);
  ASSERT_EQ(w.bodies.size(), 1u);
  ASSERT_TRUE(w.bodies[0].deform);
  // Bound where they were sampled.
  std::vector<Vec3f> x;
  const Mat3d P = w.bodies[0].principal.toRotationMatrix();
  for (const Vec3f& r : w.bodies[0].r)
    x.push_back((w.bodies[0].pivot + P * r.cast<double>()).cast<float>());
  EXPECT_LT(w.bodies[0].deform->bindingError(x), 1e-6);
  Solver solver(w);
  solver.advanceTo(0.3);
  const double before = meanLevel(w, 0.02);
  // The expanding surface pushes the water at nodes up to a cell and a half
  // ahead of it, and the water it leaves closes in again over about 0.7 s
  // once the growth ends (0.8 s): the level reads 42-48 mm at 0.9-1.4 s, then
  // 37.5-41 mm until 2.8 s. The mean over 1.6-2.2 s.
  solver.advanceTo(1.6);
  double after = 0;
  for (int k = 0; k <= 6; ++k) {
    solver.advanceTo(1.6 + 0.1 * k);
    after += meanLevel(w, 0.02) / 7;
  }
  // The water's own volume is conserved, so the rise is the sphere's.
  const double gained = 4.0 / 3.0 * M_PI * (std::pow(r1, 3) - std::pow(r0, 3));
  const double expect = gained / (0.4 * 0.4);
  size_t inside = 0;
  for (const ParticleSet& s : w.sets)
    for (const Vec3f& p : s.x)
      inside += (p.cast<double>() - Vec3d(0.2, 0.14, 0.2)).norm() < r1 - 0.02;
  std::printf("level %.4f -> %.4f m: rise %.4f m (expected %.4f), %zu particles inside\n",
              before, after, after - before, expect, inside);
  EXPECT_NEAR(after - before, expect, 0.1 * expect);
  EXPECT_EQ(inside, 0u);
  // The collider's mesh in the cache follows the sequence.
  TriSurface s = worldSurface(w.bodies[0]);
  double r = 0;
  for (const Vec3f& v : s.vertices) r += (v.cast<double>() - Vec3d(0.2, 0.14, 0.2)).norm();
  EXPECT_NEAR(r / double(s.vertices.size()), r1, 1e-4);
}

// Writes a box from lo to hi(frame) as dir/NAME.FFFF.obj for frames
// 0..count: one topology, its top face moving.
void writeBoxSequence(const std::filesystem::path& dir, const std::string& name, int count,
                      const std::array<double, 3>& lo,
                      const std::function<std::array<double, 3>(int)>& hi) {
  const TriSurface unit = primitiveSurface(BoxDesc{{0, 0, 0}, {1, 1, 1}});
  for (int f = 0; f <= count; ++f) {
    char file[64];
    std::snprintf(file, sizeof file, "%s.%04d.obj", name.c_str(), f);
    std::ofstream out(dir / file);
    const std::array<double, 3> h = hi(f);
    for (const Vec3f& v : unit.vertices)
      out << "v " << lo[0] + v.x() * (h[0] - lo[0]) << " " << lo[1] + v.y() * (h[1] - lo[1]) << " "
          << lo[2] + v.z() * (h[2] - lo[2]) << "\n";
    for (const auto& t : unit.triangles)
      out << "f " << t[0] + 1 << " " << t[1] + 1 << " " << t[2] + 1 << "\n";
  }
}

// A floor that is a mesh sequence: its top rises from 0.10 to 0.15 m
// between 0.1 and 0.6 s (0.1 m/s), the floor stretching as it goes.
double floorTop(double t) { return 0.10 + 0.1 * std::clamp(t - 0.1, 0.0, 0.5); }

json risingFloorScene(const std::filesystem::path& dir, const std::string& name) {
  const int frames = 16;
  writeBoxSequence(dir, "floor", frames, {0.04, 0.04, 0.04}, [&](int f) {
    return std::array<double, 3>{0.56, floorTop(f / 20.0), 0.36};
  });
  json j = test::baseScene(name, {0.6, 0.4, 0.4}, 0.02);
  j["frames"] = {{"count", frames}, {"fps", 20}};
  j["objects"].push_back({{"name", "floor"}, {"kind", "collider"}, {"friction", 0.5},
                          {"shape", {{"mesh", {{"path", "floor.####.obj"}}}}}});
  return j;
}

// Rigid bodies meet a deforming collider where its surface is now, not
// where its frame 0 was: a box resting on the rising floor is lifted with
// it (before, it fell through to the domain's floor).
TEST(DeformingCollider, LiftsARigidBoxRestingOnIt) {
  const std::filesystem::path dir = test::tempDir("deforming_lifts_box");
  json j = risingFloorScene(dir, "deforming_lifts_box");
  j["objects"].push_back({{"name", "box"}, {"kind", "rigid"}, {"density", 500}, {"friction", 0.5},
                          {"shape", box({0.24, 0.102, 0.14}, {0.36, 0.2, 0.26})}});
  World w = test::loadWorld(dir, j);
  ASSERT_TRUE(w.bodies[0].deform);
  Solver solver(w);
  const RigidBody& b = w.bodies[1];
  solver.advanceTo(0.4);
  const double rising = b.state.v.y();
  solver.advanceTo(0.8);
  const double bottom = b.state.x.y() - 0.049;
  std::printf("box rising at %.4f m/s at 0.4 s (floor 0.1); bottom %.4f m on a floor at %.4f m\n",
              rising, bottom, floorTop(0.8));
  EXPECT_NEAR(rising, 0.1, 0.01);
  EXPECT_NEAR(bottom, floorTop(0.8), 0.01);
}

// Elastic solids too, explicit and implicit: a jelly cube on the rising
// floor is lifted with it, its lowest node no deeper than a quarter cell
// into the floor (the implicit one over 0.4 s, the floor a cell and a half
// up by then: its solve takes 45 ms a step here).
TEST(DeformingCollider, LiftsAnElasticSolidRestingOnIt) {
  for (const char* integrator : {"explicit", "implicit"}) {
    const std::string name = std::string("deforming_lifts_jelly_") + integrator;
    const std::filesystem::path dir = test::tempDir(name);
    json j = risingFloorScene(dir, name);
    j["materials"]["jelly"] = {{"model", "fixed_corotated"}, {"density", 1000},
                               {"youngs_modulus", 5e4}, {"poisson_ratio", 0.3}};
    j["objects"].push_back({{"name", "cube"}, {"kind", "elastic"}, {"material", "jelly"},
                            {"friction", 0.5}, {"integrator", integrator},
                            {"shape", box({0.25, 0.1, 0.15}, {0.35, 0.2, 0.25})}});
    World w = test::loadWorld(dir, j);
    Solver solver(w);
    double deepest = 0;
    const int tenths = std::string(integrator) == "implicit" ? 4 : 8;
    for (int k = 1; k <= tenths; ++k) {
      solver.advanceTo(0.1 * k);
      double lowest = 1;
      for (const Vec3d& x : w.elastics[0].fem.x) lowest = std::min(lowest, x.y());
      deepest = std::max(deepest, floorTop(0.1 * k) - lowest);
    }
    std::printf("%s jelly: deepest node %.4f m into the floor\n", integrator, deepest);
    EXPECT_LT(deepest, 0.005) << integrator;
  }
}

// Sand resting on the rising floor has no particle inside it at any tenth
// of a second. The grid contact keeps it out; the push-out, which now
// queries the collider where its surface is, must not put any in (its
// search for the far side of a thin part would find the holes that a
// stretching surface leaves between its samples: it is not made there).
TEST(DeformingCollider, KeepsMaterialOutOfItself) {
  const std::filesystem::path dir = test::tempDir("deforming_keeps_sand_out");
  json j = risingFloorScene(dir, "deforming_keeps_sand_out");
  j["materials"]["sand"] = {{"model", "drucker_prager"}, {"density", 1600},
                            {"youngs_modulus", 3e5}, {"poisson_ratio", 0.3}};
  j["objects"].push_back({{"name", "sand"}, {"kind", "mpm"}, {"material", "sand"},
                          {"shape", box({0.2, 0.1, 0.12}, {0.4, 0.2, 0.28})}});
  World w = test::loadWorld(dir, j);
  Solver solver(w);
  size_t most = 0;
  for (int k = 1; k <= 8; ++k) {
    solver.advanceTo(0.1 * k);
    size_t inside = 0;
    for (const ParticleSet& s : w.sets)
      for (const Vec3f& x : s.x)
        inside += x.y() < floorTop(0.1 * k) - 0.005 && x.x() > 0.05 && x.x() < 0.55;
    most = std::max(most, inside);
  }
  std::printf("sand: at most %zu particles inside the floor\n", most);
  EXPECT_EQ(most, 0u);
}

// Every frame's file is checked before simulating: a missing one, or one
// of other topology, is exit status 2 naming it.
TEST(DeformingCollider, MissingOrMismatchedFramesAreInputErrors) {
  const std::filesystem::path dir = test::tempDir("sequence_errors");
  writeSphereSequence(dir, "ball", 4, {0.2, 0.2, 0.2}, [](int f) { return 0.05 + 0.01 * f; });
  json j = test::baseScene("sequence_errors", {0.4, 0.4, 0.4}, 0.04);
  j["frames"] = {{"count", 4}, {"fps", 24}};
  j["objects"].push_back(
      {{"name", "ball"}, {"kind", "collider"}, {"shape", {{"mesh", {{"path", "ball.####.obj"}}}}}});
  j["output"] = {{"vdb", false}, {"png", false}, {"ply", false}};
  const auto run = [&](const json& scene) {
    return test::runTriad(dir, "run " + test::writeScene(dir, scene) + " --out " +
                                   (dir / "out").string() + " --quiet");
  };
  ASSERT_EQ(run(j).status, 0);
  // The scene's hash covers the sequence: with a frame changed, its
  // checkpoints are refused.
  writeSphereSequence(dir, "ball", 4, {0.2, 0.2, 0.2}, [](int f) { return 0.05 + 0.012 * f; });
  test::CliResult r = test::runTriad(dir, "run " + (dir / "scene.json").string() + " --out " +
                                              (dir / "out").string() + " --quiet --resume");
  EXPECT_EQ(r.status, 2) << r.err;
  EXPECT_NE(r.err.find("refusing to resume"), std::string::npos) << r.err;
  // One frame more than the files.
  json longer = j;
  longer["frames"]["count"] = 5;
  r = run(longer);
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("objects[0].shape.mesh.path"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("ball.0005.obj"), std::string::npos) << r.err;
  // Frame 3 of other topology (a triangle less).
  {
    std::ifstream in(dir / "ball.0003.obj");
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    text.erase(text.rfind("f "));
    std::ofstream(dir / "ball.0003.obj") << text;
  }
  r = run(j);
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("ball.0003.obj"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("frame 0's vertices and triangles"), std::string::npos) << r.err;
  // Sequences are for colliders only.
  json rigid = j;
  rigid["objects"][0]["kind"] = "rigid";
  rigid["objects"][0]["density"] = 500;
  r = run(rigid);
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("for colliders only"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace triad
