// The `triad` command line: a thin layer over the pipeline in app/.
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <cstdlib>
#include <string>

#include "app/check_scene.h"
#include "app/compare_caches.h"
#include "app/render_cache.h"
#include "app/run_scene.h"

int main(int argc, char** argv) {
  // OpenMP threads that spin at barriers starve each other on a machine
  // whose cores are busy (a run six times slower beside one compile):
  // unless the user chose a wait policy, run with threads that sleep
  // (5% slower on an idle machine, bench/RESULTS.md). A short spin before
  // sleeping (libgomp's GOMP_SPINCOUNT, a few microseconds) saves the
  // wake-ups of barriers that the other thread reaches soon after: 9-20%
  // of a small scene's step on an idle machine, no measurable cost on a
  // busy one. The OpenMP runtime reads both when it loads, so the program
  // starts itself again with them.
  if (!std::getenv("OMP_WAIT_POLICY")) {
    setenv("OMP_WAIT_POLICY", "passive", 1);
    if (!std::getenv("GOMP_SPINCOUNT")) setenv("GOMP_SPINCOUNT", "3000", 1);
    execv("/proc/self/exe", argv);  // returns only if it failed: go on as we are
  }
  CLI::App app{"Triad: MPM simulation of sand, snow, fluids and soft materials into VFX caches"};
  app.set_version_flag("--version", "triad 0.1.0");
  app.require_subcommand(1);

  triad::RunOptions run;
  bool quiet = false, plain = false;
  CLI::App* run_cmd = app.add_subcommand("run", "Simulate a scene and write its cache");
  run_cmd->add_option("scene", run.scene_path, "Scene file (JSON)")->required();
  run_cmd->add_option("--out", run.out_dir, "Output directory (overrides output.dir)");
  run_cmd->add_option("--threads", run.threads, "Worker threads (default: all cores)")
      ->check(CLI::Range(1, 1024));
  run_cmd->add_flag("--quiet", quiet, "No progress display");
  run_cmd->add_flag("--plain", plain, "Plain progress lines even on a terminal");
  run_cmd->add_option("--quality", run.quality,
                      "Quality preset: draft (2x dx, fewer particles, larger steps), preview "
                      "(dx as written), final (dx / 2); sets solver.particles_per_cell, cfl and "
                      "transfer too. Without it the scene runs as written");
  run_cmd->add_flag("--no-probe", run.no_probe,
                    "Skip the short rate probe before the first frame (the estimate's wall time "
                    "at a fixed rate)");
  run_cmd->add_flag("--no-overlap", run.no_overlap,
                    "Write each frame before stepping the next (by default a frame is written on "
                    "a thread of its own from a copy while the next one steps)");
  run_cmd->add_flag("--resume", run.resume,
                    "Continue from the last complete frame's checkpoint in the output directory");
  run_cmd
      ->add_option("--balance", run.balance,
                   "Under mpirun: cut the grid between processes for equal particle counts "
                   "(particles, the default) or for equal work, measured each frame (work). "
                   "Results are the same bytes either way")
      ->check(CLI::IsMember({"particles", "work"}));

  triad::RenderCacheOptions render;
  CLI::App* render_cmd =
      app.add_subcommand("render", "Re-render the PNG previews of an existing cache");
  render_cmd->add_option("cache", render.cache_dir, "Cache directory (a run's output)")->required();
  render_cmd->add_option("--threads", render.threads, "Worker threads")->check(CLI::Range(1, 1024));

  triad::CheckOptions check;
  CLI::App* check_cmd = app.add_subcommand(
      "check", "Validate a scene and estimate what its run needs (particles, memory, steps), "
               "without simulating");
  check_cmd->add_option("scene", check.scene_path, "Scene file (JSON)")->required();
  check_cmd->add_option("--quality", check.quality, "Quality preset, as for run");
  check_cmd->add_flag("--json", check.json, "The estimate as JSON on stdout");
  check_cmd
      ->add_option("--probe", check.probe,
                   "Also build the scene and step it for about this many seconds: its measured "
                   "rate, step and whole-run time")
      ->check(CLI::Range(0.0, 3600.0));
  check_cmd->add_flag("--no-probe", check.no_probe,
                      "Skip the short rate probe: wall time at the 2-core machine's fixed rate");

  triad::CompareOptions compare;
  CLI::App* compare_cmd = app.add_subcommand(
      "compare", "Compare two caches (or a cache and a golden folder) frame by frame: previews "
                 "with the golden tests' pixel metric, particles by id; exit 0 within "
                 "tolerance, 1 when a frame differs");
  compare_cmd->add_option("cache_a", compare.a, "The cache to check")->required();
  compare_cmd->add_option("cache_b", compare.b, "The reference cache or golden folder")->required();
  compare_cmd->add_option("--out", compare.out, "Folder for the diff images (default CACHE_A/compare)");
  compare_cmd->add_option("--pixel-threshold", compare.pixel_threshold,
                          "A pixel differs when a channel differs by more than this (0-255)")
      ->check(CLI::Range(0, 255));
  compare_cmd->add_option("--max-fraction", compare.max_fraction,
                          "Largest share of differing pixels a frame may have (default 0.002)")
      ->check(CLI::Range(0.0, 1.0));
  compare_cmd->add_option("--max-mean", compare.max_mean,
                          "Largest mean channel difference a frame may have (0-255, default 1)")
      ->check(CLI::Range(0.0, 255.0));
  compare_cmd->add_option("--max-rms", compare.max_rms,
                          "Largest RMS particle position difference, m (default 1e-4 of the "
                          "reference's domain diagonal)")
      ->check(CLI::NonNegativeNumber);
  compare_cmd->add_option("--max-position", compare.max_position,
                          "Largest single particle position difference, m (default 10 x --max-rms)")
      ->check(CLI::NonNegativeNumber);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // Usage errors are invalid input: exit status 2, as for a bad scene.
    const int code = app.exit(e);
    return code == 0 ? 0 : triad::kExitBadInput;
  }
  if (render_cmd->parsed()) return triad::renderCache(render);
  if (check_cmd->parsed()) return triad::checkScene(check);
  if (compare_cmd->parsed()) return triad::compareCaches(compare);
  if (quiet) run.progress = triad::ProgressMode::Quiet;
  else if (plain) run.progress = triad::ProgressMode::Plain;
  return triad::runScene(run);
}
