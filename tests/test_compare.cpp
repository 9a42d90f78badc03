// `triad compare` end to end: a studio's regression check of a Triad shot.
// Two runs of one scene compare equal; a run with the block moved two cells
// differs, frame by frame, in its previews and its particles; a golden
// folder of previews alone is enough; thresholds from the command line
// decide; bad input exits 2 naming the folder.
#include <gtest/gtest.h>

#include <regex>

#include "cli_fixture.h"
#include "scene_fixture.h"

namespace triad {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

json dropScene(double x0) {
  json j = test::baseScene("drop", {0.4, 0.4, 0.4}, 0.04);
  j["frames"] = {{"count", 2}, {"fps", 24}};
  j["materials"] = {{"jelly",
                     {{"model", "fixed_corotated"},
                      {"density", 1000},
                      {"youngs_modulus", 2e4},
                      {"poisson_ratio", 0.3}}}};
  j["objects"] = {{{"name", "block"},
                   {"kind", "mpm"},
                   {"material", "jelly"},
                   {"shape", test::box({x0, 0.12, 0.12}, {x0 + 0.12, 0.24, 0.24})}}};
  j["output"] = {{"vdb", false}, {"checkpoints", false}};
  j["render"] = {{"resolution", {96, 64}}};
  return j;
}

fs::path run(const fs::path& dir, const std::string& name, const json& scene) {
  const fs::path out = dir / name;
  const test::CliResult r =
      test::runTriad(dir, "run " + test::writeScene(dir, scene, name + ".json") + " --out " +
                              out.string() + " --quiet");
  EXPECT_EQ(r.status, 0) << r.err;
  return out;
}

size_t count(const std::string& text, const std::string& word) {
  size_t n = 0;
  for (size_t at = text.find(word); at != std::string::npos; at = text.find(word, at + 1)) ++n;
  return n;
}

TEST(Compare, EqualRunsPassMovedBlockFailsFrameByFrame) {
  const fs::path dir = test::tempDir("compare");
  const fs::path a = run(dir, "a", dropScene(0.12)), b = run(dir, "b", dropScene(0.12)),
                 moved = run(dir, "moved", dropScene(0.2));

  // The same scene twice: every frame within tolerance, diff images written.
  test::CliResult r = test::runTriad(dir, "compare " + a.string() + " " + b.string());
  EXPECT_EQ(r.status, 0) << r.out << r.err;
  EXPECT_EQ(count(r.out, "  ok"), 3u) << r.out;
  EXPECT_NE(r.out.find("rms 0 m"), std::string::npos) << r.out;
  for (const char* f : {"diff.0000.png", "diff.0002.png", "contact_sheet.png"})
    EXPECT_TRUE(fs::exists(a / "compare" / f)) << f;

  // Moved by two cells: frame 0 already differs, in pixels and positions
  // (0.08 m for every particle), and the exit status says so.
  r = test::runTriad(
      dir, "compare " + moved.string() + " " + a.string() + " --out " + (dir / "diffs").string());
  EXPECT_EQ(r.status, 1) << r.out << r.err;
  EXPECT_EQ(count(r.out, "DIFFERS"), 3u) << r.out;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(r.out, m, std::regex(R"(frame 0000 .*rms ([0-9.e-]+) m)")))
      << r.out;
  EXPECT_NEAR(std::stod(m[1].str()), 0.08, 1e-4);
  EXPECT_TRUE(fs::exists(dir / "diffs" / "contact_sheet.png"));

  // Thresholds loose enough let it pass.
  r = test::runTriad(dir, "compare " + moved.string() + " " + a.string() +
                              " --max-fraction 1 --max-mean 255 --max-rms 1 --max-position 1");
  EXPECT_EQ(r.status, 0) << r.out << r.err;
}

TEST(Compare, GoldenFolderOfPreviewsAndBadInput) {
  const fs::path dir = test::tempDir("golden");
  const fs::path a = run(dir, "a", dropScene(0.12));
  // A golden folder: the previews only.
  fs::create_directories(dir / "golden" / "preview");
  for (const auto& e : fs::directory_iterator(a / "preview"))
    if (e.path().extension() == ".png")
      fs::copy(e.path(), dir / "golden" / "preview" / e.path().filename());
  test::CliResult r =
      test::runTriad(dir, "compare " + a.string() + " " + (dir / "golden").string());
  EXPECT_EQ(r.status, 0) << r.out << r.err;
  EXPECT_EQ(r.out.find("particles:"), std::string::npos) << r.out;
  // A frame the reference lacks is a difference.
  fs::remove(dir / "golden" / "preview" / "preview.0001.png");
  r = test::runTriad(dir, "compare " + a.string() + " " + (dir / "golden").string());
  EXPECT_EQ(r.status, 1) << r.out;
  EXPECT_NE(r.out.find("frame 0001  preview: missing in B"), std::string::npos) << r.out;
  // No such folder.
  r = test::runTriad(dir, "compare " + a.string() + " " + (dir / "nowhere").string());
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("nowhere"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("no such cache directory"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace triad
