#include "app/progress.h"

#include <unistd.h>

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

Progress::Progress(ProgressMode mode, int frames, double end_time, std::FILE* out)
    : out_(out), frames_(frames), end_time_(end_time) {
  quiet_ = mode == ProgressMode::Quiet;
  live_ = mode == ProgressMode::Auto && ::isatty(::fileno(out));
  start_ = last_draw_ = std::chrono::steady_clock::now();
}

double Progress::etaSeconds(double time) const {
  const double elapsed =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  if (time <= 0.0) return -1.0;
  return elapsed * (end_time_ - time) / time;
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
  if (quiet_ || !live_) return;
  // Redraw a terminal line at most ten times a second.
  const auto now = std::chrono::steady_clock::now();
  if (now - last_draw_ < std::chrono::milliseconds(100)) return;
  last_draw_ = now;
  print(frame, steps, time, dt, false);
}

void Progress::frameDone(int frame, int64_t steps, double time) {
  if (quiet_ || live_) return;
  print(frame, steps, time, last_dt_, true);
}

void Progress::finish() {
  if (live_ && !quiet_) {
    std::fprintf(out_, "\r\033[K");
    std::fflush(out_);
  }
}

}  // namespace triad
