// `triad run --resume` end to end: a run killed with SIGKILL and resumed
// writes exactly the bytes of an uninterrupted run; damaged checkpoints fall
// back to the previous one; a changed scene is refused.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <fstream>
#include <sstream>
#include <thread>

#include "cli_fixture.h"
#include "scene_fixture.h"

namespace triad {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

using test::slurp;

struct Result {
  int status = -1;
  std::string err;
};

// Runs `triad run SCENE --out OUT [extra]` to completion. One thread: on a
// loaded machine OpenMP's barriers make two threads many times slower, and
// tests/test_cli.cpp already checks that the bytes do not depend on it.
Result runTriad(const std::string& scene, const fs::path& out, const std::string& extra = "") {
  fs::create_directories(out.parent_path());
  const test::CliResult r = test::runTriad(
      out.parent_path(), "run " + scene + " --out " + out.string() + " --quiet --threads 1 " + extra);
  return {r.status, r.err};
}

// Starts the same run and SIGKILLs it as soon as `marker` exists. Returns
// false if the run ended by itself first.
bool runAndKill(const std::string& scene, const fs::path& out, const fs::path& marker) {
  const pid_t pid = fork();
  if (pid == 0) {
    const int devnull = ::open("/dev/null", O_WRONLY);
    dup2(devnull, 1);
    dup2(devnull, 2);
    execl(TRIAD_EXE, TRIAD_EXE, "run", scene.c_str(), "--out", out.c_str(), "--quiet",
          "--threads", "1", static_cast<char*>(nullptr));
    _exit(127);
  }
  bool killed = false;
  for (;;) {
    int status = 0;
    if (waitpid(pid, &status, WNOHANG) == pid) return killed;
    if (!killed && fs::exists(marker)) {
      kill(pid, SIGKILL);
      killed = true;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
}

std::string frameFile(const fs::path& out, const char* kind, int frame) {
  char buf[64];
  if (std::string(kind) == "ply")
    std::snprintf(buf, sizeof(buf), "particles/particles.%04d.ply", frame);
  else
    std::snprintf(buf, sizeof(buf), "volumes/density.%04d.vdb", frame);
  return (out / buf).string();
}

// Sand settling under a falling jelly cube: a few thousand particles,
// plasticity, collisions, ~10 frames in a few seconds.
json resumeScene(int frames) {
  json j = test::baseScene("resume", {0.4, 0.4, 0.4}, 0.02);
  j["frames"] = {{"count", frames}, {"fps", 24}};
  j["materials"] = {
      {"sand", {{"model", "drucker_prager"}, {"density", 1600}, {"youngs_modulus", 1e5},
                {"poisson_ratio", 0.3}, {"friction_angle_deg", 35}}},
      {"jelly", {{"model", "fixed_corotated"}, {"density", 1000}, {"youngs_modulus", 5e4},
                 {"poisson_ratio", 0.3}}}};
  j["objects"] = {
      {{"name", "sand"}, {"kind", "mpm"}, {"material", "sand"},
       {"shape", test::box({0.04, 0.0, 0.04}, {0.36, 0.08, 0.36})}},
      {{"name", "cube"}, {"kind", "mpm"}, {"material", "jelly"},
       {"shape", test::box({0.14, 0.18, 0.14}, {0.26, 0.30, 0.26})}, {"velocity", {0.3, -1, 0}}}};
  j["output"] = {{"png", false}, {"vdb_surface", true}};
  return j;
}

void expectSameFrames(const fs::path& a, const fs::path& b, int first, int last) {
  for (int f = first; f <= last; ++f)
    for (const char* kind : {"ply", "vdb"}) {
      const std::string fa = slurp(frameFile(a, kind, f)), fb = slurp(frameFile(b, kind, f));
      ASSERT_FALSE(fa.empty()) << frameFile(a, kind, f);
      EXPECT_TRUE(fa == fb) << kind << " frame " << f << " differs";
    }
}

json runJson(const fs::path& out) { return json::parse(slurp(out / "run.json")); }

std::vector<std::string> checkpointNames(const fs::path& out) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(out / "checkpoints"))
    names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

// Runs `j` uninterrupted and killed once frame 4 is on disk, then resumed:
// every frame must come out byte for byte the same. `ref_record` receives
// the uninterrupted run's run.json.
void expectKilledRunResumes(const std::string& name, const json& j, int frames,
                            json* ref_record = nullptr) {
  const fs::path dir = test::tempDir(name);
  const std::string scene = test::writeScene(dir, j);

  // The uninterrupted run.
  const Result ref = runTriad(scene, dir / "ref");
  ASSERT_EQ(ref.status, 0) << ref.err;
  EXPECT_EQ(checkpointNames(dir / "ref"),
            (std::vector<std::string>{"state.0009.bin", "state.0010.bin"}));

  // Killed once frame 4 is on disk, then resumed.
  const fs::path out = dir / "killed";
  ASSERT_TRUE(runAndKill(scene, out, frameFile(out, "vdb", 4)))
      << "the run finished before it could be killed";
  ASSERT_FALSE(fs::exists(frameFile(out, "ply", frames))) << "killed too late to test anything";
  EXPECT_FALSE(runJson(out)["finished"].get<bool>());
  const Result resumed = runTriad(scene, out, "--resume");
  ASSERT_EQ(resumed.status, 0) << resumed.err;
  EXPECT_NE(resumed.err.find("resuming after frame"), std::string::npos) << resumed.err;

  // Every frame, PLY and VDB, byte for byte.
  expectSameFrames(dir / "ref", out, 0, frames);
  const json rj = runJson(out);
  EXPECT_TRUE(rj["finished"].get<bool>());
  EXPECT_EQ(rj["frames"]["written"], frames + 1);
  ASSERT_TRUE(rj.contains("resumed")) << rj.dump(2);
  EXPECT_GE(rj["resumed"]["from_frame"].get<int>(), 3);
  EXPECT_LT(rj["resumed"]["from_frame"].get<int>(), frames);
  EXPECT_EQ(rj["steps"], runJson(dir / "ref")["steps"]);
  EXPECT_EQ(rj["sleeping_particle_substeps"], runJson(dir / "ref")["sleeping_particle_substeps"]);
  EXPECT_FALSE(runJson(dir / "ref").contains("resumed"));
  // The latest two checkpoints, and no temporaries left by the kill.
  EXPECT_EQ(checkpointNames(out), checkpointNames(dir / "ref"));
  for (const char* sub : {"particles", "volumes"})
    for (const auto& e : fs::directory_iterator(out / sub))
      EXPECT_EQ(e.path().string().find(".tmp"), std::string::npos) << e.path();
  if (ref_record) *ref_record = runJson(dir / "ref");
}

TEST(Resume, KilledRunResumesToTheSameBytes) {
  const int frames = 10;
  expectKilledRunResumes("resume_killed", resumeScene(frames), frames);
}

// Sleeping material: which blocks have been still, and for how long, is
// part of the checkpoint, so a resumed run puts the same blocks to sleep.
TEST(Resume, SleepingMaterialResumesToTheSameBytes) {
  const int frames = 10;
  json j = resumeScene(frames);
  j["solver"]["sleep"] = {{"speed", 0.2}, {"delay", 0.02}};
  json ref;
  expectKilledRunResumes("resume_sleep", j, frames, &ref);
  ASSERT_TRUE(ref.contains("sleeping_particle_substeps"));
  EXPECT_GT(ref["sleeping_particle_substeps"].get<double>(), 0.0);
}

// Frames are written on their own thread while the next one steps, from a
// copy of the world: every file comes out as when each frame is written
// before the solver steps on (--no-overlap), previews, bodies and
// checkpoints included, and run.json says which way it ran.
TEST(Resume, OverlappedOutputWritesTheSameBytes) {
  const fs::path dir = test::tempDir("overlapped_output");
  const int frames = 6;
  json j = resumeScene(frames);
  j["output"]["png"] = true;
  j["render"] = {{"resolution", {160, 90}}};
  j["objects"].push_back({{"name", "crate"}, {"kind", "rigid"}, {"density", 400},
                          {"shape", test::box({0.25, 0.12, 0.25}, {0.31, 0.18, 0.31})}});
  const std::string scene = test::writeScene(dir, j);
  const Result a = runTriad(scene, dir / "overlap");
  ASSERT_EQ(a.status, 0) << a.err;
  const Result b = runTriad(scene, dir / "serial", "--no-overlap");
  ASSERT_EQ(b.status, 0) << b.err;
  EXPECT_TRUE(runJson(dir / "overlap")["output_overlap"].get<bool>());
  EXPECT_FALSE(runJson(dir / "serial")["output_overlap"].get<bool>());
  size_t files = 0;
  for (const auto& e : fs::recursive_directory_iterator(dir / "serial")) {
    if (!e.is_regular_file() || e.path().filename() == "run.json") continue;
    const fs::path rel = fs::relative(e.path(), dir / "serial");
    const std::string fa = slurp(dir / "overlap" / rel), fb = slurp(e.path());
    ASSERT_FALSE(fb.empty()) << rel;
    EXPECT_TRUE(fa == fb) << rel << " differs";
    ++files;
  }
  // 7 frames of particles, volumes, previews and the crate, 2 checkpoints,
  // the tables, the contact sheet and the preview settings at least.
  EXPECT_GT(files, 30u);
}

TEST(Resume, DamagedLatestCheckpointFallsBackToThePrevious) {
  const fs::path dir = test::tempDir("resume_damaged");
  const int frames = 3;
  json j = resumeScene(frames);
  j["output"]["vdb_surface"] = false;
  const std::string scene = test::writeScene(dir, j);
  const fs::path out = dir / "out";
  ASSERT_EQ(runTriad(scene, out).status, 0);
  ASSERT_EQ(checkpointNames(out), (std::vector<std::string>{"state.0002.bin", "state.0003.bin"}));
  const std::string ply = slurp(frameFile(out, "ply", frames));
  const std::string vdb = slurp(frameFile(out, "vdb", frames));
  const fs::path latest = out / "checkpoints" / "state.0003.bin";

  // Truncated: resume from frame 2 and write frame 3 again, identically.
  fs::resize_file(latest, fs::file_size(latest) / 2);
  Result r = runTriad(scene, out, "--resume");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find("state.0003.bin: not used: truncated"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("resuming after frame 2"), std::string::npos) << r.err;
  EXPECT_TRUE(slurp(frameFile(out, "ply", frames)) == ply);
  EXPECT_TRUE(slurp(frameFile(out, "vdb", frames)) == vdb);
  EXPECT_EQ(runJson(out)["resumed"]["from_frame"], 2);

  // One flipped byte: caught by the checksum, same fallback.
  std::string bytes = slurp(latest);
  bytes[bytes.size() / 3] ^= 0x01;
  std::ofstream(latest, std::ios::binary) << bytes;
  r = runTriad(scene, out, "--resume");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find("checksum"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("resuming after frame 2"), std::string::npos) << r.err;
  EXPECT_TRUE(slurp(frameFile(out, "ply", frames)) == ply);
  EXPECT_TRUE(slurp(frameFile(out, "vdb", frames)) == vdb);

  // A complete latest checkpoint whose frame's volume is missing: fall back too.
  fs::remove(frameFile(out, "vdb", frames));
  r = runTriad(scene, out, "--resume");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find("resuming after frame 2"), std::string::npos) << r.err;
  EXPECT_TRUE(slurp(frameFile(out, "vdb", frames)) == vdb);

  // An intact latest checkpoint of the last frame: nothing left to simulate.
  r = runTriad(scene, out, "--resume");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find("resuming after frame 3"), std::string::npos) << r.err;
  EXPECT_TRUE(runJson(out)["finished"].get<bool>());
  EXPECT_EQ(runJson(out)["frames"]["written"], frames + 1);
}

TEST(Resume, ChangedSceneIsRefused) {
  const fs::path dir = test::tempDir("resume_changed");
  json j = resumeScene(1);
  j["output"]["vdb_surface"] = false;
  const std::string scene = test::writeScene(dir, j);
  const fs::path out = dir / "out";
  ASSERT_EQ(runTriad(scene, out).status, 0);
  const std::string before = slurp(frameFile(out, "ply", 1));

  j["gravity"] = {0, -9.0, 0};
  test::writeScene(dir, j);
  const Result r = runTriad(scene, out, "--resume");
  EXPECT_EQ(r.status, 2) << r.err;
  EXPECT_NE(r.err.find("different scene file"), std::string::npos) << r.err;
  EXPECT_TRUE(slurp(frameFile(out, "ply", 1)) == before);
}

TEST(Resume, WithoutCheckpointStartsFromFrameZero) {
  const fs::path dir = test::tempDir("resume_none");
  json j = resumeScene(1);
  j["output"]["vdb_surface"] = false;
  const std::string scene = test::writeScene(dir, j);
  const Result r = runTriad(scene, dir / "out", "--resume");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find("starting from frame 0"), std::string::npos) << r.err;
  const json rj = runJson(dir / "out");
  EXPECT_TRUE(rj["resumed"]["from_frame"].is_null()) << rj.dump(2);
  EXPECT_EQ(rj["frames"]["written"], 2);
  EXPECT_TRUE(fs::exists(frameFile(dir / "out", "vdb", 1)));
}

}  // namespace
}  // namespace triad
