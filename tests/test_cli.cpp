// The `triad` command line end to end: exit statuses, messages, caches.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <fstream>
#include <initializer_list>
#include <sstream>
#include <thread>

#include "cli_fixture.h"
#include "scene_fixture.h"

namespace triad {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

using test::slurp;
using Result = test::CliResult;

Result triad(const fs::path& dir, const std::string& args, const std::string& env = "") {
  return test::runTriad(dir, args, env);
}

// Every material model in one small scene, colliding, so that a thread-count
// dependence anywhere shows up in the bytes.
json mixedScene() {
  json j = test::baseScene("mixed", {0.4, 0.4, 0.4}, 0.02);
  j["frames"] = {{"count", 3}, {"fps", 24}};
  j["materials"] = {
      {"jelly", {{"model", "fixed_corotated"}, {"density", 1000}, {"youngs_modulus", 5e4},
                 {"poisson_ratio", 0.3}}},
      {"rubber", {{"model", "neo_hookean"}, {"density", 1100}, {"youngs_modulus", 8e4},
                  {"poisson_ratio", 0.4}}},
      {"snow", {{"model", "snow"}, {"density", 400}, {"youngs_modulus", 1.4e5},
                {"poisson_ratio", 0.2}}},
      {"sand", {{"model", "drucker_prager"}, {"density", 1600}, {"youngs_modulus", 1e5},
                {"poisson_ratio", 0.3}, {"friction_angle_deg", 35}, {"cohesion", 10}}},
      {"water", {{"model", "water"}, {"density", 1000}, {"bulk_modulus", 1e5},
                 {"viscosity", 0.001}}}};
  auto obj = [](const char* name, const char* mat, json shape, std::array<double, 3> v) {
    return json{{"name", name}, {"kind", "mpm"}, {"material", mat}, {"shape", shape},
                {"velocity", v}};
  };
  j["objects"] = {
      obj("sand", "sand", test::box({0.02, 0.0, 0.02}, {0.38, 0.08, 0.38}), {0, 0, 0}),
      obj("jelly", "jelly", test::box({0.05, 0.15, 0.05}, {0.15, 0.25, 0.15}), {0.5, -1, 0}),
      obj("rubber", "rubber", json{{"sphere", {{"center", {0.3, 0.2, 0.3}}, {"radius", 0.05}}}},
          {-0.5, -1, 0}),
      obj("snow", "snow", test::box({0.2, 0.12, 0.05}, {0.3, 0.2, 0.15}), {0, -2, 0.5}),
      obj("water", "water", test::box({0.05, 0.12, 0.25}, {0.15, 0.3, 0.35}), {1, 0, -1})};
  j["output"] = {{"vdb", false}, {"png", false}};
  return j;
}

TEST(Cli, SameBytesForOneAndTwoThreads) {
  const fs::path dir = test::tempDir("cli_threads");
  const std::string scene = test::writeScene(dir, mixedScene());
  const Result one = triad(dir, "run " + scene + " --threads 1 --quiet --out " + (dir / "t1").string());
  ASSERT_EQ(one.status, 0) << one.err;
  const Result two = triad(dir, "run " + scene + " --threads 2 --quiet --out " + (dir / "t2").string());
  ASSERT_EQ(two.status, 0) << two.err;
  for (int f = 0; f <= 3; ++f) {
    char name[64];
    std::snprintf(name, sizeof(name), "particles/particles.%04d.ply", f);
    const std::string a = slurp(dir / "t1" / name), b = slurp(dir / "t2" / name);
    ASSERT_GT(a.size(), 1000u) << name;
    EXPECT_TRUE(a == b) << name << " differs between 1 and 2 threads";
  }
  // The scene did move: frame 3 differs from frame 0.
  EXPECT_NE(slurp(dir / "t1/particles/particles.0000.ply"),
            slurp(dir / "t1/particles/particles.0003.ply"));
}

// With a solver thread on every core, the solver gives the writer one of
// them while it writes a frame (run.json counts those steps), and takes it
// back after: the steps run on changing thread counts, and every file is
// still the bytes of a run on one thread.
TEST(Cli, TheSolverGivesTheWriterACoreAndWritesTheSameBytes) {
  const fs::path dir = test::tempDir("cli_writer_core");
  json j = mixedScene();
  j["output"] = {{"vdb", true}, {"png", true}};
  j["render"] = {{"resolution", {320, 180}}};
  const std::string scene = test::writeScene(dir, j);
  const int cores = int(std::max(2u, std::thread::hardware_concurrency()));
  const Result one =
      triad(dir, "run " + scene + " --threads 1 --quiet --out " + (dir / "t1").string());
  ASSERT_EQ(one.status, 0) << one.err;
  const Result all = triad(dir, "run " + scene + " --threads " + std::to_string(cores) +
                                    " --quiet --out " + (dir / "all").string());
  ASSERT_EQ(all.status, 0) << all.err;
  const json rec = json::parse(slurp(dir / "all/run.json"));
  ASSERT_TRUE(rec.contains("threads_while_writing")) << "no core given to the writer";
  EXPECT_EQ(rec["threads_while_writing"].get<int>(), cores - 1);
  EXPECT_GT(rec["steps_while_writing"].get<int>(), 0);
  EXPECT_LT(rec["steps_while_writing"].get<int>(), rec["steps"].get<int>());
  // One thread leaves every core free: nothing to give.
  EXPECT_FALSE(json::parse(slurp(dir / "t1/run.json")).contains("threads_while_writing"));
  size_t files = 0;
  for (const auto& e : fs::recursive_directory_iterator(dir / "t1")) {
    if (!e.is_regular_file() || e.path().filename() == "run.json") continue;
    const fs::path rel = fs::relative(e.path(), dir / "t1");
    EXPECT_TRUE(slurp(e.path()) == slurp(dir / "all" / rel)) << rel << " differs";
    ++files;
  }
  // 4 frames of particles, volumes and previews, and the contact sheet.
  EXPECT_GE(files, 13u);
}

// The mixed scene with rigid bodies: a box thrown into the sand and
// against a wall, a ball falling on it, and a fixed sphere in the way.
json withRigidBodies(json j) {
  auto rigid = [](const char* name, json shape, double density, std::array<double, 3> v) {
    return json{{"name", name}, {"kind", "rigid"}, {"density", density}, {"friction", 0.4},
                {"shape", shape}, {"velocity", v}};
  };
  j["objects"].push_back(rigid("crate", test::box({0.25, 0.1, 0.2}, {0.33, 0.16, 0.28}), 600,
                               {2, -1, 0}));
  j["objects"].push_back(rigid("ball", json{{"sphere", {{"center", {0.3, 0.3, 0.24}}, {"radius", 0.04}}}},
                               3000, {0, -2, 0}));
  json post = rigid("post", json{{"sphere", {{"center", {0.1, 0.1, 0.3}}, {"radius", 0.05}}}}, 1000,
                    {0, 0, 0});
  post["fixed"] = true;
  j["objects"].push_back(post);
  return j;
}

// Runs scene j on 1 and 2 threads and expects the same bytes in `files`,
// and the crate moved.
void expectSameBytesWithBodies(const std::string& tag, const json& j,
                               std::initializer_list<const char*> files) {
  const fs::path dir = test::tempDir(tag);
  const std::string scene = test::writeScene(dir, j);
  const Result one = triad(dir, "run " + scene + " --threads 1 --quiet --out " + (dir / "t1").string());
  ASSERT_EQ(one.status, 0) << one.err;
  const Result two = triad(dir, "run " + scene + " --threads 2 --quiet --out " + (dir / "t2").string());
  ASSERT_EQ(two.status, 0) << two.err;
  for (const char* name : files) {
    const std::string a = slurp(dir / "t1" / name), b = slurp(dir / "t2" / name);
    ASSERT_GT(a.size(), 100u) << name;
    EXPECT_TRUE(a == b) << name << " differs between 1 and 2 threads";
  }
  EXPECT_NE(slurp(dir / "t1/bodies/crate.0000.ply"), slurp(dir / "t1/bodies/crate.0003.ply"));
}

TEST(Cli, SameBytesForOneAndTwoThreadsWithRigidBodies) {
  expectSameBytesWithBodies("cli_threads_rigid", withRigidBodies(mixedScene()),
                            {"particles/particles.0003.ply", "bodies/rigid_states.csv",
                             "bodies/crate.0003.ply", "bodies/ball.0003.ply"});
}

// The same with two fields on the solids' nodes (solver.front_fields): the
// scan's node sums go colour by colour, and every particle is corrected
// alone. The rigid bodies above, and an elastic block.
TEST(Cli, SameBytesForOneAndTwoThreadsWithFrontFields) {
  json j = withRigidBodies(mixedScene());
  j["solver"]["front_fields"] = true;
  j["objects"].push_back({{"name", "block"},
                          {"kind", "elastic"},
                          {"material", "jelly"},
                          {"friction", 0.4},
                          {"shape", test::box({0.2, 0.25, 0.05}, {0.28, 0.33, 0.13})},
                          {"velocity", {0, -2, 0}}});
  expectSameBytesWithBodies("cli_threads_fronts", j,
                            {"particles/particles.0003.ply", "bodies/rigid_states.csv",
                             "bodies/crate.0003.ply", "bodies/block.0003.ply"});
}

// The same with an elastic solid falling into the sand: its element
// forces, deformed normals and push-out of particles run in parallel (the
// sand's set is over the push-out's parallel threshold of 8192 particles).
TEST(Cli, SameBytesForOneAndTwoThreadsWithAnElasticSolid) {
  const fs::path dir = test::tempDir("cli_threads_elastic");
  json j = mixedScene();
  j["objects"].push_back({{"name", "block"},
                          {"kind", "elastic"},
                          {"material", "jelly"},
                          {"friction", 0.4},
                          {"shape", test::box({0.22, 0.1, 0.22}, {0.34, 0.2, 0.34})},
                          {"velocity", {0, -2, 0}}});
  const std::string scene = test::writeScene(dir, j);
  const Result one =
      triad(dir, "run " + scene + " --threads 1 --quiet --out " + (dir / "t1").string());
  ASSERT_EQ(one.status, 0) << one.err;
  const Result two =
      triad(dir, "run " + scene + " --threads 2 --quiet --out " + (dir / "t2").string());
  ASSERT_EQ(two.status, 0) << two.err;
  for (const char* name : {"particles/particles.0003.ply", "bodies/block.0003.ply"}) {
    const std::string a = slurp(dir / "t1" / name), b = slurp(dir / "t2" / name);
    ASSERT_GT(a.size(), 100u) << name;
    EXPECT_TRUE(a == b) << name << " differs between 1 and 2 threads";
  }
  EXPECT_NE(slurp(dir / "t1/bodies/block.0000.ply"), slurp(dir / "t1/bodies/block.0003.ply"));
}

TEST(Cli, WritesCacheAndRunRecord) {
  const fs::path dir = test::tempDir("cli_record");
  json j = mixedScene();
  j["frames"]["count"] = 2;
  const std::string scene = test::writeScene(dir, j);
  const Result r = triad(dir, "run " + scene + " --threads 2 --out " + (dir / "cache").string());
  ASSERT_EQ(r.status, 0) << r.err;
  // Plain progress lines when not a terminal, and a closing summary.
  EXPECT_NE(r.err.find("frame 2/2"), std::string::npos) << r.err;
  EXPECT_NE(r.out.find("particle-substeps/s"), std::string::npos) << r.out;
  const json rec = json::parse(slurp(dir / "cache/run.json"));
  EXPECT_TRUE(rec["finished"].get<bool>());
  EXPECT_EQ(rec["frames"]["written"].get<int>(), 3);
  EXPECT_EQ(rec["threads"].get<int>(), 2);
  EXPECT_GT(rec["steps"].get<int>(), 0);
  EXPECT_GT(rec["particles"]["per_object"]["water"].get<int>(), 0);
  EXPECT_EQ(rec["scene"]["name"], "mixed");
  EXPECT_LE(rec["dt"]["min"].get<double>(), rec["dt"]["max"].get<double>());
  EXPECT_GT(rec["wall_seconds"]["phases"]["p2g"].get<double>(), 0.0);
  // No solids, no solids phase to take apart.
  EXPECT_FALSE(rec["wall_seconds"].contains("solids_parts"));
}

// With solids, run.json takes the solids phase apart (what a user tuning a
// shot with bodies looks at), the parts in the step's order and summing to
// the phase; the summary prints them.
TEST(Cli, RunRecordTakesTheSolidsPhaseApart) {
  const fs::path dir = test::tempDir("cli_solids_parts");
  json j = mixedScene();
  j["frames"]["count"] = 2;
  j["objects"].push_back({{"name", "cube"},
                          {"kind", "elastic"},
                          {"material", "jelly"},
                          {"shape", test::box({0.22, 0.12, 0.22}, {0.32, 0.22, 0.32})},
                          {"velocity", {0, -1, 0}}});
  j["objects"].push_back(
      {{"name", "ball"},
       {"kind", "rigid"},
       {"density", 500},
       {"shape", json{{"sphere", {{"center", {0.1, 0.25, 0.3}}, {"radius", 0.04}}}}},
       {"velocity", {0, -1, 0}}});
  const std::string scene = test::writeScene(dir, j);
  const Result r = triad(dir, "run " + scene + " --threads 2 --out " + (dir / "cache").string());
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("solids by part: elastic_forces"), std::string::npos) << r.out;
  const auto rec = nlohmann::ordered_json::parse(slurp(dir / "cache/run.json"));
  const auto& parts = rec["wall_seconds"]["solids_parts"];
  std::vector<std::string> names;
  double sum = 0.0;
  for (const auto& [name, s] : parts.items()) {
    names.push_back(name);
    EXPECT_GE(s.get<double>(), 0.0) << name;
    sum += s.get<double>();
  }
  EXPECT_EQ(names,
            (std::vector<std::string>{"elastic_forces", "poses", "scatter", "gaps", "collide",
                                      "fronts", "push_out", "gather", "bodies", "elastic"}));
  for (const char* busy : {"elastic_forces", "scatter", "collide", "push_out", "gather"})
    EXPECT_GT(parts[busy].get<double>(), 0.0) << busy;
  EXPECT_EQ(parts["fronts"].get<double>(), 0.0);  // solver.front_fields is off
  const double solids = rec["wall_seconds"]["phases"]["solids"].get<double>();
  EXPECT_NEAR(sum, solids, 0.02 * solids + 1e-3);
}

// Without OMP_WAIT_POLICY the program runs with sleeping OpenMP threads
// (it restarts itself with the variable set); a policy the user set stays.
TEST(Cli, OpenMpThreadsSleepUnlessTheUserSaysOtherwise) {
  const fs::path dir = test::tempDir("cli_wait_policy");
  json j = mixedScene();
  j["frames"]["count"] = 1;
  const std::string scene = test::writeScene(dir, j);
  for (const auto& [env, expect] :
       {std::pair<std::string, std::string>{"env -u OMP_WAIT_POLICY -u GOMP_SPINCOUNT", "passive"},
        {"env -u GOMP_SPINCOUNT OMP_WAIT_POLICY=active", "active"}}) {
    const Result r = triad(dir, "run " + scene + " --quiet --out " + (dir / "cache").string(), env);
    ASSERT_EQ(r.status, 0) << r.err;
    const json rec = json::parse(slurp(dir / "cache/run.json"));
    EXPECT_EQ(rec["omp_wait_policy"], expect) << env;
    // Threads that sleep spin briefly first; a policy of the user's own is left as it is.
    if (expect == "passive")
      EXPECT_EQ(rec.value("omp_spin_count", ""), "3000") << env;
    else
      EXPECT_FALSE(rec.contains("omp_spin_count")) << env;
  }
}

// A shorter run into the directory of a longer one leaves no stale frames.
TEST(Cli, RerunRemovesFramesBeyondTheNewCount) {
  const fs::path dir = test::tempDir("cli_rerun");
  json j = mixedScene();
  j["frames"]["count"] = 3;
  j["output"] = {{"vdb", true}, {"png", false}};
  const std::string out = (dir / "cache").string();
  ASSERT_EQ(triad(dir, "run " + test::writeScene(dir, j) + " --quiet --out " + out).status, 0);
  ASSERT_TRUE(fs::exists(dir / "cache/particles/particles.0003.ply"));
  j["frames"]["count"] = 1;
  ASSERT_EQ(triad(dir, "run " + test::writeScene(dir, j) + " --quiet --out " + out).status, 0);
  EXPECT_TRUE(fs::exists(dir / "cache/particles/particles.0001.ply"));
  EXPECT_TRUE(fs::exists(dir / "cache/volumes/density.0001.vdb"));
  for (const char* stale : {"particles/particles.0002.ply", "particles/particles.0003.ply",
                            "volumes/density.0002.vdb", "volumes/density.0003.vdb"})
    EXPECT_FALSE(fs::exists(dir / "cache" / stale)) << stale;
  // A file of the user's with a frame number no run writes (more than nine
  // digits) is left alone, and does not stop the run (it once made the
  // tidying's number conversion throw: "triad: error: stoi", exit 1).
  const fs::path stray = dir / "cache/particles/particles.12345678901.ply";
  std::ofstream(stray) << "not ours";
  ASSERT_EQ(triad(dir, "run " + test::writeScene(dir, j) + " --quiet --out " + out).status, 0);
  EXPECT_TRUE(fs::exists(stray));
  EXPECT_TRUE(fs::exists(dir / "cache/particles/particles.0001.ply"));
}

TEST(Cli, TypoInSceneExitsTwoNamingTheKey) {
  const fs::path dir = test::tempDir("cli_typo");
  json j = mixedScene();
  j["materials"]["jelly"].erase("youngs_modulus");
  j["materials"]["jelly"]["youngs_modulu"] = 5e4;
  const std::string scene = test::writeScene(dir, j);
  const Result r = triad(dir, "run " + scene + " --out " + (dir / "cache").string());
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("scene.json"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("materials.jelly.youngs_modulu"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("youngs_modulus"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "cache")) << "nothing may be written for bad input";
}

TEST(Cli, BadMaterialReferenceAndMissingFileExitTwo) {
  const fs::path dir = test::tempDir("cli_bad");
  json j = mixedScene();
  j["objects"][1]["material"] = "jely";
  const Result r = triad(dir, "run " + test::writeScene(dir, j));
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("objects[1].material"), std::string::npos) << r.err;
  const Result missing = triad(dir, "run " + (dir / "nope.json").string());
  EXPECT_EQ(missing.status, 2);
  EXPECT_NE(missing.err.find("nope.json"), std::string::npos) << missing.err;
  const Result usage = triad(dir, "run");
  EXPECT_EQ(usage.status, 2);
}

// Mesh objects run end to end; a broken mesh exits 2 naming the file.
TEST(Cli, MeshObjectsRunAndBrokenMeshesExitTwo) {
  const fs::path dir = test::tempDir("cli_mesh");
  fs::copy_file(fs::path(TRIAD_SOURCE_DIR) / "scenes/meshes/torus.obj", dir / "torus.obj");
  json j = test::baseScene("mesh", {0.4, 0.4, 0.4}, 0.02);
  j["frames"] = {{"count", 1}, {"fps", 24}};
  j["materials"]["jelly"] = {{"model", "fixed_corotated"}, {"density", 1000},
                             {"youngs_modulus", 5e4}, {"poisson_ratio", 0.3}};
  j["objects"].push_back(
      {{"name", "torus"}, {"kind", "mpm"}, {"material", "jelly"},
       {"shape", {{"mesh", {{"path", "torus.obj"}, {"scale", 0.1}, {"translate", {0.2, 0.2, 0.2}}}}}}});
  j["output"] = {{"vdb", false}, {"png", false}};
  const Result ok =
      triad(dir, "run " + test::writeScene(dir, j) + " --quiet --out " + (dir / "cache").string());
  ASSERT_EQ(ok.status, 0) << ok.err;
  const json rec = json::parse(slurp(dir / "cache/run.json"));
  // Torus volume 2 pi^2 R r^2 at 8 particles per cell of (0.02 m)^3, within 5%.
  const double expected = 2 * M_PI * M_PI * 0.1 * 0.04 * 0.04 / (0.02 * 0.02 * 0.02 / 8);
  EXPECT_NEAR(rec["particles"]["total"].get<double>(), expected, 0.05 * expected);

  std::ofstream(dir / "broken.obj") << "v 0 0 0\nv 1 0 0\nl 1 2\n";
  j["objects"][0]["shape"]["mesh"]["path"] = "broken.obj";
  const Result bad = triad(dir, "run " + test::writeScene(dir, j, "bad.json") + " --quiet --out " +
                                     (dir / "bad").string());
  EXPECT_EQ(bad.status, 2);
  EXPECT_NE(bad.err.find("broken.obj"), std::string::npos) << bad.err;
}

// A run that goes non-finite stops with exit 1, names the step, particle and
// object, and leaves every frame already written intact.
TEST(Cli, BlowUpExitsOneKeepingFrames) {
  const fs::path dir = test::tempDir("cli_blowup");
  json j = mixedScene();
  j["frames"]["count"] = 3;
  const std::string scene = test::writeScene(dir, j);
  const Result good = triad(dir, "run " + scene + " --quiet --out " + (dir / "good").string());
  ASSERT_EQ(good.status, 0);
  const json rec_good = json::parse(slurp(dir / "good/run.json"));
  // Poison one particle's velocity in the middle of frame 2.
  const int64_t steps = rec_good["steps"].get<int64_t>();
  const std::string env = "TRIAD_FAULT_STEP=" + std::to_string(steps * 5 / 6);
  const Result bad = triad(dir, "run " + scene + " --quiet --out " + (dir / "bad").string(), env);
  EXPECT_EQ(bad.status, 1) << bad.err;
  EXPECT_NE(bad.err.find("non-finite"), std::string::npos) << bad.err;
  EXPECT_NE(bad.err.find("object '"), std::string::npos) << bad.err;
  EXPECT_NE(bad.err.find("step "), std::string::npos) << bad.err;
  const json rec = json::parse(slurp(dir / "bad/run.json"));
  EXPECT_FALSE(rec["finished"].get<bool>());
  EXPECT_FALSE(rec["error"].is_null());
  const int written = rec["frames"]["written"].get<int>();
  ASSERT_GE(written, 2);
  ASSERT_LE(written, 3);
  // Frames already written are complete and equal to the good run's.
  for (int f = 0; f < written; ++f) {
    char name[64];
    std::snprintf(name, sizeof(name), "particles/particles.%04d.ply", f);
    EXPECT_EQ(slurp(dir / "bad" / name), slurp(dir / "good" / name)) << name;
  }
  char next[64];
  std::snprintf(next, sizeof(next), "particles/particles.%04d.ply", written);
  EXPECT_FALSE(fs::exists(dir / "bad" / next));
  // No temporary files are left behind.
  for (const auto& e : fs::recursive_directory_iterator(dir / "bad"))
    EXPECT_EQ(e.path().string().find(".tmp"), std::string::npos) << e.path();
}

}  // namespace
}  // namespace triad
