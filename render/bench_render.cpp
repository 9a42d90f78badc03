// Preview render timing: seconds per frame for 10k, 100k and 1M particles at
// 640x360 and 1280x720 (bench/RESULTS.md, "Preview render timing (issue 6)").
//   bench_render [runs=3] [supersample=3] [counts...]
// Particles fill a block of a 1 m domain on a regular lattice, drawn with
// radius half the lattice spacing, as MPM samples are; automatic camera.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include "render/png_writer.h"
#include "render/preview_renderer.h"

using namespace triad::render;
using Clock = std::chrono::steady_clock;

namespace {

double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

// n particles in three blocks (three objects) filling 0.18 m^3 of the domain.
PreviewFrame lattice(size_t n, float& radius) {
  const double volume = 0.6 * 0.5 * 0.6;
  const double s = std::cbrt(volume / double(n));
  radius = float(0.5 * s);
  PreviewFrame f;
  f.xyz.reserve(n * 3);
  f.object.reserve(n);
  const int nx = int(std::ceil(0.6 / s)), ny = int(std::ceil(0.5 / s));
  for (size_t i = 0; i < n; ++i) {
    const size_t ix = i % size_t(nx), iy = (i / size_t(nx)) % size_t(ny), iz = i / size_t(nx * ny);
    const float x = float(0.2 + (ix + 0.5) * s), y = float((iy + 0.5) * s), z = float(0.2 + (iz + 0.5) * s);
    f.xyz.insert(f.xyz.end(), {x, y, z});
    f.object.push_back(uint16_t(x < 0.4f ? 0 : x < 0.6f ? 1 : 2));
  }
  return f;
}

}  // namespace

int main(int argc, char** argv) {
  const int runs = argc > 1 ? std::max(1, std::atoi(argv[1])) : 3;
  const int ss = argc > 2 ? std::max(1, std::atoi(argv[2])) : 3;
  std::vector<size_t> counts;
  for (int i = 3; i < argc; ++i) counts.push_back(size_t(std::atoll(argv[i])));
  if (counts.empty()) counts = {10000, 100000, 1000000};
  const int resolutions[2][2] = {{640, 360}, {1280, 720}};

  PreviewSettings s;
  s.domain = {{0, 0, 0}, {1, 1, 1}};
  s.supersample = ss;
  PreviewRenderer renderer(s);
  std::printf("# %s; %u hardware threads; supersample %d; median of %d frames\n",
              renderer.glDescription().c_str(), std::thread::hardware_concurrency(), ss, runs);
  std::printf("| particles | resolution | render s/frame | PNG write s/frame | total s/frame |\n");
  std::printf("|---|---|---|---|---|\n");
  const std::string png = (std::filesystem::temp_directory_path() / "bench_render.png").string();
  for (size_t n : counts) {
    float radius = 0;
    const PreviewFrame frame = lattice(n, radius);
    for (const auto& res : resolutions) {
      s.width = res[0];
      s.height = res[1];
      s.particle_radius = radius;
      s.camera = autoCamera(s.domain, double(s.width) / s.height);
      renderer.setSettings(s);
      Image img = renderer.render(frame);  // warm-up: buffer allocation, shader JIT
      std::vector<double> t_render, t_png;
      for (int r = 0; r < runs; ++r) {
        auto t0 = Clock::now();
        img = renderer.render(frame);
        t_render.push_back(since(t0));
        t0 = Clock::now();
        writePng(png, img);
        t_png.push_back(since(t0));
      }
      std::printf("| %zu | %dx%d | %.3f | %.3f | %.3f |\n", n, s.width, s.height, median(t_render),
                  median(t_png), median(t_render) + median(t_png));
      std::fflush(stdout);
    }
  }
  std::filesystem::remove(png);
  return 0;
}
