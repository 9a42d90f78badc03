// One simulation split over several processes (`mpirun -np N triad run`),
// end to end: the cache is a single process's, bit for bit (particles,
// volumes, bodies and their forces), for any thread count; momentum crosses
// the cut between processes intact while particles migrate, the split
// follows the material, and a run stopped under one process count resumes
// under another to the same bytes.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>

#include "cli_fixture.h"
#include "scene_fixture.h"

namespace triad {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

#ifdef TRIAD_HAVE_MPI

bool haveMpirun() {
  return std::system("command -v mpirun >/dev/null 2>&1") == 0;
}

// The launcher's prefix: N processes of one thread each, on any machine
// (more processes than cores, as root in containers).
std::string mpirun(int n) {
  return "OMP_NUM_THREADS=1 mpirun --allow-run-as-root --oversubscribe -np " + std::to_string(n);
}

// `triad run` of `scene` into `out` under `prefix` (an mpirun line or an environment).
test::CliResult run(const fs::path& dir, const std::string& scene, const fs::path& out,
                    const std::string& prefix, const std::string& extra = "") {
  return test::runTriad(
      dir, "run " + scene + " --out " + out.string() + " --quiet --no-probe " + extra, prefix);
}

struct Particle {
  float x[3], v[3];
  int32_t object;
  float J;
  int32_t id;
};

// A frame's particles as the PLY writer lays them out (sorted by id).
std::vector<Particle> readParticles(const fs::path& path) {
  const std::string bytes = test::slurp(path);
  const size_t end = bytes.find("end_header\n");
  EXPECT_NE(end, std::string::npos) << path;
  const size_t at = bytes.find("element vertex ");
  const size_t n = std::stoul(bytes.substr(at + 15));
  std::vector<Particle> p(n);
  EXPECT_EQ(bytes.size() - (end + 11), n * sizeof(Particle)) << path;
  std::memcpy(static_cast<void*>(p.data()), bytes.data() + end + 11, n * sizeof(Particle));
  return p;
}

fs::path framePly(const fs::path& out, int frame) {
  char name[32];
  std::snprintf(name, sizeof(name), "particles.%04d.ply", frame);
  return out / "particles" / name;
}

fs::path frameVdb(const fs::path& out, int frame) {
  char name[32];
  std::snprintf(name, sizeof(name), "density.%04d.vdb", frame);
  return out / "volumes" / name;
}

fs::path frameVtp(const fs::path& out, int frame) {
  char name[32];
  std::snprintf(name, sizeof(name), "particles.%04d.vtp", frame);
  return out / "vtk" / name;
}

// A frame's file OUT/FOLDER/STEM.FFFF.EXT.
fs::path frameFile(const fs::path& out, const char* folder, const char* stem, int frame,
                   const char* ext) {
  char name[64];
  std::snprintf(name, sizeof(name), "%s.%04d.%s", stem, frame, ext);
  return out / folder / name;
}

// Whether two files exist and hold the same bytes.
bool sameFile(const fs::path& a, const fs::path& b) {
  return fs::exists(a) && fs::exists(b) && test::slurp(a) == test::slurp(b);
}

// Whether `out` holds every checkpoint of `ref`, byte for byte.
bool sameCheckpoints(const fs::path& out, const fs::path& ref) {
  bool any = false;
  for (const auto& e : fs::directory_iterator(ref / "checkpoints")) {
    any = true;
    if (!sameFile(out / "checkpoints" / e.path().filename(), e.path())) return false;
  }
  return any;
}

// Largest distance between the same particle (by id) in two frames.
double largestDifference(const std::vector<Particle>& a, const std::vector<Particle>& b) {
  EXPECT_EQ(a.size(), b.size());
  double worst = 0.0;
  for (size_t i = 0; i < std::min(a.size(), b.size()); ++i) {
    EXPECT_EQ(a[i].id, b[i].id);
    double d2 = 0.0;
    for (int k = 0; k < 3; ++k) d2 += std::pow(double(a[i].x[k]) - double(b[i].x[k]), 2);
    worst = std::max(worst, std::sqrt(d2));
  }
  return worst;
}

json runJson(const fs::path& out) {
  return json::parse(test::slurp(out / "run.json"));
}

// The materials the scenes below share.
json sandMaterial() {
  return {{"model", "drucker_prager"},
          {"density", 1600},
          {"youngs_modulus", 2e5},
          {"poisson_ratio", 0.3},
          {"friction_angle_deg", 32}};
}
json jellyMaterial() {
  return {{"model", "fixed_corotated"},
          {"density", 1000},
          {"youngs_modulus", 4e4},
          {"poisson_ratio", 0.3}};
}

// An elastic solid's mesh vertices from its bodies/NAME.FFFF.ply (binary
// floats x y z after the header).
std::vector<float> meshVertices(const fs::path& ply) {
  const std::string bytes = test::slurp(ply);
  const size_t end = bytes.find("end_header\n") + 11;
  const size_t n = std::stoul(bytes.substr(bytes.find("element vertex ") + 15));
  std::vector<float> v(3 * n);
  std::memcpy(v.data(), bytes.data() + end, v.size() * sizeof(float));
  return v;
}

// Blocks of every MPM material side by side, falling onto the floor.
json everyMaterial(int frames) {
  json j = test::baseScene("mpi_materials", {0.64, 0.4, 0.2}, 0.02);
  j["frames"]["count"] = frames;
  j["materials"] = {{"water", {{"model", "water"}, {"density", 1000}, {"bulk_modulus", 1e5}}},
                    {"sand", sandMaterial()},
                    {"jelly", jellyMaterial()},
                    {"snow",
                     {{"model", "snow"},
                      {"density", 400},
                      {"youngs_modulus", 5e4},
                      {"poisson_ratio", 0.2},
                      {"critical_compression", 0.025},
                      {"critical_stretch", 0.0075},
                      {"hardening", 4}}}};
  const char* names[] = {"water", "sand", "jelly", "snow"};
  for (int i = 0; i < 4; ++i) {
    const double x0 = 0.04 + 0.15 * i;
    j["objects"].push_back({{"name", names[i]},
                            {"kind", "mpm"},
                            {"material", names[i]},
                            {"shape", test::box({x0, 0.1, 0.04}, {x0 + 0.1, 0.2, 0.16})}});
  }
  j["output"] = {{"vdb", true}, {"png", false}};
  return j;
}

// A jelly cube from (0.25, 0.1, 0.25) to `hi` in a 1 m box at dx 0.01 (8
// particles a cell), two frames of 0.5 ms: its scene file.
std::string jellyCube(const fs::path& dir, const char* name, std::array<double, 3> hi,
                      const json& output) {
  json j = test::baseScene(name, {1.0, 1.0, 1.0}, 0.01);
  j["frames"] = {{"count", 2}, {"fps", 2000}};
  j["materials"] = {{"jelly", jellyMaterial()}};
  j["objects"] = json::array({{{"name", "cube"},
                               {"kind", "mpm"},
                               {"material", "jelly"},
                               {"shape", test::box({0.25, 0.1, 0.25}, hi)}}});
  j["output"] = output;
  return test::writeScene(dir, j, std::string(name) + ".json");
}

class Mpi : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!haveMpirun()) GTEST_SKIP() << "mpirun is not installed";
  }
};

// Two and three processes write the cache one process writes, byte for
// byte; the split keeps every process within 20% of the mean particle count
// in every frame.
TEST_F(Mpi, TwoAndThreeProcessesAgreeWithOne) {
  const fs::path dir = test::tempDir("agree");
  const int frames = 6;
  json j = everyMaterial(frames);
  j["output"]["vtk"] = true;
  const std::string scene = test::writeScene(dir, j);
  const test::CliResult one = run(dir, scene, dir / "one", "OMP_NUM_THREADS=1");
  ASSERT_EQ(one.status, 0) << one.err;
  EXPECT_FALSE(runJson(dir / "one").contains("mpi"));
  for (int n : {2, 3}) {
    const fs::path out = dir / ("np" + std::to_string(n));
    // Three processes send process 0 their particles in chunks of 4 KiB
    // (4 MiB unless a test asks), dozens of messages a frame.
    const test::CliResult r =
        run(dir, scene, out, (n == 3 ? "TRIAD_MPI_GATHER_CHUNK=4096 " : "") + mpirun(n));
    ASSERT_EQ(r.status, 0) << r.err;
    const json rj = runJson(out);
    ASSERT_TRUE(rj.contains("mpi")) << rj.dump(2);
    EXPECT_EQ(rj["mpi"]["ranks"].get<int>(), n);
    EXPECT_EQ(rj["particles"]["total"], runJson(dir / "one")["particles"]["total"]);
    EXPECT_EQ(rj["steps"], runJson(dir / "one")["steps"]);
    // Balance: each frame's share per process.
    ASSERT_EQ(rj["mpi"]["particles_per_frame"].size(), size_t(frames + 1));
    for (const json& f : rj["mpi"]["particles_per_frame"]) {
      ASSERT_EQ(f.size(), size_t(n));
      double total = 0;
      for (const json& c : f) total += c.get<double>();
      for (const json& c : f) EXPECT_NEAR(c.get<double>(), total / n, 0.2 * total / n) << f.dump();
    }
    EXPECT_GT(rj["mpi"]["bytes_sent"][0].get<double>(), 0.0);
    ASSERT_EQ(rj["mpi"]["peak_rss_bytes"].size(), size_t(n));
    for (const json& m : rj["mpi"]["peak_rss_bytes"]) EXPECT_GT(m.get<double>(), 1e6);
    // Process 0 keeps room for its own share, not the whole world it built
    // at the start (run.json's particle memory is process 0's).
    EXPECT_LT(rj["memory"]["particle_bytes"].get<double>(),
              (1.3 / n) * runJson(dir / "one")["memory"]["particle_bytes"].get<double>())
        << n;
    // Bit for bit: every node sums its particles in the order one process
    // does, so the particles and the volumes are the same bytes.
    for (int f = 0; f <= frames; ++f) {
      EXPECT_EQ(largestDifference(readParticles(framePly(out, f)),
                                  readParticles(framePly(dir / "one", f))),
                0.0)
          << n << " processes, frame " << f;
      EXPECT_TRUE(sameFile(framePly(out, f), framePly(dir / "one", f))) << n << " frame " << f;
      EXPECT_TRUE(sameFile(frameVdb(out, f), frameVdb(dir / "one", f))) << n << " frame " << f;
      EXPECT_TRUE(sameFile(frameVtp(out, f), frameVtp(dir / "one", f))) << n << " frame " << f;
    }
    // And so are the checkpoints the processes wrote together.
    for (const char* ckpt : {"state.0005.bin", "state.0006.bin"})
      EXPECT_TRUE(sameFile(out / "checkpoints" / ckpt, dir / "one" / "checkpoints" / ckpt))
          << n << " " << ckpt;
  }
}

// Water started at its hydrostatic pressure: every process builds the
// levels from the whole world's water, not from its share, so its
// particles start with the J one process gives them, and stay the same
// bytes.
TEST_F(Mpi, HydrostaticStartAgreesWithOneProcess) {
  const fs::path dir = test::tempDir("hydrostatic");
  json j = test::baseScene("mpi_tank", {0.4, 0.3, 0.2}, 0.02);
  j["frames"]["count"] = 2;
  j["materials"] = {{"water", {{"model", "water"}, {"density", 1000}, {"bulk_modulus", 1e5}}}};
  j["objects"].push_back({{"name", "lower"},
                          {"kind", "mpm"},
                          {"material", "water"},
                          {"initial_pressure", "hydrostatic"},
                          {"shape", test::box({0, 0, 0}, {0.4, 0.1, 0.2})}});
  j["objects"].push_back({{"name", "upper"},
                          {"kind", "mpm"},
                          {"material", "water"},
                          {"initial_pressure", "hydrostatic"},
                          {"shape", test::box({0, 0.1, 0}, {0.4, 0.2, 0.2})}});
  j["output"] = {{"vdb", false}, {"png", false}};
  const std::string scene = test::writeScene(dir, j);
  const test::CliResult one = run(dir, scene, dir / "one", "OMP_NUM_THREADS=1");
  ASSERT_EQ(one.status, 0) << one.err;
  // The deepest water starts at about rho g h = 1962 Pa (J 0.980).
  const std::vector<Particle> start = readParticles(framePly(dir / "one", 0));
  const auto deepest = std::min_element(
      start.begin(), start.end(), [](const Particle& a, const Particle& b) { return a.J < b.J; });
  ASSERT_NE(deepest, start.end());
  EXPECT_NEAR(deepest->J, std::pow(1.0 + 7.0 * 1000 * 9.81 * 0.195 / 1e5, -1.0 / 7.0), 1e-5);
  const test::CliResult two = run(dir, scene, dir / "np2", mpirun(2));
  ASSERT_EQ(two.status, 0) << two.err;
  for (int f = 0; f <= 2; ++f)
    EXPECT_TRUE(sameFile(framePly(dir / "np2", f), framePly(dir / "one", f))) << "frame " << f;
}

// `scene` run under n processes into DIR/npN, which it returns (empty if
// the run failed, which it reports); what run.json says every process made
// its part of must be `together`, and no process gathers particles.
fs::path splitRun(const fs::path& dir, const std::string& scene, int n, const json& together) {
  const fs::path out = dir / ("np" + std::to_string(n));
  const test::CliResult r = run(dir, scene, out, mpirun(n));
  EXPECT_EQ(r.status, 0) << r.err;
  if (r.status != 0) return {};
  const json mpi = runJson(out)["mpi"];
  EXPECT_EQ(mpi["gathered"], "nothing") << mpi.dump();
  EXPECT_EQ(mpi["gathered_for"], json::array());
  EXPECT_EQ(mpi["written_by_every_process"], together);
  return out;
}

// Previews under two and three processes: each draws its own particles and
// process 0 composites the layers by depth and draw order, so no process
// gathers particles for them; the previews and the contact sheet are the
// single process's bytes. Every material and a rigid ball falling into them
// (drawn by every process), the camera close enough that the particles
// overlap and a process's particles hide another's.
TEST_F(Mpi, PreviewsAreCompositedFromEveryProcessToOneProcesssBytes) {
  const fs::path dir = test::tempDir("previews");
  const int frames = 4;
  json j = everyMaterial(frames);
  j["objects"].push_back(
      {{"name", "ball"},
       {"kind", "rigid"},
       {"density", 500},
       {"velocity", {0, -1, 0}},
       {"shape", {{"sphere", {{"center", {0.3, 0.3, 0.1}}, {"radius", 0.06}}}}}});
  j["output"] = {{"vdb", false}, {"ply", true}, {"png", true}};
  j["render"] = {
      {"resolution", {320, 180}},
      {"camera", {{"eye", {0.9, 0.45, 0.7}}, {"target", {0.3, 0.12, 0.1}}, {"fov_deg", 40}}}};
  const std::string scene = test::writeScene(dir, j);
  const test::CliResult one = run(dir, scene, dir / "one", "OMP_NUM_THREADS=1");
  ASSERT_EQ(one.status, 0) << one.err;
  auto preview = [](const fs::path& out, int f) {
    return frameFile(out, "preview", "preview", f, "png");
  };
  for (int n : {2, 3}) {
    const fs::path out =
        splitRun(dir, scene, n, json::array({"particles", "checkpoints", "previews"}));
    if (out.empty()) continue;
    for (int f = 0; f <= frames; ++f) {
      EXPECT_TRUE(sameFile(framePly(out, f), framePly(dir / "one", f))) << n << " frame " << f;
      EXPECT_TRUE(sameFile(preview(out, f), preview(dir / "one", f))) << n << " frame " << f;
    }
    EXPECT_TRUE(sameFile(out / "preview" / "contact_sheet.png",
                         dir / "one" / "preview" / "contact_sheet.png"))
        << n;
  }
}

// Level sets and surfaces under two and three processes: each process
// rasterises its own particles and the others' within reach of its region
// and keeps the leaves it owns; process 0 puts the leaves together. The
// volumes (with their level set `surface`), each material's surface mesh
// and the previews drawn from those meshes are the single process's bytes,
// and no process gathers particles.
TEST_F(Mpi, SurfacesAreMadeInPartsToOneProcesssBytes) {
  const fs::path dir = test::tempDir("surfaces");
  const int frames = 3;
  json j = everyMaterial(frames);
  j["output"] = {{"vdb", true},  {"vdb_surface", true}, {"surface_mesh", true},
                 {"ply", false}, {"png", true},         {"checkpoints", false}};
  j["render"] = {{"resolution", {160, 90}}, {"style", "surface"}};
  const std::string scene = test::writeScene(dir, j);
  const test::CliResult one = run(dir, scene, dir / "one", "OMP_NUM_THREADS=1");
  ASSERT_EQ(one.status, 0) << one.err;
  for (int n : {2, 3}) {
    const fs::path out = splitRun(
        dir, scene, n, json::array({"volumes", "volumes' surface", "surfaces", "previews"}));
    if (out.empty()) continue;
    for (int f = 0; f <= frames; ++f) {
      EXPECT_TRUE(sameFile(frameVdb(out, f), frameVdb(dir / "one", f))) << n << " frame " << f;
      for (const char* m : {"water", "sand", "jelly", "snow"})
        EXPECT_TRUE(sameFile(frameFile(out, "surfaces", m, f, "ply"),
                             frameFile(dir / "one", "surfaces", m, f, "ply")))
            << n << " " << m << " frame " << f;
      EXPECT_TRUE(sameFile(frameFile(out, "preview", "preview", f, "png"),
                           frameFile(dir / "one", "preview", "preview", f, "png")))
          << n << " frame " << f;
    }
  }
}

// No process builds the whole world: each makes only its share of the
// particles (their positions alone are made whole, 12 bytes each), and the
// run is the same bytes as when each built everything and kept its share.
TEST_F(Mpi, EachProcessBuildsOnlyItsShare) {
  const fs::path dir = test::tempDir("share");
  auto scene = [&](const char* name, std::array<double, 3> hi) {
    return jellyCube(dir, name, hi, {{"ply", false}, {"vdb", false}, {"png", false}});
  };
  // 400,000 particles of 102 bytes (39 MiB in all), and a scene of 1,000
  // for the memory every process has without particles.
  const std::string big = scene("share_big", {0.65, 0.35, 0.75});
  const std::string tiny = scene("share_tiny", {0.3, 0.15, 0.3});
  const int n = 4;
  // Small gather messages, so that a process's copy of its share for them
  // does not hide what the build holds.
  const std::string launch = "TRIAD_MPI_GATHER_CHUNK=1048576 " + mpirun(n);
  const test::CliResult r0 = run(dir, tiny, dir / "tiny", launch);
  ASSERT_EQ(r0.status, 0) << r0.err;
  const test::CliResult r = run(dir, big, dir / "big", launch);
  ASSERT_EQ(r.status, 0) << r.err;
  const json base = runJson(dir / "tiny")["mpi"], rj = runJson(dir / "big");
  const double total = rj["particles"]["total"].get<double>();
  ASSERT_EQ(total, 400000.0);
  // Each process held its share when the split began, and together all.
  double sum = 0.0;
  for (const json& c : rj["mpi"]["particles_at_start"]) {
    EXPECT_NEAR(c.get<double>(), total / n, 0.2 * total / n);
    sum += c.get<double>();
  }
  EXPECT_EQ(sum, total);
  // Processes 1..3 never gather: their peak above a particle-less run's
  // stays well under the whole world's particles (measured 0.44 of them;
  // building the whole world and keeping a share, 1.16).
  const double whole_bytes = total * 102.0;
  auto expectShareOnly = [&](const json& mpi, double most, const char* what) {
    for (int p = 1; p < n; ++p) {
      const double over = mpi["peak_rss_bytes"][size_t(p)].get<double>() -
                          base["peak_rss_bytes"][size_t(p)].get<double>();
      EXPECT_LT(over, most * whole_bytes) << what << ", process " << p;
    }
  };
  expectShareOnly(rj["mpi"], 0.7, "built");
  // The same resumed from frame 1's checkpoint (as if the run had been
  // stopped before the last): each process reads its share of it, beside
  // the share it built (measured 0.63 of the whole world's bytes; reading
  // the file whole and then all of its arrays, 2.97).
  fs::remove(dir / "big" / "checkpoints" / "state.0002.bin");
  const test::CliResult resumed = run(dir, big, dir / "big", launch, "--resume");
  ASSERT_EQ(resumed.status, 0) << resumed.err;
  EXPECT_NE(resumed.err.find("resuming after frame 1"), std::string::npos) << resumed.err;
  const json again = runJson(dir / "big");
  double sum_again = 0.0;
  for (const json& c : again["mpi"]["particles_at_start"]) sum_again += c.get<double>();
  EXPECT_EQ(sum_again, total);
  expectShareOnly(again["mpi"], 1.0, "resumed");
}

// The frame's particle cache, volumes and checkpoint come from every
// process at once: each writes its own particles into the PLY and the
// checkpoint, and splats them for the volumes, so that process 0 holds no
// other process's particles (previews, off here, gather positions). The
// files are the bytes process 0 writes when it gathers everything (as on
// machines that share no file system).
TEST_F(Mpi, NoProcessGathersTheCacheWithoutPreviews) {
  const fs::path dir = test::tempDir("write_together");
  auto scene = [&](const char* name, std::array<double, 3> hi) {
    return jellyCube(dir, name, hi, {{"ply", true}, {"vdb", true}, {"vtk", true}, {"png", false}});
  };
  const std::string big = scene("together_big", {0.65, 0.35, 0.75});  // 400,000 particles
  const std::string tiny = scene("together_tiny", {0.3, 0.15, 0.3});
  const int n = 4;
  const std::string launch = "TRIAD_MPI_GATHER_CHUNK=1048576 " + mpirun(n);
  const std::string gathering = "TRIAD_MPI_SHARED_FILES=0 " + launch;
  for (const auto& [out, prefix] : {std::pair{"tiny", launch},
                                    {"big", launch},
                                    {"tiny_gathered", gathering},
                                    {"big_gathered", gathering}}) {
    const test::CliResult r =
        run(dir, std::string(out).find("big") == 0 ? big : tiny, dir / out, prefix);
    ASSERT_EQ(r.status, 0) << out << ": " << r.err;
  }
  const json together = runJson(dir / "big")["mpi"],
             gathered = runJson(dir / "big_gathered")["mpi"];
  EXPECT_EQ(together["gathered"], "nothing");
  EXPECT_EQ(together["written_by_every_process"],
            json::array({"particles", "volumes", "vtk particles", "checkpoints"}));
  EXPECT_EQ(gathered["gathered"], "every attribute");
  EXPECT_EQ(gathered["gathered_for"], json::array({"vtk particles", "particles", "checkpoints"}));
  // The same files either way.
  for (int f = 0; f <= 2; ++f) {
    EXPECT_TRUE(sameFile(framePly(dir / "big", f), framePly(dir / "big_gathered", f))) << f;
    EXPECT_TRUE(sameFile(frameVdb(dir / "big", f), frameVdb(dir / "big_gathered", f))) << f;
    EXPECT_TRUE(sameFile(frameVtp(dir / "big", f), frameVtp(dir / "big_gathered", f))) << f;
  }
  for (const char* ckpt : {"state.0001.bin", "state.0002.bin"})
    EXPECT_TRUE(
        sameFile(dir / "big" / "checkpoints" / ckpt, dir / "big_gathered" / "checkpoints" / ckpt))
        << ckpt;
  // Process 0's peak above a particle-less run's, against the whole
  // world's particle bytes: 0.67 when every process writes (process 1:
  // 0.56; process 0 adds up the volumes' voxels), 3.99 when it gathers
  // them.
  const double whole_bytes = 400000.0 * 102.0;
  auto over = [&](const char* out, const char* base, int p) {
    return runJson(dir / out)["mpi"]["peak_rss_bytes"][size_t(p)].get<double>() -
           runJson(dir / base)["mpi"]["peak_rss_bytes"][size_t(p)].get<double>();
  };
  std::printf(
      "process 0 above its base: %.2f of the whole world's particle bytes writing "
      "together, %.2f gathering; process 1: %.2f\n",
      over("big", "tiny", 0) / whole_bytes, over("big_gathered", "tiny_gathered", 0) / whole_bytes,
      over("big", "tiny", 1) / whole_bytes);
  EXPECT_LT(over("big", "tiny", 0), 0.8 * whole_bytes);
  EXPECT_GT(over("big_gathered", "tiny_gathered", 0), 1.0 * whole_bytes);
}

// A process that cannot write its part of a frame's file (a full disk)
// ends the run on every process: process 0 names the file and records the
// failure, the frames before stay complete with their checkpoints, no
// temporary is left, and the run resumes to the bytes of one that never
// failed.
TEST_F(Mpi, AFailedSharedWriteEndsTheRunAndItResumes) {
  const fs::path dir = test::tempDir("shared_write_fails");
  const std::string scene = test::writeScene(dir, everyMaterial(3));
  const test::CliResult one = run(dir, scene, dir / "one", "OMP_NUM_THREADS=1");
  ASSERT_EQ(one.status, 0) << one.err;
  // Frames 0 and 1 write a PLY and a checkpoint each; process 1 fails the
  // fifth file, frame 2's particles.
  const fs::path out = dir / "np3";
  const test::CliResult r = run(dir, scene, out, "TRIAD_FAULT_SHARED_WRITE=1:4 " + mpirun(3));
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.err.find("particles.0002.ply: a process could not write its part"), std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("frames 0..1 are complete"), std::string::npos) << r.err;
  EXPECT_NE(runJson(out)["error"].get<std::string>().find("particles.0002.ply"), std::string::npos);
  for (const char* sub : {"particles", "checkpoints", "volumes"})
    for (const auto& e : fs::directory_iterator(out / sub))
      EXPECT_EQ(e.path().filename().string().find(".tmp"), std::string::npos) << e.path();
  EXPECT_FALSE(fs::exists(framePly(out, 2)));
  EXPECT_TRUE(fs::exists(out / "checkpoints" / "state.0001.bin"));
  const test::CliResult resumed = run(dir, scene, out, mpirun(3), "--resume");
  ASSERT_EQ(resumed.status, 0) << resumed.err;
  EXPECT_NE(resumed.err.find("resuming after frame 1"), std::string::npos) << resumed.err;
  for (int f = 0; f <= 3; ++f)
    EXPECT_TRUE(sameFile(framePly(out, f), framePly(dir / "one", f))) << f;

  // With VTK files too, process 2 fails the fifth file, frame 1's VTK
  // particles: the frame's PLY, which its processes had written, goes too.
  json j = everyMaterial(2);
  j["output"]["vtk"] = true;
  const std::string with_vtk = test::writeScene(dir, j, "with_vtk.json");
  const fs::path vtk_out = dir / "np2_vtk";
  const test::CliResult v =
      run(dir, with_vtk, vtk_out, "TRIAD_FAULT_SHARED_WRITE=2:4 " + mpirun(3));
  EXPECT_NE(v.status, 0);
  EXPECT_NE(v.err.find("particles.0001.vtp: a process could not write its part"), std::string::npos)
      << v.err;
  EXPECT_TRUE(fs::exists(frameVtp(vtk_out, 0)));
  EXPECT_FALSE(fs::exists(frameVtp(vtk_out, 1)));
  EXPECT_FALSE(fs::exists(framePly(vtk_out, 1)));
  for (const char* sub : {"particles", "checkpoints", "vtk"})
    for (const auto& e : fs::directory_iterator(vtk_out / sub))
      EXPECT_EQ(e.path().filename().string().find(".tmp"), std::string::npos) << e.path();
}

// For a fixed number of processes the bytes do not depend on the threads.
TEST_F(Mpi, SameBytesForOneAndTwoThreadsPerProcess) {
  const fs::path dir = test::tempDir("threads");
  const std::string scene = test::writeScene(dir, everyMaterial(3));
  const test::CliResult a = run(dir, scene, dir / "t1", mpirun(2));
  ASSERT_EQ(a.status, 0) << a.err;
  const test::CliResult b = run(
      dir, scene, dir / "t2", "OMP_NUM_THREADS=2 mpirun --allow-run-as-root --oversubscribe -np 2");
  ASSERT_EQ(b.status, 0) << b.err;
  // Nor on where the cut falls: cuts that follow each process's measured
  // work (a different split every run) write the same bytes.
  const test::CliResult c = run(dir, scene, dir / "t3", mpirun(2), "--balance work");
  ASSERT_EQ(c.status, 0) << c.err;
  for (const char* f : {"particles/particles.0003.ply", "volumes/density.0003.vdb"}) {
    EXPECT_TRUE(sameFile(dir / "t1" / f, dir / "t2" / f)) << f;
    EXPECT_TRUE(sameFile(dir / "t1" / f, dir / "t3" / f)) << f;
  }
  const test::CliResult bad = run(dir, scene, dir / "t4", mpirun(2), "--balance nonsense");
  EXPECT_EQ(bad.status, 2) << bad.err;
}

// A jelly block flies into a resting one without gravity, through the cut
// between two processes: its particles migrate to the other process and the
// total momentum stays what it was.
TEST_F(Mpi, MomentumCrossesTheCutAndParticlesMigrate) {
  const fs::path dir = test::tempDir("momentum");
  json j = test::baseScene("mpi_momentum", {0.8, 0.32, 0.24}, 0.02);
  j["frames"]["count"] = 6;
  j["gravity"] = {0, 0, 0};
  j["materials"] = {{"jelly", jellyMaterial()}};
  j["objects"] = {{{"name", "moving"},
                   {"kind", "mpm"},
                   {"material", "jelly"},
                   {"velocity", {1.0, 0, 0}},
                   {"shape", test::box({0.1, 0.08, 0.06}, {0.24, 0.22, 0.18})}},
                  {{"name", "resting"},
                   {"kind", "mpm"},
                   {"material", "jelly"},
                   {"shape", test::box({0.34, 0.08, 0.06}, {0.48, 0.22, 0.18})}}};
  j["output"] = {{"vdb", false}, {"png", false}};
  const std::string scene = test::writeScene(dir, j);
  const test::CliResult r = run(dir, scene, dir / "np2", mpirun(2));
  ASSERT_EQ(r.status, 0) << r.err;
  const test::CliResult one = run(dir, scene, dir / "one", "OMP_NUM_THREADS=1");
  ASSERT_EQ(one.status, 0) << one.err;

  auto momentum = [](const std::vector<Particle>& p) {
    double px = 0, py = 0, pz = 0, scale = 0;
    for (const Particle& q : p) {
      px += q.v[0];
      py += q.v[1];
      pz += q.v[2];
      scale += std::sqrt(q.v[0] * q.v[0] + q.v[1] * q.v[1] + q.v[2] * q.v[2]);
    }
    return std::array<double, 4>{px, py, pz, scale};
  };
  const std::vector<Particle> first = readParticles(framePly(dir / "np2", 0));
  const auto p0 = momentum(first);
  ASSERT_GT(p0[0], 0.0);
  for (int f = 1; f <= 6; ++f) {
    const std::vector<Particle> now = readParticles(framePly(dir / "np2", f));
    ASSERT_EQ(now.size(), first.size());
    const auto p = momentum(now);
    // Equal-mass particles: the sum of velocities is the momentum per particle mass.
    EXPECT_NEAR(p[0], p0[0], 1e-5 * p0[3]) << "frame " << f;
    EXPECT_NEAR(p[1], 0.0, 1e-5 * p0[3]) << "frame " << f;
    EXPECT_NEAR(p[2], 0.0, 1e-5 * p0[3]) << "frame " << f;
  }
  // The blocks met: the resting one moves now.
  const std::vector<Particle> last = readParticles(framePly(dir / "np2", 6));
  double resting_vx = 0;
  size_t resting = 0;
  for (const Particle& q : last)
    if (q.object == 1) resting_vx += q.v[0], ++resting;
  EXPECT_GT(resting_vx / double(resting), 0.1);
  for (int f = 0; f <= 6; ++f)
    EXPECT_TRUE(sameFile(framePly(dir / "np2", f), framePly(dir / "one", f))) << "frame " << f;
  EXPECT_TRUE(sameCheckpoints(dir / "np2", dir / "one"));
  // The material moved right and particles changed process: more than the
  // block's leading layer of cells arrived on the second.
  const json rj = runJson(dir / "np2");
  EXPECT_GT(rj["mpi"]["particles_received"][1].get<double>(), 0.05 * double(first.size()))
      << rj["mpi"].dump();
}

// A run that fails under two processes resumes under three from its last
// complete frame and ends where a single process ends.
TEST_F(Mpi, ResumesUnderAnotherProcessCount) {
  const fs::path dir = test::tempDir("resume");
  const int frames = 6;
  const std::string scene = test::writeScene(dir, everyMaterial(frames));
  const test::CliResult one = run(dir, scene, dir / "one", "OMP_NUM_THREADS=1");
  ASSERT_EQ(one.status, 0) << one.err;
  const int64_t steps = runJson(dir / "one")["steps"].get<int64_t>();
  // A particle's velocity turns NaN two thirds of the way: the run stops there.
  const test::CliResult failed =
      run(dir, scene, dir / "split",
          "TRIAD_FAULT_STEP=" + std::to_string(2 * steps / 3) + " " + mpirun(2));
  ASSERT_NE(failed.status, 0) << failed.err;
  EXPECT_NE(failed.err.find("non-finite"), std::string::npos) << failed.err;
  EXPECT_FALSE(fs::exists(framePly(dir / "split", frames)));
  const test::CliResult resumed = run(dir, scene, dir / "split", mpirun(3), "--resume");
  ASSERT_EQ(resumed.status, 0) << resumed.err;
  EXPECT_NE(resumed.err.find("resuming after frame"), std::string::npos) << resumed.err;
  const json rj = runJson(dir / "split");
  EXPECT_EQ(rj["mpi"]["ranks"].get<int>(), 3);
  EXPECT_GE(rj["resumed"]["from_frame"].get<int>(), 2);
  EXPECT_EQ(rj["steps"].get<int64_t>(), steps);
  // The checkpoint holds the particles in the order one process holds
  // them: the resumed run ends on the same bytes.
  EXPECT_TRUE(sameFile(framePly(dir / "split", frames), framePly(dir / "one", frames)));
  EXPECT_TRUE(sameFile(frameVdb(dir / "split", frames), frameVdb(dir / "one", frames)));
}

// A checkpoint read under a split and then passed over (its frame's
// particles are gone) leaves the run to start over from the share each
// process built, under the cut the checkpoint's particles gave (here far
// from the start's). The split moves the particles to where that cut says
// before the first step, and the run still writes one process's bytes.
// (Left where they were built, the first step's migration would move them
// too, and the bytes would be the same: this guards the bytes of the path,
// not where the particles wait.)
TEST_F(Mpi, ACheckpointPassedOverLeavesTheBuiltShareWhereTheCutSays) {
  const fs::path dir = test::tempDir("passed_over");
  // Water released at the left runs to the right: by the checkpoint the
  // cut (along x first) lies far from where the start's particles put it.
  const int frames = 4;
  json j = test::baseScene("mpi_passed_over", {0.64, 0.3, 0.1}, 0.02);
  j["frames"] = {{"count", frames}, {"fps", 12}};
  j["materials"] = {{"water", {{"model", "water"}, {"density", 1000}, {"bulk_modulus", 1e5}}}};
  j["objects"] = json::array({{{"name", "water"},
                               {"kind", "mpm"},
                               {"material", "water"},
                               {"shape", test::box({0.0, 0.0, 0.0}, {0.16, 0.24, 0.1})}}});
  j["output"] = {{"vdb", true}, {"png", false}};
  const std::string scene = test::writeScene(dir, j);
  const test::CliResult one = run(dir, scene, dir / "one", "OMP_NUM_THREADS=1");
  ASSERT_EQ(one.status, 0) << one.err;
  const test::CliResult split = run(dir, scene, dir / "split", mpirun(3));
  ASSERT_EQ(split.status, 0) << split.err;
  for (const auto& e : fs::directory_iterator(dir / "split" / "checkpoints"))
    if (e.path().filename() != "state.0004.bin") fs::remove(e.path());
  ASSERT_TRUE(fs::exists(dir / "split" / "checkpoints" / "state.0004.bin"));
  fs::remove(framePly(dir / "split", frames));
  const test::CliResult again = run(dir, scene, dir / "split", mpirun(3), "--resume");
  ASSERT_EQ(again.status, 0) << again.err;
  EXPECT_NE(again.err.find("not used"), std::string::npos) << again.err;
  EXPECT_NE(again.err.find("starting from frame 0"), std::string::npos) << again.err;
  for (int f = 0; f <= frames; ++f) {
    EXPECT_TRUE(sameFile(framePly(dir / "split", f), framePly(dir / "one", f))) << f;
    EXPECT_TRUE(sameFile(frameVdb(dir / "split", f), frameVdb(dir / "one", f))) << f;
  }
}

// A ball dropped into water beside a fixed wall, and sand pushed by an
// animated collider (with `elastic`, a jelly cube dropped onto the sand
// too), run under one process and under each of `counts` with `solver`:
// the bodies, their forces, every particle and the checkpoints must be the
// single process's bytes.
void bodiesAgreeWithOneProcess(const std::string& tag, const json& solver, int frames, bool elastic,
                               std::initializer_list<int> counts) {
  const fs::path dir = test::tempDir(tag);
  json j = test::baseScene("mpi_" + tag, {0.64, 0.4, 0.24}, 0.02);
  j["frames"]["count"] = frames;
  if (!solver.empty()) j["solver"] = solver;
  j["materials"] = {{"water", {{"model", "water"}, {"density", 1000}, {"bulk_modulus", 1e5}}},
                    {"sand", sandMaterial()}};
  j["objects"] = {
      {{"name", "pool"},
       {"kind", "mpm"},
       {"material", "water"},
       {"shape", test::box({0, 0, 0}, {0.4, 0.12, 0.24})}},
      {{"name", "heap"},
       {"kind", "mpm"},
       {"material", "sand"},
       {"shape", test::box({0.46, 0, 0.04}, {0.6, 0.1, 0.2})}},
      {{"name", "ball"},
       {"kind", "rigid"},
       {"density", 500},
       {"friction", 0.5},
       {"velocity", {0, -1, 0}},
       {"shape", {{"sphere", {{"center", {0.2, 0.2, 0.12}}, {"radius", 0.05}}}}}},
      {{"name", "wall"},
       {"kind", "rigid"},
       {"density", 1000},
       {"fixed", true},
       {"shape", test::box({0.4, 0, 0}, {0.44, 0.16, 0.24})}},
      {{"name", "pusher"},
       {"kind", "collider"},
       {"shape", test::box({0.58, 0, 0.04}, {0.62, 0.14, 0.2})},
       {"animation", {{"keys", {{{"time", 0}}, {{"time", 0.4}, {"translate", {-0.08, 0, 0}}}}}}}}};
  if (elastic) {
    j["materials"]["jelly"] = jellyMaterial();
    j["objects"].push_back({{"name", "cube"},
                            {"kind", "elastic"},
                            {"material", "jelly"},
                            {"sample_spacing", 0.02},
                            {"velocity", {0, -1.5, 0}},
                            {"shape", test::box({0.48, 0.14, 0.08}, {0.56, 0.22, 0.16})}});
  }
  j["output"] = {{"vdb", false}, {"png", false}};
  const std::string scene = test::writeScene(dir, j);
  const test::CliResult one = run(dir, scene, dir / "one", "OMP_NUM_THREADS=1");
  ASSERT_EQ(one.status, 0) << one.err;
  // The ball's last row of bodies/rigid_states.csv (frame, time, name, then
  // position, orientation, velocity, spin).
  auto ballAtEnd = [](const fs::path& out) {
    std::ifstream in(out / "bodies" / "rigid_states.csv");
    std::string line, last;
    while (std::getline(in, line))
      if (line.find(",ball,") != std::string::npos) last = line;
    std::vector<double> v;
    std::stringstream ss(last);
    std::string cell;
    for (int c = 0; std::getline(ss, cell, ','); ++c)
      if (c >= 3) v.push_back(std::stod(cell));
    return v;
  };
  const std::vector<double> ref = ballAtEnd(dir / "one");
  ASSERT_EQ(ref.size(), 13u);
  EXPECT_LT(ref[1], 0.16) << tag;  // it fell into the water
  for (int n : counts) {
    const fs::path out = dir / ("np" + std::to_string(n));
    const test::CliResult r = run(dir, scene, out, mpirun(n));
    ASSERT_EQ(r.status, 0) << r.err;
    // Bit for bit: the bodies, their forces and every particle.
    for (const char* f : {"bodies/rigid_states.csv", "bodies/forces.csv"})
      EXPECT_TRUE(sameFile(out / f, dir / "one" / f)) << tag << " " << n << " " << f;
    for (int f = 1; f <= frames; ++f) {
      EXPECT_TRUE(sameFile(framePly(out, f), framePly(dir / "one", f)))
          << tag << " " << n << " frame " << f;
      char mesh[32];
      std::snprintf(mesh, sizeof(mesh), "bodies/cube.%04d.ply", f);
      if (elastic) {
        EXPECT_TRUE(sameFile(out / mesh, dir / "one" / mesh)) << tag << " " << mesh;
      }
    }
    EXPECT_TRUE(sameCheckpoints(out, dir / "one")) << tag << " " << n;
  }
}

// Bodies are whole on every process, each node's collision is its owner's,
// and the bodies move as under one process. The ball's friction makes the
// collision's passes sum over its nodes in float, in the order of their
// blocks' keys on any split.
TEST_F(Mpi, RigidBodiesAndCollidersAgreeWithOneProcess) {
  bodiesAgreeWithOneProcess("bodies", json::object(), 8, false, {2, 3});
}

// The coupling's other variants split alike: one grid for solids and
// material, solids that read the combined grid back (each node's as its
// owner summed it), and two fields at moving solids' nodes (their sums
// cross the cut in colour order, as P2G's do), each with an elastic solid
// as well as rigid ones.
TEST_F(Mpi, CouplingVariantsAgreeWithOneProcess) {
  bodiesAgreeWithOneProcess("single_grid", {{"coupling", "single_grid"}}, 4, true, {2, 3});
  bodiesAgreeWithOneProcess("combined", {{"solid_readback", "combined"}}, 4, true, {2, 3});
  bodiesAgreeWithOneProcess("fronts", {{"front_fields", true}}, 4, true, {2, 3});
}

// An elastic (FEM) cube dropped into sand: the solid is whole on every
// process, each of its points reads every node's change, and its mesh and
// the sand end where a single process puts them.
TEST_F(Mpi, ElasticSolidAgreesWithOneProcess) {
  const fs::path dir = test::tempDir("elastic");
  json j = test::baseScene("mpi_elastic", {0.48, 0.4, 0.24}, 0.02);
  j["frames"]["count"] = 8;
  j["materials"] = {{"sand", sandMaterial()}, {"jelly", jellyMaterial()}};
  j["objects"] = {{{"name", "bed"},
                   {"kind", "mpm"},
                   {"material", "sand"},
                   {"shape", test::box({0, 0, 0}, {0.48, 0.08, 0.24})}},
                  {{"name", "cube"},
                   {"kind", "elastic"},
                   {"material", "jelly"},
                   {"friction", 0.6},
                   {"sample_spacing", 0.02},
                   {"velocity", {0, -1.5, 0}},
                   {"shape", test::box({0.18, 0.14, 0.06}, {0.3, 0.26, 0.18})}}};
  j["output"] = {{"vdb", false}, {"png", false}};
  const std::string scene = test::writeScene(dir, j);
  const test::CliResult one = run(dir, scene, dir / "one", "OMP_NUM_THREADS=1");
  ASSERT_EQ(one.status, 0) << one.err;
  auto vertices = [](const fs::path& out) {
    return meshVertices(out / "bodies" / "cube.0008.ply");
  };
  const std::vector<float> ref = vertices(dir / "one");
  ASSERT_EQ(ref.size(), 24u);
  EXPECT_LT(ref[1], 0.12f);  // it hit the sand and sank into it
  for (int n : {2, 3}) {
    const fs::path out = dir / ("np" + std::to_string(n));
    const test::CliResult r = run(dir, scene, out, mpirun(n));
    ASSERT_EQ(r.status, 0) << r.err;
    for (int f = 1; f <= 8; ++f) {
      char mesh[32];
      std::snprintf(mesh, sizeof(mesh), "bodies/cube.%04d.ply", f);
      EXPECT_TRUE(sameFile(out / mesh, dir / "one" / mesh)) << n << " " << mesh;
      EXPECT_TRUE(sameFile(framePly(out, f), framePly(dir / "one", f))) << n << " frame " << f;
    }
    EXPECT_TRUE(sameCheckpoints(out, dir / "one")) << n;
  }
}

// A stiff implicit cube placed on sand across the cut, where the elastic
// contact passes act: every process holds the cube's points and every
// shared node, and solves the passes alike. Its mesh and the sand are the
// single process's bytes at every frame, and it rests on the surface.
// Measured: its bottom at 0.1017 m from frame 4 on; with no passes it
// creeps 0.5 mm a frame (0.1010 m at frame 5, 0.0984 at frame 10).
TEST_F(Mpi, ElasticContactPassesAgreeWithOneProcess) {
  const fs::path dir = test::tempDir("elastic_passes");
  json j = test::baseScene("mpi_elastic_passes", {0.4, 0.3, 0.2}, 0.05);
  j["frames"]["count"] = 10;
  j["materials"] = {{"sand", sandMaterial()},
                    {"stiff",
                     {{"model", "fixed_corotated"},
                      {"density", 1000},
                      {"youngs_modulus", 1e7},
                      {"poisson_ratio", 0.3}}}};
  j["objects"] = {{{"name", "bed"},
                   {"kind", "mpm"},
                   {"material", "sand"},
                   {"shape", test::box({0, 0, 0}, {0.4, 0.1, 0.2})}},
                  {{"name", "cube"},
                   {"kind", "elastic"},
                   {"material", "stiff"},
                   {"integrator", "implicit"},
                   {"friction", 0.5},
                   {"shape", test::box({0.15, 0.105, 0.05}, {0.25, 0.205, 0.15})}}};
  j["output"] = {{"vdb", false}, {"png", false}};
  const std::string scene = test::writeScene(dir, j);
  const test::CliResult one = run(dir, scene, dir / "one", "OMP_NUM_THREADS=1");
  ASSERT_EQ(one.status, 0) << one.err;
  auto bottom = [&](const char* mesh) {
    const std::vector<float> v = meshVertices(dir / "one" / "bodies" / mesh);
    float lo = 1e9f;
    for (size_t k = 1; k < v.size(); k += 3) lo = std::min(lo, v[k]);
    return lo;
  };
  // Resting on the surface, not creeping into it.
  EXPECT_NEAR(bottom("cube.0010.ply"), bottom("cube.0005.ply"), 3e-4);
  EXPECT_GT(bottom("cube.0010.ply"), 0.1f);
  for (int n : {2, 3}) {
    const fs::path out = dir / ("np" + std::to_string(n));
    const test::CliResult r = run(dir, scene, out, mpirun(n));
    ASSERT_EQ(r.status, 0) << r.err;
    for (int f = 1; f <= 10; ++f) {
      char mesh[32];
      std::snprintf(mesh, sizeof(mesh), "bodies/cube.%04d.ply", f);
      EXPECT_TRUE(sameFile(out / mesh, dir / "one" / mesh)) << n << " " << mesh;
      EXPECT_TRUE(sameFile(framePly(out, f), framePly(dir / "one", f))) << n << " frame " << f;
    }
  }
}

// Water, snow and rubber thrown at an elastic block: about 1400 particles
// are pushed out of it, all on one process, and every process applies
// them all, in id order, to the block, whose state must agree bit for bit
// between processes at every frame (or the run stops), and with a single
// process's.
TEST_F(Mpi, ParticlesPushedOutOfAnElasticSolidMoveItAlikeEverywhere) {
  const fs::path dir = test::tempDir("pushed");
  json j = everyMaterial(3);
  j["materials"]["rubber"] = {
      {"model", "neo_hookean"}, {"density", 1100}, {"youngs_modulus", 8e4}, {"poisson_ratio", 0.4}};
  j["domain"]["max"] = {0.4, 0.4, 0.4};
  auto obj = [](const char* name, const char* mat, json shape, std::array<double, 3> v) {
    return json{
        {"name", name}, {"kind", "mpm"}, {"material", mat}, {"shape", shape}, {"velocity", v}};
  };
  j["objects"] = {
      obj("sand", "sand", test::box({0.02, 0.0, 0.02}, {0.38, 0.08, 0.38}), {0, 0, 0}),
      obj("rubber", "rubber", json{{"sphere", {{"center", {0.3, 0.2, 0.3}}, {"radius", 0.05}}}},
          {-0.5, -1, 0}),
      obj("snow", "snow", test::box({0.2, 0.12, 0.05}, {0.3, 0.2, 0.15}), {0, -2, 0.5}),
      obj("water", "water", test::box({0.05, 0.12, 0.25}, {0.15, 0.3, 0.35}), {1, 0, -1}),
      {{"name", "block"},
       {"kind", "elastic"},
       {"material", "jelly"},
       {"friction", 0.4},
       {"shape", test::box({0.22, 0.1, 0.22}, {0.34, 0.2, 0.34})},
       {"velocity", {0, -2, 0}}}};
  const std::string scene = test::writeScene(dir, j);
  const test::CliResult one = run(dir, scene, dir / "one", "OMP_NUM_THREADS=1");
  ASSERT_EQ(one.status, 0) << one.err;
  const test::CliResult two = run(dir, scene, dir / "np2", mpirun(2));
  ASSERT_EQ(two.status, 0) << two.err;
  const auto vertices = meshVertices;
  const std::vector<float> a = vertices(dir / "one/bodies/block.0003.ply"),
                           b = vertices(dir / "np2/bodies/block.0003.ply"),
                           start = vertices(dir / "one/bodies/block.0000.ply");
  ASSERT_EQ(a.size(), b.size());
  float moved = 0.0f;
  for (size_t k = 0; k < a.size(); ++k) moved = std::max(moved, std::abs(a[k] - start[k]));
  EXPECT_GT(moved, 0.02f);  // the block fell 3 cm and deformed
  EXPECT_EQ(a, b);          // and ends where one process puts it, bit for bit
  EXPECT_TRUE(sameFile(framePly(dir / "np2", 3), framePly(dir / "one", 3)));
}

// A source pours water through the cut between processes into a sink:
// every process finds the same empty sites from all processes' particles,
// makes the same particles and keeps its own; each removes its own in the
// sink. Counts and particles are those of one process, bit for bit.
TEST_F(Mpi, SourcesAndSinksMakeAndRemoveWhatOneProcessDoes) {
  const fs::path dir = test::tempDir("sources");
  json j = test::baseScene("mpi_sources", {0.48, 0.48, 0.24}, 0.02);
  j["frames"]["count"] = 10;
  j["materials"] = {{"water", {{"model", "water"}, {"density", 1000}, {"bulk_modulus", 1e5}}}};
  j["objects"] = {{{"name", "tap"},
                   {"kind", "mpm"},
                   {"material", "water"},
                   {"velocity", {1.0, -0.5, 0}},
                   {"shape", test::box({0.04, 0.3, 0.08}, {0.12, 0.38, 0.16})},
                   {"emit", {{"start", 0.0}, {"end", 0.3}}}},
                  {{"name", "drain"},
                   {"kind", "sink"},
                   {"shape", test::box({0.3, 0.0, 0.0}, {0.48, 0.06, 0.24})}}};
  j["output"] = {{"vdb", false}, {"png", false}};
  const std::string scene = test::writeScene(dir, j);
  const test::CliResult one = run(dir, scene, dir / "one", "OMP_NUM_THREADS=1");
  ASSERT_EQ(one.status, 0) << one.err;
  const json ref = runJson(dir / "one");
  ASSERT_GT(ref["particles"]["emitted"]["tap"].get<int>(), 1000);
  ASSERT_GT(ref["particles"]["removed"]["drain"].get<int>(), 100);
  for (int n : {2, 3}) {
    const fs::path out = dir / ("np" + std::to_string(n));
    const test::CliResult r = run(dir, scene, out, mpirun(n));
    ASSERT_EQ(r.status, 0) << r.err;
    const json rj = runJson(out);
    EXPECT_EQ(rj["particles"]["emitted"], ref["particles"]["emitted"]) << n;
    EXPECT_EQ(rj["particles"]["removed"], ref["particles"]["removed"]) << n;
    EXPECT_EQ(rj["particles"]["total"], ref["particles"]["total"]) << n;
    for (int f = 1; f <= 10; ++f)
      EXPECT_TRUE(sameFile(framePly(out, f), framePly(dir / "one", f))) << n << " frame " << f;
    // The checkpoints too: they count what every process's sinks removed
    // (they held process 0's count alone).
    EXPECT_TRUE(sameFile(out / "checkpoints" / "state.0010.bin",
                         dir / "one" / "checkpoints" / "state.0010.bin"))
        << n;
  }
  // Resumed under 2 processes from frame 9 of the 3-process run: the
  // removed count goes on from the whole run's, counted once.
  const fs::path out = dir / "np3";
  fs::remove(out / "checkpoints" / "state.0010.bin");
  const test::CliResult resumed = run(dir, scene, out, mpirun(2), "--resume");
  ASSERT_EQ(resumed.status, 0) << resumed.err;
  EXPECT_EQ(runJson(out)["particles"]["removed"], ref["particles"]["removed"]);
  EXPECT_TRUE(sameFile(out / "checkpoints" / "state.0010.bin",
                       dir / "one" / "checkpoints" / "state.0010.bin"));
}

// FLIP's velocity changes are summed and sent back as the velocities are.
TEST_F(Mpi, FlipAgreesWithOneProcess) {
  const fs::path dir = test::tempDir("flip");
  json j = everyMaterial(4);
  j["solver"] = {{"transfer", "flip"}, {"flip_ratio", 0.95}};
  const std::string scene = test::writeScene(dir, j);
  const test::CliResult one = run(dir, scene, dir / "one", "OMP_NUM_THREADS=1");
  ASSERT_EQ(one.status, 0) << one.err;
  const test::CliResult two = run(dir, scene, dir / "np2", mpirun(2));
  ASSERT_EQ(two.status, 0) << two.err;
  for (int f = 1; f <= 4; ++f)
    EXPECT_TRUE(sameFile(framePly(dir / "np2", f), framePly(dir / "one", f))) << "frame " << f;
  EXPECT_TRUE(sameCheckpoints(dir / "np2", dir / "one"));
}

// SIGTERM to every process (as a batch system sends it) stops them all at
// the same step: the frames written stay, the record says why, and the run
// resumes under another count to the single process's end.
TEST_F(Mpi, SigtermStopsEveryProcessAtTheSameStepAndTheRunResumes) {
  const fs::path dir = test::tempDir("sigterm");
  const int frames = 24;
  const std::string scene = test::writeScene(dir, everyMaterial(frames));
  const fs::path out = dir / "split";
  const std::string cmd = "(" + mpirun(2) + " " + TRIAD_EXE + " run " + scene + " --out " +
                          out.string() + " --quiet --no-probe >" + (dir / "run.txt").string() +
                          " 2>&1 &) ; for i in $(seq 1 600); do "
                          "[ -f " +
                          framePly(out, 2).string() +
                          " ] && break; sleep 0.05; done; pkill -TERM -f '^" + TRIAD_EXE + " run " +
                          scene + "'; for i in $(seq 1 600); do pgrep -f '^mpirun .* run " + scene +
                          "' >/dev/null || exit 0; sleep 0.05; done; exit 1";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << test::slurp(dir / "run.txt");
  const json stopped = runJson(out);
  ASSERT_TRUE(stopped.contains("interrupted")) << stopped.dump(2);
  EXPECT_EQ(stopped["interrupted"]["signal"], "SIGTERM");
  const int written = stopped["frames"]["written"].get<int>();
  EXPECT_GE(written, 3);
  EXPECT_LT(written, frames + 1);
  EXPECT_FALSE(stopped["finished"].get<bool>());
  const test::CliResult resumed = run(dir, scene, out, mpirun(3), "--resume");
  ASSERT_EQ(resumed.status, 0) << resumed.err;
  const test::CliResult one = run(dir, scene, dir / "one", "OMP_NUM_THREADS=1");
  ASSERT_EQ(one.status, 0) << one.err;
  EXPECT_TRUE(runJson(out)["finished"].get<bool>());
  EXPECT_TRUE(sameFile(framePly(out, frames), framePly(dir / "one", frames)));
}

// Sleeping material across the cut: a sand layer settles and sleeps, then
// a ball thrown up lands on it and wakes it. Sleeping blocks' sums at rest
// cross the cut as any block's sums do, and each process wakes its own
// blocks from the velocities it gets back: the cache is one process's.
TEST_F(Mpi, SleepingMaterialSleepsAndWakesAsUnderOneProcess) {
  const fs::path dir = test::tempDir("sleep");
  json j = test::baseScene("mpi_sleep", {0.4, 1.4, 0.4}, 0.02);
  j["frames"] = {{"count", 12}, {"fps", 12}};
  j["solver"] = {{"sleep", {{"speed", 0.01}, {"delay", 0.1}}}};
  j["materials"] = {{"sand", sandMaterial()}};
  j["objects"] = {{{"name", "layer"},
                   {"kind", "mpm"},
                   {"material", "sand"},
                   {"shape", test::box({0.02, 0.0, 0.02}, {0.38, 0.1, 0.38})}},
                  {{"name", "ball"},
                   {"kind", "rigid"},
                   {"density", 3000},
                   {"friction", 0.5},
                   {"velocity", {0, 4.0, 0}},
                   {"shape", {{"sphere", {{"center", {0.2, 0.3, 0.2}}, {"radius", 0.05}}}}}}};
  j["output"] = {{"vdb", false}, {"png", false}};
  const std::string scene = test::writeScene(dir, j);
  const test::CliResult one = run(dir, scene, dir / "one", "OMP_NUM_THREADS=1");
  ASSERT_EQ(one.status, 0) << one.err;
  const json ref = runJson(dir / "one");
  // Most of the layer slept before the ball came.
  EXPECT_GT(ref["sleeping_particle_substeps"].get<double>(),
            0.3 * ref["particle_substeps"].get<double>());
  // Two processes, and three whose cuts follow each process's measured
  // work (they move every frame): each process keeps its own blocks' still
  // times, sends those beside another's blocks to it each step, and hands a
  // block's state to its new owner when the cut moves (without checkpoints:
  // a checkpoint gathers every process's state, which then holds them all).
  j["output"]["checkpoints"] = false;
  const std::string no_checkpoints = test::writeScene(dir, j, "no_checkpoints.json");
  for (const auto& [name, launch, extra] :
       {std::tuple{"np2", mpirun(2), ""}, {"np3_work", mpirun(3), "--balance work"}}) {
    const fs::path out = dir / name;
    const bool checkpoints = std::string(name) == "np2";
    const test::CliResult r = run(dir, checkpoints ? scene : no_checkpoints, out, launch, extra);
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_EQ(runJson(out)["sleeping_particle_substeps"], ref["sleeping_particle_substeps"])
        << name;
    for (const char* f : {"bodies/rigid_states.csv", "bodies/forces.csv"})
      EXPECT_TRUE(sameFile(out / f, dir / "one" / f)) << name << " " << f;
    for (int f = 1; f <= 12; ++f)
      EXPECT_TRUE(sameFile(framePly(out, f), framePly(dir / "one", f))) << name << " frame " << f;
    if (checkpoints) {
      EXPECT_TRUE(sameCheckpoints(out, dir / "one")) << name;
    }
  }
}

#else

TEST(Mpi, BuiltWithoutMpi) {
  GTEST_SKIP() << "this build has no MPI (dist/ needs libopenmpi-dev)";
}

#endif

}  // namespace
}  // namespace triad
