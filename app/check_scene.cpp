#include "app/check_scene.h"

#include <chrono>
#include <cstdio>
#include <optional>

#include <nlohmann/json.hpp>

#include "app/rate_probe.h"
#include "app/run_scene.h"
#include "import/estimate.h"
#include "import/mesh_sampler.h"
#include "import/quality.h"
#include "import/scene_loader.h"
#include "sim/errors.h"
#include "sim/solver.h"

namespace triad {

namespace {

// The scene built and stepped for about `seconds` of wall time (at least
// one step, at most the whole run): the measured rate in particle-substeps
// a second, the steps it took, and the whole run's wall time at that rate
// and step. The fixed-rate estimate knows neither this machine nor the
// scene's solids, nor how the step shrinks once material moves.
nlohmann::json probeScene(const SceneDesc& scene, double seconds) {
  using Clock = std::chrono::steady_clock;
  const auto t0 = Clock::now();
  World w = buildSceneWorld(scene);
  const double build_s = std::chrono::duration<double>(Clock::now() - t0).count();
  Solver solver(w);
  const double end = scene.frames.count / scene.frames.fps;
  const auto t1 = Clock::now();
  double wall = 0.0;
  // Frame after frame as the run steps them, stopped after the step that
  // passes the probe's time.
  struct Enough {};
  try {
    for (int f = 1; f <= scene.frames.count; ++f)
      solver.advanceTo(f / scene.frames.fps, [&](double) {
        wall = std::chrono::duration<double>(Clock::now() - t1).count();
        if (wall >= seconds) throw Enough{};
      });
  } catch (const Enough&) {
  }
  wall = std::chrono::duration<double>(Clock::now() - t1).count();
  const StepRecord& r = solver.record();
  const double rate = wall > 0 ? double(r.particle_steps) / wall : 0.0;
  const double mean_dt = r.steps > 0 ? w.time / double(r.steps) : 0.0;
  const double steps_left = mean_dt > 0 ? (end - w.time) / mean_dt : 0.0;
  const double per_step = r.steps > 0 ? wall / double(r.steps) : 0.0;
  const double total = build_s + wall + steps_left * per_step;
  return {{"build_seconds", build_s},
          {"steps", r.steps},
          {"simulated_seconds", w.time},
          {"wall_seconds", wall},
          {"particle_substeps_per_second", rate},
          {"mean_dt", mean_dt},
          {"run_wall_seconds", total},
          {"whole_run", w.time >= end}};
}

std::string describeProbe(const nlohmann::json& p) {
  char line[512];
  std::snprintf(line, sizeof line,
                "  probe: built in %.2f s, %d steps (%.3g s simulated, mean step %.3g s) in %.2f "
                "s: %.3g particle-substeps/s; the whole run about %.3g s at that rate and step%s\n",
                p["build_seconds"].get<double>(), p["steps"].get<int>(),
                p["simulated_seconds"].get<double>(), p["mean_dt"].get<double>(),
                p["wall_seconds"].get<double>(), p["particle_substeps_per_second"].get<double>(),
                p["run_wall_seconds"].get<double>(),
                p["whole_run"].get<bool>() ? " (the probe ran all of it)" : "");
  return line;
}

}  // namespace

int checkScene(const CheckOptions& options) {
  try {
    if (!options.quality.empty() && !findQualityPreset(options.quality))
      throw InputError("--quality", "expected one of " + qualityPresetNames() + ", got \"" +
                                        options.quality + "\"");
    SceneDesc scene = loadScene(options.scene_path);
    if (!options.quality.empty()) applyQuality(scene, options.quality);
    SceneEstimate e = estimateScene(scene);
    // A probe only of a scene that fits; the estimate is printed either way,
    // then the refusal.
    std::optional<InputError> unfit;
    try {
      requireFits(scene, e);
    } catch (const InputError& err) {
      unfit = err;
    }
    RateProbe rate;
    rate.why_not = unfit ? "the scene does not fit in memory" : "--no-probe";
    if (!unfit && !options.no_probe) rate = probeRate(scene, e);
    applyRate(e, rate);
    for (const std::string& w : extremeWarnings(scene, e))
      std::fprintf(stderr, "triad: warning: %s\n", w.c_str());
    nlohmann::json probe;
    if (!unfit && options.probe > 0) probe = probeScene(scene, options.probe);
    if (options.json) {
      nlohmann::ordered_json j = nlohmann::ordered_json::parse(estimateJson(e));
      if (!probe.is_null()) j["probe"] = probe;
      // The settings the run would use, defaults and --quality included.
      j["solver"] = solverSettings(scene.solver);
      std::printf("%s\n", j.dump().c_str());
    } else {
      std::printf("%s: valid; estimate:\n%s%s", scene.source_path.c_str(),
                  describeEstimate(e).c_str(), probe.is_null() ? "" : describeProbe(probe).c_str());
    }
    if (unfit) throw *unfit;
  } catch (const InputError& err) {
    std::fprintf(stderr, "triad: error: %s\n", err.what());
    return kExitBadInput;
  }
  return kExitOk;
}

}  // namespace triad
