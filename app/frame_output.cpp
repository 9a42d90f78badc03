#include "app/frame_output.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>

#include "app/run_scene.h"
#include "export/atomic_file.h"
#include "export/particle_surface.h"
#include "export/ply_writer.h"
#include "export/vdb_writer.h"
#include "export/vtk_writer.h"
#include "sim/errors.h"
#include "sim/frame_name.h"

namespace triad {

namespace {

namespace fs = std::filesystem;

std::string frameName(const std::string& dir, const char* stem, int frame, const char* ext) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), ".%04d.", frame);
  return dir + "/" + stem + buf + ext;
}

// Body meshes are NAME.FFFF.ply; names may hold dots, the frame is the last
// number.
bool isBodyFile(const std::string& name, FrameName& n) {
  return parseFrameName(name, n) && n.ext == "ply";
}

// The header of a PLY file we wrote: its size and element counts.
struct PlyHeader {
  size_t bytes = 0;
  std::map<std::string, size_t> elements;
};

// Reads the header; empty when the file is missing or has none.
std::optional<PlyHeader> readPlyHeader(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return std::nullopt;
  PlyHeader h;
  std::string line;
  while (std::getline(in, line) && h.bytes < 4096) {
    h.bytes += line.size() + 1;
    std::istringstream words(line);
    std::string a, b;
    words >> a >> b;
    if (a == "element") words >> h.elements[b];
    if (line == "end_header") return h;
  }
  return std::nullopt;
}

// A cache is complete when its size is the header's plus each element's
// count times its record size: 36 bytes a particle; 12 a body vertex and 13
// a triangle (uchar count, three int indices).
std::string checkPlySize(const std::string& path, const PlyHeader& h, size_t data_bytes) {
  std::error_code ec;
  const auto size = fs::file_size(path, ec);
  if (ec || size != h.bytes + data_bytes) return "truncated";
  return "";
}

std::string checkParticlesPly(const std::string& path, size_t particles) {
  const auto h = readPlyHeader(path);
  if (!h) return fs::exists(path) ? "no PLY header" : "missing";
  const size_t vertices = h->elements.count("vertex") ? h->elements.at("vertex") : 0;
  if (vertices != particles)
    return std::to_string(vertices) + " particles, the checkpoint has " + std::to_string(particles);
  return checkPlySize(path, *h, vertices * 36);
}

// A mesh of vertices and triangles, complete by its header's counts; with
// `expected` (a body's surface), also of that many (surface meshes have only
// their own header to go by).
std::string checkMeshPly(const std::string& path, const TriSurface* expected = nullptr) {
  const auto h = readPlyHeader(path);
  if (!h) return fs::exists(path) ? "no PLY header" : "missing";
  const size_t v = h->elements.count("vertex") ? h->elements.at("vertex") : 0;
  const size_t f = h->elements.count("face") ? h->elements.at("face") : 0;
  if (expected && (v != expected->vertices.size() || f != expected->triangles.size()))
    return std::to_string(v) + " vertices and " + std::to_string(f) + " faces, the body has " +
           std::to_string(expected->vertices.size()) + " and " +
           std::to_string(expected->triangles.size());
  return checkPlySize(path, *h, v * 12 + f * 13);
}

// What is wrong with the frame's cache files (empty when they are complete).
// Fills `logs` with the body tables' rows up to frame.
// `particles`: the checkpoint's count (sources and sinks change it).
std::string checkFrameCaches(const SceneDesc& scene, const std::string& out_dir, int frame,
                             const World& world, size_t particles, BodyLogs& logs) {
  if (scene.output.ply) {
    const std::string p = particlesPath(out_dir, frame);
    const std::string why = checkParticlesPly(p, particles);
    if (!why.empty()) return p + ": " + why;
  }
  std::vector<std::string> names;
  for (const RigidBody& b : world.bodies) {
    const std::string p = bodyMeshPath(out_dir, b.name, frame);
    const std::string why = checkMeshPly(p, &b.surface);
    if (!why.empty()) return p + ": " + why;
    names.push_back(b.name);
  }
  for (const ElasticSolid& e : world.elastics) {
    const std::string p = bodyMeshPath(out_dir, e.name, frame);
    const std::string why = checkMeshPly(p, &e.surface);
    if (!why.empty()) return p + ": " + why;
  }
  if (!names.empty()) {
    const std::string p = rigidStatesPath(out_dir);
    const std::string why = logs.states.load(p, frame, names);
    if (!why.empty()) return p + ": " + why;
    const std::string f = bodyForcesPath(out_dir);
    const std::string why_f = logs.forces.load(f, frame, names);
    if (!why_f.empty()) return f + ": " + why_f;
  }
  if (scene.output.vdb) {
    const std::string p = volumesPath(out_dir, frame);
    const std::string why = fs::exists(p) ? checkVolumesVdb(p) : "missing";
    if (!why.empty()) return p + ": " + why;
  }
  if (scene.output.surface_mesh) {
    for (int m : surfaceMaterials(scene)) {
      const std::string p = surfaceMeshPath(out_dir, scene.materials[size_t(m)].name, frame);
      const std::string why = checkMeshPly(p);
      if (!why.empty()) return p + ": " + why;
    }
  }
  return "";
}

}  // namespace

std::string particlesPath(const std::string& out_dir, int frame) {
  return frameName(out_dir + "/particles", "particles", frame, "ply");
}

std::string volumesPath(const std::string& out_dir, int frame) {
  return frameName(out_dir + "/volumes", "density", frame, "vdb");
}

std::string checkpointDir(const std::string& out_dir) { return out_dir + "/checkpoints"; }

std::string bodiesDir(const std::string& out_dir) { return out_dir + "/bodies"; }

std::string bodyMeshPath(const std::string& out_dir, const std::string& name, int frame) {
  return frameName(bodiesDir(out_dir), name.c_str(), frame, "ply");
}

std::string rigidStatesPath(const std::string& out_dir) {
  return bodiesDir(out_dir) + "/rigid_states.csv";
}

std::string bodyForcesPath(const std::string& out_dir) {
  return bodiesDir(out_dir) + "/forces.csv";
}

std::string surfacesDir(const std::string& out_dir) { return out_dir + "/surfaces"; }

std::string vtkDir(const std::string& out_dir) { return out_dir + "/vtk"; }
std::string vtkParticlesPath(const std::string& out_dir, int frame) {
  return frameName(vtkDir(out_dir), "particles", frame, "vtp");
}

std::string surfaceMeshPath(const std::string& out_dir, const std::string& material, int frame) {
  return frameName(surfacesDir(out_dir), material.c_str(), frame, "ply");
}

std::vector<int> surfaceMaterials(const SceneDesc& scene) {
  std::vector<int> out;
  for (const ObjectDesc& o : scene.objects)
    if (o.kind == ObjectKind::Mpm && o.material >= 0) out.push_back(o.material);
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

std::string checkpointPath(const std::string& out_dir, int frame) {
  return frameName(checkpointDir(out_dir), "state", frame, "bin");
}

void makeOutputDirectories(const SceneDesc& scene, const std::string& out_dir) {
  makeDirectories(out_dir);
  if (scene.output.ply) makeDirectories(out_dir + "/particles");
  if (scene.output.vdb) makeDirectories(out_dir + "/volumes");
  if (scene.output.checkpoints) makeDirectories(checkpointDir(out_dir));
  if (scene.output.surface_mesh) makeDirectories(surfacesDir(out_dir));
  if (scene.output.vtk) {
    makeDirectories(vtkDir(out_dir) + "/bodies");
    if (scene.output.surface_mesh) makeDirectories(vtkDir(out_dir) + "/surfaces");
  }
  if (std::any_of(scene.objects.begin(), scene.objects.end(),
                  [](const ObjectDesc& o) {
                    return o.kind != ObjectKind::Mpm && o.kind != ObjectKind::Sink;
                  }))
    makeDirectories(bodiesDir(out_dir));
}

namespace {

// The VTK series of this scene, in the order of their parts in cache.pvd:
// (part name, file stem relative to vtk/) for particles, solids, surfaces.
std::vector<std::pair<std::string, std::string>> vtkSeries(const SceneDesc& scene) {
  std::vector<std::pair<std::string, std::string>> series{{"particles", "particles"}};
  for (const ObjectDesc& o : scene.objects)
    if (o.kind == ObjectKind::Rigid || o.kind == ObjectKind::Elastic ||
        o.kind == ObjectKind::Collider)
      series.push_back({o.name, "bodies/" + o.name});
  if (scene.output.surface_mesh)
    for (int m : surfaceMaterials(scene)) {
      const std::string& name = scene.materials[size_t(m)].name;
      series.push_back({"surface " + name, "surfaces/" + name});
    }
  return series;
}

// The collection of every series for frames 0..frame, at the frames' times.
void writeCachePvd(const SceneDesc& scene, const std::string& out_dir, int frame) {
  std::vector<PvdEntry> entries;
  const auto series = vtkSeries(scene);
  for (int f = 0; f <= frame; ++f)
    for (size_t p = 0; p < series.size(); ++p) {
      const std::string file = frameName(".", series[p].second.c_str(), f, "vtp").substr(2);
      entries.push_back({f / scene.frames.fps, int(p), series[p].first, file});
    }
  writePvd(vtkDir(out_dir) + "/cache.pvd", entries);
}

}  // namespace

std::vector<std::pair<int, TriSurface>> writeFrameCaches(const SceneDesc& scene,
                                                         const std::string& out_dir,
                                                         const World& world, int frame,
                                                         const SharedWrites& shared) {
  std::vector<std::pair<int, TriSurface>> surfaces;
  const bool vtk = scene.output.vtk;
  // A level set the processes of a split run made in parts.
  auto made = [&](int material) -> const LevelSetParts* {
    if (!shared.surfaces) return nullptr;
    const auto it = shared.surfaces->find(material);
    return it == shared.surfaces->end() ? nullptr : &it->second;
  };
  // The VDB voxel, which also bounds the surfaces' level-set voxel.
  const double voxel =
      scene.output.vdb_voxel_size > 0 ? scene.output.vdb_voxel_size : scene.domain.dx;
  if (!shared.particles.empty())
    moveIntoPlace(shared.particles, particlesPath(out_dir, frame));
  else if (scene.output.ply)
    writeParticlesPly(particlesPath(out_dir, frame), world);
  if (!shared.vtk_particles.empty())
    moveIntoPlace(shared.vtk_particles, vtkParticlesPath(out_dir, frame));
  else if (vtk)
    writeParticlesVtp(vtkParticlesPath(out_dir, frame), world);
  if (scene.output.vdb) {
    VdbFrameInfo info;
    info.frame = frame;
    info.time = world.time;
    info.scene_name = scene.name;
    info.voxel_size = voxel;
    info.surface = scene.output.vdb_surface;
    const LevelSetParts* surface = made(-1);
    if (shared.volumes)
      writeVolumesVdb(volumesPath(out_dir, frame), shared.volumes->sums, shared.volumes->scale,
                      world, info, surface);
    else
      writeVolumesVdb(volumesPath(out_dir, frame), world, info);
  }
  const bool preview_surfaces = scene.output.png && scene.render.style == RenderStyle::Surface;
  if (scene.output.surface_mesh || preview_surfaces) {
    SurfaceMeshSettings settings;
    settings.voxel_size = voxel;
    settings.smoothing = scene.output.surface_smoothing;
    settings.adaptivity = scene.output.surface_adaptivity;
    for (int m : surfaceMaterials(scene)) {
      const std::string& name = scene.materials[size_t(m)].name;
      TriSurface mesh = materialSurfaceMesh(world, m, settings, made(m));
      if (scene.output.surface_mesh) {
        char comment[96];
        std::snprintf(comment, sizeof(comment), "surface of material %s at t=%.9g s",
                      name.c_str(), world.time);
        writeSurfacePly(surfaceMeshPath(out_dir, name, frame), mesh, comment);
        if (vtk)
          writeSurfaceVtp(frameName(vtkDir(out_dir) + "/surfaces", name.c_str(), frame, "vtp"),
                          mesh);
      }
      surfaces.emplace_back(m, std::move(mesh));
    }
  }
  if (vtk) {
    const std::string bodies = vtkDir(out_dir) + "/bodies";
    for (const RigidBody& b : world.bodies)
      writeSurfaceVtp(frameName(bodies, b.name.c_str(), frame, "vtp"), worldSurface(b));
    for (const ElasticSolid& e : world.elastics)
      writeSurfaceVtp(frameName(bodies, e.name.c_str(), frame, "vtp"), e.worldSurface());
    writeCachePvd(scene, out_dir, frame);
  }
  return surfaces;
}

void writeFrameBodies(const std::string& out_dir, const World& world, int frame, BodyLogs& logs,
                      const std::vector<BodyLoad>& loads) {
  for (const ElasticSolid& e : world.elastics)
    writeElasticPly(bodyMeshPath(out_dir, e.name, frame), e, world.time);
  if (world.bodies.empty()) return;
  for (const RigidBody& b : world.bodies)
    writeBodyPly(bodyMeshPath(out_dir, b.name, frame), b, world.time);
  // The forces of the frame's steps, then the state table last: its rows of
  // a frame say that frame's files are written.
  if (frame > 0)
    logs.forces.record(frame, world.time, world.bodies, loads);
  else
    logs.forces.clear();
  logs.forces.write(bodyForcesPath(out_dir));
  logs.states.record(frame, world.time, world.bodies);
  logs.states.write(rigidStatesPath(out_dir));
}

void writeFrameCheckpoint(const std::string& out_dir, int frame, const std::string& scene_hash,
                          const World& world, const SolverState& solver, const StepRecord& record,
                          const std::string& written) {
  if (!written.empty())
    moveIntoPlace(written, checkpointPath(out_dir, frame));
  else
    writeCheckpoint(checkpointPath(out_dir, frame), frame, scene_hash, world, solver, record);
  // Keep this one and the one before (the fallback if this one is damaged).
  for (const auto& [f, path] : listCheckpoints(checkpointDir(out_dir))) {
    if (f == frame || f == frame - 1) continue;
    std::error_code ignored;
    fs::remove(path, ignored);
  }
}

void removeStaleTemporaries(const std::string& out_dir) {
  for (const std::string& dir : {out_dir, out_dir + "/particles", out_dir + "/volumes",
                                 out_dir + "/preview", bodiesDir(out_dir), surfacesDir(out_dir),
                                 vtkDir(out_dir), vtkDir(out_dir) + "/bodies",
                                 vtkDir(out_dir) + "/surfaces", checkpointDir(out_dir)}) {
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(dir, ec)) {
      std::error_code ignored;
      if (e.is_regular_file(ignored) && isTemporaryName(e.path().filename().string()))
        fs::remove(e.path(), ignored);
    }
  }
}

void removeCheckpoints(const std::string& out_dir) {
  for (const auto& [f, path] : listCheckpoints(checkpointDir(out_dir))) {
    std::error_code ignored;
    fs::remove(path, ignored);
  }
}

void removeFramesAfter(const std::string& out_dir, int last_frame) {
  // The frame files of each folder: particles, density and previews by
  // their stems, body and surface meshes (NAME.FFFF.ply) and VTK files
  // (NAME.FFFF.vtp) by their extension.
  auto frameFile = [](const FrameName& n) {
    return (n.stem == "particles" || n.stem == "density" || n.stem == "preview") &&
           (n.ext == "ply" || n.ext == "vdb" || n.ext == "png");
  };
  auto meshFile = [](const FrameName& n) { return n.ext == "ply"; };
  auto vtkFile = [](const FrameName& n) { return n.ext == "vtp"; };
  const std::pair<std::string, bool (*)(const FrameName&)> dirs[] = {
      {out_dir + "/particles", frameFile},    {out_dir + "/volumes", frameFile},
      {out_dir + "/preview", frameFile},      {bodiesDir(out_dir), meshFile},
      {surfacesDir(out_dir), meshFile},       {vtkDir(out_dir), vtkFile},
      {vtkDir(out_dir) + "/bodies", vtkFile}, {vtkDir(out_dir) + "/surfaces", vtkFile}};
  for (const auto& [dir, ours] : dirs) {
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(dir, ec)) {
      FrameName n;
      if (!parseFrameName(e.path().filename().string(), n) || !ours(n) || n.frame <= last_frame)
        continue;
      std::error_code ignored;
      fs::remove(e.path(), ignored);
    }
  }
}

void removeOtherBodies(const std::string& out_dir, const World& world) {
  const std::string dir = bodiesDir(out_dir);
  std::error_code ec, ignored;
  if (world.bodies.empty()) {
    fs::remove(rigidStatesPath(out_dir), ignored);
    fs::remove(bodyForcesPath(out_dir), ignored);
  }
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    FrameName n;
    if (!isBodyFile(e.path().filename().string(), n)) continue;
    const bool ours = std::any_of(world.bodies.begin(), world.bodies.end(),
                                  [&](const RigidBody& b) { return b.name == n.stem; }) ||
                      std::any_of(world.elastics.begin(), world.elastics.end(),
                                  [&](const ElasticSolid& b) { return b.name == n.stem; });
    if (!ours) fs::remove(e.path(), ignored);
  }
  // Surface meshes of materials this run does not mesh.
  std::vector<std::string> meshed;
  if (world.scene.output.surface_mesh)
    for (int k : surfaceMaterials(world.scene)) meshed.push_back(world.scene.materials[size_t(k)].name);
  for (const auto& e : fs::directory_iterator(surfacesDir(out_dir), ec)) {
    FrameName n;
    if (!isBodyFile(e.path().filename().string(), n)) continue;
    if (std::find(meshed.begin(), meshed.end(), n.stem) == meshed.end())
      fs::remove(e.path(), ignored);
  }
}

namespace {

constexpr const char* kQualityTag = "+quality:";

// A checkpoint key's scene hash and quality preset ("" for none).
std::pair<std::string, std::string> splitCheckpointKey(const std::string& key) {
  const size_t at = key.find(kQualityTag);
  if (at == std::string::npos) return {key, ""};
  return {key.substr(0, at), key.substr(at + std::string(kQualityTag).size())};
}

std::string qualityLabel(const std::string& q) {
  return q.empty() ? "no --quality (the scene as written)" : "--quality " + q;
}

}  // namespace

std::string checkpointKey(const std::string& scene_hash, const std::string& quality) {
  return quality.empty() ? scene_hash : scene_hash + kQualityTag + quality;
}

std::optional<ResumePoint> resumeFromCheckpoint(const SceneDesc& scene, const std::string& out_dir,
                                                const std::string& key, World& world,
                                                Solver& solver, ParticleShare* share) {
  const auto [scene_hash, quality] = splitCheckpointKey(key);
  for (const auto& [f, path] : listCheckpoints(checkpointDir(out_dir))) {
    try {
      // Read and verify the file; a damaged one is passed over.
      Checkpoint ckpt = readCheckpoint(path, share);
      // A checkpoint of another scene file, or of another quality preset, is
      // refused, not passed over.
      const auto [ckpt_hash, ckpt_quality] = splitCheckpointKey(ckpt.scene_hash);
      if (ckpt_hash == scene_hash && ckpt_quality != quality)
        throw InputError(path, "written under " + qualityLabel(ckpt_quality) + ", this run asks for " +
                                   qualityLabel(quality) +
                                   ": refusing to resume at another resolution. Run with the "
                                   "checkpoint's quality, or without --resume to start over");
      if (ckpt_hash != scene_hash)
        throw InputError(path, "written for a different scene file (" + ckpt_hash +
                                   "; " + scene.source_path + " is now " + scene_hash +
                                   "): refusing to resume. Restore the scene file, or run "
                                   "without --resume to start over");
      if (ckpt.frame < 0 || ckpt.frame > scene.frames.count)
        throw CheckpointError("frame " + std::to_string(ckpt.frame) + " outside 0.." +
                              std::to_string(scene.frames.count));
      // The frame's cache files must be complete too.
      BodyLogs logs;
      const std::string why =
          checkFrameCaches(scene, out_dir, ckpt.frame, world, ckpt.whole_particles, logs);
      if (!why.empty()) throw CheckpointError("its frame's cache is incomplete: " + why);
      ResumePoint rp{ckpt.frame, path, ckpt.record, std::move(logs)};
      restoreCheckpoint(std::move(ckpt), world, solver);
      return rp;
    } catch (const CheckpointError& e) {
      std::fprintf(stderr, "triad: note: %s: not used: %s\n", path.c_str(), e.what());
    }
  }
  return std::nullopt;
}

}  // namespace triad
