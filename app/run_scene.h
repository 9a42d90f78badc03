#pragma once
// Runs a scene file into a cache: the whole pipeline behind `triad run`.
#include <string>

#include "app/progress.h"

namespace triad {

struct RunOptions {
  std::string scene_path;
  std::string out_dir;  // overrides output.dir when not empty
  int threads = 0;      // 0: OpenMP's default
  ProgressMode progress = ProgressMode::Auto;
  bool resume = false;  // continue from the last complete frame's checkpoint
  std::string quality;  // --quality preset (import/quality.h); empty: the scene as written
  bool no_probe = false;  // no rate probe before the first frame (app/rate_probe.h)
  bool no_overlap = false;  // write each frame before stepping on (app/output_thread.h)
  // Split over processes: "particles" (equal counts) or "work" (equal time).
  std::string balance = "particles";
};

// Exit statuses of the command line contract.
enum ExitStatus { kExitOk = 0, kExitRunFailed = 1, kExitBadInput = 2 };

// Loads, validates, simulates and writes the cache. Reports errors on stderr
// and a summary on stdout; returns the exit status.
int runScene(const RunOptions& options);

// Cache paths, shared with readers and tests.
std::string particlesPath(const std::string& out_dir, int frame);
std::string runRecordPath(const std::string& out_dir);

}  // namespace triad
