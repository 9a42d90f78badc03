#include "app/run_scene.h"

#include <omp.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "app/frame_output.h"
#include "app/interrupt.h"
#include "app/output_thread.h"
#include "app/rate_probe.h"
#include "app/run_split.h"
#include "export/atomic_file.h"
#include "export/run_record.h"
#include "import/estimate.h"
#include "import/mesh_sampler.h"
#include "import/quality.h"
#include "import/scene_loader.h"
#include "render/preview_writer.h"
#include "sim/errors.h"
#include "sim/solver.h"
#include "sim/world.h"

namespace triad {

namespace {

void printSummary(const RunRecord& rec, const std::string& out_dir) {
  std::printf("%s: %zu particles, %d frames, %lld substeps, dt %.3g .. %.3g s\n",
              rec.scene_name.c_str(), rec.particles, rec.frames_written - 1,
              static_cast<long long>(rec.steps), rec.dt_min, rec.dt_max);
  std::printf("wall time %.2f s:", rec.wall_seconds);
  for (const auto& [name, s] : rec.phase_seconds) std::printf(" %s %.2f", name.c_str(), s);
  const double solve = rec.phase_seconds.count("solve") ? rec.phase_seconds.at("solve") : 0.0;
  if (!rec.solids_seconds.empty()) {
    std::printf("\nsolids by part:");
    for (const auto& [name, s] : rec.solids_seconds)
      if (s > 0.0) std::printf(" %s %.2f", name.c_str(), s);
  }
  std::printf("\n%.3g particle-substeps/s on %d threads, peak memory %.1f MiB\n",
              solve > 0 ? double(rec.particle_steps) / solve : 0.0, rec.threads,
              double(rec.peak_rss_bytes) / (1024.0 * 1024.0));
  std::printf("estimated before the run: %.3g s solving (%s rate)\n", rec.estimated_wall_seconds,
              rec.rate_from.c_str());
  std::printf("cache: %s\n", out_dir.c_str());
}

}  // namespace

std::string runRecordPath(const std::string& out_dir) { return out_dir + "/run.json"; }

int runScene(const RunOptions& options_in) {
  const double t_start = omp_get_wtime();
  // Under mpirun, one of several processes: process 0 speaks and writes.
  std::unique_ptr<RunSplit> split_owner;
  try {
    split_owner = std::make_unique<RunSplit>();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "triad: error: %s\n", e.what());
    return kExitBadInput;
  }
  RunSplit& split = *split_owner;
  RunOptions options = options_in;
  if (!split.root()) {
    options.progress = ProgressMode::Quiet;
    options.no_probe = true;
  }
  if (options.threads > 0) omp_set_num_threads(options.threads);
  if (!options.quality.empty() && !findQualityPreset(options.quality)) {
    std::fprintf(stderr, "triad: error: --quality: expected one of %s, got \"%s\"\n",
                 qualityPresetNames().c_str(), options.quality.c_str());
    return kExitBadInput;
  }
  RunRecord rec;
  rec.started_utc = utcNow();
  rec.threads = omp_get_max_threads();
  const char* policy = std::getenv("OMP_WAIT_POLICY");
  rec.omp_wait_policy = policy ? policy : "";
  const char* spin = std::getenv("GOMP_SPINCOUNT");
  rec.omp_spin_count = spin ? spin : "";

  // Load and build everything before any simulation work: bad input exits 2.
  SceneDesc scene;
  World world;
  std::string out_dir;
  // One cache for the run: a mesh used twice is loaded and voxelized once.
  auto mesh_cache = std::make_shared<MeshCache>();
  bool copy_fits = true;     // room for a frame's copy (estimate)
  double copy_bytes = 0.0;
  auto printMeshWarnings = [&]() {
    for (const MeshWarning& w : mesh_cache->warnings())
      std::fprintf(stderr, "triad: warning: %s: %s\n", w.file.c_str(), w.text.c_str());
  };
  try {
    scene = loadScene(options.scene_path);
    if (!options.quality.empty()) applyQuality(scene, options.quality);
    // What the run will need, before anything is sampled: a scene that
    // cannot fit is refused, an extreme one said so at once.
    SceneEstimate estimate = estimateScene(scene);
    requireFits(scene, estimate);
    copy_fits = overlapFits(estimate);
    copy_bytes = estimate.output_copy_bytes;
    // This machine's rate for the scene, from a coarser copy stepped a
    // moment: the estimate's wall time, in run.json and said at once.
    RateProbe rate;
    rate.why_not = "--no-probe";
    if (!options.no_probe) rate = probeRate(scene, estimate);
    applyRate(estimate, rate);
    rec.estimated_wall_seconds = estimate.wall_seconds;
    rec.estimated_rate = estimate.rate;
    rec.rate_from = rate.ran ? "probe" : "fixed";
    rec.probe_seconds = rate.ran ? rate.seconds : 0.0;
    if (options.progress != ProgressMode::Quiet)
      std::fprintf(stderr, "triad: estimate: about %.3g s solving, at %.3g particle-substeps/s (%s)\n",
                   estimate.wall_seconds, estimate.rate,
                   rate.ran ? "measured here by a probe" : ("fixed rate; " + rate.why_not).c_str());
    for (const std::string& w : extremeWarnings(scene, estimate))
      std::fprintf(stderr, "triad: warning: %s\n", w.c_str());
    // Split over processes, each builds only its share of the particles.
    world = buildSceneWorld(scene, mesh_cache, split.share(scene));
    if (split.root()) printMeshWarnings();
    out_dir = options.out_dir.empty() ? scene.output.dir : options.out_dir;
    try {
      if (split.root()) makeOutputDirectories(scene, out_dir);
    } catch (const std::exception& e) {
      throw InputError(options.out_dir.empty() ? scene.source_path + ": output.dir" : "--out",
                       e.what());
    }
  } catch (const InputError& e) {
    if (split.root()) {
      printMeshWarnings();
      std::fprintf(stderr, "triad: error: %s\n", e.what());
    }
    return kExitBadInput;
  }
  // Frames are written on a thread of their own while the next one steps,
  // from a copy of the world, one frame in flight; without room for the
  // copy (or with --no-overlap), each frame before the solver steps on.
  const bool overlap = !options.no_overlap && copy_fits;
  if (!options.no_overlap && !copy_fits && options.progress != ProgressMode::Quiet)
    std::fprintf(stderr,
                 "triad: note: no room for a frame's copy (about %.3g MiB): each frame is written "
                 "before the next steps\n",
                 copy_bytes / (1024.0 * 1024.0));
  // The writer needs a core while it works. With a solver thread on every
  // core, one of them would share its core with the writer, and each of the
  // step's barriers would wait for that thread's next time slice: a draft
  // run's solve took 1.7 times as long. So while a frame is being written
  // the solver steps with one thread fewer (results do not depend on the
  // thread count), and llvmpipe rasterises on the writer's thread alone
  // (its own threads, one per core, took the solver's cores too: the
  // default scene's run is 2-5% shorter without them) unless LP_NUM_THREADS
  // says otherwise; it reads that when the context below is made.
  const int solver_threads = omp_get_max_threads();
  const bool yield_core = overlap && solver_threads > 1 && solver_threads >= omp_get_num_procs();
  if (yield_core) setenv("LP_NUM_THREADS", "0", /*overwrite=*/0);

  // The preview renderer keeps one OSMesa context for the whole run. Made
  // before the writer, so that the writer's thread ends before it goes.
  // Split over processes, every process draws its own particles and
  // process 0 composites them; previews of surfaces draw no particles, and
  // process 0 draws the surfaces made in parts.
  std::unique_ptr<render::PreviewWriter> preview;
  std::unique_ptr<render::PreviewRenderer> layers;
  const bool composited_previews =
      split.active() && scene.output.png && scene.render.style != RenderStyle::Surface;
  if (scene.output.png && (split.root() || composited_previews)) {
    try {
      if (split.root())
        preview = std::make_unique<render::PreviewWriter>(scene, out_dir);
      else
        layers = std::make_unique<render::PreviewRenderer>(render::previewSettingsForScene(scene));
    } catch (const std::exception& e) {
      std::fprintf(stderr, "triad: error: %spreviews: %s\n",
                   split.active() ? ("process " + std::to_string(split.rank()) + ": ").c_str() : "",
                   e.what());
      split.abort(kExitRunFailed);
    }
  }

  OutputThread output(overlap);
  rec.output_overlap = overlap;
  if (yield_core) rec.threads_while_writing = solver_threads - 1;
  uint64_t steps_while_writing = 0;
  auto shareCores = [&]() {
    if (yield_core) omp_set_num_threads(output.busy() ? solver_threads - 1 : solver_threads);
  };

  rec.scene_name = scene.name;
  rec.scene_path = scene.source_path;
  // The scene file's bytes, and every mesh sequence's: a checkpoint is
  // refused when a frame of a deforming collider has changed.
  std::vector<std::string> hashed{scene.source_path};
  for (const ObjectDesc& o : scene.objects)
    if (const auto* m = std::get_if<MeshDesc>(&o.shape); m && m->sequence_digits > 0)
      for (int f = 0; f <= scene.frames.count; ++f)
        hashed.push_back(sequenceFrame(m->resolved_path, m->sequence_digits, f));
  rec.scene_hash = hashFiles(hashed);
  rec.quality = options.quality;
  rec.dx = scene.domain.dx;
  rec.particles_per_cell = scene.solver.particles_per_cell;
  rec.cfl = scene.solver.cfl;
  rec.transfer = transferName(scene.solver.transfer);
  rec.solver = solverSettings(scene.solver).dump();
  // Checkpoints are tied to the scene file and to the quality preset: a
  // checkpoint of another resolution cannot continue this run.
  const std::string checkpoint_key = checkpointKey(rec.scene_hash, options.quality);
  rec.particles = world.whole_particles;
  for (size_t i = 0; i < scene.objects.size(); ++i)
    rec.object_particles.emplace_back(scene.objects[i].name, world.object_particles[i]);
  rec.bodies = world.bodies.size();
  rec.frames_requested = scene.frames.count;
  rec.fps = scene.frames.fps;
  for (int m : surfaceMaterials(scene))
    rec.material_density.emplace_back(scene.materials[size_t(m)].name,
                                      scene.materials[size_t(m)].density);
  rec.domain_min = scene.domain.min;
  rec.domain_max = scene.domain.max;

  Solver solver(world);
  // Testing aid (tests/test_cli.cpp): force a blow-up at a given substep.
  if (const char* fault = std::getenv("TRIAD_FAULT_STEP")) solver.injectFaultAtStep(std::atoll(fault));

  // Resume from the newest usable checkpoint, or start over without stale ones.
  int start_frame = 0;
  int resumed_from = -1;
  StepRecord before;  // step statistics of the run before it was resumed
  BodyLogs body_logs;  // bodies/rigid_states.csv and forces.csv: rows of the frames written
  try {
    if (split.root()) {
      removeStaleTemporaries(out_dir);
      removeFramesAfter(out_dir, scene.frames.count);
      removeOtherBodies(out_dir, world);
    }
    split.barrier();  // the others read the folder only once it is tidied
    if (options.resume) {
      if (auto rp = resumeFromCheckpoint(scene, out_dir, checkpoint_key, world, solver,
                                         split.share(scene))) {
        start_frame = resumed_from = rp->frame;
        before = rp->record;
        body_logs = std::move(rp->logs);
        if (split.root())
          std::fprintf(stderr, "triad: resuming after frame %d from %s\n", rp->frame,
                       rp->checkpoint.c_str());
      } else if (split.root()) {
        std::fprintf(stderr, "triad: note: no usable checkpoint in %s: starting from frame 0\n",
                     checkpointDir(out_dir).c_str());
      }
    } else if (split.root()) {
      removeCheckpoints(out_dir);
    }
  } catch (const InputError& e) {
    if (split.root()) std::fprintf(stderr, "triad: error: %s\n", e.what());
    return kExitBadInput;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "triad: error: %s\n", e.what());
    split.abort(kExitRunFailed);
  }
  // Every process has read the same checkpoint (or none): each keeps its
  // share of the particles from here on. Only process 0 counts the steps
  // before a resume, so that their sum is the run's.
  split.barrier();
  split.attach(world, solver, options.balance == "work");
  split.checkSharedFolder(out_dir);
  if (!split.root()) {
    before = StepRecord{};
    // A checkpoint holds the sinks' whole counts, which process 0 keeps.
    for (Sink& sink : world.sinks) sink.removed = 0;
  }
  rec.frames_written = resumed_from + 1;  // frames 0..resumed_from are on disk
  rec.resume = options.resume;
  rec.resumed_from_frame = resumed_from;

  // Step statistics of the whole run, across a resume.
  auto runSteps = [&]() {
    const StepRecord& now = solver.record();
    StepRecord all = before;
    all.steps += now.steps;
    all.particle_steps += now.particle_steps;
    all.sleeping_steps += now.sleeping_steps;
    if (now.steps > 0) {
      all.dt_min = before.steps > 0 ? std::min(before.dt_min, now.dt_min) : now.dt_min;
      all.dt_max = std::max(before.dt_max, now.dt_max);
    }
    return all;
  };

  // What run.json says of the simulation, taken on the solver's thread at a
  // frame's end: the writer records it while the next frame steps.
  struct SimState {
    PhaseTimes times;
    StepRecord steps;
    size_t particles = 0;
    std::vector<std::pair<std::string, uint64_t>> emitted, removed;
    double time = 0.0;
    size_t particle_bytes = 0, grid_bytes = 0;
    uint64_t steps_while_writing = 0;
  };
  auto simState = [&]() {
    SimState s;
    s.times = solver.phaseTimes();
    s.steps = runSteps();
    s.particles = world.particleCount();
    for (const Source& src : world.sources) s.emitted.emplace_back(src.name, src.emitted);
    for (const Sink& sink : world.sinks) s.removed.emplace_back(sink.name, sink.removed);
    if (split.active()) {
      // Every process's share (a collective: all processes call this together).
      s.particles = size_t(split.sum(double(s.particles)));
      s.steps.particle_steps = uint64_t(split.sum(double(s.steps.particle_steps)));
      s.steps.sleeping_steps = uint64_t(split.sum(double(s.steps.sleeping_steps)));
      // Each process's sinks remove its own particles; sources make the
      // same count on every process.
      for (auto& [name, n] : s.removed) n = uint64_t(split.sum(double(n)));
      // From here process 0 holds the whole count and the others start
      // again from none: the sum stays the run's, and process 0's world
      // (which the checkpoint takes) holds all of it.
      for (size_t k = 0; k < world.sinks.size(); ++k)
        world.sinks[k].removed = split.root() ? s.removed[k].second : 0;
    }
    s.time = world.time;
    s.steps_while_writing = steps_while_writing;
    s.particle_bytes = world.particleBytes();
    s.grid_bytes = solver.bytes();
    return s;
  };
  // Seconds the solver waited for output (copying a frame, waiting for the
  // frame before it to be written, or writing it where frames do not overlap).
  double output_seconds = 0.0;
  auto record = [&](const SimState& sim, bool finished, const std::string& error) {
    const PhaseTimes& t = sim.times;
    rec.phase_seconds = {{"bin", t.bin},
                         {"p2g", t.p2g},
                         {"grid", t.grid},
                         {"g2p", t.g2p},
                         {"solids", t.solids},
                         {"shot", t.shot},
                         {"solve", t.total()},
                         {"output", output_seconds},
                         {"writing", output.busySeconds()}};
    rec.solids_seconds.clear();
    if (t.solids > 0.0)
      for (const auto& [name, s] : t.solid_parts.parts()) rec.solids_seconds.emplace_back(name, s);
    rec.particles = sim.particles;
    rec.emitted = sim.emitted;
    rec.removed = sim.removed;
    rec.simulated_time = sim.time;
    rec.steps = sim.steps.steps;
    rec.dt_min = sim.steps.dt_min;
    rec.dt_max = sim.steps.dt_max;
    rec.particle_steps = sim.steps.particle_steps;
    rec.sleeping_steps = sim.steps.sleeping_steps;
    rec.steps_while_writing = sim.steps_while_writing;
    rec.wall_seconds = omp_get_wtime() - t_start;
    rec.peak_rss_bytes = peakResidentBytes();
    rec.particle_bytes = sim.particle_bytes;
    rec.grid_bytes = sim.grid_bytes;
    rec.finished = finished;
    rec.error = error;
    rec.ended_utc = utcNow();
    if (split.root()) writeRunRecord(runRecordPath(out_dir), rec);
  };

  // Everything a frame writes, in this order: the cache files, then the
  // checkpoint (its presence means the frame is complete), then run.json.
  // `w` is the world at the frame's end: a copy when frames overlap.
  auto writeFrameFiles = [&](const World& w, int frame, const SimState& sim,
                             const std::vector<BodyLoad>& loads, const SolverState& solver_state,
                             const SharedWrites& shared) {
    // Particles (PLY), volumes (VDB), rigid body meshes and states.
    const auto surfaces = writeFrameCaches(scene, out_dir, w, frame, shared);
    writeFrameBodies(out_dir, w, frame, body_logs, loads);
    // The preview render (rigid bodies drawn as meshes; with render.style
    // "surface" the materials' surfaces instead of their particles).
    if (preview && shared.preview) {
      preview->writeImage(frame, *shared.preview);
    } else if (preview) {
      const bool surface_style = scene.render.style == RenderStyle::Surface;
      std::vector<render::PreviewMesh> meshes;
      for (const auto& [m, mesh] : surfaces)
        for (const render::LegendEntry& e : preview->settings().surfaces)
          if (surface_style && e.label == scene.materials[size_t(m)].name) {
            render::PreviewMesh pm = render::previewMesh(mesh, -1);
            pm.color = e.color;
            meshes.push_back(std::move(pm));
          }
      preview->writeFrame(w, frame, meshes, !surface_style);
    }
    // The checkpoint, last: --resume trusts every file of a checkpointed frame.
    if (scene.output.checkpoints)
      writeFrameCheckpoint(out_dir, frame, checkpoint_key, w, solver_state, sim.steps,
                           shared.checkpoint);
    rec.frames_written = frame + 1;
    record(sim, false, "");
  };
  // Split over processes: which files every process writes its particles
  // into, and what process 0 gathers of every particle for the rest.
  const bool shared_files = split.active() && split.sharedFiles();
  const bool shared_volumes = split.active() && scene.output.vdb;
  const RunSplit::Gather gather = split.planOutput(scene.output, rec);
  // Split over processes, the level sets every process makes its part of:
  // each material's that surfaces are made of, and the volumes' (-1).
  std::vector<int> split_surfaces;
  if (split.active()) {
    if (scene.output.surface_mesh ||
        (scene.output.png && scene.render.style == RenderStyle::Surface))
      split_surfaces = surfaceMaterials(scene);
    if (scene.output.vdb && scene.output.vdb_surface) split_surfaces.push_back(-1);
  }
  const double vdb_voxel =
      scene.output.vdb_voxel_size > 0 ? scene.output.vdb_voxel_size : scene.domain.dx;
  auto writeFrame = [&](int frame) {
    const double t0 = omp_get_wtime();
    SimState sim = simState();
    // Split over processes on a file system they share, every process
    // writes its own particles into the frame's particle cache and
    // checkpoint, under temporary names that process 0 renames into place
    // with the frame's other files.
    SharedWrites shared;
    RunSplit::SharedParticles written;
    // The checkpoint holds the whole world's solver state.
    if (split.active() && scene.output.checkpoints) solver.gatherState();
    try {
      if (shared_files && (scene.output.ply || scene.output.vtk))
        split.writeParticlesShared(scene.output.ply ? particlesPath(out_dir, frame) : "",
                                   scene.output.vtk ? vtkParticlesPath(out_dir, frame) : "", world,
                                   written);
      if (shared_files && scene.output.checkpoints)
        shared.checkpoint =
            split.writeCheckpointShared(checkpointPath(out_dir, frame), frame, checkpoint_key,
                                        world, solver.state(), sim.steps);
    } catch (const std::exception&) {
      // The frame's files go into place together or not at all: process 0
      // removes those its processes wrote before the one that failed.
      if (split.root()) removeTemporaries({written.ply, written.vtp});
      throw;
    }
    shared.particles = written.ply;
    shared.vtk_particles = written.vtp;
    if (shared_volumes) {
      auto volumes = std::make_shared<SharedWrites::Volumes>();
      volumes->sums = split.splatVolumesShared(world, vdb_voxel, volumes->scale);
      shared.volumes = std::move(volumes);
    }
    if (!split_surfaces.empty())
      shared.surfaces = std::make_shared<const std::map<int, LevelSetParts>>(
          split.surfaceParts(world, split_surfaces, vdb_voxel));
    if (composited_previews)
      shared.preview = std::make_shared<const render::Image>(
          split.renderPreview(split.root() ? preview->renderer() : *layers, world));
    // The frame's state; the world itself is copied only when the solver
    // steps on while it is written. Split over processes, process 0 gathers
    // every particle into a copy of its own where an output needs them all,
    // and alone writes.
    std::shared_ptr<const World> w =
        split.active() ? split.gather(world, gather)
        : overlap      ? std::make_shared<const World>(world)
                       : std::shared_ptr<const World>(&world, [](const World*) {});
    split.record(rec, world);
    if (!split.root()) return;
    std::vector<BodyLoad> loads = solver.bodyLoads();
    const SolverState solver_state = solver.state();
    output.submit([&writeFrameFiles, w, frame, sim = std::move(sim), loads = std::move(loads),
                   solver_state, shared]() {
      try {
        writeFrameFiles(*w, frame, sim, loads, solver_state, shared);
      } catch (const std::exception& e) {
        throw std::runtime_error("writing frame " + std::to_string(frame) + ": " + e.what());
      }
    });
    output_seconds += omp_get_wtime() - t0;
  };
  // Waits for the frame in flight before the record is read or written
  // here; a failure to write it was already reported where it surfaced.
  auto drainOutput = [&]() {
    try {
      output.wait();
    } catch (const std::exception& e) {
      std::fprintf(stderr, "triad: error: %s\n", e.what());
    }
  };

  const int frames = scene.frames.count;
  Progress progress(options.progress, frames, frames / scene.frames.fps);
  int frame = start_frame;
  // SIGINT / SIGTERM: stop at the next step boundary (below).
  struct Interrupted {
    int sig;
  };
  InterruptGuard interrupt_guard;
  // Split over processes, all of them stop at the same step.
  auto checkInterrupt = [&split] {
    if (const int sig = split.anyInterrupt(pendingInterrupt())) throw Interrupted{sig};
  };
  try {
    if (resumed_from < 0) writeFrame(0);
    for (frame = start_frame + 1; frame <= frames; ++frame) {
      checkInterrupt();
      const double t_frame = frame / scene.frames.fps;
      solver.resetLoads();
      shareCores();
      solver.advanceTo(t_frame, [&](double dt) {
        if (omp_get_max_threads() < solver_threads) ++steps_while_writing;
        shareCores();
        progress.step(frame, world.steps, world.time, dt);
        checkInterrupt();
      });
      split.rebalance(world);  // the split follows the material
      writeFrame(frame);
      progress.frameDone(frame, world.steps, world.time);
    }
    const double t_wait = omp_get_wtime();
    output.wait();
    output_seconds += omp_get_wtime() - t_wait;
  } catch (const Interrupted& stop) {
    // Every complete frame and its checkpoint stay (the one being written
    // is finished first); the frame in progress is dropped (no file of it
    // was written).
    drainOutput();
    progress.finish();
    const SimState stopped = simState();  // every process stops here together
    if (!split.root()) return interruptedExitStatus(stop.sig);
    const std::string why = "interrupted by " + signalName(stop.sig) + " in frame " +
                            std::to_string(frame) + " at t = " + std::to_string(world.time) + " s";
    std::fprintf(stderr, "triad: %s: frames 0..%d are complete in %s\n", why.c_str(),
                 rec.frames_written - 1, out_dir.c_str());
    if (scene.output.checkpoints) {
      auto quote = [](const std::string& a) {
        return a.find_first_of(" \t'\"$\\") == std::string::npos ? a : "'" + a + "'";
      };
      std::string cmd = "triad run " + quote(options.scene_path) + " --out " + quote(out_dir);
      if (!options.quality.empty()) cmd += " --quality " + options.quality;
      std::fprintf(stderr, "triad: to continue after frame %d: %s --resume\n",
                   rec.frames_written - 1, cmd.c_str());
    } else {
      std::fprintf(stderr, "triad: note: output.checkpoints is false: a rerun starts over\n");
    }
    rec.interrupted_by = signalName(stop.sig);
    rec.interrupted_frame = frame;
    try {
      record(stopped, false, why);
    } catch (const std::exception& e2) {
      std::fprintf(stderr, "triad: error: %s\n", e2.what());
    }
    return interruptedExitStatus(stop.sig);
  } catch (const std::exception& e) {
    drainOutput();
    progress.finish();
    const bool sim = dynamic_cast<const SimulationError*>(&e) != nullptr;
    // A failure every process met together process 0 alone reports; the
    // others end quietly (none waits in an exchange). Any other failure
    // of a process ends every process at once.
    const bool together = dynamic_cast<const SplitFailure*>(&e) != nullptr;
    if (split.active() && !split.root() && together) return kExitRunFailed;
    const std::string msg = std::string(sim ? "simulation failed in frame " : "failed in frame ") +
                            std::to_string(frame) + ": " + e.what();
    std::fprintf(stderr, "triad: error: %s%s\n",
                 split.active() && !together
                     ? ("process " + std::to_string(split.rank()) + ": ").c_str()
                     : "",
                 msg.c_str());
    if (split.active() && !split.root()) split.abort(kExitRunFailed);
    std::fprintf(stderr, "triad: frames 0..%d are complete in %s\n", rec.frames_written - 1,
                 out_dir.c_str());
    try {
      // Split, the other processes may wait in an exchange: no collective here.
      // Steps are the same on every process; the particle counts stay those
      // of the last frame written.
      if (split.active()) {
        SimState local;
        local.times = solver.phaseTimes();
        local.steps = runSteps();
        local.steps.particle_steps = rec.particle_steps;
        local.particles = rec.particles;
        local.emitted = rec.emitted;
        local.removed = rec.removed;
        local.time = world.time;
        record(local, false, msg);
      } else {
        record(simState(), false, msg);
      }
    } catch (const std::exception& e2) {
      std::fprintf(stderr, "triad: error: %s\n", e2.what());
    }
    // Others may wait in an exchange: end them, unless every process met
    // the failure and ends on its own.
    if (split.active() && !together) split.abort(kExitRunFailed);
    return kExitRunFailed;
  }
  progress.finish();
  try {
    if (preview) output_seconds += preview->finish();  // the contact sheet
    const SimState last = simState();
    if (!split.root()) return kExitOk;
    record(last, true, "");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "triad: error: %s\n", e.what());
    return kExitRunFailed;
  }
  printSummary(rec, out_dir);
  return kExitOk;
}

}  // namespace triad
