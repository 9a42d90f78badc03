// Cost of a deforming collider (a mesh sequence): loading and checking its
// frames and binding its samples once, then per substep and per frame, for
// pulsing UV spheres of about 1k, 10k and 100k triangles, 100 cells across,
// a water layer under them so that the coupling runs.
// Usage: bench_deforming [frames]
#include <omp.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

#include "import/mesh_sampler.h"
#include "import/scene_loader.h"
#include "sim/solver.h"

using namespace triad;

int main(int argc, char** argv) {
  const int frames = argc > 1 ? std::max(1, std::atoi(argv[1])) : 4;
  const double fps = 24, dx = 0.005, r = 0.25;
  const auto dir = std::filesystem::temp_directory_path() / "triad_bench_deforming";
  std::filesystem::create_directories(dir);
  std::printf("| triangles | collider samples | load + bind s | substeps | solids s per substep | "
              "of which riding s | solids s per frame |\n|---|---|---|---|---|---|---|\n");
  for (auto [nu, nv] : {std::pair{32, 16}, std::pair{100, 50}, std::pair{316, 158}}) {
    // The sequence: a sphere pulsing by 5% of its radius.
    const std::string stem = "ball" + std::to_string(nu);
    for (int f = 0; f <= frames; ++f) {
      const double rf = r * (1 + 0.05 * std::sin(f));
      char name[64];
      std::snprintf(name, sizeof name, "%s.%04d.obj", stem.c_str(), f);
      saveMesh(uvSphere({0.5, 0.5, 0.5}, rf, nu, nv), (dir / name).string(), "obj");
    }
    nlohmann::json j = {
        {"version", 1},
        {"name", "deforming_" + std::to_string(nu)},
        {"frames", {{"count", frames}, {"fps", fps}}},
        {"domain", {{"min", {0, 0, 0}}, {"max", {1, 1, 1}}, {"dx", dx}}},
        {"materials", {{"water", {{"model", "water"}, {"density", 1000}, {"bulk_modulus", 1e5}}}}},
        {"objects",
         {{{"name", "pool"}, {"kind", "mpm"}, {"material", "water"},
           {"shape", {{"box", {{"min", {0.3, 0.0, 0.3}}, {"max", {0.7, 0.27, 0.7}}}}}}},
          {{"name", "ball"}, {"kind", "collider"},
           {"shape", {{"mesh", {{"path", stem + ".####.obj"}}}}}}}}};
    const std::string scene_path = (dir / (stem + ".json")).string();
    std::ofstream(scene_path) << j.dump(2);
    const double t0 = omp_get_wtime();
    World w = buildSceneWorld(loadScene(scene_path));
    const double build = omp_get_wtime() - t0;
    // The riding alone: vertices and every sample placed, as each substep does.
    const RigidBody& b = w.bodies[0];
    std::vector<Vec3f> px(b.deform->samples()), pv(px.size()), pn(px.size());
    const double t1 = omp_get_wtime();
    const int reps = 20;
    for (int k = 0; k < reps; ++k)
      b.deform->placeAll(0.5 / fps, Mat3d::Identity(), b.pivot, b.pivot, Vec3d::Zero(),
                         Vec3d::Zero(), px, pv, pn, 0);
    const double riding = (omp_get_wtime() - t1) / reps;
    Solver solver(w);
    solver.advanceTo(frames / fps);
    const double per_step = solver.phaseTimes().solids / double(solver.record().steps);
    std::printf("| %zu | %zu | %.2f | %lld | %.4f | %.4f | %.3f |\n", b.deform->triangles().size(),
                b.deform->samples(), build, (long long)solver.record().steps, per_step, riding,
                per_step * double(solver.record().steps) / frames);
    std::fflush(stdout);
  }
  return 0;
}
