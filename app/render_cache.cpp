#include "app/render_cache.h"

#include <cstdio>

namespace triad {

int renderCache(const RenderCacheOptions& options) {
  std::fprintf(stderr, "triad: error: %s: re-rendering previews is not implemented yet\n",
               options.cache_dir.c_str());
  return 1;
}

}  // namespace triad
