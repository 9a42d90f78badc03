// Sources and sinks: a source keeps its shape full while its material flows
// out at the object's velocity (rho A |v| through an open face A); a sink
// removes what enters it; particle ids stay unique and are never reused;
// memory follows the particles.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <set>

#include "scene_fixture.h"
#include "sim/solver.h"

namespace triad {
namespace {

using nlohmann::json;
using test::box;

constexpr double kRho = 1000;

json waterScene(const std::string& name, const std::array<double, 3>& max, double dx) {
  json j = test::baseScene(name, max, dx);
  j["materials"]["water"] = {{"model", "water"}, {"density", kRho}, {"bulk_modulus", 1e5}};
  return j;
}

size_t countOf(const World& w, int object) {
  size_t n = 0;
  for (const ParticleSet& s : w.sets)
    n += size_t(std::count(s.object.begin(), s.object.end(), uint16_t(object)));
  return n;
}

// Gravity off, a 0.1 m cube source of water at 1 m/s along x: the face it
// flows out of has A = 0.01 m^2, so after the first fill it emits
// rho A |v| = 10 kg/s. Measured between 0.1 and 0.5 s.
TEST(Source, EmitsRhoAreaSpeedThroughItsOpenFace) {
  json j = waterScene("source_rate", {1.0, 0.3, 0.3}, 0.02);
  j["gravity"] = {0, 0, 0};
  j["objects"].push_back({{"name", "nozzle"}, {"kind", "mpm"}, {"material", "water"},
                          {"velocity", {1.0, 0, 0}},
                          {"shape", box({0.04, 0.1, 0.1}, {0.14, 0.2, 0.2})},
                          {"emit", {{"start", 0.0}, {"end", 2.0}}}});
  World w = test::loadWorld(test::tempDir("source_rate"), j);
  ASSERT_EQ(w.sources.size(), 1u);
  const double m = w.sets[0].mass;
  // Full at the start: the cube's volume.
  EXPECT_NEAR(countOf(w, 0) * m, kRho * 1e-3, 1e-6);
  Solver solver(w);
  solver.advanceTo(0.1);
  const uint64_t at1 = w.sources[0].emitted;
  solver.advanceTo(0.5);
  const double rate = (w.sources[0].emitted - at1) * m / 0.4;
  std::printf("emitted %.3f kg/s (rho A v = 10), %zu particles\n", rate, countOf(w, 0));
  EXPECT_NEAR(rate, kRho * 0.01 * 1.0, 0.3);
  EXPECT_EQ(countOf(w, 0), w.sources[0].emitted);
  // The jet's front has travelled with it: 0.14 + 0.5 m.
  float front = 0;
  for (const Vec3f& x : w.sets[0].x) front = std::max(front, x.x());
  EXPECT_NEAR(front, 0.64, 0.02);
}

// Before its start a source holds nothing; after its end it makes nothing.
TEST(Source, EmitsOnlyBetweenStartAndEnd) {
  json j = waterScene("source_window", {0.6, 0.3, 0.3}, 0.02);
  j["gravity"] = {0, 0, 0};
  j["objects"].push_back({{"name", "nozzle"}, {"kind", "mpm"}, {"material", "water"},
                          {"velocity", {1.0, 0, 0}},
                          {"shape", box({0.04, 0.1, 0.1}, {0.14, 0.2, 0.2})},
                          {"emit", {{"start", 0.1}, {"end", 0.2}}}});
  World w = test::loadWorld(test::tempDir("source_window"), j);
  EXPECT_EQ(w.particleCount(), 0u);
  Solver solver(w);
  solver.advanceTo(0.0999);
  EXPECT_EQ(w.particleCount(), 0u);
  solver.advanceTo(0.2);
  const size_t after = w.particleCount();
  // The fill (1 kg) and 0.1 s of 10 kg/s, to within a layer of sites.
  EXPECT_NEAR(after * w.sets[0].mass, 2.0, 0.12);
  solver.advanceTo(0.3);
  EXPECT_EQ(w.particleCount(), after);
}

// Under gravity a source's material accelerates out of it, and on the grid
// the fast material and the new, slower particles bunch: the shape stays
// full but never holds more than it was seeded with. Layers of sites
// empty and refill together, so up to two of its eight layers can be in
// transit across its faces at a frame: 480-640 of 640 measured.
// (Refilling every empty site alone packed 2-2.6 times the particles into
// it and emitted 5 times the mass.)
TEST(Source, StaysFullNotOverfullUnderGravity) {
  json j = waterScene("source_gravity", {0.4, 1.0, 0.4}, 0.02);
  j["materials"]["sand"] = {{"model", "drucker_prager"}, {"density", 1600},
                            {"youngs_modulus", 2e5}, {"poisson_ratio", 0.3}};
  j["objects"].push_back({{"name", "hopper"}, {"kind", "mpm"}, {"material", "sand"},
                          {"velocity", {0, -1.0, 0}},
                          {"shape", box({0.16, 0.82, 0.15}, {0.24, 0.9, 0.25})},
                          {"emit", {{"start", 0.0}, {"end", 0.6}}}});
  World w = test::loadWorld(test::tempDir("source_gravity"), j);
  const size_t sites = w.sources[0].sites.size();
  ASSERT_EQ(sites, 640u);
  Solver solver(w);
  for (double t : {0.05, 0.1, 0.2, 0.3, 0.5}) {
    solver.advanceTo(t);
    size_t inside = 0;
    for (const Vec3f& x : w.sets[0].x)
      inside += x.x() >= 0.16f && x.x() < 0.24f && x.y() >= 0.82f && x.y() < 0.9f &&
                x.z() >= 0.15f && x.z() < 0.25f;
    std::printf("t %.1f: %zu particles in the source (%zu sites), %llu emitted\n", t, inside,
                sites, (unsigned long long)w.sources[0].emitted);
    EXPECT_LE(inside, sites + sites / 20) << t;
    EXPECT_GE(inside, sites * 7 / 10) << t;
  }
}

// A source pours into a sink: at every frame's end no particle is inside
// the sink, every id is unique, an id once removed never comes back, and
// the count is the emitted minus the removed.
TEST(Sink, RemovesWhatEntersAndIdsAreNeverReused) {
  json j = waterScene("source_sink", {0.4, 0.6, 0.4}, 0.02);
  j["objects"].push_back({{"name", "tap"}, {"kind", "mpm"}, {"material", "water"},
                          {"velocity", {0, -1.0, 0}},
                          {"shape", box({0.15, 0.45, 0.15}, {0.25, 0.55, 0.25})},
                          {"emit", {{"start", 0.0}, {"end", 0.6}}}});
  j["objects"].push_back({{"name", "drain"}, {"kind", "sink"},
                          {"shape", box({0.0, 0.0, 0.0}, {0.4, 0.08, 0.4})}});
  World w = test::loadWorld(test::tempDir("source_sink"), j);
  ASSERT_EQ(w.sinks.size(), 1u);
  Solver solver(w);
  std::set<uint32_t> seen, live;
  uint32_t highest = 0;
  size_t peak = 0, peak_bytes = 0;
  for (int f = 1; f <= 16; ++f) {
    solver.advanceTo(f / 16.0);
    std::set<uint32_t> now;
    for (const ParticleSet& s : w.sets)
      for (size_t i = 0; i < s.size(); ++i) {
        EXPECT_FALSE(s.x[i].y() <= 0.08f) << "particle " << s.id[i] << " inside the sink, frame " << f;
        EXPECT_TRUE(now.insert(s.id[i]).second) << "id " << s.id[i] << " twice";
        // A particle is either still alive from before or new (above every id so far).
        EXPECT_TRUE(live.count(s.id[i]) || !seen.count(s.id[i])) << "id " << s.id[i] << " reused";
      }
    for (uint32_t id : now)
      if (!seen.count(id)) {
        EXPECT_GE(id, highest) << "a new id below an old one";
        highest = std::max(highest, id + 1);
        seen.insert(id);
      }
    live = now;
    peak = std::max(peak, w.particleCount());
    peak_bytes = std::max(peak_bytes, w.particleBytes());
  }
  const uint64_t emitted = w.sources[0].emitted, removed = w.sinks[0].removed;
  std::printf("emitted %llu, removed %llu, left %zu (peak %zu)\n", (unsigned long long)emitted,
              (unsigned long long)removed, w.particleCount(), peak);
  EXPECT_GT(removed, emitted / 3);
  EXPECT_EQ(w.particleCount(), emitted - removed);
  // The tap closed at 0.6 s; by 1 s the water has drained: memory given back.
  solver.advanceTo(1.5);
  EXPECT_LT(w.particleCount(), peak / 4);
  EXPECT_LT(w.particleBytes(), peak_bytes / 2);
}

// A sink moved by its animation sweeps through resting water and removes
// what it passes.
TEST(Sink, AnimatedSinkSweepsThroughWater) {
  json j = waterScene("sweeping_sink", {0.6, 0.3, 0.3}, 0.02);
  j["objects"].push_back({{"name", "pool"}, {"kind", "mpm"}, {"material", "water"},
                          {"shape", box({0, 0, 0}, {0.6, 0.1, 0.3})}});
  j["objects"].push_back(
      {{"name", "scoop"}, {"kind", "sink"},
       {"shape", {{"sphere", {{"center", {0.05, 0.1, 0.15}}, {"radius", 0.05}}}}},
       {"animation",
        {{"keys", json::array({{{"time", 0.0}}, {{"time", 0.25}, {"translate", {0.5, 0, 0}}}})}}}});
  World w = test::loadWorld(test::tempDir("sweeping_sink"), j);
  const size_t start = w.particleCount();
  Solver solver(w);
  solver.advanceTo(0.25);
  const double removed_volume = double(start - w.particleCount()) * w.sets[0].volume;
  // A half-sphere's trail: about 0.5 m x (pi r^2 / 2) and the caps.
  std::printf("removed %.5f m^3 (half-cylinder trail %.5f)\n", removed_volume,
              0.5 * M_PI * 0.05 * 0.05 / 2);
  EXPECT_GT(removed_volume, 0.5 * 0.5 * M_PI * 0.05 * 0.05 / 2);
  EXPECT_EQ(w.sinks[0].removed, start - w.particleCount());
}

// A sink of a mesh shape (a box written as OBJ) removes what a box sink of
// the same box does, to within its voxelization (dx/2).
TEST(Sink, MeshSinkRemovesWhatTheBoxSinkDoes) {
  const auto dir = test::tempDir("mesh_sink");
  {
    std::ofstream obj(dir / "drain.obj");
    const double lo[3] = {0.1, -0.05, 0.1}, hi[3] = {0.3, 0.06, 0.2};
    for (int k = 0; k < 8; ++k)
      obj << "v " << (k & 1 ? hi[0] : lo[0]) << " " << (k & 2 ? hi[1] : lo[1]) << " "
          << (k & 4 ? hi[2] : lo[2]) << "\n";
    // Outward faces of the cube of corners 1..8 (bit 0: x, bit 1: y, bit 2: z).
    obj << "f 1 3 4\nf 1 4 2\nf 5 6 8\nf 5 8 7\nf 1 2 6\nf 1 6 5\n"
        << "f 3 7 8\nf 3 8 4\nf 1 5 7\nf 1 7 3\nf 2 4 8\nf 2 8 6\n";
  }
  size_t removed[2];
  for (int mesh = 0; mesh < 2; ++mesh) {
    json j = waterScene("mesh_sink", {0.4, 0.3, 0.3}, 0.02);
    j["objects"].push_back({{"name", "pool"}, {"kind", "mpm"}, {"material", "water"},
                            {"shape", box({0, 0, 0}, {0.4, 0.1, 0.3})}});
    json shape = mesh ? json{{"mesh", {{"path", "drain.obj"}}}} : box({0.1, -0.05, 0.1}, {0.3, 0.06, 0.2});
    j["objects"].push_back({{"name", "drain"}, {"kind", "sink"}, {"shape", shape}});
    World w = test::loadWorld(dir, j);
    Solver solver(w);
    solver.advanceTo(0.01);
    removed[mesh] = w.sinks[0].removed;
  }
  std::printf("box sink removed %zu, mesh sink %zu\n", removed[0], removed[1]);
  EXPECT_GT(removed[0], 1000u);
  EXPECT_NEAR(double(removed[1]), double(removed[0]), 0.05 * removed[0]);
}

}  // namespace
}  // namespace triad
