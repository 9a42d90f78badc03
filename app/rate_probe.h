#pragma once
// This machine's rate for a scene, measured in a moment: the scene built
// again at a coarser dx (every object and material kept, at most some tens
// of thousands of particles), a warm-up step, then a few substeps timed.
// Its particle-substeps per second turn the estimate's particles and
// substeps into wall time. `triad check` and `triad run` probe before
// anything else; the probe writes nothing.
#include "import/estimate.h"
#include "sim/scene_desc.h"

namespace triad {

// Probes `scene`, whose estimate `e` says how many particles it makes.
// Never throws: a scene the probe cannot build or step is reported in
// why_not (the run itself judges it).
RateProbe probeRate(const SceneDesc& scene, const SceneEstimate& e);

}  // namespace triad
