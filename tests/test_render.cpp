// Preview renderer units: PNG files, determinism, camera, particles, ground,
// settings and PLY round trips, the contact sheet and the golden metric.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>

#include "export/ply_writer.h"
#include "render/particle_ply_reader.h"
#include "render/png_writer.h"
#include "render/preview_renderer.h"
#include "render/preview_settings_io.h"
#include "render/preview_writer.h"
#include "scene_fixture.h"
#include "sim/errors.h"
#include "sim/frame_name.h"

// Mesa's OSMesa/llvmpipe keeps a few small allocations past exit (its shader
// compiler and screen): not ours, so LeakSanitizer (sanitizer build) ignores them.
extern "C" const char* __lsan_default_suppressions() {
  return "leak:libOSMesa.so\nleak:libLLVM\nleak:libgallium\n";
}

namespace triad {
namespace {

namespace fs = std::filesystem;
using namespace triad::render;

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

Image pattern(int w, int h) {
  Image img(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      uint8_t* p = img.at(x, y);
      p[0] = uint8_t(x * 7 + y);
      p[1] = uint8_t(y * 13);
      p[2] = uint8_t((x ^ y) * 3);
    }
  return img;
}

// A small settings block: unit domain, 160x90, a camera looking at its centre.
PreviewSettings smallSettings() {
  PreviewSettings s;
  s.width = 160;
  s.height = 90;
  s.supersample = 2;
  s.domain = {{0, 0, 0}, {1, 1, 1}};
  s.camera = {{2.0, 1.5, 2.5}, {0.5, 0.5, 0.5}, 40.0};
  s.particle_radius = 0.05f;
  return s;
}

// Angle-free colour match: cosine between RGB directions.
double colourCosine(const uint8_t* p, const std::array<float, 3>& c) {
  const double a[3] = {double(p[0]), double(p[1]), double(p[2])};
  const double dot = a[0] * c[0] + a[1] * c[1] + a[2] * c[2];
  const double na = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
  const double nc = std::sqrt(double(c[0]) * c[0] + double(c[1]) * c[1] + double(c[2]) * c[2]);
  return na > 0 ? dot / (na * nc) : 0.0;
}

int nearestPaletteEntry(const uint8_t* p) {
  int best = -1;
  double best_cos = -1;
  for (int i = 0; i < kPaletteSize; ++i) {
    const double c = colourCosine(p, objectColor(i));
    if (c > best_cos) best_cos = c, best = i;
  }
  return best;
}

int saturation(const uint8_t* p) {
  return std::max({p[0], p[1], p[2]}) - std::min({p[0], p[1], p[2]});
}

TEST(Png, RoundTripKeepsPixelsAndHasNoTimeOrText) {
  const fs::path dir = test::tempDir("png_roundtrip");
  const Image img = pattern(37, 23);
  const std::string path = (dir / "a.png").string();
  writePng(path, img);
  const Image back = readPng(path);
  ASSERT_EQ(back.width, 37);
  ASSERT_EQ(back.height, 23);
  EXPECT_TRUE(back.rgb == img.rgb);
  // Same pixels, same bytes; and only IHDR / IDAT / IEND chunks.
  writePng((dir / "b.png").string(), img);
  const std::string bytes = slurp(path);
  EXPECT_EQ(bytes, slurp(dir / "b.png"));
  for (const char* chunk : {"tIME", "tEXt", "zTXt", "iTXt"})
    EXPECT_EQ(bytes.find(chunk), std::string::npos) << chunk;
  // Atomic: no temporary left beside it.
  int files = 0;
  for (const auto& e : fs::directory_iterator(dir)) files += e.is_regular_file();
  EXPECT_EQ(files, 2);
}

TEST(Png, ErrorsNameTheFile) {
  const fs::path dir = test::tempDir("png_errors");
  std::ofstream(dir / "junk.png") << "not a png";
  try {
    readPng((dir / "junk.png").string());
    FAIL() << "expected an error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("junk.png"), std::string::npos) << e.what();
  }
  EXPECT_THROW(writePng((dir / "no/such/dir/x.png").string(), pattern(4, 4)), std::runtime_error);
}

TEST(Render, SameInputGivesSameBytes) {
  PreviewSettings s = smallSettings();
  PreviewFrame f;
  for (int i = 0; i < 200; ++i) {
    f.xyz.insert(f.xyz.end(), {0.2f + 0.03f * float(i % 10), 0.05f + 0.03f * float(i / 40),
                               0.3f + 0.03f * float((i / 10) % 4)});
    f.object.push_back(uint16_t(i % 3));
  }
  PreviewMesh tri;
  tri.xyz = {0.7f, 0.0f, 0.7f, 0.9f, 0.0f, 0.7f, 0.8f, 0.3f, 0.8f};
  tri.triangles = {0, 1, 2};
  tri.color = {0.8f, 0.2f, 0.2f};
  f.meshes.push_back(tri);
  PreviewRenderer a(s);
  const Image first = a.render(f);
  const Image second = a.render(f);
  PreviewRenderer b(s);  // a fresh context too
  const Image third = b.render(f);
  EXPECT_TRUE(first.rgb == second.rgb);
  EXPECT_TRUE(first.rgb == third.rgb);
  const fs::path dir = test::tempDir("render_determinism");
  writePng((dir / "1.png").string(), first);
  writePng((dir / "2.png").string(), third);
  EXPECT_EQ(slurp(dir / "1.png"), slurp(dir / "2.png"));
}

TEST(Render, ParticleAtTargetIsAtImageCentreInItsColour) {
  PreviewSettings s = smallSettings();
  s.domain_outline = false;
  s.particle_radius = 0.15f;  // about 7 pixels
  for (int object : {0, 3, 5}) {
    PreviewFrame f;
    f.xyz = {0.5f, 0.5f, 0.5f};
    f.object = {uint16_t(object)};
    PreviewRenderer r(s);
    const Image img = r.render(f);
    const uint8_t* c = img.at(s.width / 2, s.height / 2);
    EXPECT_EQ(nearestPaletteEntry(c), object);
    EXPECT_GT(colourCosine(c, objectColor(object)), 0.995) << int(c[0]) << " " << int(c[1]) << " " << int(c[2]);
    // The sphere is round and centred: its coloured pixels are symmetric about the centre.
    int left = 0, right = 0, up = 0, down = 0;
    for (int d = 1; d < 40; ++d) {
      left += colourCosine(img.at(s.width / 2 - d, s.height / 2), objectColor(object)) > 0.99;
      right += colourCosine(img.at(s.width / 2 + d - 1, s.height / 2), objectColor(object)) > 0.99;
      up += colourCosine(img.at(s.width / 2, s.height / 2 - d), objectColor(object)) > 0.99;
      down += colourCosine(img.at(s.width / 2, s.height / 2 + d - 1), objectColor(object)) > 0.99;
    }
    EXPECT_GT(left, 2);
    EXPECT_NEAR(left, right, 1);
    EXPECT_NEAR(up, down, 1);
    EXPECT_LT(left, 30);
    // Far from the centre there is no particle colour.
    EXPECT_LT(saturation(img.at(5, 5)), 40);
  }
}

TEST(Render, EmptyFrameShowsOnlyBackgroundAndGround) {
  PreviewSettings s = smallSettings();
  PreviewRenderer r(s);
  const Image img = r.render(PreviewFrame{});
  int max_sat = 0;
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) max_sat = std::max(max_sat, saturation(img.at(x, y)));
  EXPECT_LT(max_sat, 40) << "a coloured pixel in an empty frame";
  // The ground is there: the floor below the target differs from the sky above it.
  const Projected floor = project(s.camera, s.width, s.height, {0.5, 0.0, 0.5});
  const uint8_t* g = img.at(int(floor.x), int(floor.y));
  const uint8_t* sky = img.at(s.width / 2, 2);
  EXPECT_GT(std::abs(int(g[0]) - int(sky[0])) + std::abs(int(g[2]) - int(sky[2])), 20);
  // The checker has two shades on the floor.
  std::vector<int> shades;
  for (double x = 0.05; x < 1.0; x += 0.1) {
    const Projected p = project(s.camera, s.width, s.height, {x, 0.0, 0.55});
    shades.push_back(img.at(int(p.x), int(p.y))[1]);
  }
  EXPECT_GT(*std::max_element(shades.begin(), shades.end()) -
                *std::min_element(shades.begin(), shades.end()), 8);
}

TEST(Camera, AutomaticCameraFramesAllDomainCorners) {
  const Box domains[] = {{{0, 0, 0}, {1, 1, 1}},
                         {{0, 0, 0}, {4, 0.5, 1}},
                         {{-1, 0, -1}, {-0.6, 2, -0.6}},
                         {{0, 0, 0}, {1, 0.8, 0.6}}};
  const int sizes[][2] = {{640, 360}, {300, 300}, {360, 640}};
  for (const Box& d : domains)
    for (const auto& sz : sizes) {
      const Camera cam = autoCamera(d, double(sz[0]) / sz[1]);
      double max_frac = 0;
      for (int i = 0; i < 8; ++i) {
        const render::Vec3 p{(i & 1) ? d.max[0] : d.min[0], (i & 2) ? d.max[1] : d.min[1],
                     (i & 4) ? d.max[2] : d.min[2]};
        const Projected q = project(cam, sz[0], sz[1], p);
        EXPECT_GT(q.depth, 0);
        EXPECT_GE(q.x, 0);
        EXPECT_LE(q.x, sz[0]);
        EXPECT_GE(q.y, 0);
        EXPECT_LE(q.y, sz[1]);
        max_frac = std::max({max_frac, std::fabs(q.x / sz[0] - 0.5) * 2, std::fabs(q.y / sz[1] - 0.5) * 2});
      }
      EXPECT_GT(max_frac, 0.8) << "the domain should fill the image, not float in it";
    }
}

TEST(Render, AutomaticCameraShowsParticlesAtTheCorners) {
  PreviewSettings s = smallSettings();
  s.width = 320;
  s.height = 180;
  s.domain = {{0, 0, 0}, {1, 0.8, 0.6}};
  s.camera = autoCamera(s.domain, 320.0 / 180.0);
  s.particle_radius = 0.04f;
  s.domain_outline = false;  // the box edges may pass in front of corner particles
  PreviewFrame f;
  for (int i = 0; i < 8; ++i) {
    const float r = s.particle_radius;
    f.xyz.insert(f.xyz.end(), {(i & 1) ? 1.0f - r : r, (i & 2) ? 0.8f - r : r, (i & 4) ? 0.6f - r : r});
    f.object.push_back(uint16_t(i % 3));
  }
  PreviewRenderer renderer(s);
  const Image img = renderer.render(f);
  for (int i = 0; i < 8; ++i) {
    const Projected p = project(s.camera, s.width, s.height,
                                {f.xyz[size_t(i) * 3], f.xyz[size_t(i) * 3 + 1], f.xyz[size_t(i) * 3 + 2]});
    ASSERT_TRUE(p.x >= 0 && p.x < s.width && p.y >= 0 && p.y < s.height) << i;
    EXPECT_EQ(nearestPaletteEntry(img.at(int(p.x), int(p.y))), i % 3) << "corner " << i;
    EXPECT_GT(saturation(img.at(int(p.x), int(p.y))), 40) << "corner " << i;
  }
}

TEST(Render, MeshesAreDrawnInTheirColour) {
  PreviewSettings s = smallSettings();
  PreviewFrame f;
  PreviewMesh quad;  // a vertical square facing the camera through the target
  quad.xyz = {0.3f, 0.3f, 0.5f, 0.7f, 0.3f, 0.5f, 0.7f, 0.7f, 0.5f, 0.3f, 0.7f, 0.5f};
  quad.triangles = {0, 1, 2, 0, 2, 3};
  quad.object = 4;
  f.meshes.push_back(quad);
  PreviewRenderer r(s);
  const Image img = r.render(f);
  EXPECT_EQ(nearestPaletteEntry(img.at(s.width / 2, s.height / 2)), 4);
  EXPECT_GT(saturation(img.at(s.width / 2, s.height / 2)), 40);
}

// Particles split between layers (as between processes), each layer drawn
// alone and composited by depth and draw-order key, give the image of all
// of them drawn at once, byte for byte: ties included (every third particle
// has a twin of another colour at the same place, drawn later, in another
// layer; some lie on the domain's outline; a mesh cuts through them).
TEST(Render, LayersCompositeToTheWholeFrame) {
  PreviewSettings s = smallSettings();
  s.legend = {{"sand", objectColor(1)}};
  PreviewFrame whole;
  std::vector<int> layer_of;
  auto add = [&](float x, float y, float z, int object, int layer) {
    whole.xyz.insert(whole.xyz.end(), {x, y, z});
    whole.object.push_back(uint16_t(object));
    layer_of.push_back(layer);
  };
  for (int i = 0; i < 600; ++i) {
    const float x = 0.03f * float(i % 12), y = 0.03f * float(i / 72),
                z = 0.03f * float((i / 12) % 6);
    add(x, y, z, i % 3, i % 3);
    if (i % 3 == 0) add(x, y, z, 5, 1 + (i / 3) % 2);  // the twin, drawn after it
  }
  PreviewMesh tri;
  tri.xyz = {0.0f, 0.0f, 0.1f, 0.4f, 0.0f, 0.1f, 0.2f, 0.3f, 0.1f};
  tri.triangles = {0, 1, 2};
  tri.object = 4;
  whole.meshes.push_back(tri);
  PreviewRenderer r(s);
  const Image expected = r.render(whole);

  std::vector<PreviewLayer> layers;
  for (int l = 0; l < 3; ++l) {
    PreviewFrame part;
    std::vector<uint64_t> keys;
    for (size_t i = 0; i < layer_of.size(); ++i)
      if (layer_of[i] == l) {
        part.xyz.insert(part.xyz.end(), &whole.xyz[3 * i], &whole.xyz[3 * i] + 3);
        part.object.push_back(whole.object[i]);
        keys.push_back(kFirstParticleKey + i);
      }
    layers.push_back(r.renderLayer(part.particles(), whole.meshes, keys.data()));
  }
  // One layer of every particle is the plain render.
  {
    std::vector<uint64_t> keys(whole.object.size());
    for (size_t i = 0; i < keys.size(); ++i) keys[i] = kFirstParticleKey + i;
    EXPECT_TRUE(r.finish(r.renderLayer(whole.particles(), whole.meshes, keys.data())).rgb ==
                expected.rgb);
  }
  PreviewLayer composite = layers[0];
  size_t sent = 0;
  for (int l : {2, 1}) {  // in any order
    const std::vector<LayerPixel> px = particlePixels(layers[size_t(l)]);
    sent += px.size();
    mergePixels(composite, px.data(), px.size());
  }
  EXPECT_GT(sent, 1000u);
  EXPECT_LT(sent, composite.pixels() / 2);
  const Image got = r.finish(composite);
  const ImageDiff diff = compareImages(got, expected, 0);
  std::printf("composited from %zu pixels of two layers: %.5f of pixels differ\n", sent,
              diff.fraction_over);
  EXPECT_TRUE(got.rgb == expected.rgb);

  // The keys decide ties: the later-drawn twins winning them is another image.
  PreviewLayer later = layers[0];
  for (int l : {1, 2}) {
    std::vector<LayerPixel> px = particlePixels(layers[size_t(l)]);
    for (LayerPixel& p : px) p.key = 0;
    mergePixels(later, px.data(), px.size());
  }
  EXPECT_FALSE(r.finish(later).rgb == expected.rgb);

  // A layer without particles (a process that holds none) is the frame's
  // ground and solids.
  PreviewFrame solids_only;
  solids_only.meshes = whole.meshes;
  EXPECT_TRUE(r.finish(r.renderLayer({}, whole.meshes, nullptr)).rgb == r.render(solids_only).rgb);
  EXPECT_TRUE(r.renderParticlePixels({}, whole.meshes, nullptr).empty());

  // Keys out of order, or outside the particles' range, are refused.
  const uint64_t bad[2] = {5, 5};
  EXPECT_THROW(r.renderLayer({whole.xyz.data(), whole.object.data(), 2}, {}, bad),
               std::runtime_error);
  EXPECT_THROW(r.finish(PreviewLayer{}), std::runtime_error);
}

// More particles than one draw batch (65,536), split between two layers
// particle by particle: still the whole frame's bytes. A layer's particle
// pixels read back in bands are those of the whole layer.
TEST(Render, LayersCompositeAcrossDrawBatches) {
  PreviewSettings s = smallSettings();
  s.particle_radius = 0.01f;
  PreviewFrame whole;
  uint32_t state = 12345;
  auto next = [&]() {
    state = state * 1664525u + 1013904223u;
    return float(state >> 8) / float(1 << 24);
  };
  const size_t n = 150000;
  for (size_t i = 0; i < n; ++i) {
    whole.xyz.insert(whole.xyz.end(), {next(), 0.5f * next(), next()});
    whole.object.push_back(uint16_t(i % 4));
  }
  PreviewRenderer r(s);
  const Image expected = r.render(whole);
  PreviewLayer composite;
  for (int l = 0; l < 2; ++l) {
    PreviewFrame part;
    std::vector<uint64_t> keys;
    for (size_t i = size_t(l); i < n; i += 2) {
      part.xyz.insert(part.xyz.end(), &whole.xyz[3 * i], &whole.xyz[3 * i] + 3);
      part.object.push_back(whole.object[i]);
      keys.push_back(kFirstParticleKey + i);
    }
    if (l == 0) {
      composite = r.renderLayer(part.particles(), {}, keys.data());
      continue;
    }
    const std::vector<LayerPixel> banded =
        r.renderParticlePixels(part.particles(), {}, keys.data());
    const std::vector<LayerPixel> all =
        particlePixels(r.renderLayer(part.particles(), {}, keys.data()));
    ASSERT_EQ(banded.size(), all.size());
    EXPECT_EQ(std::memcmp(banded.data(), all.data(), all.size() * sizeof(LayerPixel)), 0);
    // Each pixel's key is the particle's drawn there, in every batch: its
    // colour is that particle's object's (the palette's nearest entry;
    // shading and edges blur a few).
    size_t agree = 0, late = 0;
    for (const LayerPixel& p : banded) {
      const size_t i = size_t(p.key - kFirstParticleKey);
      agree += nearestPaletteEntry(p.rgba) == whole.object[i];
      late += i >= (size_t(1) << 17);
    }
    EXPECT_GT(late, banded.size() / 20);  // from the second batch
    EXPECT_GT(agree, 0.97 * double(banded.size())) << agree << " of " << banded.size();
    mergePixels(composite, banded.data(), banded.size());
  }
  EXPECT_TRUE(r.finish(composite).rgb == expected.rgb);
}

TEST(Render, RejectsUnusableSettings) {
  PreviewSettings s = smallSettings();
  s.width = 0;
  EXPECT_THROW(PreviewRenderer{s}, std::runtime_error);
  s = smallSettings();
  s.width = 100000;
  EXPECT_THROW(PreviewRenderer{s}, std::runtime_error);
}

// The legend lists what is drawn, in the colour it is drawn in: each MPM
// object (or, in surface style, each material once) and each solid, never a
// sink; it survives settings.json, and drawLegend paints its swatches.
TEST(PreviewLegend, WhatIsDrawnInItsColour) {
  const fs::path dir = test::tempDir("legend");
  nlohmann::json j = test::baseScene("legend", {1, 0.5, 0.5}, 0.05);
  j["materials"] = {
      {"water", {{"model", "water"}, {"density", 1000}, {"bulk_modulus", 1e5}}},
      {"sand", {{"model", "drucker_prager"}, {"density", 1600}, {"youngs_modulus", 1e6},
                {"poisson_ratio", 0.3}}}};
  j["objects"] = {
      {{"name", "pool"}, {"kind", "mpm"}, {"material", "water"},
       {"shape", test::box({0.1, 0, 0.1}, {0.3, 0.1, 0.3})}},
      {{"name", "pond"}, {"kind", "mpm"}, {"material", "water"},
       {"shape", test::box({0.5, 0, 0.1}, {0.7, 0.1, 0.3})}},
      {{"name", "pile"}, {"kind", "mpm"}, {"material", "sand"},
       {"shape", test::box({0.8, 0, 0.1}, {0.9, 0.1, 0.3})}},
      {{"name", "crate"}, {"kind", "rigid"}, {"density", 500},
       {"shape", test::box({0.4, 0.3, 0.2}, {0.5, 0.4, 0.3})}},
      {{"name", "drain"}, {"kind", "sink"}, {"shape", test::box({0, 0, 0}, {0.05, 0.05, 0.05})}}};
  auto labels = [](const PreviewSettings& s) {
    std::vector<std::string> out;
    for (const LegendEntry& e : s.legend) out.push_back(e.label);
    return out;
  };
  const PreviewSettings particles = previewSettingsForScene(loadScene(test::writeScene(dir, j)));
  EXPECT_EQ(labels(particles), (std::vector<std::string>{"pool", "pond", "pile", "crate"}));
  EXPECT_EQ(particles.legend[1].color, objectColor(1));
  EXPECT_EQ(particles.legend[3].color, objectColor(3));
  j["render"] = {{"style", "surface"}};
  const PreviewSettings surface = previewSettingsForScene(loadScene(test::writeScene(dir, j)));
  EXPECT_EQ(labels(surface), (std::vector<std::string>{"water", "sand", "crate"}));
  EXPECT_EQ(surface.legend[0].color, materialColor(MaterialModel::Water, 0));
  EXPECT_EQ(surface.legend[1].color, materialColor(MaterialModel::DruckerPrager, 2));
  EXPECT_NE(surface.legend[0].color, surface.legend[1].color);

  j["render"]["legend"] = false;
  EXPECT_TRUE(previewSettingsForScene(loadScene(test::writeScene(dir, j))).legend.empty());

  writePreviewSettings(dir.string(), surface, "legend");
  const PreviewSettings back = readPreviewSettings(previewSettingsPath(dir.string()));
  ASSERT_EQ(labels(back), labels(surface));
  for (size_t i = 0; i < back.legend.size(); ++i) EXPECT_EQ(back.legend[i].color, surface.legend[i].color);

  Image img(200, 100, 128);
  drawLegend(img, surface.legend);
  const uint8_t* swatch = img.at(3, 3);  // inside the first swatch (pad 2, 5 wide)
  for (int c = 0; c < 3; ++c) EXPECT_EQ(swatch[c], std::lround(surface.legend[0].color[size_t(c)] * 255.0f)) << c;
  EXPECT_LT(img.at(20, 1)[0], 128);  // the panel (31 pixels wide here) darkens what is under it
  EXPECT_EQ(img.at(199, 99)[0], 128);  // and nothing beyond it
}

// Frame file names as the cache's listing, resume and tidying read them:
// the stem may hold dots, the frame is the number before the extension.
TEST(FrameName, SplitsStemFrameAndExtension) {
  FrameName n;
  ASSERT_TRUE(parseFrameName("particles.0042.ply", n));
  EXPECT_EQ(n.stem, "particles");
  EXPECT_EQ(n.frame, 42);
  EXPECT_EQ(n.ext, "ply");
  ASSERT_TRUE(parseFrameName("my.crate.v2.123456789.ply", n));
  EXPECT_EQ(n.stem, "my.crate.v2");
  EXPECT_EQ(n.frame, 123456789);
  ASSERT_TRUE(parseFrameName("a.0001.0002.vtp", n));
  EXPECT_EQ(n.stem, "a.0001");
  EXPECT_EQ(n.frame, 2);
  // Too few or too many digits (ten would overflow an int), no stem, no
  // digits, not digits.
  for (const char* bad :
       {"particles.042.ply", "particles.1234567890.ply", ".0001.ply", "particles..ply",
        "particles.00a1.ply", "particles.0001", "0001.ply", "particles.0001.ply.tmp123", ""})
    EXPECT_FALSE(parseFrameName(bad, n)) << bad;
  // A narrower range (checkpoints: 4-6 digits).
  EXPECT_TRUE(parseFrameName("state.123456.bin", n, 4, 6));
  EXPECT_FALSE(parseFrameName("state.1234567.bin", n, 4, 6));
  EXPECT_TRUE(isTemporaryName("particles.0001.ply.tmp12345"));
  EXPECT_TRUE(isTemporaryName("run.json.tmp7"));
  for (const char* bad : {"particles.0001.ply", ".tmp12", "a.tmp", "a.tmp12x", "a.tmpl2"})
    EXPECT_FALSE(isTemporaryName(bad)) << bad;
}

TEST(PreviewSettingsIo, RoundTripAndSceneDefaults) {
  const fs::path dir = test::tempDir("preview_settings");
  nlohmann::json j = test::baseScene("settings", {1, 0.5, 0.5}, 0.02);
  j["solver"] = {{"particles_per_cell", 8}};
  j["materials"]["jelly"] = {{"model", "fixed_corotated"}, {"density", 1000},
                             {"youngs_modulus", 5e4}, {"poisson_ratio", 0.3}};
  j["objects"].push_back({{"name", "cube"}, {"kind", "mpm"}, {"material", "jelly"},
                          {"shape", test::box({0.1, 0, 0.1}, {0.2, 0.1, 0.2})}});
  const SceneDesc scene = loadScene(test::writeScene(dir, j));
  const PreviewSettings s = previewSettingsForScene(scene);
  EXPECT_TRUE(s.camera_automatic);
  EXPECT_EQ(s.width, 640);
  EXPECT_EQ(s.height, 360);
  EXPECT_NEAR(s.particle_radius, 0.005, 1e-7);  // 0.5 * 0.02 / 2
  ASSERT_EQ(s.object_names.size(), 1u);
  writePreviewSettings(dir.string(), s, "settings");
  const PreviewSettings back = readPreviewSettings(previewSettingsPath(dir.string()));
  EXPECT_EQ(back.width, s.width);
  EXPECT_EQ(back.height, s.height);
  EXPECT_EQ(back.supersample, s.supersample);
  for (size_t i = 0; i < 3; ++i) {
    EXPECT_DOUBLE_EQ(back.camera.eye[i], s.camera.eye[i]);
    EXPECT_DOUBLE_EQ(back.camera.target[i], s.camera.target[i]);
    EXPECT_DOUBLE_EQ(back.domain.max[i], s.domain.max[i]);
  }
  EXPECT_EQ(back.particle_radius, s.particle_radius);
  EXPECT_EQ(back.object_names, s.object_names);
  // A broken file names itself and the key.
  std::ofstream(dir / "bad.json") << R"({"resolution": [640], "camera": {}})";
  try {
    readPreviewSettings((dir / "bad.json").string());
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("bad.json: resolution"), std::string::npos) << e.what();
  }
}

TEST(ParticlePly, ReadsWhatTheCacheWriterWritesAndRejectsTruncation) {
  const fs::path dir = test::tempDir("preview_ply");
  nlohmann::json j = test::baseScene("ply", {0.2, 0.2, 0.2}, 0.02);
  j["materials"]["jelly"] = {{"model", "fixed_corotated"}, {"density", 1000},
                             {"youngs_modulus", 5e4}, {"poisson_ratio", 0.3}};
  j["materials"]["water"] = {{"model", "water"}, {"density", 1000}, {"bulk_modulus", 1e5}};
  j["objects"].push_back({{"name", "a"}, {"kind", "mpm"}, {"material", "jelly"},
                          {"shape", test::box({0.02, 0.02, 0.02}, {0.08, 0.08, 0.08})}});
  j["objects"].push_back({{"name", "b"}, {"kind", "mpm"}, {"material", "water"},
                          {"shape", test::box({0.1, 0.02, 0.1}, {0.16, 0.08, 0.16})}});
  const World w = test::loadWorld(dir, j);
  const std::string path = (dir / "p.ply").string();
  writeParticlesPly(path, w);
  PreviewFrame f;
  readParticlesPly(path, f);
  const PreviewFrame expect = previewFrameFromWorld(w);
  ASSERT_GT(expect.object.size(), 100u);
  EXPECT_EQ(f.xyz, expect.xyz);
  EXPECT_EQ(f.object, expect.object);
  EXPECT_EQ(std::count(f.object.begin(), f.object.end(), 1), long(w.object_particles[1]));
  // Truncated data and a broken header are input errors naming the file.
  const std::string bytes = slurp(path);
  std::ofstream(dir / "cut.ply", std::ios::binary) << bytes.substr(0, bytes.size() - 10);
  std::ofstream(dir / "junk.ply", std::ios::binary) << "ply\nformat ascii 1.0\nend_header\n";
  for (const char* bad : {"cut.ply", "junk.ply", "missing.ply"}) {
    try {
      readParticlesPly((dir / bad).string(), f);
      FAIL() << bad;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(bad), std::string::npos) << e.what();
    }
  }
}

TEST(ContactSheet, GridOfThumbnailsWithLabels) {
  std::vector<Image> frames(11, pattern(320, 180));
  std::vector<int> labels(11);
  for (int i = 0; i < 11; ++i) labels[size_t(i)] = i;
  const Image sheet = contactSheet(frames, labels, 160, 4);
  EXPECT_EQ(sheet.width, 4 * 160 + 5 * 4);
  EXPECT_EQ(sheet.height, 3 * 90 + 4 * 4);
  // A label's white pixels sit in the first thumbnail's corner.
  int white = 0;
  for (int y = 4; y < 20; ++y)
    for (int x = 4; x < 20; ++x) white += sheet.at(x, y)[0] == 255 && sheet.at(x, y)[1] == 255;
  EXPECT_GT(white, 3);
  // Writing from a cache's preview folder picks up every preview in order.
  const fs::path dir = test::tempDir("contact_sheet");
  fs::create_directories(dir / "preview");
  for (int i : {0, 1, 2}) writePng(previewImagePath(dir.string(), i), pattern(64, 36));
  EXPECT_EQ(writeContactSheet(dir.string()), 3);
  const Image back = readPng(contactSheetPath(dir.string()));
  EXPECT_EQ(back.width, 3 * 64 + 4 * 4);
}

// A run keeps each preview's thumbnail as it writes it; the sheet at the
// end reads back only the frames it does not hold (a resumed run's earlier
// ones), and comes out the same either way.
TEST(ContactSheet, HeldThumbnailsGiveTheSheetOfThePreviewsOnDisk) {
  const fs::path dir = test::tempDir("contact_sheet_held");
  fs::create_directories(dir / "preview");
  std::vector<Image> images;
  for (int i = 0; i < 3; ++i) {
    Image img = pattern(300, 170);
    for (size_t k = 0; k < img.rgb.size(); k += 3) img.rgb[k] = uint8_t(img.rgb[k] + 60 * i);
    writePng(previewImagePath(dir.string(), i), img);
    images.push_back(img);
  }
  ASSERT_EQ(writeContactSheet(dir.string()), 3);
  const Image from_disk = readPng(contactSheetPath(dir.string()));
  EXPECT_EQ(from_disk.rgb, contactSheet(images, {0, 1, 2}).rgb);
  // Frame 0 read back, frames 1 and 2 held.
  ASSERT_EQ(writeContactSheet(dir.string(),
                              {{1, holdThumbnail(images[1])}, {2, holdThumbnail(images[2])}}),
            3);
  EXPECT_EQ(readPng(contactSheetPath(dir.string())).rgb, from_disk.rgb);
  // Every frame held.
  ASSERT_EQ(writeContactSheet(dir.string(), {{0, holdThumbnail(images[0])},
                                             {1, holdThumbnail(images[1])},
                                             {2, holdThumbnail(images[2])}}),
            3);
  EXPECT_EQ(readPng(contactSheetPath(dir.string())).rgb, from_disk.rgb);
  // A held thumbnail is what the sheet shows (not the file read again)...
  ASSERT_EQ(writeContactSheet(dir.string(), {{2, holdThumbnail(images[0])}}), 3);
  EXPECT_NE(readPng(contactSheetPath(dir.string())).rgb, from_disk.rgb);
  // ...unless its size is not the sheet's: then the file is read.
  ASSERT_EQ(writeContactSheet(dir.string(), {{2, holdThumbnail(pattern(150, 170))}}), 3);
  EXPECT_EQ(readPng(contactSheetPath(dir.string())).rgb, from_disk.rgb);
}

TEST(GoldenMetric, IdenticalPassesShiftedFails) {
  const Image a = pattern(100, 60);
  ImageDiff d = compareImages(a, a);
  EXPECT_TRUE(d.same_size);
  EXPECT_EQ(d.fraction_over, 0.0);
  EXPECT_EQ(d.mean_abs, 0.0);
  Image b = a;
  for (int y = 0; y < 10; ++y)
    for (int x = 0; x < 10; ++x) b.at(x, y)[0] = uint8_t(b.at(x, y)[0] + 100);
  d = compareImages(a, b);
  EXPECT_NEAR(d.fraction_over, 100.0 / 6000.0, 1e-12);
  EXPECT_FALSE(compareImages(a, pattern(100, 61)).same_size);
  const Image diff = diffImage(a, b);
  EXPECT_GT(diff.at(5, 5)[0], 200);
  EXPECT_EQ(diff.at(5, 5)[1], 0);
}

}  // namespace
}  // namespace triad
