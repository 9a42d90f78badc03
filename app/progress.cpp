#include "app/progress.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>

namespace triad {

void formatDuration(double seconds, char* buf, size_t size) {
  if (!std::isfinite(seconds) || seconds < 0) {
    std::snprintf(buf, size, "--:--:--");
    return;
  }
  const long s = std::lround(seconds);
  std::snprintf(buf, size, "%ld:%02ld:%02ld", s / 3600, (s / 60) % 60, s % 60);
}

Progress::Progress(ProgressMode mode, int frames, double end_time, std::FILE* out,
                   double heartbeat)
    : out_(out), frames_(frames), end_time_(end_time), heartbeat_(heartbeat) {
  quiet_ = mode == ProgressMode::Quiet;
  live_ = mode == ProgressMode::Auto && ::isatty(::fileno(out));
  start_ = last_draw_ = std::chrono::steady_clock::now();
}

double Progress::etaSeconds(double time) const {
  const double elapsed =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  // From the rate since the first step: a resumed run starts mid-way.
  const double done = time - std::max(0.0, first_time_);
  if (done <= 0.0) return -1.0;
  return elapsed * (end_time_ - time) / done;
}

void Progress::print(int frame, int64_t steps, double time, double dt, bool final_line) {
  char eta[32];
  formatDuration(etaSeconds(time), eta, sizeof(eta));
  std::fprintf(out_, "%sframe %d/%d  substep %lld  t = %.4f s  dt = %.2e s  ETA %s%s",
               live_ ? "\r" : "", frame, frames_, static_cast<long long>(steps), time, dt, eta,
               live_ && !final_line ? "\033[K" : "\n");
  std::fflush(out_);
}

void Progress::step(int frame, int64_t steps, double time, double dt) {
  last_dt_ = dt;
  if (first_time_ < 0.0) {
    // The clock starts at the first step: setup is not simulation.
    first_time_ = time - dt;
    start_ = last_draw_ = std::chrono::steady_clock::now();
  }
  if (quiet_) return;
  const auto now = std::chrono::steady_clock::now();
  if (live_) {
    // Redraw a terminal line at most ten times a second.
    if (now - last_draw_ < std::chrono::milliseconds(100)) return;
    last_draw_ = now;
    print(frame, steps, time, dt, false);
    return;
  }
  // A log: a line inside a long frame once the heartbeat has passed.
  if (std::chrono::duration<double>(now - last_draw_).count() < heartbeat_) return;
  last_draw_ = now;
  print(frame, steps, time, dt, true);
}

void Progress::frameDone(int frame, int64_t steps, double time) {
  if (quiet_ || live_) return;
  last_draw_ = std::chrono::steady_clock::now();
  print(frame, steps, time, last_dt_, true);
}

void Progress::finish() {
  if (live_ && !quiet_) {
    std::fprintf(out_, "\r\033[K");
    std::fflush(out_);
  }
}

}  // namespace triad
