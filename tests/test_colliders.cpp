// Colliders: solids moved exactly by their animation, never by anything
// else. Material meets them through the three-grid contact with the
// collider's own velocity, so friction carries material along a moving
// surface; rigid bodies meet them as an immovable body that moves; and
// what the material does to them is measured like a rigid body's load.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "cli_fixture.h"
#include "scene_fixture.h"
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

}  // namespace
}  // namespace triad
