// Solver throughput and memory on a scene: particle-substeps per second and
// peak bytes per particle. Run one scene per process so that the peak
// resident size belongs to that scene alone:
//   bench_mpm SCENE.json [--time T] [--threads N]
#include <omp.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <utility>

#include "export/run_record.h"
#include "import/mesh_sampler.h"
#include "import/scene_loader.h"
#include "sim/solver.h"
#include "sim/world.h"

namespace {

size_t currentResidentBytes() {
  std::FILE* f = std::fopen("/proc/self/statm", "r");
  if (!f) return 0;
  unsigned long pages_total = 0, pages_resident = 0;
  const int n = std::fscanf(f, "%lu %lu", &pages_total, &pages_resident);
  std::fclose(f);
  return n == 2 ? pages_resident * 4096ul : 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s SCENE.json [--time T] [--threads N]\n", argv[0]);
    return 2;
  }
  double sim_time = -1.0;
  for (int i = 2; i + 1 < argc; i += 2) {
    if (!std::strcmp(argv[i], "--time")) sim_time = std::atof(argv[i + 1]);
    else if (!std::strcmp(argv[i], "--threads")) omp_set_num_threads(std::atoi(argv[i + 1]));
  }
  const triad::SceneDesc scene = triad::loadScene(argv[1]);
  if (sim_time < 0) sim_time = scene.frames.count / scene.frames.fps;

  const size_t rss_before = currentResidentBytes();
  triad::World world = triad::buildSceneWorld(scene);
  triad::Solver solver(world);
  const size_t n = world.particleCount();

  // Step frame by frame, as a run does, without writing caches.
  const double t0 = omp_get_wtime();
  const int frames = std::max(1, int(std::lround(sim_time * scene.frames.fps)));
  for (int f = 1; f <= frames; ++f) solver.advanceTo(sim_time * f / frames);
  const double wall = omp_get_wtime() - t0;

  const size_t peak = triad::peakResidentBytes();
  const triad::PhaseTimes& t = solver.phaseTimes();
  const double rate = double(solver.record().particle_steps) / wall;
  std::printf(
      "scene=%s particles=%zu threads=%d steps=%lld sim_time=%.3f wall=%.2f "
      "particle_substeps_per_s=%.3e peak_rss_mib=%.1f bytes_per_particle_rss=%.0f "
      "bytes_per_particle_held=%.0f phases[bin=%.2f p2g=%.2f grid=%.2f g2p=%.2f solids=%.2f]\n",
      scene.name.c_str(), n, omp_get_max_threads(), static_cast<long long>(solver.record().steps),
      sim_time, wall, rate, double(peak) / (1024.0 * 1024.0), double(peak - rss_before) / double(n),
      double(world.particleBytes() + solver.bytes()) / double(n), t.bin, t.p2g, t.grid, t.g2p,
      t.solids);
  if (t.solids > 0.0) {
    std::printf("solids_parts[");
    const char* sep = "";
    for (const auto& [name, s] : t.solid_parts.parts())
      std::printf("%s%s=%.2f", std::exchange(sep, " "), name, s);
    std::printf("]\n");
  }
  return 0;
}
