#pragma once
// Preview settings from a scene, and their record in a cache
// (`preview/settings.json`), so that `triad render CACHE_DIR` draws what the
// run drew without the scene file.
#include <map>
#include <string>

#include "render/preview_renderer.h"
#include "sim/scene_desc.h"

namespace triad::render {

// Resolution and camera from the scene's `render` block (automatic camera
// when absent), the domain box, the drawn particle radius from dx and
// particles_per_cell, every object's name, and the legend: each drawn MPM
// object (render.style "particles") or material ("surface") and each solid,
// in its colour (at most 12 lines, the last saying how many more).
PreviewSettings previewSettingsForScene(const SceneDesc& scene);

// The colour a material's surface is drawn in (render.style "surface"),
// linear RGB: water blue, sand tan, snow white; elastic MPM materials take
// the palette colour of `first_object`, the first object made of them.
std::array<float, 3> materialColor(MaterialModel model, int first_object);

// `OUT/preview/settings.json` and `OUT/preview/preview.FFFF.png`.
std::string previewSettingsPath(const std::string& out_dir);
std::string previewImagePath(const std::string& out_dir, int frame);

// The frame files DIR/STEM.FFFF.EXT (four or more digits), by frame number;
// empty when DIR is missing.
std::map<int, std::string> listFrameFiles(const std::string& dir, const std::string& stem,
                                          const std::string& ext);
std::string contactSheetPath(const std::string& out_dir);

// Writes OUT/preview/settings.json atomically (creating OUT/preview).
// Throws std::runtime_error naming the file.
void writePreviewSettings(const std::string& out_dir, const PreviewSettings& settings,
                          const std::string& scene_name = "");

// Reads a settings file; throws triad::InputError naming the file and the key.
PreviewSettings readPreviewSettings(const std::string& path);

}  // namespace triad::render
