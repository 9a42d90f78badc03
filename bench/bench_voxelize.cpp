// Cost of a mesh shape (issue 3): load (assimp) + voxelize (OpenVDB, full
// interior SDF at dx/2) + sample (8 particles per cell), for spheres of about
// 1k, 10k and 100k triangles at 20, 50 and 100 cells across. Each figure is
// a fresh MeshCache (nothing reused), median of `runs` (argv[1], default 3).
// Usage: bench_voxelize [runs]
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <vector>

#include "import/mesh_loader.h"
#include "import/mesh_sampler.h"

using namespace triad;

int main(int argc, char** argv) {
  const int runs = argc > 1 ? std::max(1, std::atoi(argv[1])) : 3;
  using clock = std::chrono::steady_clock;
  const auto dir = std::filesystem::temp_directory_path() / "triad_bench_voxelize";
  std::filesystem::create_directories(dir);
  std::printf("| triangles | cells across | dx | particles | SDF active voxels | load s | voxelize s | sample s | total s |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|\n");
  for (auto [nu, nv] : {std::pair{32, 16}, std::pair{100, 50}, std::pair{316, 158}}) {
    const TriangleMesh m = uvSphere({0.5137, 0.4871, 0.5093}, 0.25, nu, nv);
    const std::string path = (dir / ("sphere_" + std::to_string(m.triangles.size()) + ".stl")).string();
    saveMesh(m, path, "stlb");
    MeshDesc desc;
    desc.path = desc.resolved_path = path;
    for (int across : {20, 50, 100}) {
      DomainDesc dom;
      dom.dx = 0.5 / across;
      std::vector<double> tl, tv, ts, tt;
      size_t particles = 0, voxels = 0;
      for (int r = 0; r < runs; ++r) {
        const auto t0 = clock::now();
        MeshLoadResult loaded = loadMesh(desc);
        const auto t1 = clock::now();
        MeshVolume vol(loaded.mesh, 0.5 * dom.dx, Vec3d::Constant(0.25 * dom.dx));
        const auto t2 = clock::now();
        voxels = vol.activeVoxels();
        (void)vol;
        // Sampling through the public path (its own cache: load and voxelize
        // again), minus the two phases measured above.
        auto cache = std::make_shared<MeshCache>();
        const auto t3 = clock::now();
        particles = makeMeshSampler(cache)(desc, dom, 8).size();
        const auto t4 = clock::now();
        const double load = std::chrono::duration<double>(t1 - t0).count();
        const double vox = std::chrono::duration<double>(t2 - t1).count();
        const double total = std::chrono::duration<double>(t4 - t3).count();
        tl.push_back(load);
        tv.push_back(vox);
        ts.push_back(std::max(0.0, total - load - vox));
        tt.push_back(total);
      }
      auto med = [](std::vector<double> v) {
        std::sort(v.begin(), v.end());
        return v[v.size() / 2];
      };
      std::printf("| %zu | %d | %.4g | %zu | %zu | %.3f | %.3f | %.3f | %.3f |\n", m.triangles.size(), across,
                  dom.dx, particles, voxels, med(tl), med(tv), med(ts), med(tt));
      std::fflush(stdout);
    }
  }
  std::filesystem::remove_all(dir);
}
