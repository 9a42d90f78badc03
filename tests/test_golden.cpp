// Golden-image regression tests of the preview renderer: small scenes are
// simulated, rendered and compared with the references in tests/golden/
// (regenerate them with scripts/update_golden.sh). Also `triad render` end to
// end, and proof that the comparison can fail.
//
// The metric (render::compareImages): a pixel differs visibly when the largest
// of its three channel differences exceeds 24 (of 255). An image passes when
//   - fewer than 0.2% of its pixels differ visibly, and
//   - the mean absolute difference over all channels is below 1.0.
// This absorbs round-off differences of the solver across CPUs (sub-pixel
// motion that changes a few edge pixels slightly) but fails for a block
// moved by two cells or a camera moved by 2% (tests below).
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdlib>
#include <fstream>
#include <iostream>
#include <sstream>

#include "import/mesh_sampler.h"
#include "render/png_writer.h"
#include "render/preview_renderer.h"
#include "render/preview_settings_io.h"
#include "render/preview_writer.h"
#include "cli_fixture.h"
#include "scene_fixture.h"
#include "sim/solver.h"

namespace triad {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using namespace triad::render;

constexpr int kPixelThreshold = 24;
constexpr double kMaxFractionOver = 0.002;
constexpr double kMaxMeanAbs = 1.0;

bool passes(const ImageDiff& d) {
  return d.same_size && d.fraction_over < kMaxFractionOver && d.mean_abs < kMaxMeanAbs;
}

std::string describe(const ImageDiff& d) {
  std::ostringstream s;
  s << "visibly different pixels " << d.fraction_over * 100 << "% (limit " << kMaxFractionOver * 100
    << "%), mean |diff| " << d.mean_abs << " (limit " << kMaxMeanAbs << "), max " << d.max_abs;
  return s.str();
}

const fs::path kGoldenDir = fs::path(TRIAD_SOURCE_DIR) / "tests" / "golden";

bool updating() {
  const char* u = std::getenv("TRIAD_UPDATE_GOLDEN");
  return u && *u && std::string(u) != "0";
}

// Compares with tests/golden/NAME.png (or rewrites it under
// TRIAD_UPDATE_GOLDEN=1). On failure, writes the actual image and a diff
// picture and prints their paths.
void checkGolden(const std::string& name, const Image& actual) {
  const fs::path ref = kGoldenDir / (name + ".png");
  if (updating()) {
    fs::create_directories(kGoldenDir);
    writePng(ref.string(), actual);
    // Rewritten, not compared: reported as skipped, never as a pass.
    GTEST_SKIP() << "updated " << ref.string() << " (not compared)";
  }
  ASSERT_TRUE(fs::exists(ref)) << "missing reference " << ref << " (run scripts/update_golden.sh)";
  const Image expected = readPng(ref.string());
  const ImageDiff d = compareImages(actual, expected, kPixelThreshold);
  if (!passes(d)) {
    const fs::path out = fs::temp_directory_path() / "triad_golden";
    fs::create_directories(out);
    const fs::path actual_path = out / (name + ".actual.png"), diff_path = out / (name + ".diff.png");
    writePng(actual_path.string(), actual);
    if (d.same_size) writePng(diff_path.string(), diffImage(actual, expected, kPixelThreshold));
    ADD_FAILURE() << name << " differs from " << ref.string() << ": " << describe(d)
                  << (d.same_size ? "" : " (size differs)") << "\n  actual: " << actual_path.string()
                  << "\n  diff:   " << diff_path.string();
  }
}

json mpmObject(const std::string& name, const std::string& mat, const json& shape,
               const std::array<double, 3>& v = {0, 0, 0}) {
  return {{"name", name}, {"kind", "mpm"}, {"material", mat}, {"shape", shape}, {"velocity", v}};
}

// A jelly cube dropped onto a sand layer; explicit camera. About 6k particles.
json sandJellyScene() {
  json j = test::baseScene("golden_sand_jelly", {0.4, 0.4, 0.4}, 0.02);
  j["frames"] = {{"count", 4}, {"fps", 24}};
  j["materials"]["sand"] = {{"model", "drucker_prager"}, {"density", 1600}, {"youngs_modulus", 1e5},
                            {"poisson_ratio", 0.3}, {"friction_angle_deg", 32}};
  j["materials"]["jelly"] = {{"model", "fixed_corotated"}, {"density", 1000},
                             {"youngs_modulus", 4e4}, {"poisson_ratio", 0.3}};
  j["objects"] = {mpmObject("sand", "sand", test::box({0.02, 0.0, 0.02}, {0.38, 0.04, 0.38})),
                  mpmObject("jelly", "jelly", test::box({0.14, 0.14, 0.14}, {0.24, 0.24, 0.24}),
                            {0.5, -1.5, 0})};
  j["output"] = {{"vdb", false}, {"png", true}};
  j["render"] = {{"resolution", {320, 180}},
                 {"camera", {{"eye", {0.95, 0.55, 0.9}}, {"target", {0.2, 0.08, 0.2}}, {"fov_deg", 40}}}};
  return j;
}

// A water column collapsing; no camera: the automatic one.
json waterAutoScene() {
  json j = test::baseScene("golden_water_auto", {0.5, 0.3, 0.24}, 0.02);
  j["frames"] = {{"count", 3}, {"fps", 24}};
  j["materials"]["water"] = {{"model", "water"}, {"density", 1000}, {"bulk_modulus", 1e5}};
  // json::array: a braced single json is a copy of it under clang, an array under GCC.
  j["objects"] =
      json::array({mpmObject("water", "water", test::box({0.02, 0.0, 0.02}, {0.16, 0.2, 0.22}))});
  j["output"] = {{"vdb", false}, {"png", true}};
  j["render"] = {{"resolution", {320, 180}}};
  return j;
}

// Frame 0 only (no stepping): a snow ball and a jelly slab beside two solid
// meshes passed through the mesh API, as later rigid bodies will be.
json meshScene() {
  json j = test::baseScene("golden_meshes", {0.6, 0.4, 0.4}, 0.02);
  j["materials"]["snow"] = {{"model", "snow"}, {"density", 400}, {"youngs_modulus", 1.4e5},
                            {"poisson_ratio", 0.2}};
  j["materials"]["jelly"] = {{"model", "fixed_corotated"}, {"density", 1000},
                             {"youngs_modulus", 4e4}, {"poisson_ratio", 0.3}};
  j["objects"] = {
      mpmObject("ball", "snow", json{{"sphere", {{"center", {0.15, 0.2, 0.2}}, {"radius", 0.08}}}}),
      mpmObject("slab", "jelly", test::box({0.3, 0.0, 0.05}, {0.55, 0.06, 0.35}))};
  j["render"] = {{"resolution", {320, 180}},
                 {"camera", {{"eye", {0.9, 0.6, 1.1}}, {"target", {0.3, 0.1, 0.2}}, {"fov_deg", 38}}}};
  return j;
}

// A snow ball thrown at a free rigid box on the floor, beside an elastic
// (FEM) jelly cube landing: snow, a rigid body and an elastic solid, their
// surfaces drawn as the run draws them. About 4k particles, 0.17 s.
json solidsScene() {
  json j = test::baseScene("golden_solids", {0.4, 0.3, 0.3}, 0.02);
  j["frames"] = {{"count", 4}, {"fps", 24}};
  j["materials"]["snow"] = {{"model", "snow"}, {"density", 400}, {"youngs_modulus", 1.4e5},
                            {"poisson_ratio", 0.2}};
  j["materials"]["jelly"] = {{"model", "fixed_corotated"}, {"density", 1000},
                             {"youngs_modulus", 3e4}, {"poisson_ratio", 0.3}};
  j["objects"] = {
      mpmObject("snowball", "snow", json{{"sphere", {{"center", {0.08, 0.14, 0.15}}, {"radius", 0.05}}}},
                {1.5, -0.5, 0}),
      {{"name", "box"}, {"kind", "rigid"}, {"density", 300},
       {"shape", test::box({0.16, 0.0, 0.09}, {0.24, 0.1, 0.21})}},
      {{"name", "jelly"}, {"kind", "elastic"}, {"material", "jelly"},
       {"shape", test::box({0.28, 0.08, 0.1}, {0.36, 0.16, 0.18})}, {"velocity", {0, -1, 0}}}};
  j["output"] = {{"vdb", false}, {"png", true}};
  j["render"] = {{"resolution", {320, 180}},
                 {"camera", {{"eye", {0.75, 0.45, 0.8}}, {"target", {0.2, 0.07, 0.15}}, {"fov_deg", 40}}}};
  return j;
}

std::vector<PreviewMesh> solidMeshes() {
  PreviewMesh pyramid;  // square base on the slab, apex above
  pyramid.xyz = {0.36f, 0.06f, 0.12f, 0.48f, 0.06f, 0.12f, 0.48f, 0.06f, 0.24f,
                 0.36f, 0.06f, 0.24f, 0.42f, 0.2f, 0.18f};
  pyramid.triangles = {0, 1, 4, 1, 2, 4, 2, 3, 4, 3, 0, 4, 0, 2, 1, 0, 3, 2};
  pyramid.object = 2;
  PreviewMesh ramp;  // an explicitly coloured inclined quad
  ramp.xyz = {0.05f, 0.0f, 0.3f, 0.25f, 0.0f, 0.3f, 0.25f, 0.1f, 0.38f, 0.05f, 0.1f, 0.38f};
  ramp.triangles = {0, 1, 2, 0, 2, 3};
  ramp.color = {0.75f, 0.75f, 0.78f};
  return {pyramid, ramp};
}

struct Simulated {
  PreviewSettings settings;
  PreviewFrame frame;
  double dx = 0;
};

// Runs the scene frame by frame as `triad run` does (same step sequence).
Simulated simulate(const json& j) {
  const fs::path dir = test::tempDir(j["name"].get<std::string>());
  const SceneDesc scene = loadScene(test::writeScene(dir, j));
  World w = buildSceneWorld(scene);
  Solver solver(w);
  for (int f = 1; f <= scene.frames.count; ++f) solver.advanceTo(f / scene.frames.fps);
  return {previewSettingsForScene(scene), previewFrameFromWorld(w), scene.domain.dx};
}

const Simulated& sandJelly() {
  static const Simulated s = simulate(sandJellyScene());
  return s;
}

Image render(const PreviewSettings& s, const PreviewFrame& f) {
  PreviewRenderer r(s);
  return r.render(f);
}

TEST(Golden, SandJellyLastFrame) {
  const Simulated& s = sandJelly();
  checkGolden("sand_jelly", render(s.settings, s.frame));
}

TEST(Golden, WaterAutomaticCamera) {
  const Simulated s = simulate(waterAutoScene());
  ASSERT_TRUE(s.settings.camera_automatic);
  checkGolden("water_auto", render(s.settings, s.frame));
}

TEST(Golden, SolidMeshesAndParticles) {
  json j = meshScene();
  j["frames"]["count"] = 0;
  Simulated s = simulate(j);
  s.frame.meshes = solidMeshes();
  checkGolden("meshes", render(s.settings, s.frame));
}

TEST(Golden, SnowRigidAndElasticSolids) {
  const Simulated s = simulate(solidsScene());
  ASSERT_EQ(s.frame.meshes.size(), 2u);  // the box and the jelly cube
  checkGolden("solids", render(s.settings, s.frame));
}

// A change of physics, not only of pictures, fails the goldens: the solids
// scene coupled through a single grid (snow sticks to the box instead of
// sliding off it and pushing it) differs visibly from its reference.
TEST(GoldenMetric, SingleGridCouplingFailsTheSolidsGolden) {
  if (updating()) GTEST_SKIP() << "updating references";
  json j = solidsScene();
  // Its own name, so its own temporary directory: Golden.SnowRigidAndElasticSolids
  // may be writing and reading the solids scene's at the same time.
  j["name"] = "solids_single_grid";
  j["solver"]["coupling"] = "single_grid";
  const Simulated s = simulate(j);
  const Image expected = readPng((kGoldenDir / "solids.png").string());
  const ImageDiff d = compareImages(render(s.settings, s.frame), expected, kPixelThreshold);
  std::cout << "single grid against the three-grid golden: " << describe(d) << "\n";
  EXPECT_FALSE(passes(d)) << describe(d);
}

// The metric is not vacuous: the golden scene with a block moved by two
// cells, or seen from a slightly moved camera, fails it; tiny noise passes.
TEST(GoldenMetric, MovedBlockAndMovedCameraFailNoisePasses) {
  if (updating()) GTEST_SKIP() << "updating references";
  const Simulated& s = sandJelly();
  const Image expected = readPng((kGoldenDir / "sand_jelly.png").string());
  ASSERT_TRUE(passes(compareImages(render(s.settings, s.frame), expected, kPixelThreshold)));

  PreviewFrame shifted = s.frame;
  for (size_t i = 0; i < shifted.object.size(); ++i)
    if (shifted.object[i] == 1) shifted.xyz[i * 3] += float(2 * s.dx);
  const ImageDiff moved = compareImages(render(s.settings, shifted), expected, kPixelThreshold);
  std::cout << "jelly moved by 2 cells: " << describe(moved) << "\n";
  EXPECT_FALSE(passes(moved)) << "jelly moved by 2 cells: " << describe(moved);

  PreviewSettings cam = s.settings;
  const double dist = std::hypot(cam.camera.eye[0] - cam.camera.target[0],
                                 cam.camera.eye[2] - cam.camera.target[2]);
  cam.camera.eye[0] += 0.02 * dist;  // 2% of the distance sideways
  const ImageDiff panned = compareImages(render(cam, s.frame), expected, kPixelThreshold);
  std::cout << "camera moved 2%: " << describe(panned) << "\n";
  EXPECT_FALSE(passes(panned)) << "camera moved 2%: " << describe(panned);

  // Round-off-sized motion (1e-4 m, 0.5% of a cell) of every particle passes.
  PreviewFrame noisy = s.frame;
  uint32_t state = 12345;
  for (float& x : noisy.xyz) {
    state = state * 1664525u + 1013904223u;
    x += float((double(state >> 8) / double(1u << 24) - 0.5) * 2e-4);
  }
  const ImageDiff noise = compareImages(render(s.settings, noisy), expected, kPixelThreshold);
  std::cout << "1e-4 m noise: " << describe(noise) << "\n";
  EXPECT_TRUE(passes(noise)) << "1e-4 m noise: " << describe(noise);
}

// ---- `triad render CACHE_DIR` end to end ----

using test::slurp;
using Result = test::CliResult;

Result triad(const fs::path& dir, const std::string& args) { return test::runTriad(dir, args); }

TEST(RenderCommand, RunThenRenderMatchesGolden) {
  const fs::path dir = test::tempDir("render_cmd");
  const std::string scene = test::writeScene(dir, sandJellyScene());
  const fs::path cache = dir / "cache";
  const Result run = triad(dir, "run " + scene + " --quiet --out " + cache.string());
  ASSERT_EQ(run.status, 0) << run.err;
  // When the run wrote previews itself, re-rendering must give the same bytes.
  const std::string from_run = slurp(previewImagePath(cache.string(), 4));
  const Result r = triad(dir, "render " + cache.string());
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("contact_sheet.png"), std::string::npos) << r.out;
  for (int f = 0; f <= 4; ++f) EXPECT_TRUE(fs::exists(previewImagePath(cache.string(), f))) << f;
  EXPECT_TRUE(fs::exists(previewSettingsPath(cache.string())));
  const Image sheet = readPng(contactSheetPath(cache.string()));
  EXPECT_GT(sheet.width, 5 * 100);
  if (!from_run.empty()) {
    EXPECT_EQ(from_run, slurp(previewImagePath(cache.string(), 4)));
  }
  if (!updating()) {
    const Image last = readPng(previewImagePath(cache.string(), 4));
    const ImageDiff d = compareImages(last, readPng((kGoldenDir / "sand_jelly.png").string()));
    EXPECT_TRUE(passes(d)) << describe(d);
  }
  // Rendering again gives the same bytes.
  const std::string first = slurp(previewImagePath(cache.string(), 2));
  const std::string sheet_bytes = slurp(contactSheetPath(cache.string()));
  ASSERT_EQ(triad(dir, "render " + cache.string()).status, 0);
  EXPECT_EQ(first, slurp(previewImagePath(cache.string(), 2)));
  EXPECT_EQ(sheet_bytes, slurp(contactSheetPath(cache.string())));
}

TEST(RenderCommand, BadInputExitsTwoNamingTheFile) {
  const fs::path dir = test::tempDir("render_bad");
  const Result missing = triad(dir, "render " + (dir / "nope").string());
  EXPECT_EQ(missing.status, 2);
  EXPECT_NE(missing.err.find("nope"), std::string::npos) << missing.err;

  // A cache without settings and without run.json.
  fs::create_directories(dir / "bare" / "particles");
  const Result bare = triad(dir, "render " + (dir / "bare").string());
  EXPECT_EQ(bare.status, 2);
  EXPECT_NE(bare.err.find("settings.json"), std::string::npos) << bare.err;

  // Settings but no particle caches.
  PreviewSettings s;
  writePreviewSettings((dir / "bare").string(), s);
  const Result empty = triad(dir, "render " + (dir / "bare").string());
  EXPECT_EQ(empty.status, 2);
  EXPECT_NE(empty.err.find("particles"), std::string::npos) << empty.err;

  // A corrupt particle cache.
  std::ofstream(dir / "bare/particles/particles.0000.ply", std::ios::binary)
      << "ply\nformat binary_little_endian 1.0\nelement vertex 1000\nproperty float x\n"
         "property float y\nproperty float z\nproperty int object\nend_header\nabc";
  const Result corrupt = triad(dir, "render " + (dir / "bare").string());
  EXPECT_EQ(corrupt.status, 2);
  EXPECT_NE(corrupt.err.find("particles.0000.ply"), std::string::npos) << corrupt.err;
  EXPECT_NE(corrupt.err.find("truncated"), std::string::npos) << corrupt.err;

  // A corrupt settings file.
  std::ofstream(dir / "bare/preview/settings.json") << "{ \"resolution\": ";
  const Result bad_settings = triad(dir, "render " + (dir / "bare").string());
  EXPECT_EQ(bad_settings.status, 2);
  EXPECT_NE(bad_settings.err.find("settings.json"), std::string::npos) << bad_settings.err;
}

// render.style "surface": the preview draws the water's surface mesh in
// water's blue instead of the particles in their object's palette colour.
TEST(RenderStyle, SurfaceDrawsWaterAsItsSurfaceInBlue) {
  const fs::path dir = test::tempDir("style");
  json j = test::baseScene("style", {0.4, 0.3, 0.3}, 0.025);
  j["frames"] = {{"count", 1}, {"fps", 24}};
  j["materials"] = {{"water", {{"model", "water"}, {"density", 1000}, {"bulk_modulus", 1e5}}}};
  j["objects"] = {{{"name", "pool"}, {"kind", "mpm"}, {"material", "water"},
                   {"shape", test::box({0.05, 0.0, 0.05}, {0.35, 0.12, 0.25})}}};
  j["output"] = {{"vdb", false}, {"ply", false}, {"checkpoints", false}};
  j["render"] = {{"resolution", {160, 90}}};
  auto bluish = [&](const std::string& style) {
    j["render"]["style"] = style;
    const fs::path out = dir / style;
    const test::CliResult r = test::runTriad(
        dir, "run " + test::writeScene(dir, j, style + ".json") + " --out " + out.string() + " --quiet");
    EXPECT_EQ(r.status, 0) << r.err;
    const Image img = readPng((out / "preview/preview.0000.png").string());
    size_t n = 0;
    for (int y = 0; y < img.height; ++y)
      for (int x = 0; x < img.width; ++x) {
        const uint8_t* p = img.at(x, y);
        if (p[2] > 3 * p[0] && p[2] > p[1] + 40) ++n;
      }
    return double(n) / double(img.width * img.height);
  };
  const double surface = bluish("surface"), particles = bluish("particles");
  std::printf("water-blue pixels: surface style %.1f%%, particle style %.1f%%\n", 100 * surface,
              100 * particles);
  EXPECT_GT(surface, 0.05);
  EXPECT_LT(particles, 0.005);

  // triad render draws a surface-style cache from its surface meshes: the
  // same image, byte for byte; without them it says so and draws particles.
  j["render"]["style"] = "surface";
  j["output"] = {{"vdb", false}, {"checkpoints", false}, {"surface_mesh", true}};
  const fs::path cache = dir / "cache";
  ASSERT_EQ(test::runTriad(dir, "run " + test::writeScene(dir, j, "cache.json") + " --out " +
                                    cache.string() + " --quiet")
                .status,
            0);
  const std::string preview = (cache / "preview/preview.0000.png").string();
  const std::string first = test::slurp(preview);
  test::CliResult r = test::runTriad(dir, "render " + cache.string());
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_TRUE(test::slurp(preview) == first) << "triad render drew another image";
  fs::remove_all(cache / "surfaces");
  r = test::runTriad(dir, "render " + cache.string());
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find("no surface meshes"), std::string::npos) << r.err;
  EXPECT_FALSE(test::slurp(preview) == first);
}

}  // namespace
}  // namespace triad
