#pragma once
// Progress display for long runs: one self-updating line on a terminal,
// plain lines when the output is a pipe or a file: one per frame, and one
// at least every `heartbeat` seconds inside a long frame, so that a log
// never goes silent.
#include <chrono>
#include <cstdint>
#include <cstdio>

namespace triad {

enum class ProgressMode { Auto, Plain, Quiet };

class Progress {
 public:
  Progress(ProgressMode mode, int frames, double end_time, std::FILE* out = stderr,
           double heartbeat = 10.0);
  // After each substep: frame being computed, substeps so far, time, step.
  void step(int frame, int64_t steps, double time, double dt);
  // After a frame is written.
  void frameDone(int frame, int64_t steps, double time);
  // Clears the live line before other output.
  void finish();

 private:
  void print(int frame, int64_t steps, double time, double dt, bool final_line);
  double etaSeconds(double time) const;

  std::FILE* out_;
  bool live_ = false;   // a terminal: rewrite one line in place
  bool quiet_ = false;
  int frames_;
  double end_time_;
  std::chrono::steady_clock::time_point start_, last_draw_;
  double last_dt_ = 0.0;
  double heartbeat_;
  double first_time_ = -1.0;  // simulated time at the first step (a resumed run's start)
};

// Formats seconds as H:MM:SS.
void formatDuration(double seconds, char* buf, size_t size);

}  // namespace triad
