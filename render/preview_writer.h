#pragma once
// Previews in the run pipeline: frames built from a triad::World, written as
// OUT/preview/preview.FFFF.png with one renderer kept for the whole run, and
// the contact sheet OUT/preview/contact_sheet.png.
#include <map>
#include <memory>
#include <string>

#include "render/preview_renderer.h"
#include "render/preview_settings_io.h"
#include "sim/world.h"

namespace triad::render {

// Every MPM particle of the world (positions and scene object indices), and
// every rigid body's surface where it is now, in its object's colour.
PreviewFrame previewFrameFromWorld(const World& world);
// Its rigid bodies' and elastic solids' surfaces alone.
std::vector<PreviewMesh> previewMeshesFromWorld(const World& world);

// A world-space surface as a mesh to draw in scene object `object`'s colour.
PreviewMesh previewMesh(const TriSurface& surface, int object);

// A preview's thumbnail for the contact sheet, made when the preview was
// written, and the size of the preview it came from.
struct HeldThumbnail {
  int width = 0, height = 0;
  Image thumb;
};
HeldThumbnail holdThumbnail(const Image& preview);

// Thumbnails of every OUT/preview/preview.FFFF.png in frame order, labelled
// with frame numbers, written atomically to OUT/preview/contact_sheet.png.
// Frames in `held` take their thumbnail from there; the others are read
// back (a resumed run's earlier frames). Returns the number of frames on
// the sheet (0: no previews, nothing written). Throws std::runtime_error
// naming a file that cannot be read or written.
int writeContactSheet(const std::string& out_dir, const std::map<int, HeldThumbnail>& held = {});

// What app/run_scene.cpp holds during a run with output.png.
class PreviewWriter {
 public:
  // Creates OUT/preview, writes OUT/preview/settings.json and the renderer
  // (OSMesa context). Throws std::runtime_error on failure.
  PreviewWriter(const SceneDesc& scene, const std::string& out_dir);
  ~PreviewWriter();

  // Renders the world's particles and rigid bodies (and `meshes`, more
  // world-space solids) and writes OUT/preview/preview.FFFF.png atomically.
  // Returns seconds spent.
  // With `particles` false the MPM particles are not drawn (render.style
  // "surface": `meshes` holds the materials' surfaces instead).
  double writeFrame(const World& world, int frame, const std::vector<PreviewMesh>& meshes = {},
                    bool particles = true);
  // Writes `image`, the frame's preview drawn elsewhere (composited from
  // the processes of a split run), as writeFrame would. Returns seconds spent.
  double writeImage(int frame, const Image& image);
  // Writes the contact sheet of every preview in OUT/preview. Returns seconds spent.
  double finish();

  const PreviewSettings& settings() const { return settings_; }
  PreviewRenderer& renderer() { return *renderer_; }

 private:
  std::string out_dir_;
  PreviewSettings settings_;
  std::unique_ptr<PreviewRenderer> renderer_;
  // Made as each frame is written, so that the contact sheet at the end
  // reads no preview back (reading them was most of the sheet's time).
  std::map<int, HeldThumbnail> thumbnails_;
};

}  // namespace triad::render
