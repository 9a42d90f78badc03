#include "render/preview_layers.h"

#include <cstring>
#include <stdexcept>
#include <string>

namespace triad::render {

void appendParticlePixels(const uint8_t* rgba, const uint32_t* depth, const uint64_t* key,
                          size_t count, uint32_t first, std::vector<LayerPixel>& out) {
  for (size_t i = 0; i < count; ++i) {
    if (key[i] == kSceneKey || key[i] == kOutlineKey) continue;
    LayerPixel p{};
    p.key = key[i];
    p.index = first + uint32_t(i);
    p.depth = depth[i];
    std::memcpy(p.rgba, rgba + 4 * i, 4);
    out.push_back(p);
  }
}

std::vector<LayerPixel> particlePixels(const PreviewLayer& layer) {
  std::vector<LayerPixel> out;
  appendParticlePixels(layer.rgba.data(), layer.depth.data(), layer.key.data(), layer.pixels(), 0,
                       out);
  return out;
}

void mergePixels(PreviewLayer& layer, const LayerPixel* pixels, size_t count) {
  const size_t n = layer.pixels();
  for (size_t k = 0; k < count; ++k) {
    const LayerPixel& p = pixels[k];
    if (p.index >= n)
      throw std::runtime_error("preview compositing: pixel " + std::to_string(p.index) +
                               " outside a layer of " + std::to_string(n));
    const uint32_t d = layer.depth[p.index];
    if (p.depth > d || (p.depth == d && p.key >= layer.key[p.index])) continue;
    layer.depth[p.index] = p.depth;
    layer.key[p.index] = p.key;
    std::memcpy(&layer.rgba[4 * size_t(p.index)], p.rgba, 4);
  }
}

}  // namespace triad::render
