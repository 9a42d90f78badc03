// A jelly cube resting on another on a frictional floor, measured:
//   study_stack [--dx M] [--time S] [--implicit] [--friction MU] [--E PA]
//               [--model fixed_corotated|neo_hookean] [--every FRAMES]
//               [--damping ETA]
// Two 10 cm cubes (rho 1000, nu 0.3), the upper placed on the lower, no MPM
// material. Prints, every 0.05 s, the upper cube's sideways drift (mean of
// its nodes against the start), its sink, the overlap of the two faces
// (the lower's top-face nodes over the upper's bottom-face nodes, mean and
// largest) and the lower cube's drift, then the largest drift over the run.
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>

#include "import/mesh_sampler.h"
#include "import/scene_loader.h"
#include "sim/solver.h"

namespace {

using nlohmann::json;
using triad::Vec3d;

json box(const std::array<double, 3>& lo, const std::array<double, 3>& hi) {
  return {{"box", {{"min", lo}, {"max", hi}}}};
}

Vec3d mean(const std::vector<Vec3d>& x) {
  Vec3d m = Vec3d::Zero();
  for (const Vec3d& p : x) m += p;
  return m / double(x.size());
}

}  // namespace

int main(int argc, char** argv) {
  double dx = 0.05, time = 2.0, mu = 0.5, E = 2e4, damping = 0.0;
  bool implicit = false;
  std::string model = "fixed_corotated";
  int every = 1;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() { return std::string(argv[++i]); };
    if (a == "--dx")
      dx = std::stod(next());
    else if (a == "--time")
      time = std::stod(next());
    else if (a == "--implicit")
      implicit = true;
    else if (a == "--friction")
      mu = std::stod(next());
    else if (a == "--E")
      E = std::stod(next());
    else if (a == "--model")
      model = next();
    else if (a == "--damping")
      damping = std::stod(next());
    else if (a == "--every")
      every = std::stoi(next());
    else {
      std::fprintf(stderr, "unknown argument %s\n", a.c_str());
      return 2;
    }
  }
  json j = {
      {"version", 1},
      {"name", "stack"},
      {"domain",
       {{"min", {0, 0, 0}},
        {"max", {0.4, 0.4, 0.4}},
        {"dx", dx},
        {"boundary", {{"type", "slip"}, {"friction", mu}}}}},
      {"materials",
       {{"jelly",
         {{"model", model}, {"density", 1000}, {"youngs_modulus", E}, {"poisson_ratio", 0.3}}}}},
      {"objects", json::array()}};
  const char* names[2] = {"lower", "upper"};
  for (int k = 0; k < 2; ++k) {
    json o = {{"name", names[k]},
              {"kind", "elastic"},
              {"material", "jelly"},
              {"friction", mu},
              {"shape", box({0.15, 0.1 * k, 0.15}, {0.25, 0.1 * (k + 1), 0.25})}};
    if (implicit) o["integrator"] = "implicit";
    if (damping > 0) o["damping"] = damping;
    j["objects"].push_back(o);
  }
  triad::World w;
  try {
    w = triad::buildSceneWorld(triad::parseScene(j, "study_stack.json"));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 1;
  }
  triad::Solver solver(w);
  const triad::FemBody& lo = w.elastics[0].fem;
  const triad::FemBody& up = w.elastics[1].fem;
  const Vec3d lo0 = mean(lo.x), up0 = mean(up.x);
  // Face nodes at rest: the lower's top, the upper's bottom, paired by
  // their x and z.
  double top = -1e9;
  for (const Vec3d& p : lo.mesh.nodes) top = std::max(top, p.y());
  std::vector<std::pair<size_t, size_t>> face;
  for (size_t a = 0; a < lo.nodes(); ++a) {
    if (std::abs(lo.mesh.nodes[a].y() - top) > 1e-9) continue;
    for (size_t b = 0; b < up.nodes(); ++b)
      if (std::abs(up.mesh.nodes[b].x() - lo.mesh.nodes[a].x()) < 1e-9 &&
          std::abs(up.mesh.nodes[b].z() - lo.mesh.nodes[a].z()) < 1e-9 &&
          up.mesh.nodes[b].y() < top + 0.5 * lo.mesh.spacing)
        face.emplace_back(a, b);
  }
  const double wall0 = omp_get_wtime();
  double worst = 0.0;
  const int n = int(std::round(time * 20));
  std::printf(
      "# t  upper drift x z (mm)  sink (mm)  overlap mean max (mm)  lower drift x z, sink (mm)\n");
  for (int k = 1; k <= n; ++k) {
    solver.advanceTo(k / 20.0);
    const Vec3d du = (mean(up.x) - up0) * 1e3, dl = (mean(lo.x) - lo0) * 1e3;
    double sum = 0, most = -1e9;
    for (const auto& [a, b] : face) {
      const double o = (lo.x[a].y() - up.x[b].y()) * 1e3;
      sum += o;
      most = std::max(most, o);
    }
    worst = std::max(worst, std::hypot(du.x(), du.z()));
    if (k % every == 0 || k == n)
      std::printf("%.2f  %+.3f %+.3f  %+.2f  %+.2f %+.2f  %+.3f %+.3f %+.2f\n", k / 20.0, du.x(),
                  du.z(), du.y(), sum / double(face.size()), most, dl.x(), dl.z(), dl.y());
  }
  std::printf("largest sideways drift %.3f mm over %.1f s (%zu face nodes, %.1f s wall)\n", worst,
              time, face.size(), omp_get_wtime() - wall0);
  return 0;
}
