#pragma once
// `triad check SCENE.json`: the scene validated as `triad run` would and
// what it will need estimated, in a moment: a short probe of a coarser
// copy measures this machine's rate for it; with --probe, a few seconds of
// the run itself measure its rate and step.
#include <string>

namespace triad {

struct CheckOptions {
  std::string scene_path;
  std::string quality;  // --quality preset; empty: as written
  bool json = false;    // the estimate as JSON on stdout, for tools
  // Seconds of a probe run: the scene built and stepped on this machine for
  // about that long, its rate and step measured (0: no probe).
  double probe = 0.0;
  // Without the short rate probe (app/rate_probe.h): wall time at the
  // fixed rate.
  bool no_probe = false;
};

// Exit 0 when the scene is valid and fits, 2 otherwise (with the message).
int checkScene(const CheckOptions& options);

}  // namespace triad
