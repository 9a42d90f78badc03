#include "app/run_scene.h"

#include <omp.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>

#include "export/atomic_file.h"
#include "export/ply_writer.h"
#include "export/run_record.h"
#include "import/scene_loader.h"
#include "sim/errors.h"
#include "sim/solver.h"
#include "sim/world.h"

namespace triad {

namespace {

std::string frameName(const std::string& dir, const char* stem, int frame, const char* ext) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), ".%04d.", frame);
  return dir + "/" + stem + buf + ext;
}

void printSummary(const RunRecord& rec, const std::string& out_dir) {
  std::printf("%s: %zu particles, %d frames, %lld substeps, dt %.3g .. %.3g s\n",
              rec.scene_name.c_str(), rec.particles, rec.frames_written - 1,
              static_cast<long long>(rec.steps), rec.dt_min, rec.dt_max);
  std::printf("wall time %.2f s:", rec.wall_seconds);
  for (const auto& [name, s] : rec.phase_seconds) std::printf(" %s %.2f", name.c_str(), s);
  const double solve = rec.phase_seconds.count("solve") ? rec.phase_seconds.at("solve") : 0.0;
  std::printf("\n%.3g particle-substeps/s on %d threads, peak memory %.1f MiB\n",
              solve > 0 ? double(rec.particle_steps) / solve : 0.0, rec.threads,
              double(rec.peak_rss_bytes) / (1024.0 * 1024.0));
  std::printf("cache: %s\n", out_dir.c_str());
}

}  // namespace

std::string particlesPath(const std::string& out_dir, int frame) {
  return frameName(out_dir + "/particles", "particles", frame, "ply");
}

std::string runRecordPath(const std::string& out_dir) { return out_dir + "/run.json"; }

int runScene(const RunOptions& options) {
  const double t_start = omp_get_wtime();
  if (options.threads > 0) omp_set_num_threads(options.threads);
  RunRecord rec;
  rec.started_utc = utcNow();
  rec.threads = omp_get_max_threads();

  // Load and build everything before any simulation work: bad input exits 2.
  SceneDesc scene;
  World world;
  std::string out_dir;
  try {
    scene = loadScene(options.scene_path);
    world = buildWorld(scene);
    out_dir = options.out_dir.empty() ? scene.output.dir : options.out_dir;
    try {
      makeDirectories(out_dir + "/particles");
    } catch (const std::exception& e) {
      throw InputError(options.out_dir.empty() ? scene.source_path + ": output.dir" : "--out",
                       e.what());
    }
  } catch (const InputError& e) {
    std::fprintf(stderr, "triad: error: %s\n", e.what());
    return kExitBadInput;
  }
  if (scene.output.vdb || scene.output.png)
    std::fprintf(stderr,
                 "triad: note: VDB volumes and PNG previews are not written yet; writing PLY "
                 "particle caches and run.json\n");

  rec.scene_name = scene.name;
  rec.scene_path = scene.source_path;
  rec.scene_hash = hashFile(scene.source_path);
  rec.particles = world.particleCount();
  for (size_t i = 0; i < scene.objects.size(); ++i)
    rec.object_particles.emplace_back(scene.objects[i].name, world.object_particles[i]);
  rec.frames_requested = scene.frames.count;

  Solver solver(world);
  // Testing aid (tests/test_cli.cpp): force a blow-up at a given substep.
  if (const char* fault = std::getenv("TRIAD_FAULT_STEP")) solver.injectFaultAtStep(std::atoll(fault));
  double output_seconds = 0.0;
  auto record = [&](bool finished, const std::string& error) {
    const PhaseTimes& t = solver.phaseTimes();
    rec.phase_seconds = {{"bin", t.bin},   {"stress", t.stress}, {"p2g", t.p2g},
                         {"grid", t.grid}, {"g2p", t.g2p},       {"solve", t.total()},
                         {"output", output_seconds}};
    rec.simulated_time = world.time;
    rec.steps = solver.record().steps;
    rec.dt_min = solver.record().dt_min;
    rec.dt_max = solver.record().dt_max;
    rec.particle_steps = solver.record().particle_steps;
    rec.wall_seconds = omp_get_wtime() - t_start;
    rec.peak_rss_bytes = peakResidentBytes();
    rec.particle_bytes = world.particleBytes();
    rec.grid_bytes = solver.bytes();
    rec.finished = finished;
    rec.error = error;
    rec.ended_utc = utcNow();
    writeRunRecord(runRecordPath(out_dir), rec);
  };
  auto writeFrame = [&](int frame) {
    const double t0 = omp_get_wtime();
    if (scene.output.ply) writeParticlesPly(particlesPath(out_dir, frame), world);
    rec.frames_written = frame + 1;
    output_seconds += omp_get_wtime() - t0;
    record(false, "");
  };

  const int frames = scene.frames.count;
  Progress progress(options.progress, frames, frames / scene.frames.fps);
  int frame = 0;
  try {
    writeFrame(0);
    for (frame = 1; frame <= frames; ++frame) {
      const double t_frame = frame / scene.frames.fps;
      solver.advanceTo(t_frame, [&](double dt) {
        progress.step(frame, world.steps, world.time, dt);
      });
      writeFrame(frame);
      progress.frameDone(frame, world.steps, world.time);
    }
  } catch (const std::exception& e) {
    progress.finish();
    const bool sim = dynamic_cast<const SimulationError*>(&e) != nullptr;
    const std::string msg = std::string(sim ? "simulation failed in frame " : "failed in frame ") +
                            std::to_string(frame) + ": " + e.what();
    std::fprintf(stderr, "triad: error: %s\n", msg.c_str());
    std::fprintf(stderr, "triad: frames 0..%d are complete in %s\n", rec.frames_written - 1,
                 out_dir.c_str());
    try {
      record(false, msg);
    } catch (const std::exception& e2) {
      std::fprintf(stderr, "triad: error: %s\n", e2.what());
    }
    return kExitRunFailed;
  }
  progress.finish();
  try {
    record(true, "");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "triad: error: %s\n", e.what());
    return kExitRunFailed;
  }
  printSummary(rec, out_dir);
  return kExitOk;
}

}  // namespace triad
