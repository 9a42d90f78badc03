#pragma once
// Helpers for tests that build scenes: write JSON into a temporary folder,
// load it through the real scene loader, and measure particle state.
#include <gtest/gtest.h>

#include <array>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>

#include "import/scene_loader.h"
#include "import/mesh_sampler.h"
#include "sim/world.h"

namespace triad::test {

// A fresh folder for `name`, under one of the running test's own: ctest runs
// tests (each parameter of one too) in parallel processes, which must not
// share a folder whatever names they pick.
inline std::filesystem::path tempDir(const std::string& name) {
  std::string test = "none";
  if (const auto* info = ::testing::UnitTest::GetInstance()->current_test_info())
    test = std::string(info->test_suite_name()) + "." + info->name();
  for (char& c : test)
    if (c == '/') c = '_';
  const auto dir = std::filesystem::temp_directory_path() / "triad_tests" / test / name;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

inline std::string writeScene(const std::filesystem::path& dir, const nlohmann::json& j,
                              const std::string& file = "scene.json") {
  const auto path = dir / file;
  std::ofstream(path) << j.dump(2);
  return path.string();
}

// A scene with the given domain and no objects; callers add materials and objects.
inline nlohmann::json baseScene(const std::string& name, const std::array<double, 3>& max,
                                double dx) {
  return {{"version", 1},
          {"name", name},
          {"frames", {{"count", 1}, {"fps", 24}}},
          {"domain", {{"min", {0, 0, 0}}, {"max", max}, {"dx", dx}}},
          {"materials", nlohmann::json::object()},
          {"objects", nlohmann::json::array()}};
}

inline nlohmann::json box(const std::array<double, 3>& lo, const std::array<double, 3>& hi) {
  return {{"box", {{"min", lo}, {"max", hi}}}};
}

// MPM objects water0..water5 of `material` filling a tank of `x` by `z`
// to `depth` round the box [lo, hi] inside it: under it, over it, then
// either side along x, then along z.
inline void addWaterRoundBox(nlohmann::json& scene, const std::string& material, double x, double z,
                             double depth, const std::array<double, 3>& lo,
                             const std::array<double, 3>& hi) {
  const std::array<std::pair<std::array<double, 3>, std::array<double, 3>>, 6> boxes = {{
      {{0, 0, 0}, {x, lo[1], z}},
      {{0, hi[1], 0}, {x, depth, z}},
      {{0, lo[1], 0}, {lo[0], hi[1], z}},
      {{hi[0], lo[1], 0}, {x, hi[1], z}},
      {{lo[0], lo[1], 0}, {hi[0], hi[1], lo[2]}},
      {{lo[0], lo[1], hi[2]}, {hi[0], hi[1], z}},
  }};
  for (size_t k = 0; k < boxes.size(); ++k)
    scene["objects"].push_back({{"name", "water" + std::to_string(k)},
                                {"kind", "mpm"},
                                {"material", material},
                                {"shape", box(boxes[k].first, boxes[k].second)}});
}

inline World loadWorld(const std::filesystem::path& dir, const nlohmann::json& j) {
  return buildSceneWorld(loadScene(writeScene(dir, j)));
}

struct Moments {
  double mass = 0.0;
  Vec3d momentum = Vec3d::Zero();
  Vec3d centre = Vec3d::Zero();    // centre of mass
  double abs_momentum = 0.0;       // sum of m |v|, the scale of round-off
  double kinetic = 0.0;
};

inline Moments moments(const World& w, int object = -1) {
  Moments m;
  for (const ParticleSet& s : w.sets)
    for (size_t i = 0; i < s.size(); ++i) {
      if (object >= 0 && s.object[i] != object) continue;
      const Vec3d v = s.v[i].cast<double>();
      m.mass += s.mass;
      m.momentum += s.mass * v;
      m.centre += s.mass * s.x[i].cast<double>();
      m.abs_momentum += s.mass * v.norm();
      m.kinetic += 0.5 * s.mass * v.squaredNorm();
    }
  if (m.mass > 0) m.centre /= m.mass;
  return m;
}

// Total angular momentum about o: the rigid bodies' spin and orbit, and the
// MPM particles', with APIC's affine part m (dx^2/4) axial(C^T - C) for
// quadratic B-splines (Jiang et al. 2015: what the affine transfer keeps;
// zero under PIC, whose C is zero).
inline Vec3d angularMomentum(const World& w, const Vec3d& o) {
  const double dx = w.scene.domain.dx, d = 0.25 * dx * dx;
  Vec3d l = Vec3d::Zero();
  for (const RigidBody& b : w.bodies)
    if (!b.fixed) l += b.state.L + (b.state.x - o).cross(b.mass * b.state.v);
  for (const ParticleSet& s : w.sets)
    for (size_t i = 0; i < s.size(); ++i) {
      const Vec3d x = s.x[i].cast<double>(), v = s.v[i].cast<double>();
      const Mat3d c = s.C[i].cast<double>();
      const Vec3d affine(c(2, 1) - c(1, 2), c(0, 2) - c(2, 0), c(1, 0) - c(0, 1));
      l += double(s.mass) * ((x - o).cross(v) + d * affine);
    }
  return l;
}

}  // namespace triad::test
