// Sleeping material (solver.sleep): settled blocks skip their work, stay
// where they were, and wake when a moving solid comes near.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>

#include "scene_fixture.h"
#include "sim/solver.h"

namespace triad {
namespace {

using nlohmann::json;
using test::box;

constexpr double kDx = 0.02;

// A layer of sand at rest on the floor, and optionally a heavy ball thrown
// up from above it that lands on it at about 0.85 s.
json sandScene(const std::string& name, bool sleep, bool ball) {
  json j = test::baseScene(name, {0.4, 1.4, 0.4}, kDx);
  j["solver"] = {{"sleep", sleep ? json{{"speed", 0.01}, {"delay", 0.1}} : json(false)}};
  j["materials"]["sand"] = {{"model", "drucker_prager"}, {"density", 1600},
                            {"youngs_modulus", 1e5}, {"poisson_ratio", 0.3},
                            {"friction_angle_deg", 35}};
  j["objects"].push_back({{"name", "layer"}, {"kind", "mpm"}, {"material", "sand"},
                          {"shape", box({0.02, 0.0, 0.02}, {0.38, 0.1, 0.38})}});
  if (ball)
    j["objects"].push_back({{"name", "ball"}, {"kind", "rigid"}, {"density", 3000},
                            {"friction", 0.5}, {"velocity", {0, 4.0, 0}},
                            {"shape", {{"sphere", {{"center", {0.2, 0.3, 0.2}}, {"radius", 0.05}}}}}});
  return j;
}

// Particle positions by id.
std::map<uint32_t, Vec3f> positions(const World& w) {
  std::map<uint32_t, Vec3f> out;
  for (const ParticleSet& s : w.sets)
    for (size_t i = 0; i < s.size(); ++i) out[s.id[i]] = s.x[i];
  return out;
}

double largestDifference(const World& a, const World& b) {
  const auto pa = positions(a), pb = positions(b);
  EXPECT_EQ(pa.size(), pb.size());
  double d = 0.0;
  for (const auto& [id, x] : pa) d = std::max(d, double((x - pb.at(id)).norm()));
  return d;
}

// Sand at rest falls asleep after the delay and is then left as it was: the
// run with sleep skips most of the work and ends within 0.1 dx of the run
// without.
TEST(Sleep, SettledSandSleepsWhereItRests) {
  World awake = test::loadWorld(test::tempDir("sleep_off"), sandScene("sleep_off", false, false));
  World sleepy = test::loadWorld(test::tempDir("sleep_on"), sandScene("sleep_on", true, false));
  Solver a(awake), s(sleepy);
  // The layer rings under its own weight for about 0.4 s, then settles.
  a.advanceTo(0.9);
  s.advanceTo(0.5);
  const StepRecord settled = s.record();
  s.advanceTo(0.9);
  EXPECT_EQ(a.record().sleeping_steps, 0u);
  const double share = double(s.record().sleeping_steps - settled.sleeping_steps) /
                       double(s.record().particle_steps - settled.particle_steps);
  const double diff = largestDifference(awake, sleepy);
  std::printf("asleep %.1f%% of particle-substeps, largest difference %.2e m (%.3f dx)\n",
              100 * share, diff, diff / kDx);
  EXPECT_GT(share, 0.8);
  EXPECT_LT(diff, 0.1 * kDx);
  // Sleeping particles are still.
  for (const ParticleSet& set : sleepy.sets)
    for (const Vec3f& v : set.v) ASSERT_LT(v.norm(), 0.01f);
}

// `neighbours: false` lets a block sleep as soon as its own particles have
// been still for the delay: while the layer still rings at its edges, more
// of it sleeps than by default, and it still ends within 0.1 dx.
TEST(Sleep, WithoutWaitingForNeighboursMoreSleepsSooner) {
  json lone = sandScene("sleep_lone", true, false);
  lone["solver"]["sleep"]["neighbours"] = false;
  World awake = test::loadWorld(test::tempDir("sleep_ref"), sandScene("sleep_ref", false, false));
  World waits =
      test::loadWorld(test::tempDir("sleep_waits"), sandScene("sleep_waits", true, false));
  World alone = test::loadWorld(test::tempDir("sleep_lone"), lone);
  Solver a(awake), w(waits), l(alone);
  a.advanceTo(0.9);
  w.advanceTo(0.9);
  l.advanceTo(0.9);
  const double share_w = double(w.record().sleeping_steps) / double(w.record().particle_steps);
  const double share_l = double(l.record().sleeping_steps) / double(l.record().particle_steps);
  const double diff = largestDifference(awake, alone);
  std::printf("asleep %.1f%% (neighbours still) and %.1f%% (alone); alone %.3f dx from awake\n",
              100 * share_w, 100 * share_l, diff / kDx);
  EXPECT_GT(share_l, share_w + 0.02);
  EXPECT_LT(diff, 0.1 * kDx);
}

// A ball thrown up lands on the sleeping layer: the sand around it wakes in
// time to hold it, and it comes to rest where it does without sleep. (Were
// the sand not woken, its held nodes would stop the ball like a rigid floor:
// it rests 0.35 dx higher, with no crater.)
TEST(Sleep, ALandingBallWakesTheSandItMeets) {
  World awake = test::loadWorld(test::tempDir("sleep_ball_off"), sandScene("sleep_ball_off", false, true));
  World sleepy = test::loadWorld(test::tempDir("sleep_ball_on"), sandScene("sleep_ball_on", true, true));
  Solver a(awake), s(sleepy);
  s.advanceTo(0.6);
  const StepRecord settled = s.record();
  s.advanceTo(0.75);
  const double share = double(s.record().sleeping_steps - settled.sleeping_steps) /
                       double(s.record().particle_steps - settled.particle_steps);
  EXPECT_GT(share, 0.5) << "the layer was not asleep when the ball came";
  EXPECT_GT(sleepy.bodies[0].state.x.y(), 0.4) << "the ball came too early to test anything";
  a.advanceTo(1.4);
  s.advanceTo(1.4);
  const double ya = awake.bodies[0].state.x.y(), ys = sleepy.bodies[0].state.x.y();
  std::printf("ball at rest at y = %.4f m (awake) and %.4f m (sleep); %.1f%% asleep\n", ya, ys,
              100.0 * double(s.record().sleeping_steps) / double(s.record().particle_steps));
  EXPECT_GT(ys, 0.05 + 2 * kDx) << "the ball sank through the sand";
  EXPECT_NEAR(ys, ya, 0.25 * kDx);
  EXPECT_LT(sleepy.bodies[0].state.v.norm(), 0.05);
}

// A ball resting on the layer sleeps with it once both are still: the
// sand under it sleeps too (a body that moves would keep it awake), the
// ball stays where it rests without sleep, and its force row still
// balances its weight.
TEST(Sleep, ABallRestingOnSandSleepsWithIt) {
  auto scene = [](const std::string& name, bool sleep) {
    json j = sandScene(name, sleep, false);
    j["objects"].push_back({{"name", "ball"}, {"kind", "rigid"}, {"density", 1500},
                            {"friction", 0.5},
                            {"shape", {{"sphere", {{"center", {0.2, 0.15, 0.2}}, {"radius", 0.05}}}}}});
    return j;
  };
  World awake = test::loadWorld(test::tempDir("sleep_rest_off"), scene("sleep_rest_off", false));
  World sleepy = test::loadWorld(test::tempDir("sleep_rest_on"), scene("sleep_rest_on", true));
  Solver a(awake), s(sleepy);
  a.advanceTo(1.1);
  s.advanceTo(0.8);
  const StepRecord settled = s.record();
  s.resetLoads();
  s.advanceTo(1.1);
  const double share = double(s.record().sleeping_steps - settled.sleeping_steps) /
                       double(s.record().particle_steps - settled.particle_steps);
  const RigidBody& ball = sleepy.bodies[0];
  const double weight = ball.mass * 9.81;
  const double ya = awake.bodies[0].state.x.y(), ys = ball.state.x.y();
  std::printf("asleep %.1f%% from 0.8 s; ball at %.4f m (awake %.4f); force %.3f of its weight\n",
              100 * share, ys, ya, s.bodyLoads()[0].force().y() / weight);
  EXPECT_GT(share, 0.8);
  EXPECT_NEAR(ys, ya, 0.1 * kDx);
  EXPECT_NEAR(s.bodyLoads()[0].force().y(), weight, 0.03 * weight);
  EXPECT_LT(largestDifference(awake, sleepy), 0.1 * kDx);
}

}  // namespace
}  // namespace triad
