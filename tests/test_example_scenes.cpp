// Every scene shipped in the repository (examples, benchmarks, validation)
// loads and builds: a key renamed in the loader, or a scene left behind by
// one, fails here rather than in a user's hands.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <vector>

#include "import/mesh_sampler.h"
#include "import/scene_loader.h"
#include "sim/errors.h"

namespace triad {
namespace {

namespace fs = std::filesystem;

TEST(ExampleScenes, AllLoadAndBuild) {
  const fs::path root(TRIAD_SOURCE_DIR);
  std::vector<fs::path> files;
  for (const char* dir : {"scenes", "bench/scenes", "bench/validation/scenes"})
    for (const auto& e : fs::directory_iterator(root / dir))
      if (e.path().extension() == ".json") files.push_back(e.path());
  ASSERT_GE(files.size(), 15u);
  auto cache = std::make_shared<MeshCache>();
  for (const fs::path& f : files) {
    try {
      const SceneDesc scene = loadScene(f.string());
      const World w = buildSceneWorld(scene, cache);
      EXPECT_GT(w.particleCount() + w.bodies.size() + w.elastics.size(), 0u) << f;
    } catch (const std::exception& e) {
      ADD_FAILURE() << f << ": " << e.what();
    }
  }
}

}  // namespace
}  // namespace triad
