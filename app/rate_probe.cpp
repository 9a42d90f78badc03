#include "app/rate_probe.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>

#include "import/mesh_sampler.h"
#include "sim/solver.h"

namespace triad {

namespace {

// At most about this many particles: a substep takes milliseconds, and the
// rate per particle is that of large scenes already (bench/RESULTS.md).
constexpr double kProbeParticles = 3e4;
// Timed substeps: stop after this many, or once this much time has passed.
constexpr int kTimedSteps = 20;
constexpr double kTimedSeconds = 0.5;

}  // namespace

RateProbe probeRate(const SceneDesc& scene, const SceneEstimate& e) {
  using Clock = std::chrono::steady_clock;
  const auto t0 = Clock::now();
  auto since = [](Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); };
  RateProbe p;
  SceneDesc coarse = scene;
  // Coarser by the cube root of the particle ratio; solids' explicit
  // sample spacings with it, so that they stay as cheap beside the MPM.
  const double f = std::max(1.0, std::cbrt(e.particles / kProbeParticles));
  coarse.domain.dx *= f;
  for (ObjectDesc& o : coarse.objects) o.sample_spacing *= f;
  p.dx = coarse.domain.dx;
  try {
    World w = buildSceneWorld(coarse);
    Solver solver(w);
    const double end = scene.frames.count / scene.frames.fps;
    // The first substep allocates grids and bins: a warm-up, not timed.
    struct Enough {};
    Clock::time_point t1{};
    StepRecord before;
    bool warm = false;
    try {
      solver.advanceTo(end, [&](double) {
        if (!warm) {
          warm = true;
          before = solver.record();
          t1 = Clock::now();
          return;
        }
        const StepRecord& r = solver.record();
        if (r.steps - before.steps >= kTimedSteps || since(t1) >= kTimedSeconds) throw Enough{};
      });
    } catch (const Enough&) {
    }
    const StepRecord& r = solver.record();
    p.steps = r.steps - before.steps;
    const double timed = warm ? since(t1) : 0.0;
    const double particle_steps = double(r.particle_steps - before.particle_steps);
    p.particles = p.steps > 0 ? particle_steps / double(p.steps) : 0.0;
    if (p.steps == 0 || particle_steps == 0 || timed <= 0) {
      p.why_not = p.steps == 0 ? "the scene ends within one substep"
                               : "no MPM particles in its first substeps";
    } else {
      p.rate = particle_steps / timed;
      p.ran = true;
    }
  } catch (const std::exception& err) {
    char dx[32];
    std::snprintf(dx, sizeof dx, "%.3g", p.dx);
    p.why_not = std::string("the probe at dx ") + dx + " failed: " + err.what();
  }
  p.seconds = since(t0);
  return p;
}

}  // namespace triad
