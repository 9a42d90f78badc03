// The progress display in a log (not a terminal): a line per frame, and
// one at least every heartbeat inside a long frame, with an ETA from the
// rate since the first step (also for a run resumed mid-way).
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <string>
#include <thread>

#include "app/progress.h"

namespace triad {
namespace {

std::string contents(std::FILE* f) {
  std::fflush(f);
  std::rewind(f);
  std::string s;
  char buf[4096];
  for (size_t n; (n = std::fread(buf, 1, sizeof buf, f)) > 0;) s.append(buf, n);
  return s;
}

int lines(const std::string& s) { return int(std::count(s.begin(), s.end(), '\n')); }

TEST(Progress, LogGetsALineEveryHeartbeatInsideALongFrame) {
  std::FILE* f = std::tmpfile();
  ASSERT_TRUE(f);
  Progress p(ProgressMode::Plain, 4, 1.0, f, 0.05);
  // One frame of 30 steps, 10 ms each: 0.3 s, so about six heartbeats.
  for (int k = 1; k <= 30; ++k) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    p.step(1, k, 0.25 * k / 30.0, 0.25 / 30.0);
  }
  const std::string inside = contents(f);
  EXPECT_GE(lines(inside), 3) << inside;
  EXPECT_LE(lines(inside), 7) << inside;
  EXPECT_NE(inside.find("frame 1/4"), std::string::npos) << inside;
  std::fseek(f, 0, SEEK_END);
  p.frameDone(1, 30, 0.25);
  EXPECT_EQ(lines(contents(f)), lines(inside) + 1);
  std::fclose(f);
}

TEST(Progress, QuietPrintsNothingAndEtaCountsFromTheFirstStep) {
  std::FILE* f = std::tmpfile();
  Progress quiet(ProgressMode::Quiet, 4, 1.0, f, 0.0);
  quiet.step(1, 1, 0.1, 0.1);
  quiet.frameDone(1, 1, 0.25);
  EXPECT_EQ(contents(f), "");
  // Resumed at t = 0.5 of 1.0: 0.1 s of simulated time took about 0.2 s of
  // wall time, so the 0.4 s left take about 0.8 s: "0:00:01" rounded (up
  // to 3 on a busy machine), not the 0:00:00 that a rate from t = 0 gives.
  std::FILE* g = std::tmpfile();
  Progress p(ProgressMode::Plain, 4, 1.0, g, 1e9);
  p.step(3, 1, 0.5, 1e-3);  // the first step
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  p.step(3, 2, 0.6, 0.1);
  p.frameDone(3, 2, 0.6);
  const std::string s = contents(g);
  int h = -1, m = -1, sec = -1;
  ASSERT_EQ(std::sscanf(s.c_str() + s.find("ETA "), "ETA %d:%d:%d", &h, &m, &sec), 3) << s;
  EXPECT_TRUE(h == 0 && m == 0 && sec >= 1 && sec <= 3) << s;  // slack for a busy machine
  std::fclose(f);
  std::fclose(g);
}

}  // namespace
}  // namespace triad
