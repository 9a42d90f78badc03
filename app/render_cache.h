#pragma once
// `triad render CACHE_DIR`: re-render previews from an existing cache.
#include <string>

namespace triad {

struct RenderCacheOptions {
  std::string cache_dir;
  int threads = 0;
};

// Returns the exit status (0, 1 on a failure, 2 on bad input).
int renderCache(const RenderCacheOptions& options);

}  // namespace triad
