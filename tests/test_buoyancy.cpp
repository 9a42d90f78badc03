// Thin rigid slabs in water against Archimedes, in the setups of
// bench/study_buoyancy: a slab 0.30 m long, 0.12 m deep and 2-6 cells
// thick (dx = 0.02 m) in water 0.2 m deep (bulk modulus 2e5 Pa) in a
// domain 0.5 x 0.4 x 0.2 m. Placed at rest at its floating position it
// must stay at its draft; released under water, a slab denser than water
// sinks and one as dense stays put. With one velocity field a submerged
// ratio-0.5 slab rises at a crawl (bench/RESULTS.md, not asserted); with
// solver.front_fields, in a wider tank, it reaches the surface and floats.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "scene_fixture.h"
#include "sim/solver.h"

namespace triad {
namespace {

using nlohmann::json;
using test::box;

constexpr double kDx = 0.02, kDepth = 0.2, kSx0 = 0.1, kSx1 = 0.4;

// The tank in x and z, and the slab's extent in z (in x it spans kSx0-kSx1).
struct Tank {
  double x, z, sz0, sz1;
  double area() const { return x * z; }
  double slabArea() const { return (kSx1 - kSx0) * (sz1 - sz0); }
};
// The tank: 2 cells of water along the slab's long sides.
constexpr Tank kNarrow{0.5, 0.2, 0.04, 0.16};
// 0.1 m of water all round the slab, as `study_buoyancy --wide` sets it up.
constexpr Tank kWide{0.5, 0.32, 0.1, 0.22};

// Where a slab starts: at rest on the surface at Archimedes' draft,
// submerged with its centre at mid-depth, or dropped 1 cm onto a block of
// water 0.3 m square that slumps under it and sloshes across the tank (the
// issue's third setup; the slab then spans x 0-0.3 m).
enum class Start { Rest, Submerged, Dropped };

// A slab `cells` thick of density ratio `ratio` to water, started as `start`.
World slabInWater(const std::string& name, double cells, double ratio, Start start,
                  const Tank& tank = kNarrow, const json& solver = json::object(),
                  const std::string& kind = "rigid") {
  const double t = cells * kDx, x = tank.x, z = tank.z, sz0 = tank.sz0, sz1 = tank.sz1;
  const double share = tank.slabArea() / tank.area();
  std::vector<json> water;
  double y0, sx0 = kSx0, sx1 = kSx1;
  if (start == Start::Dropped) {
    water = {box({0, 0, 0}, {0.3, 0.3, z})};
    y0 = 0.31;
    sx0 = 0.0;  // the same slab, over the block (waterLevel takes its area)
    sx1 = kSx1 - kSx0;
  } else if (start == Start::Rest) {
    const double draft = ratio * t, level = kDepth + draft * share;
    y0 = level - draft;
    water = {box({0, 0, 0}, {x, y0, z}), box({0, y0, 0}, {kSx0, level, z}),
             box({kSx1, y0, 0}, {x, level, z}), box({kSx0, y0, 0}, {kSx1, level, sz0}),
             box({kSx0, y0, sz1}, {kSx1, level, z})};
  } else {
    y0 = 0.5 * kDepth - 0.5 * t;
    const double y1 = y0 + t, top = kDepth + t * share;
    water = {box({0, 0, 0}, {x, y0, z}),          box({0, y1, 0}, {x, top, z}),
             box({0, y0, 0}, {kSx0, y1, z}),      box({kSx1, y0, 0}, {x, y1, z}),
             box({kSx0, y0, 0}, {kSx1, y1, sz0}), box({kSx0, y0, sz1}, {kSx1, y1, z})};
  }
  json j = test::baseScene(name, {x, 0.4, z}, kDx);
  if (!solver.empty()) j["solver"] = solver;
  j["materials"]["water"] = {{"model", "water"}, {"density", 1000}, {"bulk_modulus", 2e5}};
  // An elastic slab: a jelly as stiff as study_buoyancy's.
  j["materials"]["solid"] = {{"model", "fixed_corotated"},
                             {"density", 1000 * ratio},
                             {"youngs_modulus", 3e5},
                             {"poisson_ratio", 0.3}};
  for (size_t k = 0; k < water.size(); ++k)
    j["objects"].push_back({{"name", "w" + std::to_string(k)}, {"kind", "mpm"},
                            {"material", "water"}, {"shape", water[k]}});
  json slab = {
      {"name", "slab"}, {"kind", kind}, {"shape", box({sx0, y0, sz0}, {sx1, y0 + t, sz1})}};
  if (kind == "rigid")
    slab["density"] = 1000 * ratio;
  else
    slab["material"] = "solid";
  j["objects"].push_back(slab);
  return test::loadWorld(test::tempDir(name), j);
}

// A slab's bottom from its centre of mass (an elastic slab's mesh has the
// box's faces, snapped to the samples' lattice).
double slabBottom(const World& w, double cells) {
  const double centre =
      w.bodies.empty() ? w.elastics[0].fem.centreOfMass().y() : w.bodies[0].state.x.y();
  return centre - 0.5 * cells * kDx;
}

// The water level from the water's volume (sum of J V), the slab's
// submerged part displacing it.
double waterLevel(const World& w, double cells, const Tank& tank = kNarrow) {
  double v = 0;
  for (const ParticleSet& s : w.sets)
    for (size_t i = 0; i < s.size(); ++i) v += s.volume * s.volumeRatio(i);
  const double b = slabBottom(w, cells), t = cells * kDx;
  const double area = tank.area(), slab = tank.slabArea();
  double l = v / area;
  if (l > b) l = std::min((v - slab * b) / (area - slab), (v + slab * t) / area);
  return l;
}

// The slab's mean draft over `samples` times 0.05 s apart after `from`
// seconds, less Archimedes', in cells (printed).
double meanDraftError(World& w, const char* what, double cells, double ratio, double from,
                      int samples) {
  Solver solver(w);
  solver.advanceTo(from);
  double draft = 0;
  for (int k = 1; k <= samples; ++k) {
    solver.advanceTo(from + 0.05 * k);
    draft += (waterLevel(w, cells) - slabBottom(w, cells)) / samples;
  }
  const double archimedes = ratio * cells * kDx;
  const double error = (draft - archimedes) / kDx;
  std::printf("%s %.0f cells, ratio %.1f: draft %.4f m (Archimedes %.4f), %+.2f dx\n", what, cells,
              ratio, draft, archimedes, error);
  return error;
}

class FloatingSlab : public ::testing::TestWithParam<std::tuple<double, double>> {};

// How far from Archimedes' draft a slab may float, in cells: the issue's
// target, 0.25 dx from 3 cells thick and 0.5 dx at 2. Every slab meets it
// since the rigid collision solves a body's nodes together (Newton); with
// the Jacobi passes alone, slabs whose faces lie close to a row of nodes
// floated 0.3-0.5 dx too deep (bench/RESULTS.md, "Contact normals").
// Placed elsewhere within about 0.8 dx of its draft a slab stays there too:
// dropped, one rests high (bench/RESULTS.md, "The validation's slab rests
// anywhere in a band"), which this test, started at the draft, does not see.
// The start is at the draft only to within the samples' lattice (spacing
// dx / 2), which moves the slab's faces and the water's to its nearest
// planes: the draft errors at the start are 0 or 0.1-0.3 dx, and every slab
// that starts at 0 ends within 0.07 dx. Light slabs that start deep come
// back a third of the way or not at all: the 6-cell slab at ratio 0.2
// starts +0.30 dx and ends +0.17 rigid, +0.29 elastic (bench/RESULTS.md,
// "Where a placed slab starts").
double draftTolerance(double cells, double /*ratio*/) { return cells < 3 ? 0.5 : 0.25; }

// Placed at its floating position, the slab's mean draft over the second
// half second stays at Archimedes' (ratio x thickness): within 0.25 dx from
// 3 cells thick, 0.5 dx at 2. Measured (1 s), ratio 0.2 / 0.5 / 0.8:
// 2 cells +0.03 / -0.02 / +0.04 dx; 3 cells -0.12 / +0.02 / +0.16; 4 cells
// +0.13 / +0.06 / -0.02; 6 cells +0.17 / +0.03 / -0.08. With the Jacobi
// passes alone (rigid_collision "jacobi") four of the twelve missed: 3
// cells +0.26 at ratio 0.5, 4 cells +0.30 at 0.8, 6 cells +0.44 and +0.41
// (nodes a cell outside the face, holding a sliver of solid, converge by
// their sliver per pass and let the water in).
// With the contract's summed normals (contact_normal "samples") every slab
// of ratio 0.8 floats 1.0-1.45 dx too deep: the normal at nodes beside a
// side face within a cell and a half of the top edge tilts upward, and the
// water there hangs on the body.
// The slab bobs meanwhile (up to 0.05-0.09 m/s at the end) as the water,
// placed uncompressed, settles under its weight.
TEST_P(FloatingSlab, StaysAtArchimedesDraft) {
  const auto [cells, ratio] = GetParam();
  const std::string name = "floating_slab_" + std::to_string(int(cells)) + "_" +
                           std::to_string(int(std::round(10 * ratio)));
  World w = slabInWater(name, cells, ratio, Start::Rest);
  EXPECT_LT(std::abs(meanDraftError(w, "slab", cells, ratio, 0.5, 10)),
            draftTolerance(cells, ratio));
}

INSTANTIATE_TEST_SUITE_P(ThicknessAndRatio, FloatingSlab,
                         ::testing::Combine(::testing::Values(2.0, 3.0, 4.0, 6.0),
                                            ::testing::Values(0.2, 0.5, 0.8)));

// With FLIP transfer the slab floats as with APIC. Before the collision's
// change went into the FLIP grid's, the particles kept 95% of the approach
// the collision took from their nodes, and the box took it again every
// step: the 3-cell slab of ratio 0.5 was thrown out of the water (-1.75 dx
// here; in the wide tank -1.77 dx, up to 0.28 m/s up, the water pressed 4%
// smaller). Now +0.04 dx (wide: +0.12, study_buoyancy --start rest --wide
// --solver '{"transfer":"flip"}').
TEST(FloatingSlabFlip, StaysAtArchimedesDraft) {
  World w =
      slabInWater("floating_slab_flip", 3.0, 0.5, Start::Rest, kNarrow, {{"transfer", "flip"}});
  EXPECT_LT(std::abs(meanDraftError(w, "slab", 3.0, 0.5, 0.5, 10)), 0.25);
}

// An elastic slab (a jelly, E 3e5 Pa, explicit) placed at its floating
// position stays at Archimedes' draft as a rigid one does, within the same
// tolerances. study_buoyancy --kind elastic --start rest (1 s, mean over
// the second half), draft error in cells, ratio 0.2 / 0.5 / 0.8: 2 cells
// +0.15 / +0.09 / +0.11; 3 cells -0.08 / 0.00 / +0.19; 4 cells +0.15 /
// 0.00 / +0.02; 6 cells +0.31 (a miss) / +0.04 / +0.04 (the lowest node's
// height; bench/RESULTS.md, "Elastic slabs in water"). Read from the
// centre of mass as here, the two cases below give +0.14 and +0.16 dx over
// 0.3-0.5 s. They are the thinnest slab at the lightest ratio and the
// 3-cell slab nearest its tolerance. Without the elastic contact passes
// the 3-cell case reads +0.42 dx and fails; the 2-cell one, +0.16 dx,
// still passes its half cell. The slab's explicit step (its elements' wave speed) is a
// fifth of the water's: a second takes about 10,000 steps, so the test
// runs half a second.
class FloatingElasticSlab : public ::testing::TestWithParam<std::tuple<double, double>> {};

TEST_P(FloatingElasticSlab, StaysAtArchimedesDraft) {
  const auto [cells, ratio] = GetParam();
  const std::string name = "floating_elastic_slab_" + std::to_string(int(cells)) + "_" +
                           std::to_string(int(std::round(10 * ratio)));
  World w = slabInWater(name, cells, ratio, Start::Rest, kNarrow, json::object(), "elastic");
  ASSERT_EQ(w.elastics.size(), 1u);
  // It settles within 0.3 s (3 cells, ratio 0.8, from its lowest node:
  // +0.14 dx at 0.05 s, +0.21 at 0.3 s, +0.18-0.19 from 0.4 s to 1 s): the
  // mean over 0.3-0.5 s.
  EXPECT_LT(std::abs(meanDraftError(w, "elastic slab", cells, ratio, 0.3, 4)),
            draftTolerance(cells, ratio));
}

INSTANTIATE_TEST_SUITE_P(ThicknessAndRatio, FloatingElasticSlab,
                         ::testing::Values(std::make_tuple(2.0, 0.2), std::make_tuple(3.0, 0.8)));

// Dropped 1 cm onto a block of water that slumps under it, light slabs end
// floating: their mean draft over 1.5-3 s within 0.5 dx of Archimedes'
// while the tank still sloshes and heaves them by up to 0.7 dx. With the
// issue's code the 3-cell slab of ratio 0.5 ended near the floor, covered
// by water. Measured (study_buoyancy --start dropped, 3 s), ratio 0.2 /
// 0.5: 2 cells -0.29 / -0.07 dx, 3 cells -0.24 / -0.29, 4 cells -0.25 /
// -0.24, 6 cells +0.34 / +0.20. Not asserted, as they miss item 2: at
// ratio 0.8 the 2-4 cell slabs plunge under the surface and stay there
// (+0.75 to +1.21 dx), held down by water on their top, which cannot drain
// at the default reach, and by the stall; slabs of ratio 1.5 are still
// 4-8 cm above the floor after 3 s (bench/RESULTS.md, "Slabs dropped into
// moving water"). This test's own runs read (forty-ninth session) 2 cells
// of ratio 0.5 -0.09 dx, 3 cells of 0.2 -0.48 (at the tolerance's edge:
// where a slab comes to rest inside the band moves with rounding-level
// changes, -0.50 with the rigid wall contacts' velocity passes stopped
// early), 3 cells of 0.5 -0.24, 6 cells +0.21.
class DroppedSlab : public ::testing::TestWithParam<std::tuple<double, double>> {};

TEST_P(DroppedSlab, LightOnesFloat) {
  const auto [cells, ratio] = GetParam();
  const std::string name =
      "dropped_" + std::to_string(int(cells)) + "_" + std::to_string(int(std::round(10 * ratio)));
  World w = slabInWater(name, cells, ratio, Start::Dropped);
  EXPECT_LT(std::abs(meanDraftError(w, "dropped", cells, ratio, 1.5, 30)), 0.5);
}

INSTANTIATE_TEST_SUITE_P(ThicknessAndRatio, DroppedSlab,
                         ::testing::Values(std::make_tuple(2.0, 0.5), std::make_tuple(3.0, 0.2),
                                           std::make_tuple(3.0, 0.5), std::make_tuple(6.0, 0.5)));

// Released under water at mid-depth, 3 cells thick: a slab of 1.5 times
// water's density sinks, one of water's density stays within a cell of
// where it was put over 2 s. Measured: the dense one's bottom falls 0.0069 m
// in 1 s and stalls (a plate this size would reach about 0.5 m/s in water:
// water's pressure alternating from one particle row to the next holds it,
// bench/RESULTS.md, "The stall"; with rigid_collision "jacobi" 0.0172 m),
// the neutral one moves 0.0022 m at most.
TEST(SubmergedSlab, DenseSinksNeutralStays) {
  {
    World w = slabInWater("submerged_dense", 3, 1.5, Start::Submerged);
    const double start = slabBottom(w, 3);
    Solver solver(w);
    solver.advanceTo(1.0);
    std::printf("ratio 1.5: bottom %.4f -> %.4f m\n", start, slabBottom(w, 3));
    EXPECT_LT(slabBottom(w, 3), start - 0.25 * kDx);
  }
  {
    World w = slabInWater("submerged_neutral", 3, 1.0, Start::Submerged);
    const double start = slabBottom(w, 3);
    Solver solver(w);
    double furthest = 0;
    for (int k = 1; k <= 8; ++k) {
      solver.advanceTo(0.25 * k);
      furthest = std::max(furthest, std::abs(slabBottom(w, 3) - start));
    }
    std::printf("ratio 1.0: bottom moved at most %.4f m over 2 s\n", furthest);
    EXPECT_LT(furthest, kDx);
  }
}

// An elastic slab released under water at mid-depth (3 cells, half water's
// density) in still water has nothing to keep it ringing: after the
// release's transient (0.02 m/s at 0.05 s, 0.01 at 0.1-0.2 s) the
// mass-weighted RMS of its nodes' velocities about their mean stays small
// (measured: at most 0.011 m/s from 0.15 to 0.5 s, 0.004 from 0.25 s).
// Water particles pushed out of its mesh used to hand its light corner
// nodes their whole approach momentum: a kick at 0.33 s set it ringing at
// 0.49 m/s, 0.85 by 2 s, and that ringing pumped it up to the surface
// (bench/RESULTS.md, "The push-out's kick").
TEST(SubmergedSlab, ElasticOneStaysCalm) {
  World w = slabInWater("submerged_elastic", 3, 0.5, Start::Submerged, kNarrow, json::object(),
                        "elastic");
  ASSERT_EQ(w.elastics.size(), 1u);
  const FemBody& fem = w.elastics[0].fem;
  auto vibration = [&]() {
    double m = 0;
    Vec3d p = Vec3d::Zero();
    for (size_t i = 0; i < fem.nodes(); ++i) m += fem.mass[i], p += fem.mass[i] * fem.v[i];
    const Vec3d mean = p / m;
    double e = 0;
    for (size_t i = 0; i < fem.nodes(); ++i) e += fem.mass[i] * (fem.v[i] - mean).squaredNorm();
    return std::sqrt(e / m);
  };
  Solver solver(w);
  solver.advanceTo(0.1);
  double worst = 0;
  for (int k = 3; k <= 10; ++k) {
    solver.advanceTo(0.05 * k);
    worst = std::max(worst, vibration());
  }
  std::printf("submerged elastic slab: vibration at most %.4f m/s over 0.15-0.5 s\n", worst);
  EXPECT_LT(worst, 0.03);
}

// Released under water at mid-depth with 0.1 m of water all round, a
// 3-cell slab of half water's density rises to the surface and floats
// with solver.front_fields: the water beside the slab slips past its edges
// instead of being dragged along (bench/RESULTS.md, "Two fields at a
// face's edges"). Measured: it rises 7.0 cm in 1.5 s (with one field the
// slab crawls up at 2.5-3 cm/s: 2.9 cm in 1 s) and reaches the surface by
// 2.2 s; over 2.5-3 s its draft is 0.37-0.40 dx deeper than Archimedes'
// (the band of rest). Until the water's volume took only the front field's
// correction it rose twice as fast, partly lifted by the water over its
// edges expanding (SubmergedCube below).
TEST(SubmergedSlab, RisesAndFloatsWithFrontFields) {
  const double ratio = 0.5;
  World w =
      slabInWater("submerged_fronts", 3, ratio, Start::Submerged, kWide, {{"front_fields", true}});
  const double start = slabBottom(w, 3), archimedes = ratio * 3 * kDx;
  auto draft = [&]() { return waterLevel(w, 3, kWide) - slabBottom(w, 3); };
  const double draft0 = draft();
  Solver solver(w);
  solver.advanceTo(1.5);
  const double rise = slabBottom(w, 3) - start;
  // Then its mean draft over 2.5-3 s.
  double mean = 0;
  for (int k = 0; k < 5; ++k) {
    solver.advanceTo(2.6 + 0.1 * k);
    mean += draft() / 5;
  }
  const double error = (mean - archimedes) / kDx;
  std::printf(
      "front fields, ratio 0.5: draft %.4f (bottom %.4f), risen %.4f m by 1.5 s, draft %.4f m "
      "(mean over 2.5-3 s), Archimedes %.4f, %+.2f dx\n",
      draft0, start, rise, mean, archimedes, error);
  EXPECT_GT(rise, 2.75 * kDx);
  EXPECT_LT(std::abs(error), 0.5);
}

// A cube 4 cells across (0.08 m) released under water at mid-depth in a
// tank 0.4 m square, water 0.3 m deep, with solver.front_fields: as dense
// as water it stays within a cell of where it was put, 1.5 times as dense
// it sinks. Each water particle used to take the two fields' correction
// into its J at once: at a face's edge, where it is in front at some
// nodes and in the rest at others, that divergence expanded the water over
// the edges and drew the cube up, so both cubes rose to the surface (the
// neutral one 10 cm in 0.9 s). Measured now over 1.2 s: the neutral cube
// moves at most 0.0093 m, the dense one sinks 0.067 m (with one field the
// neutral one sinks 0.026 m and the dense one 0.054 m).
TEST(SubmergedCube, FrontFieldsNeitherLiftNorHoldIt) {
  for (const double ratio : {1.0, 1.5}) {
    const std::string name = "cube_fronts_" + std::to_string(int(std::lround(10 * ratio)));
    json j = test::baseScene(name, {0.4, 0.4, 0.4}, kDx);
    j["solver"]["front_fields"] = true;
    j["materials"]["water"] = {{"model", "water"}, {"density", 1000}, {"bulk_modulus", 2e5}};
    const std::array<double, 3> lo{0.16, 0.11, 0.16}, hi{0.24, 0.19, 0.24};
    test::addWaterRoundBox(j, "water", 0.4, 0.4, 0.3, lo, hi);
    j["objects"].push_back(
        {{"name", "cube"}, {"kind", "rigid"}, {"density", 1000 * ratio}, {"shape", box(lo, hi)}});
    World w = test::loadWorld(test::tempDir(name), j);
    const double y0 = w.bodies[0].state.x.y();
    Solver solver(w);
    double furthest = 0;
    for (int k = 1; k <= 12; ++k) {
      solver.advanceTo(0.1 * k);
      furthest = std::max(furthest, std::abs(w.bodies[0].state.x.y() - y0));
    }
    const double moved = w.bodies[0].state.x.y() - y0;
    std::printf("front fields, cube of ratio %.1f: moved %+.4f m in 1.2 s (at most %.4f)\n", ratio,
                moved, furthest);
    if (ratio == 1.0)
      EXPECT_LT(furthest, kDx) << "a cube as dense as water drifted";
    else
      EXPECT_LT(moved, -2 * kDx) << "a cube denser than water did not sink";
  }
}

// A frictionless ball of half water's density dropped onto calm water
// (0.1 m across, 5 cells) bobs and floats; no force normal to its surface
// has a moment about its centre, so once it floats it must not turn. With
// the solid velocity at its nodes taken from its samples' mean there
// (solver.rigid_node_velocity samples, the contract's step 1) a turning ball
// met the water where its surface moved along the nodes' normals, and the
// impulses spun it on: 4.4 rad/s over 1.5-3 s here (bench/RESULTS.md, "A
// floating ball spun"). The landing still turns it a little (up to about
// 0.7 rad/s in the first half second): the nodes' normals are off the
// ball's radius by a few degrees.
TEST(FloatingBall, DoesNotSpin) {
  json j = test::baseScene("float_ball", {0.4, 0.4, 0.4}, kDx);
  j["materials"]["water"] = {{"model", "water"}, {"density", 1000}, {"bulk_modulus", 2e5}};
  j["objects"].push_back({{"name", "water"},
                          {"kind", "mpm"},
                          {"material", "water"},
                          {"shape", box({0, 0, 0}, {0.4, kDepth, 0.4})}});
  j["objects"].push_back(
      {{"name", "ball"},
       {"kind", "rigid"},
       {"density", 500},
       {"friction", 0.0},
       {"shape", {{"sphere", {{"center", {0.2, 0.253, 0.2}}, {"radius", 0.05}}}}}});
  World w = test::loadWorld(test::tempDir("float_ball"), j);
  Solver solver(w);
  double spin = 0.0;
  for (int k = 1; k <= 60; ++k) {
    solver.advanceTo(0.05 * k);
    if (k > 30) spin = std::max(spin, w.bodies[0].omega().norm());
  }
  std::printf("largest spin over 1.5-3 s: %.3f rad/s\n", spin);
  EXPECT_LT(spin, 0.3);
  // It floats half under: its centre at the water level (0.2008 m, the
  // level with its displacement and the water's compression), high by no
  // more than a cell (the band of rest) and low by no more than a quarter.
  const double y = w.bodies[0].state.x.y();
  EXPECT_GT(y, 0.2008 - 0.25 * kDx);
  EXPECT_LT(y, 0.2008 + kDx);
}

// A log of rectangular section w x h and half water's density, tilted by
// tilt0 degrees about its long axis, in a quasi-2D tank (4 cells thick, the
// log spanning it wall to wall, frictionless): water 0.3 m deep placed round
// the tilted log (columns one particle spacing wide, cut at its faces), its
// centre `depth` under the water level. At depth 0 a section symmetric
// about its centre displaces half its area at any tilt, so that only the
// water's moment is out of balance. The scene's files go to `dir`.
json logScene(const std::filesystem::path& dir, double w, double h, double tilt0, double depth,
              bool fixed, double time, int sides = 4) {
  const double level = 0.3, length = 4 * kDx, x_len = std::max(0.6, 4 * std::max(w, h));
  const double xc = x_len / 2, yc = level - depth, t = tilt0 * M_PI / 180;
  json j =
      test::baseScene(dir.filename().string(), {x_len, level + std::max(w, h) + 0.1, length}, kDx);
  j["domain"]["boundary"] = {{"type", "slip"}, {"friction", 0}};
  j["frames"] = {{"count", int(std::lround(time * 4))}, {"fps", 4}};
  j["materials"]["water"] = {{"model", "water"}, {"density", 1000}, {"bulk_modulus", 2e5}};
  // The section's outline counter-clockwise about its centre, its corners
  // in the tank, and its vertical extent at x.
  std::vector<std::array<double, 2>> outline, c;
  if (sides == 4)
    outline = {{w / 2, h / 2}, {-w / 2, h / 2}, {-w / 2, -h / 2}, {w / 2, -h / 2}};
  else
    for (int k = 0; k < sides; ++k)
      outline.push_back(
          {w / 2 * std::cos(2 * M_PI * k / sides), h / 2 * std::sin(2 * M_PI * k / sides)});
  for (const auto& [x, y] : outline)
    c.push_back({xc + x * std::cos(t) - y * std::sin(t), yc + x * std::sin(t) + y * std::cos(t)});
  auto span = [&](double x, double& lo, double& hi) {
    lo = INFINITY, hi = -INFINITY;
    for (size_t k = 0; k < c.size(); ++k) {
      const auto& p = c[k];
      const auto& q = c[(k + 1) % c.size()];
      if ((p[0] - x) * (q[0] - x) > 0 || p[0] == q[0]) continue;
      const double y = p[1] + (q[1] - p[1]) * (x - p[0]) / (q[0] - p[0]);
      lo = std::min(lo, y), hi = std::max(hi, y);
    }
    return lo <= hi;
  };
  const double step = kDx / 2;  // 8 particles per cell: one column each
  for (int i = 0; i * step < x_len - 1e-9; ++i) {
    const double x0 = i * step, x1 = x0 + step;
    double lo, hi;
    std::vector<std::pair<double, double>> parts;
    if (!span(0.5 * (x0 + x1), lo, hi))
      parts = {{0.0, level}};
    else
      parts = {{0.0, std::min(lo, level)}, {hi, level}};
    for (const auto& [y0, y1] : parts)
      if (y1 > y0)
        j["objects"].push_back({{"name", "water" + std::to_string(j["objects"].size())},
                                {"kind", "mpm"},
                                {"material", "water"},
                                {"shape", box({x0, y0, 0}, {x1, y1, length})}});
  }
  {
    // The outline extruded along z: vertex 2k + 1 at -length/2, 2k + 2 at
    // +length/2; the sides, then a fan for each end.
    std::ofstream obj(dir / "log.obj");
    const size_t n = outline.size();
    for (const auto& [x, y] : outline)
      obj << "v " << x << " " << y << " " << -length / 2 << "\nv " << x << " " << y << " "
          << length / 2 << "\n";
    for (size_t k = 0; k < n; ++k) {
      const size_t a = 2 * k + 1, b = 2 * ((k + 1) % n) + 1;
      obj << "f " << a << " " << b << " " << b + 1 << "\nf " << a << " " << b + 1 << " " << a + 1
          << "\n";
    }
    for (size_t k = 1; k + 1 < n; ++k)
      obj << "f 1 " << 2 * k + 3 << " " << 2 * k + 1 << "\nf 2 " << 2 * k + 2 << " " << 2 * k + 4
          << "\n";
  }
  j["objects"].push_back({{"name", "log"},
                          {"kind", "rigid"},
                          {"density", 500},
                          {"shape",
                           {{"mesh",
                             {{"path", (dir / "log.obj").string()},
                              {"translate", {xc, yc, length / 2}},
                              {"rotate_deg", {0, 0, tilt0}}}}}}});
  if (fixed) j["objects"].back()["fixed"] = true;
  return j;
}

// The log of logScene at the water level, free: its tilt in degrees every
// 0.25 s to `time`.
std::vector<double> logTilts(const std::string& name, double w, double h, double tilt0,
                             double time) {
  const std::filesystem::path dir = test::tempDir(name);
  const json j = logScene(dir, w, h, tilt0, 0.0, false, time);
  World world = test::loadWorld(dir, j);
  const Mat3d r0 = world.bodies[0].rotation();
  Solver solver(world);
  std::vector<double> tilts;
  for (int k = 1; k <= int(std::lround(time * 4)); ++k) {
    solver.advanceTo(0.25 * k);
    const Mat3d turn = world.bodies[0].rotation() * r0.transpose();
    tilts.push_back(tilt0 + std::atan2(turn(1, 0), turn(0, 0)) * 180 / M_PI);
  }
  return tilts;
}

// The mean force on the first body of a 1.5 s scene over its second half.
Vec3d meanForceFromHalfTime(const std::filesystem::path& dir, const json& j) {
  World w = test::loadWorld(dir, j);
  Solver solver(w);
  solver.advanceTo(0.75);
  solver.resetLoads();
  solver.advanceTo(1.5);
  return solver.bodyLoads()[0].force();
}

// The log of logScene 5 cells square, fixed with its centre 0.15 m under
// water, spanning the quasi-2D tank wall to wall: the water's force is its
// buoyancy, rho g V (7.85 N), within 5% (the mean over 0.75-1.5 s; the
// level is the placed one, the water's compression lowers it by 1%).
// Measured 7.80 N. Its faces on the walls used to count as surface: the
// samples near the walls took normals along them and the force read 4.86
// N (62%); a fixed box, whose wall faces were closed, read 7.94 N.
// The same log as a collider (kind collider, not animated) reads the same,
// and as an animated collider gliding along the tank at 1 cm/s (its
// animation keeps it spanning the tank) 7.78 N (4.81 N before its faces
// were closed). The glide also reads a drag of 0.62 N (0.41 N at 0.5
// cm/s), where the water's real resistance at such speeds is a
// thousandth of that: the water behind the log lags it (not asserted).
TEST(FloatingLog, SpanningTheTankItFeelsItsBuoyancy) {
  for (const std::string kind : {"rigid", "collider", "animated collider"}) {
    std::string slug = kind;
    std::replace(slug.begin(), slug.end(), ' ', '_');
    const std::filesystem::path dir = test::tempDir("log_submerged_" + slug);
    json j = logScene(dir, 0.1, 0.1, 0.0, 0.15, true, 1.5);
    if (kind != "rigid") {
      json& log = j["objects"].back();
      log["kind"] = "collider";
      log.erase("density");
      log.erase("fixed");
      if (kind == "animated collider")
        log["animation"] = {{"keys",
                             {{{"time", 0.0}, {"translate", {0, 0, 0}}},
                              {{"time", 1.5}, {"translate", {0.015, 0, 0}}}}}};
    }
    const Vec3d f = meanForceFromHalfTime(dir, j);
    const double buoyancy = 1000 * 9.81 * 0.1 * 0.1 * 4 * kDx;
    std::printf("fixed log under water (%s): force %.3f %.3f %.3f N, rho g V %.3f N\n",
                kind.c_str(), f.x(), f.y(), f.z(), buoyancy);
    EXPECT_NEAR(f.y(), buoyancy, 0.05 * buoyancy) << kind;
    if (kind != "animated collider") {
      EXPECT_NEAR(f.x(), 0.0, 0.02 * buoyancy) << kind;
    }
  }
}

// A round log (a 32-sided prism 0.1 m across) held 0.15 m under water,
// spanning the quasi-2D tank: its faces on the walls are closed as the
// square log's are. Its force is its buoyancy within 5%: measured 6.25 N of
// rho g V = 6.12 N (102%), and 6.07 N over 3.5-4 s. Three faults read
// here, each fixed: samples replaced by the closure took the distance to
// the nearest surface point (on a face oblique to the lattice up to half a
// spacing off the sample's foot) and its normal with its lean along the
// axis (82.5% then), and the other samples within a couple of spacings of
// a wall kept normals leaning up to 0.4 towards it, whose planes hid the
// particles that crept in along the walls from the push-out (89% over
// 0.75-1.5 s then, and 71% by 4 s as water gathered inside).
TEST(FloatingLog, RoundLogSpanningTheTankFeelsItsBuoyancy) {
  const std::filesystem::path dir = test::tempDir("log_round");
  const Vec3d f = meanForceFromHalfTime(dir, logScene(dir, 0.1, 0.1, 0.0, 0.15, true, 1.5, 32));
  const double area = 0.5 * 32 * 0.05 * 0.05 * std::sin(2 * M_PI / 32);
  const double buoyancy = 1000 * 9.81 * area * 4 * kDx;
  std::printf("round log under water: force %.3f %.3f N, rho g V %.3f N (%.1f%%)\n", f.x(), f.y(),
              buoyancy, 100 * f.y() / buoyancy);
  EXPECT_NEAR(f.y(), buoyancy, 0.05 * buoyancy);
  EXPECT_NEAR(f.x(), 0.0, 0.02 * buoyancy);
}

// A square log floats flat only below 0.211 or above 0.789 of water's
// density: at half of it the metacentric height a/(12 s) - a (1 - s)/2 is
// -a/12, so tilted a little it turns on to float corner-down (45 degrees),
// the way real square timbers float. 10 cells across (0.2 m), from 10
// degrees: measured 40.1 degrees at 2.5 s (16.6 at 0.5 s, 22.2 at 1 s;
// 43.6 at 2.5 s before the closed walls' samples lost their normals' lean
// along the axis). A
// log 5 cells across holds a tilt it is given or goes flat, within the
// band of rest (bench/RESULTS.md, "A floating log's righting moment").
// With the collision's moments at the nodes left out of the body's
// response it turns far more slowly (18.8 degrees at 1 s) but still
// reaches 35.7 at 2.5 s and passes: the plank below is what catches that.
TEST(FloatingLog, SquareOfHalfWatersDensityTurnsCornerDown) {
  const std::vector<double> tilt = logTilts("log_square", 0.2, 0.2, 10.0, 2.5);
  std::printf("square log, tilt every 0.25 s:");
  for (const double a : tilt) std::printf(" %.1f", a);
  std::printf("\n");
  EXPECT_GT(tilt.back(), 35.0) << "the log did not turn corner-down";
  EXPECT_LT(tilt.back(), 52.0);
}

// A plank 0.3 x 0.1 m of half water's density is stable flat (metacentric
// height +125 mm): from 15 degrees it rights itself. Measured: 0.9 degrees
// at 0.25 s, -6.6 at 0.5 s, then within 3.4 degrees of flat from 0.75 s,
// -2.6 on average over 1.25-2.5 s. Where within that it rests moves with
// small changes (the band of rest at its edges is about 6 degrees either
// way): it averaged 1.1 before the closed walls' replaced samples dropped
// their normals' component along the axis, -1.9 before the others did.
// With the collision's moments at the nodes left out of the body's
// response (the samples' read-back alone) it stays at 11-18 degrees and
// fails.
TEST(FloatingLog, WidePlankRightsItself) {
  const std::vector<double> tilt = logTilts("log_plank", 0.3, 0.1, 15.0, 2.5);
  std::printf("plank, tilt every 0.25 s:");
  for (const double a : tilt) std::printf(" %.1f", a);
  std::printf("\n");
  double mean = 0, most = 0;
  for (size_t k = 5; k < tilt.size(); ++k) {
    mean += tilt[k] / double(tilt.size() - 5);
    most = std::max(most, std::abs(tilt[k]));
  }
  EXPECT_LT(std::abs(mean), 3.5);
  EXPECT_LT(most, 4.5);
}

// An elastic log (a jelly, E 3e5 Pa) as dense as water, 5 cells square,
// spanning the quasi-2D tank wall to wall, its centre 0.15 m under water:
// it stays where it was put (the issue asks within a cell over 2 s; here
// within a quarter over 1.5 s, and still). Measured: 0.07 dx low at 1.5 s,
// 0.0001 m/s over 1-1.5 s. Its nodes on the walls used to lie on its
// boundary, with normals along the walls: the water's pressure there went
// into the walls, and the log sank, faster and faster (0.62 dx by 1.5 s,
// 0.0076 m/s then). With the samples closed but the wall nodes left on
// the boundary (distance 0) it sank faster still: 1.41 dx by 1.5 s. The jelly is stiff so that the
// water's pressure (about 1.5 kPa) barely shrinks it: at E 3e4 (21 s -> 7 s of test) it would lose
// about 6% of its volume and rightly sink (0.67 dx by 1.5 s).
TEST(FloatingLog, ElasticSpanningTheTankStaysPutAsDenseAsWater) {
  const std::filesystem::path dir = test::tempDir("log_elastic");
  json j = logScene(dir, 0.1, 0.1, 0.0, 0.15, false, 1.5);
  j["materials"]["jelly"] = {{"model", "fixed_corotated"},
                             {"density", 1000},
                             {"youngs_modulus", 3e5},
                             {"poisson_ratio", 0.3}};
  json& log = j["objects"].back();
  log["kind"] = "elastic";
  log.erase("density");
  log["material"] = "jelly";
  World w = test::loadWorld(dir, j);
  ASSERT_EQ(w.elastics.size(), 1u);
  auto centre = [&]() { return w.elastics[0].fem.centreOfMass().y(); };
  const double y0 = centre();
  Solver solver(w);
  std::printf("elastic log under water, centre from %.4f m:", y0);
  double y1 = 0;
  for (int k = 1; k <= 6; ++k) {
    solver.advanceTo(0.25 * k);
    std::printf(" %.4f", centre());
    if (k == 4) y1 = centre();
  }
  const double speed = (centre() - y1) / 0.5;
  std::printf("\n  at 1.5 s %+.2f dx, %+.4f m/s over 1-1.5 s\n", (centre() - y0) / kDx, speed);
  EXPECT_LT(std::abs(centre() - y0), 0.25 * kDx);
  EXPECT_LT(std::abs(speed), 0.002);
}

}  // namespace
}  // namespace triad
