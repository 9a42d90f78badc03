#pragma once
// `triad render CACHE_DIR`: re-render previews from an existing cache: the
// particles of every particles/particles.FFFF.ply with the rigid bodies of
// that frame (bodies/NAME.FFFF.ply, NAME an object of preview/settings.json).
#include <string>

namespace triad {

struct RenderCacheOptions {
  std::string cache_dir;
  int threads = 0;
};

// Returns the exit status (0, 1 on a failure, 2 on bad input).
int renderCache(const RenderCacheOptions& options);

}  // namespace triad
