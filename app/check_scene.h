#pragma once
// `triad check SCENE.json`: the scene validated as `triad run` would and
// what it will need estimated, in a moment, without simulating.
#include <string>

namespace triad {

struct CheckOptions {
  std::string scene_path;
  std::string quality;  // --quality preset; empty: as written
  bool json = false;    // the estimate as JSON on stdout, for tools
};

// Exit 0 when the scene is valid and fits, 2 otherwise (with the message).
int checkScene(const CheckOptions& options);

}  // namespace triad
