// `triad run --quality draft|preview|final` end to end: what each preset
// records and simulates, bad values, and --resume across presets.
#include <gtest/gtest.h>

#include "cli_fixture.h"
#include "import/quality.h"
#include "sim/errors.h"
#include "scene_fixture.h"

namespace triad {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using test::slurp;

// A small water column: a few thousand particles, a few frames in a second.
json qualityScene(int frames) {
  json j = test::baseScene("quality", {0.4, 0.4, 0.4}, 0.02);
  j["frames"] = {{"count", frames}, {"fps", 24}};
  j["solver"] = {{"particles_per_cell", 8}, {"cfl", 0.4}, {"transfer", "flip"},
                 {"flip_ratio", 0.9}};
  j["materials"] = {{"water", {{"model", "water"}, {"density", 1000}, {"bulk_modulus", 1e5}}}};
  j["objects"] = {{{"name", "column"}, {"kind", "mpm"}, {"material", "water"},
                   {"shape", test::box({0.0, 0.0, 0.0}, {0.16, 0.2, 0.16})}}};
  j["output"] = {{"vdb", false}, {"png", false}};
  return j;
}

json runJson(const fs::path& out) { return json::parse(slurp(out / "run.json")); }

test::CliResult run(const fs::path& dir, const std::string& scene, const fs::path& out,
                    const std::string& extra = "") {
  return test::runTriad(dir, "run " + scene + " --quiet --threads 2 --out " + out.string() + " " +
                                 extra);
}

TEST(Quality, PresetsScaleDxAndSetTheSolver) {
  const fs::path dir = test::tempDir("quality_presets");
  const std::string scene = test::writeScene(dir, qualityScene(1));
  ASSERT_EQ(run(dir, scene, dir / "as_written").status, 0);
  const test::CliResult draft = run(dir, scene, dir / "draft", "--quality draft");
  ASSERT_EQ(draft.status, 0) << draft.err;
  const json w = runJson(dir / "as_written"), d = runJson(dir / "draft");
  // Without the flag: the scene as written, recorded as such.
  EXPECT_TRUE(w["quality"]["preset"].is_null());
  EXPECT_DOUBLE_EQ(w["quality"]["dx"].get<double>(), 0.02);
  EXPECT_EQ(w["quality"]["particles_per_cell"].get<int>(), 8);
  EXPECT_EQ(w["quality"]["transfer"], "flip");
  // Every solver setting the run used, the defaults spelled out.
  EXPECT_EQ(w["solver"]["transfer"], "flip");
  EXPECT_DOUBLE_EQ(w["solver"]["flip_ratio"].get<double>(), 0.9);
  EXPECT_EQ(w["solver"]["contact_gap_fixed"], true);
  EXPECT_EQ(w["solver"]["coupling"], "three_grid");
  // Draft: the preset's coarser grid and sampling, fewer particles.
  const QualityPreset p = *findQualityPreset("draft");
  EXPECT_EQ(d["quality"]["preset"], "draft");
  EXPECT_DOUBLE_EQ(d["quality"]["dx"].get<double>(), 0.02 * p.dx_factor);
  EXPECT_GT(d["quality"]["dx"].get<double>(), 0.02);
  EXPECT_EQ(d["quality"]["particles_per_cell"].get<int>(), p.particles_per_cell);
  EXPECT_LE(d["quality"]["particles_per_cell"].get<int>(), 8);
  EXPECT_DOUBLE_EQ(d["quality"]["cfl"].get<double>(), p.cfl);
  EXPECT_EQ(d["quality"]["transfer"], transferName(p.transfer));
  // The solver settings recorded are the preset's.
  EXPECT_DOUBLE_EQ(d["solver"]["cfl"].get<double>(), p.cfl);
  EXPECT_EQ(d["solver"]["particles_per_cell"].get<int>(), p.particles_per_cell);
  EXPECT_LT(d["particles"]["total"].get<int>(), w["particles"]["total"].get<int>() / 4);
  // Final: a finer grid than as written, more particles.
  const test::CliResult fin = run(dir, scene, dir / "final", "--quality final");
  ASSERT_EQ(fin.status, 0) << fin.err;
  const json f = runJson(dir / "final");
  EXPECT_EQ(f["quality"]["preset"], "final");
  EXPECT_DOUBLE_EQ(f["quality"]["dx"].get<double>(), 0.02 * findQualityPreset("final")->dx_factor);
  EXPECT_GT(f["particles"]["total"].get<int>(), w["particles"]["total"].get<int>());
  EXPECT_TRUE(d["finished"].get<bool>());
}

TEST(Quality, DraftKeepsFourCellsAcrossAThinDomain) {
  // A quasi-2D slab 4 cells thick stays 4 cells thick: dx is capped.
  SceneDesc s;
  s.domain.min = {0, 0, 0};
  s.domain.max = {1.0, 0.5, 0.08};
  s.domain.dx = 0.02;
  applyQuality(s, "draft");
  EXPECT_DOUBLE_EQ(s.domain.dx, 0.02);
  s.domain.max = {1.0, 0.5, 0.5};
  s.domain.dx = 0.02;
  applyQuality(s, "final");
  EXPECT_DOUBLE_EQ(s.domain.dx, 0.02 * findQualityPreset("final")->dx_factor);
  EXPECT_THROW(applyQuality(s, "ultra"), InputError);
}

TEST(Quality, ObjectSampleSpacingFollowsDx) {
  // A solid given its own spacing keeps it in proportion: at dx (the
  // loader's coarsest) as written, still at dx under final, not 2 dx.
  SceneDesc s;
  s.domain.max = {1.0, 1.0, 1.0};
  s.domain.dx = 0.02;
  s.objects.resize(2);
  s.objects[0].sample_spacing = 0.02;
  applyQuality(s, "final");
  EXPECT_DOUBLE_EQ(s.objects[0].sample_spacing, s.domain.dx);
  EXPECT_EQ(s.objects[1].sample_spacing, 0.0);  // the default stays dx/2
}

// A draft's previews are rendered once per pixel, the others' at 3x: the
// cache's preview settings say so, and the draft's image is the
// resolution the scene asks for either way.
TEST(Quality, DraftRendersPreviewsWithoutSupersampling) {
  const fs::path dir = test::tempDir("quality_previews");
  json j = qualityScene(1);
  j["output"]["png"] = true;
  j["render"] = {{"resolution", {160, 90}}};
  const std::string scene = test::writeScene(dir, j);
  ASSERT_EQ(run(dir, scene, dir / "draft", "--quality draft").status, 0);
  ASSERT_EQ(run(dir, scene, dir / "preview", "--quality preview").status, 0);
  ASSERT_EQ(run(dir, scene, dir / "as_written").status, 0);
  auto supersample = [&](const char* name) {
    return json::parse(slurp(dir / name / "preview/settings.json"))["supersample"].get<int>();
  };
  EXPECT_EQ(supersample("draft"), findQualityPreset("draft")->preview_supersample);
  EXPECT_EQ(supersample("draft"), 1);
  EXPECT_EQ(supersample("preview"), 3);
  EXPECT_EQ(supersample("as_written"), 3);
  for (const char* name : {"draft", "preview"}) {
    const std::string png = slurp(dir / name / "preview/preview.0001.png");
    ASSERT_GT(png.size(), 24u) << name;
    // PNG's IHDR: width and height, big-endian, at bytes 16 and 20.
    auto be32 = [&](size_t at) {
      return (uint32_t(uint8_t(png[at])) << 24) | (uint32_t(uint8_t(png[at + 1])) << 16) |
             (uint32_t(uint8_t(png[at + 2])) << 8) | uint32_t(uint8_t(png[at + 3]));
    };
    EXPECT_EQ(be32(16), 160u) << name;
    EXPECT_EQ(be32(20), 90u) << name;
  }
}

TEST(Quality, UnknownValueExitsTwoWithAMessage) {
  const fs::path dir = test::tempDir("quality_unknown");
  const std::string scene = test::writeScene(dir, qualityScene(1));
  const test::CliResult r = run(dir, scene, dir / "cache", "--quality ultra");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("--quality"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("draft, preview, final"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("ultra"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "cache")) << "nothing may be written for bad input";
}

TEST(Quality, ResumeUnderAnotherQualityIsRefused) {
  const fs::path dir = test::tempDir("quality_resume");
  const std::string scene = test::writeScene(dir, qualityScene(2));
  const fs::path out = dir / "cache";
  ASSERT_EQ(run(dir, scene, out, "--quality draft").status, 0);
  const std::string frame2 = slurp(out / "particles/particles.0002.ply");

  const test::CliResult other = run(dir, scene, out, "--resume --quality preview");
  EXPECT_EQ(other.status, 2) << other.err;
  EXPECT_NE(other.err.find("refusing to resume"), std::string::npos) << other.err;
  EXPECT_NE(other.err.find("--quality draft"), std::string::npos) << other.err;
  EXPECT_NE(other.err.find("--quality preview"), std::string::npos) << other.err;
  const test::CliResult none = run(dir, scene, out, "--resume");
  EXPECT_EQ(none.status, 2) << none.err;
  EXPECT_NE(none.err.find("the scene as written"), std::string::npos) << none.err;
  EXPECT_TRUE(slurp(out / "particles/particles.0002.ply") == frame2) << "a refused resume writes nothing";

  // The same preset resumes.
  const test::CliResult same = run(dir, scene, out, "--resume --quality draft");
  EXPECT_EQ(same.status, 0) << same.err;
  EXPECT_NE(same.err.find("resuming after frame 2"), std::string::npos) << same.err;
  EXPECT_EQ(runJson(out)["quality"]["preset"], "draft");
}

}  // namespace
}  // namespace triad
