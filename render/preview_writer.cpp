#include "render/preview_writer.h"

#include <array>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <map>

#include "render/png_writer.h"

namespace triad::render {

namespace fs = std::filesystem;

namespace {
double seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}
}  // namespace

PreviewFrame previewFrameFromWorld(const World& world) {
  PreviewFrame frame;
  const size_t n = world.particleCount();
  frame.xyz.reserve(n * 3);
  frame.object.reserve(n);
  for (const ParticleSet& set : world.sets) {
    for (size_t i = 0; i < set.size(); ++i) {
      const Vec3f& x = set.x[i];
      frame.xyz.insert(frame.xyz.end(), {x.x(), x.y(), x.z()});
    }
    frame.object.insert(frame.object.end(), set.object.begin(), set.object.end());
  }
  frame.meshes = previewMeshesFromWorld(world);
  return frame;
}

std::vector<PreviewMesh> previewMeshesFromWorld(const World& world) {
  std::vector<PreviewMesh> meshes;
  for (const RigidBody& body : world.bodies)
    meshes.push_back(previewMesh(worldSurface(body), body.object));
  for (const ElasticSolid& solid : world.elastics)
    meshes.push_back(previewMesh(solid.worldSurface(), solid.object));
  return meshes;
}

PreviewMesh previewMesh(const TriSurface& surface, int object) {
  PreviewMesh m;
  m.object = object;
  m.xyz.reserve(surface.vertices.size() * 3);
  for (const Vec3f& v : surface.vertices) m.xyz.insert(m.xyz.end(), {v.x(), v.y(), v.z()});
  m.triangles.reserve(surface.triangles.size() * 3);
  for (const auto& t : surface.triangles) m.triangles.insert(m.triangles.end(), t.begin(), t.end());
  return m;
}

HeldThumbnail holdThumbnail(const Image& preview) {
  const auto [tw, th] = thumbnailSize(preview.width, preview.height);
  return {preview.width, preview.height, resizeDown(preview, tw, th)};
}

int writeContactSheet(const std::string& out_dir, const std::map<int, HeldThumbnail>& held) {
  const auto frames = listFrameFiles(out_dir + "/preview", "preview", "png");
  if (frames.empty()) return 0;
  // The first frame's size sets the thumbnails' (as contactSheet does).
  const auto first = held.find(frames.begin()->first);
  std::array<int, 2> size;
  Image first_image;
  if (first != held.end()) {
    size = thumbnailSize(first->second.width, first->second.height);
  } else {
    first_image = readPng(frames.begin()->second);
    size = thumbnailSize(first_image.width, first_image.height);
  }
  std::vector<Image> thumbs;
  std::vector<int> labels;
  for (const auto& [frame, path] : frames) {
    const auto h = held.find(frame);
    if (h != held.end() && h->second.thumb.width == size[0] && h->second.thumb.height == size[1]) {
      thumbs.push_back(h->second.thumb);
    } else {
      const Image image = thumbs.empty() && !first_image.empty() ? first_image : readPng(path);
      thumbs.push_back(resizeDown(image, size[0], size[1]));
    }
    labels.push_back(frame);
  }
  writePng(contactSheetPath(out_dir), contactSheetOfThumbnails(thumbs, labels));
  return int(thumbs.size());
}

PreviewWriter::PreviewWriter(const SceneDesc& scene, const std::string& out_dir)
    : out_dir_(out_dir), settings_(previewSettingsForScene(scene)) {
  writePreviewSettings(out_dir_, settings_, scene.name);
  renderer_ = std::make_unique<PreviewRenderer>(settings_);
}

PreviewWriter::~PreviewWriter() = default;

double PreviewWriter::writeFrame(const World& world, int frame,
                                 const std::vector<PreviewMesh>& meshes, bool particles) {
  const auto t0 = std::chrono::steady_clock::now();
  PreviewFrame f = previewFrameFromWorld(world);
  if (!particles) {
    f.xyz.clear();
    f.object.clear();
  }
  f.meshes.insert(f.meshes.end(), meshes.begin(), meshes.end());
  writeImage(frame, renderer_->render(f));
  return seconds(t0);
}

double PreviewWriter::writeImage(int frame, const Image& image) {
  const auto t0 = std::chrono::steady_clock::now();
  writePng(previewImagePath(out_dir_, frame), image);
  thumbnails_[frame] = holdThumbnail(image);
  return seconds(t0);
}

double PreviewWriter::finish() {
  const auto t0 = std::chrono::steady_clock::now();
  writeContactSheet(out_dir_, thumbnails_);
  return seconds(t0);
}

}  // namespace triad::render
