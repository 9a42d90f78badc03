// Water that starts at rest under its own weight ("initial_pressure":
// "hydrostatic"): the pressure of its body of water above each particle,
// and a tank that then stays at rest instead of ringing.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <utility>
#include <variant>

#include "scene_fixture.h"
#include "sim/solver.h"

namespace triad {
namespace {

using nlohmann::json;
using test::box;

constexpr double kRho = 1000.0, kG = 9.81;

// A tank 0.3 x 0.2 m of water `depth` deep in two objects one over the
// other, a fixed box under water in it, and a block of water hanging over
// the tank with a gap under it; dx 0.02, 8 particles per cell.
json tankScene(const char* start, double depth) {
  json j = test::baseScene("tank", {0.3, 0.5, 0.2}, 0.02);
  j["materials"]["water"] = {{"model", "water"}, {"density", kRho}, {"bulk_modulus", 1e5}};
  const std::pair<const char*, json> waters[] = {
      {"lower", box({0, 0, 0}, {0.3, 0.1, 0.2})},
      {"upper", box({0, 0.1, 0}, {0.3, depth, 0.2})},
      {"drop", box({0.1, 0.4, 0.06}, {0.2, 0.46, 0.14})}};
  for (const auto& [name, shape] : waters)
    j["objects"].push_back(
        {{"name", name}, {"kind", "mpm"}, {"material", "water"}, {"shape", shape}});
  j["objects"].push_back({{"name", "stone"},
                          {"kind", "rigid"},
                          {"density", 2500},
                          {"fixed", true},
                          {"shape", box({0.1, 0.04, 0.06}, {0.2, 0.08, 0.14})}});
  if (start)
    for (int k = 0; k < 3; ++k) j["objects"][k]["initial_pressure"] = start;
  return j;
}

TEST(HydrostaticStart, PressureIsTheWeightOfTheWaterAbove) {
  const World w = test::loadWorld(test::tempDir("tank"), tankScene("hydrostatic", 0.2));
  ASSERT_EQ(w.sets.size(), 1u);
  const ParticleSet& set = w.sets[0];
  const auto& water = std::get<Water<float>>(set.model);
  // The surface lies half a particle spacing (0.005 m) over the highest
  // particle: at 0.2 m for the tank, whose stone under water breaks no
  // column's pressure, at 0.46 m for the hanging block, which the gap keeps
  // out of the tank's.
  double worst = 0.0;
  size_t tank = 0, drop = 0;
  for (size_t i = 0; i < set.size(); ++i) {
    const double y = set.x[i].y(), level = set.object[i] == 2 ? 0.46 : 0.2;
    const double expected = kRho * kG * (level - y), p = water.pressure(set.J[i]);
    worst = std::max(worst, std::abs(p - expected));
    (set.object[i] == 2 ? drop : tank) += 1;
    const bool under_stone = set.object[i] == 0 && y < 0.04 && set.x[i].x() > 0.12 &&
                             set.x[i].x() < 0.18 && set.x[i].z() > 0.08 && set.x[i].z() < 0.12;
    if (under_stone) {
      EXPECT_NEAR(p, kRho * kG * (0.2 - y), 1.0) << "under the stone at y " << y;
    }
  }
  EXPECT_GT(tank, 0u);
  EXPECT_GT(drop, 0u);
  // Float rounding of J near 1: a pascal is 1.4e-6 of K / gamma.
  EXPECT_LT(worst, 2.0) << "Pa";
}

TEST(HydrostaticStart, LeftOutWaterStartsWithoutPressure) {
  const World w = test::loadWorld(test::tempDir("tank"), tankScene(nullptr, 0.2));
  for (const ParticleSet& set : w.sets)
    for (size_t i = 0; i < set.size(); ++i) ASSERT_EQ(set.J[i], 1.0f);
}

// How the tank (not the hanging block, which falls) moves over its first
// 0.3 s: the largest vertical speed of its centre of mass (the water column
// ringing as a whole) and the largest RMS speed of its particles.
struct Motion {
  double bulk = 0.0, rms = 0.0;
};

Motion tankMotion(const char* start) {
  json j = tankScene(start, 0.2);
  j["objects"].erase(2);
  World w = test::loadWorld(test::tempDir(start ? start : "none"), j);
  Solver solver(w);
  Motion out;
  for (int k = 1; k <= 30; ++k) {
    solver.advanceTo(0.01 * k);
    const test::Moments m = test::moments(w);
    out.bulk = std::max(out.bulk, std::abs(m.momentum.y() / m.mass));
    out.rms = std::max(out.rms, std::sqrt(2.0 * m.kinetic / m.mass));
  }
  return out;
}

TEST(HydrostaticStart, TankStaysAtRest) {
  // From no pressure the column falls, compresses and rings as a whole
  // (quarter-wave period 4 h / c = 0.08 s, c = 10 m/s): its centre of mass
  // swings at up to 0.076 m/s, hardly damped in 0.3 s, and the particles'
  // RMS speed reaches 0.094 m/s. Started hydrostatic the centre of mass
  // moves at 1.5 mm/s at most; what is left (RMS 1 cm/s) is the surface
  // rows and the corners settling.
  const Motion ringing = tankMotion(nullptr), still = tankMotion("hydrostatic");
  std::printf(
      "over 0.3 s: centre of mass up to %.4f m/s from no pressure, %.4f hydrostatic; "
      "RMS speed up to %.4f and %.4f m/s\n",
      ringing.bulk, still.bulk, ringing.rms, still.rms);
  EXPECT_GT(ringing.bulk, 0.05);
  EXPECT_LT(still.bulk, 0.01);
  EXPECT_LT(still.rms, 0.3 * ringing.rms);
}

}  // namespace
}  // namespace triad
