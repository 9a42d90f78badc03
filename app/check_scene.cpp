#include "app/check_scene.h"

#include <cstdio>

#include "app/run_scene.h"
#include "import/estimate.h"
#include "import/quality.h"
#include "import/scene_loader.h"
#include "sim/errors.h"

namespace triad {

int checkScene(const CheckOptions& options) {
  try {
    if (!options.quality.empty() && !findQualityPreset(options.quality))
      throw InputError("--quality", "expected one of " + qualityPresetNames() + ", got \"" +
                                        options.quality + "\"");
    SceneDesc scene = loadScene(options.scene_path);
    if (!options.quality.empty()) applyQuality(scene, options.quality);
    const SceneEstimate e = estimateScene(scene);
    if (options.json) {
      std::printf("%s\n", estimateJson(e).c_str());
    } else {
      std::printf("%s: valid; estimate:\n%s", scene.source_path.c_str(),
                  describeEstimate(e).c_str());
    }
    for (const std::string& w : extremeWarnings(scene, e))
      std::fprintf(stderr, "triad: warning: %s\n", w.c_str());
    requireFits(scene, e);
  } catch (const InputError& err) {
    std::fprintf(stderr, "triad: error: %s\n", err.what());
    return kExitBadInput;
  }
  return kExitOk;
}

}  // namespace triad
