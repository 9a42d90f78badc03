#include "app/render_cache.h"

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <string>

#include "app/frame_output.h"
#include "app/run_scene.h"
#include "import/scene_loader.h"
#include "render/mesh_ply_reader.h"
#include "render/particle_ply_reader.h"
#include "render/png_writer.h"
#include "render/preview_writer.h"
#include "sim/errors.h"

namespace triad {

namespace fs = std::filesystem;

namespace {

int badInput(const std::string& msg) {
  std::fprintf(stderr, "triad: error: %s\n", msg.c_str());
  return kExitBadInput;
}

// The scene that made the cache, as run.json names it ("" when unknown).
std::string scenePathFromRunRecord(const std::string& cache_dir) {
  std::ifstream in(runRecordPath(cache_dir));
  if (!in) return "";
  try {
    const nlohmann::json j = nlohmann::json::parse(in);
    if (j.contains("scene") && j["scene"].contains("path") && j["scene"]["path"].is_string())
      return j["scene"]["path"].get<std::string>();
  } catch (const std::exception&) {
  }
  return "";
}

// The frame's rigid body meshes: bodies/NAME.FFFF.ply for each scene object
// NAME that has one, coloured as its object. Names come from the settings,
// so files of bodies that are not the scene's are not drawn.
void readBodyMeshes(const std::string& dir, const render::PreviewSettings& settings, int frame,
                    std::vector<render::PreviewMesh>& meshes) {
  meshes.clear();
  for (size_t i = 0; i < settings.object_names.size(); ++i) {
    const std::string path = bodyMeshPath(dir, settings.object_names[i], frame);
    std::error_code ec;
    if (!fs::is_regular_file(path, ec)) continue;
    render::PreviewMesh& m = meshes.emplace_back();
    m.object = int(i);
    render::readMeshPly(path, m);
  }
}

}  // namespace

int renderCache(const RenderCacheOptions& options) {
  const std::string dir = options.cache_dir;
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return badInput(dir + ": no such cache directory");
  // llvmpipe's rasterizer threads (read when the context is created).
  if (options.threads > 0) setenv("LP_NUM_THREADS", std::to_string(options.threads).c_str(), 1);

  // Settings: the cache's preview/settings.json, else the scene run.json names.
  render::PreviewSettings settings;
  const std::string settings_path = render::previewSettingsPath(dir);
  bool write_settings = false;
  try {
    if (fs::exists(settings_path, ec)) {
      settings = render::readPreviewSettings(settings_path);
    } else {
      const std::string scene_path = scenePathFromRunRecord(dir);
      if (scene_path.empty() || !fs::exists(scene_path, ec))
        return badInput(settings_path + ": not found, and " + runRecordPath(dir) +
                        " names no readable scene to take the camera from" +
                        (scene_path.empty() ? "" : " (" + scene_path + " is missing)"));
      std::fprintf(stderr, "triad: note: %s not found; using the scene %s that %s names\n",
                   settings_path.c_str(), scene_path.c_str(), runRecordPath(dir).c_str());
      const SceneDesc scene = loadScene(scene_path);
      settings = render::previewSettingsForScene(scene);
      write_settings = true;
    }
  } catch (const InputError& e) {
    return badInput(e.what());
  }

  // Frames: every particles/particles.FFFF.ply, in frame order.
  const fs::path particles_dir = fs::path(dir) / "particles";
  const auto frames = render::listFrameFiles(particles_dir.string(), "particles", "ply");
  if (frames.empty())
    return badInput(particles_dir.string() + ": no particle caches (particles.FFFF.ply) to render");

  const auto t0 = std::chrono::steady_clock::now();
  int rendered = 0;
  std::map<int, render::HeldThumbnail> held;  // for the contact sheet: no preview read back
  try {
    if (write_settings) render::writePreviewSettings(dir, settings);
    else fs::create_directories(fs::path(dir) / "preview");
    render::PreviewRenderer renderer(settings);
    render::PreviewFrame frame;
    bool noted = false;
    for (const auto& [number, ply] : frames) {
      try {
        render::readParticlesPly(ply, frame);
        readBodyMeshes(dir, settings, number, frame.meshes);
        // Surface style: the materials' surface meshes instead of particles,
        // where the cache has them (output.surface_mesh).
        if (!settings.surfaces.empty()) {
          bool all = true;
          std::vector<render::PreviewMesh> surfaces;
          for (const render::LegendEntry& e : settings.surfaces) {
            const std::string path = surfaceMeshPath(dir, e.label, number);
            if (!fs::is_regular_file(path, ec)) {
              all = false;
              break;
            }
            render::PreviewMesh& m = surfaces.emplace_back();
            m.color = e.color;
            render::readMeshPly(path, m);
          }
          if (all) {
            frame.xyz.clear();
            frame.object.clear();
            frame.meshes.insert(frame.meshes.end(), surfaces.begin(), surfaces.end());
          } else if (!noted) {
            std::fprintf(stderr, "triad: note: the previews are in surface style, but %s holds no "
                                 "surface meshes (output.surface_mesh): drawing particles\n",
                         dir.c_str());
            noted = true;
          }
        }
      } catch (const InputError& e) {
        std::fprintf(stderr, "triad: error: %s\n", e.what());
        if (rendered > 0)
          std::fprintf(stderr, "triad: %d earlier frame(s) were re-rendered\n", rendered);
        return kExitBadInput;
      }
      const render::Image image = renderer.render(frame);
      render::writePng(render::previewImagePath(dir, number), image);
      held[number] = render::holdThumbnail(image);
      ++rendered;
    }
    render::writeContactSheet(dir, held);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "triad: error: %s\n", e.what());
    return kExitRunFailed;
  }
  const double secs =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("rendered %d frame(s) at %dx%d in %.2f s: %s\ncontact sheet: %s\n", rendered,
              settings.width, settings.height, secs,
              (fs::path(dir) / "preview" / "preview.FFFF.png").string().c_str(),
              render::contactSheetPath(dir).c_str());
  return kExitOk;
}

}  // namespace triad
