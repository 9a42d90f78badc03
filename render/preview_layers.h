#pragma once
// Previews of a world split over several processes, drawn by each process
// from its own particles and composited: sort-last compositing by depth, as
// parallel renderers do (IceT, ParaView), so that no process holds every
// particle for a preview.
//
// Every process draws the same background, ground, solids and outline and
// its own particles, in the order one process would draw them all. One
// process drawing every particle keeps, at each pixel, the first fragment
// drawn at the least depth (GL_LESS). A layer records with each pixel its
// depth and the draw-order key of the fragment kept, so taking, pixel by
// pixel, the least (depth, key) over the layers picks the same fragment,
// ties included: the composite is the single process's image, byte for
// byte.
#include <cstddef>
#include <cstdint>
#include <vector>

namespace triad::render {

// Draw-order keys: what is drawn before the particles (ground, solids), the
// particles by their own keys (kFirstParticleKey and up, ascending in draw
// order), then the domain outline.
constexpr uint64_t kSceneKey = 0;
constexpr uint64_t kFirstParticleKey = 1;
constexpr uint64_t kOutlineKey = ~uint64_t(0);

// A preview at its supersampled size, rows bottom-up (as glReadPixels
// returns them).
struct PreviewLayer {
  int width = 0, height = 0;
  std::vector<uint8_t> rgba;    // 4 bytes a pixel
  std::vector<uint32_t> depth;  // the depth buffer as GL_UNSIGNED_INT
  std::vector<uint64_t> key;    // the key of the fragment kept
  size_t pixels() const { return size_t(width) * size_t(height); }
};

// One pixel of a layer, as sent between processes.
struct LayerPixel {
  uint64_t key;
  uint32_t index;  // y * width + x
  uint32_t depth;
  uint8_t rgba[4];
  uint32_t pad;  // keeps the record's bytes defined
};
static_assert(sizeof(LayerPixel) == 24, "LayerPixel is sent as bytes");

// The pixels where a particle is what the layer shows. Every other pixel
// shows what every process draws alike, so these are all another process
// needs of a layer.
std::vector<LayerPixel> particlePixels(const PreviewLayer& layer);
// The same for `count` pixels of a layer from index `first` on, appended to `out`.
void appendParticlePixels(const uint8_t* rgba, const uint32_t* depth, const uint64_t* key,
                          size_t count, uint32_t first, std::vector<LayerPixel>& out);

// Takes each pixel whose (depth, key) is less than the layer's at its place.
// Throws std::runtime_error on an index outside the layer.
void mergePixels(PreviewLayer& layer, const LayerPixel* pixels, size_t count);

}  // namespace triad::render
