// Estimates before work: `triad check` validates a scene and says what its
// run will need; `triad run` refuses at once a scene that cannot fit in
// memory, naming the object, and warns at once about an extreme one.
#include <gtest/gtest.h>
#include <sys/resource.h>

#include <chrono>

#include "cli_fixture.h"
#include "scene_fixture.h"

namespace triad {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// A box, a sphere and a mesh of MPM material, and a rigid body.
json mixedShapes(const fs::path& dir) {
  fs::copy_file(fs::path(TRIAD_SOURCE_DIR) / "scenes/meshes/torus.obj", dir / "torus.obj",
                fs::copy_options::overwrite_existing);
  json j = test::baseScene("estimate", {1, 0.6, 0.6}, 0.02);
  j["materials"]["sand"] = {{"model", "drucker_prager"}, {"density", 1600},
                            {"youngs_modulus", 2e5}, {"poisson_ratio", 0.3}};
  j["materials"]["water"] = {{"model", "water"}, {"density", 1000}, {"bulk_modulus", 1e5}};
  j["objects"] = {
      {{"name", "bed"}, {"kind", "mpm"}, {"material", "sand"},
       {"shape", test::box({0, 0, 0}, {1, 0.1, 0.6})}},
      {{"name", "drop"}, {"kind", "mpm"}, {"material", "water"},
       {"shape", {{"sphere", {{"center", {0.3, 0.3, 0.3}}, {"radius", 0.1}}}}}},
      {{"name", "ring"}, {"kind", "mpm"}, {"material", "sand"},
       {"shape", {{"mesh", {{"path", "torus.obj"}, {"scale", 0.2}, {"translate", {0.7, 0.3, 0.3}}}}}}},
      {{"name", "crate"}, {"kind", "rigid"}, {"density", 500},
       {"shape", test::box({0.2, 0.45, 0.2}, {0.3, 0.55, 0.3})}}};
  j["frames"] = {{"count", 1}, {"fps", 24}};
  j["output"] = {{"vdb", false}, {"png", false}};
  return j;
}

TEST(Estimate, CheckCountsTheParticlesARunMakes) {
  const fs::path dir = test::tempDir("estimate_count");
  const std::string scene = test::writeScene(dir, mixedShapes(dir));
  const test::CliResult c = test::runTriad(dir, "check " + scene + " --json");
  ASSERT_EQ(c.status, 0) << c.err;
  const json est = json::parse(c.out);
  ASSERT_EQ(test::runTriad(dir, "run " + scene + " --quiet --out " + (dir / "out").string()).status, 0);
  const json rec = json::parse(test::slurp(dir / "out" / "run.json"));
  for (int k = 0; k < 3; ++k) {
    const std::string name = est["objects"][k]["name"];
    const double estimated = est["objects"][k]["particles"].get<double>();
    const double made = rec["particles"]["per_object"][name].get<double>();
    EXPECT_NEAR(estimated, made, 0.01 * made) << name;  // the box exactly, the others by volume
  }
  EXPECT_EQ(est["objects"][0]["particles"].get<double>(),
            rec["particles"]["per_object"]["bed"].get<double>());
  // The solver settings the run would use are those it records.
  EXPECT_EQ(est["solver"], rec["solver"]);
  EXPECT_EQ(est["solver"]["contact_gap_fixed"], true);
  // And for people: a line per object.
  const test::CliResult text = test::runTriad(dir, "check " + scene);
  EXPECT_EQ(text.status, 0);
  EXPECT_NE(text.out.find("valid; estimate"), std::string::npos) << text.out;
  EXPECT_NE(text.out.find("bed"), std::string::npos) << text.out;
  EXPECT_NE(text.out.find("substeps a frame"), std::string::npos) << text.out;
}

// --probe steps the scene itself: long enough, it runs the whole of it, and
// takes exactly the run's steps; cut short, it has taken at least one and
// puts the whole run beyond what it measured. (Its seconds are this
// machine's and are not asserted.)
TEST(Estimate, ProbeStepsTheRunItself) {
  const fs::path dir = test::tempDir("estimate_probe");
  const std::string scene = test::writeScene(dir, mixedShapes(dir));
  const test::CliResult c = test::runTriad(dir, "check " + scene + " --json --probe 600");
  ASSERT_EQ(c.status, 0) << c.err;
  const json probe = json::parse(c.out)["probe"];
  ASSERT_EQ(test::runTriad(dir, "run " + scene + " --quiet --out " + (dir / "out").string()).status, 0);
  const json rec = json::parse(test::slurp(dir / "out" / "run.json"));
  EXPECT_TRUE(probe["whole_run"].get<bool>());
  EXPECT_EQ(probe["steps"].get<int>(), rec["steps"].get<int>());
  EXPECT_DOUBLE_EQ(probe["simulated_seconds"].get<double>(), 1.0 / 24);
  EXPECT_GT(probe["particle_substeps_per_second"].get<double>(), 0.0);
  // Cut short after its first step.
  const test::CliResult s = test::runTriad(dir, "check " + scene + " --json --probe 1e-9");
  ASSERT_EQ(s.status, 0) << s.err;
  const json p = json::parse(s.out)["probe"];
  EXPECT_FALSE(p["whole_run"].get<bool>());
  EXPECT_EQ(p["steps"].get<int>(), 1);
  EXPECT_GT(p["run_wall_seconds"].get<double>(), p["wall_seconds"].get<double>());
  // For people: a line after the estimate.
  const test::CliResult text = test::runTriad(dir, "check " + scene + " --probe 1e-9");
  EXPECT_NE(text.out.find("probe: built in"), std::string::npos) << text.out;
}

// A source kept full under gravity emits more than rho A |v|: its material
// accelerates out of it, and with no velocity at all it still pours. A
// sand hopper 4 cells tall, for 0.5 s: measured 7040 and 4389 particles
// made, estimated 6898 (-2.0%) and 4399 (+0.2%); the estimate ignoring
// gravity said 4353 and 640 (the fill alone).
TEST(Estimate, SourceEmissionFollowsGravity) {
  for (double vy : {-1.0, 0.0}) {
    const fs::path dir = test::tempDir(vy == 0 ? "estimate_pour" : "estimate_hopper");
    json j = test::baseScene("hopper", {0.4, 1.0, 0.4}, 0.02);
    j["materials"]["sand"] = {{"model", "drucker_prager"}, {"density", 1600},
                              {"youngs_modulus", 2e5}, {"poisson_ratio", 0.3}};
    j["objects"].push_back({{"name", "hopper"}, {"kind", "mpm"}, {"material", "sand"},
                            {"velocity", {0, vy, 0}},
                            {"shape", test::box({0.16, 0.82, 0.15}, {0.24, 0.9, 0.25})},
                            {"emit", {{"start", 0.0}, {"end", 5.0}}}});
    j["frames"] = {{"count", 12}, {"fps", 24}};
    j["output"] = {{"vdb", false}, {"png", false}};
    const std::string scene = test::writeScene(dir, j);
    const test::CliResult c = test::runTriad(dir, "check " + scene + " --json --no-probe");
    ASSERT_EQ(c.status, 0) << c.err;
    const double estimated = json::parse(c.out)["objects"][0]["particles"].get<double>();
    const std::string out = (dir / "out").string();
    ASSERT_EQ(test::runTriad(dir, "run " + scene + " --quiet --no-probe --out " + out).status, 0);
    const json rec = json::parse(test::slurp(dir / "out" / "run.json"));
    const double made = rec["particles"]["emitted"]["hopper"].get<double>();
    std::printf("velocity %g: estimated %.0f, made %.0f\n", vy, estimated, made);
    EXPECT_NEAR(estimated, made, 0.05 * made) << vy;
  }
}

// The wall time is at a rate measured here: a short probe of a coarser copy
// of the scene (its rate is this machine's and is not asserted), or with
// --no-probe the fixed rate. The probe writes nothing: not even the
// output directory exists after `triad check`. `triad run` records its
// estimate in run.json.
TEST(Estimate, WallTimeFromAShortProbe) {
  const fs::path dir = test::tempDir("estimate_rate");
  json j = mixedShapes(dir);
  j["output"]["dir"] = (dir / "cache").string();
  const std::string scene = test::writeScene(dir, j);
  const test::CliResult c = test::runTriad(dir, "check " + scene + " --json");
  ASSERT_EQ(c.status, 0) << c.err;
  const json est = json::parse(c.out);
  EXPECT_EQ(est["rate_from"], "probe");
  const double rate = est["rate_particle_substeps_per_s"].get<double>();
  EXPECT_GT(rate, 0.0);
  EXPECT_GT(est["rate_probe"]["steps"].get<int>(), 0);
  EXPECT_GT(est["rate_probe"]["particles"].get<double>(), 0.0);
  // particles x substeps / rate
  const double substeps = est["substeps_per_frame"].get<double>() * 1;  // one frame
  EXPECT_NEAR(est["wall_seconds"].get<double>(), est["particles"].get<double>() * substeps / rate,
              1e-6 * est["wall_seconds"].get<double>());
  EXPECT_FALSE(fs::exists(dir / "cache")) << "the probe wrote into the output directory";
  const test::CliResult text = test::runTriad(dir, "check " + scene);
  EXPECT_NE(text.out.find("measured here (probe: dx"), std::string::npos) << text.out;
  // A large scene is probed coarser, with at most some tens of thousands
  // of particles.
  const fs::path big_dir = test::tempDir("estimate_rate_big");
  json big = mixedShapes(big_dir);
  big["domain"]["dx"] = 0.005;
  big["output"]["dir"] = (big_dir / "cache").string();
  const test::CliResult b =
      test::runTriad(big_dir, "check " + test::writeScene(big_dir, big) + " --json");
  ASSERT_EQ(b.status, 0) << b.err;
  const json bj = json::parse(b.out);
  EXPECT_GT(bj["particles"].get<double>(), 5e5);
  EXPECT_EQ(bj["rate_from"], "probe");
  EXPECT_GT(bj["rate_probe"]["dx"].get<double>(), 0.005);
  EXPECT_LT(bj["rate_probe"]["particles"].get<double>(), 6e4);
  EXPECT_FALSE(fs::exists(big_dir / "cache"));
  // Without the probe: the fixed rate.
  const test::CliResult f = test::runTriad(dir, "check " + scene + " --json --no-probe");
  ASSERT_EQ(f.status, 0) << f.err;
  const json fj = json::parse(f.out);
  EXPECT_EQ(fj["rate_from"], "fixed");
  EXPECT_EQ(fj["rate_particle_substeps_per_s"].get<double>(), 9e6);
  EXPECT_EQ(fj["rate_probe"]["skipped"], "--no-probe");
  EXPECT_NE(test::runTriad(dir, "check " + scene + " --no-probe").out.find("fixed 9e+06"),
            std::string::npos);
  // The run's own estimate, in run.json.
  ASSERT_EQ(test::runTriad(dir, "run " + scene + " --quiet").status, 0);
  const json rec = json::parse(test::slurp(dir / "cache" / "run.json"));
  EXPECT_EQ(rec["estimate"]["rate_from"], "probe");
  EXPECT_GT(rec["estimate"]["wall_seconds"].get<double>(), 0.0);
  EXPECT_GT(rec["estimate"]["probe_seconds"].get<double>(), 0.0);
  ASSERT_EQ(test::runTriad(dir, "run " + scene + " --quiet --no-probe").status, 0);
  const json rec2 = json::parse(test::slurp(dir / "cache" / "run.json"));
  EXPECT_EQ(rec2["estimate"]["rate_from"], "fixed");
  EXPECT_EQ(rec2["estimate"]["probe_seconds"].get<double>(), 0.0);
}

// dx = 1e-5 m asks for about 1e14 particles: refused before any sampling,
// in well under 5 s and 1 GiB, naming the object, the count and what to
// change; `triad check` says the same with exit 2.
TEST(Estimate, SceneThatCannotFitExitsTwoAtOnce) {
  const fs::path dir = test::tempDir("estimate_huge");
  json j = mixedShapes(dir);
  j["domain"]["dx"] = 1e-5;
  const std::string scene = test::writeScene(dir, j);
  const auto t0 = std::chrono::steady_clock::now();
  const test::CliResult r = test::runTriad(
      dir, "run " + scene + " --quiet --out " + (dir / "out").string(), "ulimit -v 1048576;");
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_EQ(r.status, 2) << r.err;
  EXPECT_LT(seconds, 5.0);
  EXPECT_NE(r.err.find("objects[0]"), std::string::npos) << r.err;  // the bed asks the most
  EXPECT_NE(r.err.find("'bed' needs about"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("Raise domain.dx"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "out" / "particles")) << "nothing written";
  const test::CliResult c = test::runTriad(dir, "check " + scene);
  EXPECT_EQ(c.status, 2);
  EXPECT_NE(c.err.find("'bed' needs about"), std::string::npos) << c.err;
}

// A water of bulk modulus 1e14 Pa needs steps of about 1e-8 s: the run says
// so at once (its estimate), then goes on.
// A damped explicit elastic solid steps at its viscous limit, cfl rho h^2 /
// (6 eta): the estimate's first step is that one, within the factor the
// element height's guess (h / sqrt 3) allows, not the elastic one 100 times
// longer. Measured: 6.9e-6 s estimated, 1.0e-5 s run.
TEST(Estimate, DampedElasticStepsAtItsViscousLimit) {
  const fs::path dir = test::tempDir("estimate_damped");
  json j = test::baseScene("damped", {0.4, 0.4, 0.4}, 0.05);
  j["materials"]["jelly"] = {{"model", "fixed_corotated"}, {"density", 1000},
                             {"youngs_modulus", 2e4}, {"poisson_ratio", 0.3}};
  j["objects"].push_back({{"name", "cube"}, {"kind", "elastic"}, {"material", "jelly"},
                          {"damping", 2000}, {"shape", test::box({0.1, 0.1, 0.1}, {0.2, 0.2, 0.2})}});
  j["output"] = {{"vdb", false}, {"png", false}, {"ply", false}};
  const std::string scene = test::writeScene(dir, j);
  const test::CliResult c = test::runTriad(dir, "check " + scene + " --json");
  ASSERT_EQ(c.status, 0) << c.err;
  const double estimated = json::parse(c.out)["first_dt"].get<double>();
  ASSERT_EQ(test::runTriad(dir, "run " + scene + " --quiet --out " + (dir / "out").string()).status, 0);
  const double ran = json::parse(test::slurp(dir / "out" / "run.json"))["dt"]["max"].get<double>();
  EXPECT_GT(estimated, 0.5 * ran);
  EXPECT_LT(estimated, 1.5 * ran);
}

TEST(Estimate, StiffSceneWarnsAtOnce) {
  const fs::path dir = test::tempDir("estimate_stiff");
  json j = mixedShapes(dir);
  j["materials"]["water"]["bulk_modulus"] = 1e14;
  const std::string scene = test::writeScene(dir, j);
  const test::CliResult r = test::runTriad(
      dir, "run " + scene + " --plain --out " + (dir / "out").string(), "timeout 5");
  EXPECT_EQ(r.status, 124) << r.err;  // still running when stopped: it went on
  EXPECT_NE(r.err.find("substeps a frame"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("warning"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace triad
