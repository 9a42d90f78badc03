#pragma once
// Headless preview renders of a frame: MPM particles as lit sphere impostors
// coloured per scene object, solids as shaded triangle meshes, a checker
// ground at the domain's floor and the domain box outline, seen through the
// scene's camera. Drawn with OpenGL 3.3 core on OSMesa (llvmpipe) at
// `supersample` times the resolution and box-filtered on the CPU: the same
// input gives the same pixels, byte for byte.
#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "render/camera.h"
#include "render/image.h"
#include "render/preview_layers.h"

namespace triad::render {

struct PreviewSettings {
  int width = 640;
  int height = 360;
  int supersample = 3;  // rendered at width*s x height*s, then box-filtered
  Camera camera;        // resolved (autoCamera when the scene gives none)
  bool camera_automatic = false;
  Box domain;
  float particle_radius = 0.005f;         // m, drawn sphere radius
  std::vector<std::string> object_names;  // scene objects, by index (for messages and legends)
  bool domain_outline = true;
  std::vector<LegendEntry> legend;  // drawn in the top left corner; empty: none
  // render.style "surface": the materials whose surfaces are drawn instead
  // of particles (surfaces/MATERIAL.FFFF.ply), each in its colour; empty for
  // particle sprites.
  std::vector<LegendEntry> surfaces;
};

// A world-space triangle mesh (a rigid or elastic body's surface).
struct PreviewMesh {
  std::vector<float> xyz;           // 3 floats per vertex
  std::vector<uint32_t> triangles;  // 3 vertex indices per triangle
  int object = -1;                  // scene object index: palette colour; -1: use `color`
  std::array<float, 3> color{0.7f, 0.7f, 0.7f};  // linear 0..1
};

// One frame to draw. Particles are a plain view so that callers can pass
// their own arrays without copying; PreviewFrame owns its arrays.
struct PreviewParticles {
  const float* xyz = nullptr;       // 3 floats per particle
  const uint16_t* object = nullptr;  // scene object index per particle
  size_t count = 0;
};

struct PreviewFrame {
  std::vector<float> xyz;
  std::vector<uint16_t> object;
  std::vector<PreviewMesh> meshes;
  PreviewParticles particles() const { return {xyz.data(), object.data(), object.size()}; }
};

// The fixed palette: colour of scene object `index` (cycles after 10).
std::array<float, 3> objectColor(int index);
constexpr int kPaletteSize = 10;

// Drawn sphere radius for MPM particles sampled at `ppc` per cell of size dx:
// half the sampling spacing, 0.5 * dx * ppc^(-1/3).
float particleRadius(double dx, int particles_per_cell);

// Keeps one OSMesa context, its shaders and buffers across frames.
class PreviewRenderer {
 public:
  // Throws std::runtime_error when the context or a shader cannot be made,
  // or when the settings are unusable (resolution, supersampling).
  explicit PreviewRenderer(const PreviewSettings& settings);
  ~PreviewRenderer();
  PreviewRenderer(const PreviewRenderer&) = delete;
  PreviewRenderer& operator=(const PreviewRenderer&) = delete;

  const PreviewSettings& settings() const;
  // Changes resolution, camera etc.; buffers are reallocated when needed.
  void setSettings(const PreviewSettings& settings);

  Image render(const PreviewParticles& particles, const std::vector<PreviewMesh>& meshes = {});
  Image render(const PreviewFrame& frame) { return render(frame.particles(), frame.meshes); }

  // The same drawing kept at its supersampled size, with each pixel's depth
  // and draw-order key (render/preview_layers.h), for compositing with the
  // layers other processes drew of their particles. `keys`: one for each
  // particle, ascending (the particles are drawn in that order), between
  // kFirstParticleKey and kOutlineKey; throws std::runtime_error otherwise.
  PreviewLayer renderLayer(const PreviewParticles& particles,
                           const std::vector<PreviewMesh>& meshes, const uint64_t* keys);
  // The same drawing's particle pixels alone (particlePixels of its layer),
  // read back a band of rows at a time: what a process sends to be
  // composited, without holding its whole layer.
  std::vector<LayerPixel> renderParticlePixels(const PreviewParticles& particles,
                                               const std::vector<PreviewMesh>& meshes,
                                               const uint64_t* keys);
  // A layer (composited or not) as the preview render() gives.
  Image finish(const PreviewLayer& layer) const;

  // "llvmpipe (LLVM ...), OpenGL 3.3 ..." for benchmark records.
  std::string glDescription();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace triad::render
