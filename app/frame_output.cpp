#include "app/frame_output.h"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>

#include "app/run_scene.h"
#include "export/atomic_file.h"
#include "export/ply_writer.h"
#include "export/vdb_writer.h"
#include "sim/errors.h"

namespace triad {

namespace {

namespace fs = std::filesystem;

std::string frameName(const std::string& dir, const char* stem, int frame, const char* ext) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), ".%04d.", frame);
  return dir + "/" + stem + buf + ext;
}

// A particle cache is complete when its size is the header's plus the
// vertex count times the record size the header declares (36 bytes).
std::string checkParticlesPly(const std::string& path, size_t particles) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return "missing";
  std::string line, header;
  size_t vertices = 0;
  bool found = false;
  while (std::getline(in, line) && header.size() < 4096) {
    header += line + "\n";
    std::istringstream words(line);
    std::string a, b;
    words >> a >> b;
    if (a == "element" && b == "vertex") words >> vertices;
    if (line == "end_header") {
      found = true;
      break;
    }
  }
  if (!found) return "no PLY header";
  if (vertices != particles)
    return std::to_string(vertices) + " particles, the scene has " + std::to_string(particles);
  std::error_code ec;
  const auto size = fs::file_size(path, ec);
  if (ec || size != header.size() + vertices * 36) return "truncated";
  return "";
}

// What is wrong with the frame's cache files (empty when they are complete).
std::string checkFrameCaches(const SceneDesc& scene, const std::string& out_dir, int frame,
                             size_t particles) {
  if (scene.output.ply) {
    const std::string p = particlesPath(out_dir, frame);
    const std::string why = checkParticlesPly(p, particles);
    if (!why.empty()) return p + ": " + why;
  }
  if (scene.output.vdb) {
    const std::string p = volumesPath(out_dir, frame);
    const std::string why = fs::exists(p) ? checkVolumesVdb(p) : "missing";
    if (!why.empty()) return p + ": " + why;
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

std::string checkpointPath(const std::string& out_dir, int frame) {
  return frameName(checkpointDir(out_dir), "state", frame, "bin");
}

void makeOutputDirectories(const SceneDesc& scene, const std::string& out_dir) {
  makeDirectories(out_dir);
  if (scene.output.ply) makeDirectories(out_dir + "/particles");
  if (scene.output.vdb) makeDirectories(out_dir + "/volumes");
  if (scene.output.checkpoints) makeDirectories(checkpointDir(out_dir));
}

void writeFrameCaches(const SceneDesc& scene, const std::string& out_dir, const World& world,
                      int frame) {
  if (scene.output.ply) writeParticlesPly(particlesPath(out_dir, frame), world);
  if (scene.output.vdb) {
    VdbFrameInfo info;
    info.frame = frame;
    info.time = world.time;
    info.scene_name = scene.name;
    info.voxel_size = scene.output.vdb_voxel_size > 0 ? scene.output.vdb_voxel_size
                                                      : scene.domain.dx;
    info.surface = scene.output.vdb_surface;
    writeVolumesVdb(volumesPath(out_dir, frame), world, info);
  }
}

void writeFrameCheckpoint(const std::string& out_dir, int frame, const std::string& scene_hash,
                          const World& world, const Solver& solver, const StepRecord& record) {
  writeCheckpoint(checkpointPath(out_dir, frame), frame, scene_hash, world, solver, record);
  // Keep this one and the one before (the fallback if this one is damaged).
  for (const auto& [f, path] : listCheckpoints(checkpointDir(out_dir))) {
    if (f == frame || f == frame - 1) continue;
    std::error_code ignored;
    fs::remove(path, ignored);
  }
}

void removeStaleTemporaries(const std::string& out_dir) {
  static const std::regex tmp(R"(.+\.tmp\d+)");
  for (const std::string& dir : {out_dir, out_dir + "/particles", out_dir + "/volumes",
                                 out_dir + "/preview", checkpointDir(out_dir)}) {
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(dir, ec)) {
      std::error_code ignored;
      if (e.is_regular_file(ignored) && std::regex_match(e.path().filename().string(), tmp))
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
  static const std::regex frame_file(R"((particles|density|preview)\.(\d{4,})\.(ply|vdb|png))");
  for (const std::string& dir : {out_dir + "/particles", out_dir + "/volumes", out_dir + "/preview"}) {
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(dir, ec)) {
      std::smatch m;
      const std::string name = e.path().filename().string();
      if (!std::regex_match(name, m, frame_file) || std::stoi(m[2].str()) <= last_frame) continue;
      std::error_code ignored;
      fs::remove(e.path(), ignored);
    }
  }
}

std::optional<ResumePoint> resumeFromCheckpoint(const SceneDesc& scene, const std::string& out_dir,
                                                const std::string& scene_hash, World& world,
                                                Solver& solver) {
  for (const auto& [f, path] : listCheckpoints(checkpointDir(out_dir))) {
    try {
      // Read and verify the file; a damaged one is passed over.
      Checkpoint ckpt = readCheckpoint(path);
      // A checkpoint of another scene file is refused, not passed over.
      if (ckpt.scene_hash != scene_hash)
        throw InputError(path, "written for a different scene file (" + ckpt.scene_hash +
                                   "; " + scene.source_path + " is now " + scene_hash +
                                   "): refusing to resume. Restore the scene file, or run "
                                   "without --resume to start over");
      if (ckpt.frame < 0 || ckpt.frame > scene.frames.count)
        throw CheckpointError("frame " + std::to_string(ckpt.frame) + " outside 0.." +
                              std::to_string(scene.frames.count));
      // The frame's cache files must be complete too.
      const std::string why = checkFrameCaches(scene, out_dir, ckpt.frame, world.particleCount());
      if (!why.empty()) throw CheckpointError("its frame's cache is incomplete: " + why);
      ResumePoint rp{ckpt.frame, path, ckpt.record};
      restoreCheckpoint(std::move(ckpt), world, solver);
      return rp;
    } catch (const CheckpointError& e) {
      std::fprintf(stderr, "triad: note: %s: not used: %s\n", path.c_str(), e.what());
    }
  }
  return std::nullopt;
}

}  // namespace triad
