// SIGINT and SIGTERM during `triad run`: the run stops at the next step
// boundary with exit status 130 or 143, keeps every complete frame and
// its checkpoint, says in run.json and on stderr what happened and how to
// continue; the printed --resume writes the frames an uninterrupted run
// writes, byte for byte. A second signal ends the process at once.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <thread>

#include "cli_fixture.h"
#include "scene_fixture.h"

namespace triad {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// A scene of 8 frames that takes a second or two.
json slowScene() {
  json j = test::baseScene("interrupt", {0.6, 0.5, 0.4}, 0.02);
  j["frames"] = {{"count", 8}, {"fps", 24}};
  j["materials"]["water"] = {{"model", "water"}, {"density", 1000}, {"bulk_modulus", 2e5}};
  j["objects"].push_back({{"name", "block"}, {"kind", "mpm"}, {"material", "water"},
                          {"shape", test::box({0, 0, 0}, {0.3, 0.3, 0.4})}});
  j["output"] = {{"vdb", false}, {"png", false}};
  return j;
}

// Starts `triad ARGS` in the background, its output in dir/log.txt.
pid_t start(const fs::path& dir, const std::string& args) {
  const pid_t pid = fork();
  if (pid == 0) {
    const std::string log = (dir / "log.txt").string();
    if (!std::freopen(log.c_str(), "w", stderr) || !std::freopen("/dev/null", "w", stdout)) _exit(99);
    execl(TRIAD_EXE, TRIAD_EXE, "run", (dir / "scene.json").c_str(), "--out",
          (dir / "out").c_str(), "--threads", "2", "--plain", static_cast<char*>(nullptr));
    _exit(98);
  }
  (void)args;
  return pid;
}

// Waits until `file` exists (the run has written that far), at most 60 s.
bool waitFor(const fs::path& file) {
  for (int k = 0; k < 6000; ++k) {
    if (fs::exists(file)) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return false;
}

TEST(Interrupt, SigintStopsCleanlyAndResumeWritesTheSameFrames) {
  const fs::path dir = test::tempDir("interrupt");
  test::writeScene(dir, slowScene());
  ASSERT_EQ(test::runTriad(dir, "run " + (dir / "scene.json").string() + " --out " +
                                    (dir / "ref").string() + " --quiet")
                .status,
            0);
  const pid_t pid = start(dir, "");
  ASSERT_TRUE(waitFor(dir / "out" / "checkpoints" / "state.0002.bin"));
  kill(pid, SIGINT);
  int status = 0;
  waitpid(pid, &status, 0);
  const std::string err = test::slurp(dir / "log.txt");
  ASSERT_TRUE(WIFEXITED(status)) << err;
  EXPECT_EQ(WEXITSTATUS(status), 130) << err;
  EXPECT_NE(err.find("interrupted by SIGINT in frame"), std::string::npos) << err;
  const size_t at = err.find("to continue after frame");
  ASSERT_NE(at, std::string::npos) << err;
  EXPECT_NE(err.find("--resume", at), std::string::npos) << err;
  const json rec = json::parse(test::slurp(dir / "out" / "run.json"));
  EXPECT_FALSE(rec["finished"].get<bool>());
  EXPECT_EQ(rec["interrupted"]["signal"], "SIGINT");
  const int stopped = rec["interrupted"]["frame"].get<int>();
  EXPECT_EQ(rec["frames"]["written"].get<int>(), stopped);
  EXPECT_NE(rec["error"].get<std::string>().find("interrupted by SIGINT"), std::string::npos);
  // Nothing of the frame in progress: its particles are not there.
  char name[32];
  std::snprintf(name, sizeof name, "particles.%04d.ply", stopped);
  EXPECT_FALSE(fs::exists(dir / "out" / "particles" / name));

  // The printed command, run as printed.
  std::string cmd = err.substr(err.find(": ", at) + 2);
  cmd = cmd.substr(0, cmd.find('\n'));
  ASSERT_EQ(cmd.rfind("triad run ", 0), 0u) << cmd;
  const test::CliResult r = test::runTriad(dir, cmd.substr(6) + " --quiet");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find("resuming after frame " + std::to_string(stopped - 1)), std::string::npos)
      << r.err;
  for (int f = 0; f <= 8; ++f) {
    std::snprintf(name, sizeof name, "particles.%04d.ply", f);
    EXPECT_TRUE(test::slurp(dir / "out" / "particles" / name) ==
                test::slurp(dir / "ref" / "particles" / name))
        << "frame " << f;
  }
}

TEST(Interrupt, SigtermExits143AndASecondSignalEndsAtOnce) {
  const fs::path dir = test::tempDir("interrupt_term");
  test::writeScene(dir, slowScene());
  pid_t pid = start(dir, "");
  ASSERT_TRUE(waitFor(dir / "out" / "checkpoints" / "state.0001.bin"));
  kill(pid, SIGTERM);
  int status = 0;
  waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 143);
  EXPECT_EQ(json::parse(test::slurp(dir / "out" / "run.json"))["interrupted"]["signal"], "SIGTERM");

  // Two signals before the run has stopped: the second delivered (the
  // kernel picks the order of two pending ones) kills the process, where
  // one alone lets it exit cleanly.
  fs::remove_all(dir / "out");
  pid = start(dir, "");
  ASSERT_TRUE(waitFor(dir / "out" / "checkpoints" / "state.0001.bin"));
  kill(pid, SIGINT);
  kill(pid, SIGTERM);
  waitpid(pid, &status, 0);
  EXPECT_TRUE(WIFSIGNALED(status) && (WTERMSIG(status) == SIGTERM || WTERMSIG(status) == SIGINT))
      << "exited " << (WIFEXITED(status) ? WEXITSTATUS(status) : -1);
}

}  // namespace
}  // namespace triad
