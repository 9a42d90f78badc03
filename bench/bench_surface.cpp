// Cost of what a frame writes for renderers and ParaView: the narrow-band
// level set `surface` (particles to spheres, rebuilt to a distance), the
// surface mesh of each material (level set, erosion, smoothing,
// volume-to-mesh), and the particles as PLY and as VTK PolyData (written to
// the system's temporary folder).
//   build/bench/bench_surface SCENE.json [--time SECONDS] [--repeat N]
// simulates the scene to --time (default 0: the particles as sampled), then
// times each, N times (default 3), and prints the medians.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "export/particle_level_set.h"
#include "export/particle_surface.h"
#include "export/ply_writer.h"
#include "export/vtk_writer.h"
#include "import/mesh_sampler.h"
#include "import/scene_loader.h"
#include "sim/solver.h"

using namespace triad;

namespace {

double seconds(std::chrono::steady_clock::time_point a, std::chrono::steady_clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s SCENE.json [--time SECONDS] [--repeat N]\n", argv[0]);
    return 2;
  }
  double until = 0.0;
  int repeat = 3;
  for (int i = 2; i + 1 < argc; i += 2) {
    if (!std::strcmp(argv[i], "--time")) until = std::atof(argv[i + 1]);
    if (!std::strcmp(argv[i], "--repeat")) repeat = std::max(1, std::atoi(argv[i + 1]));
  }
  openvdb::initialize();
  const SceneDesc scene = loadScene(argv[1]);
  World world = buildSceneWorld(scene);
  Solver solver(world);
  if (until > 0) solver.advanceTo(until);

  const double voxel =
      scene.output.vdb_voxel_size > 0 ? scene.output.vdb_voxel_size : scene.domain.dx;
  size_t particles = 0;
  for (const ParticleSet& s : world.sets) particles += s.size();
  std::vector<double> t_set, t_mesh, t_ply, t_vtp;
  const std::string tmp = std::filesystem::temp_directory_path().string();
  size_t active = 0, triangles = 0;
  for (int r = 0; r < repeat; ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    const openvdb::FloatGrid::Ptr ls = particleLevelSet(world, surfaceSampling(world, voxel), -1);
    const auto t1 = std::chrono::steady_clock::now();
    SurfaceMeshSettings settings;
    settings.voxel_size = voxel;
    triangles = 0;
    for (size_t m = 0; m < scene.materials.size(); ++m)
      triangles += materialSurfaceMesh(world, int(m), settings).triangles.size();
    const auto t2 = std::chrono::steady_clock::now();
    writeParticlesPly(tmp + "/bench_surface.ply", world);
    const auto t3 = std::chrono::steady_clock::now();
    writeParticlesVtp(tmp + "/bench_surface.vtp", world);
    const auto t4 = std::chrono::steady_clock::now();
    t_set.push_back(seconds(t0, t1));
    t_mesh.push_back(seconds(t1, t2));
    t_ply.push_back(seconds(t2, t3));
    t_vtp.push_back(seconds(t3, t4));
    active = size_t(ls->activeVoxelCount());
  }
  std::printf("%s at t = %.3f s: %zu particles\n", scene.name.c_str(), world.time, particles);
  std::printf("level set `surface`: %.3f s (median of %d), %zu active voxels of %.4g m\n",
              median(t_set), repeat, active, surfaceSampling(world, voxel).voxel_size);
  std::printf("surface meshes: %.3f s, %zu triangles\n", median(t_mesh), triangles);
  std::printf("particles: PLY %.3f s, VTK %.3f s\n", median(t_ply), median(t_vtp));
  std::filesystem::remove(tmp + "/bench_surface.ply");
  std::filesystem::remove(tmp + "/bench_surface.vtp");
  return 0;
}
