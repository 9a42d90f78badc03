#pragma once
// What a scene will need, estimated from its description before anything
// is sampled: particles per object, bytes of memory, the first step and
// substeps per frame, disk per frame. `triad run` refuses a scene whose
// memory estimate exceeds the memory available (exit 2, naming the object
// that asks for the most) and says at once when a run will be extreme;
// `triad check` prints it.
#include <cstdint>
#include <string>
#include <vector>

#include "sim/scene_desc.h"

namespace triad {

struct ObjectEstimate {
  std::string name;
  double particles = 0;  // MPM particles (a source: its fill plus what it emits), or solid samples
  double bytes = 0;
};

// The short probe of this machine's rate (app/rate_probe.h), as the
// estimate reports it.
struct RateProbe {
  bool ran = false;
  double rate = 0.0;     // particle-substeps per second (MPM particles; solids' time included)
  double dx = 0.0;       // the probe's dx
  double particles = 0;  // MPM particles of the probe's world when timed
  long long steps = 0;   // substeps timed (after the warm-up)
  double seconds = 0.0;  // the probe's whole cost: build, warm-up and timed steps
  std::string why_not;   // when it did not run: why
};

struct SceneEstimate {
  std::vector<ObjectEstimate> objects;  // scene order
  double particles = 0;                 // MPM particles in all
  double memory_bytes = 0;              // peak resident: particles, grids, solids, the process itself
  // One frame's copy of the particles and solids, which `triad run` holds
  // while it writes that frame and steps the next (not in memory_bytes: a
  // run without room for it writes each frame before stepping on).
  double output_copy_bytes = 0;
  double baseline_bytes = 0;            // the process's own resident size (code, libraries)
  double first_dt = 0;                  // s, from the materials' wave speeds and solver.max_dt
  double substeps_per_frame = 0;
  double disk_bytes_per_frame = 0;      // PLY particles and VDB volumes, roughly
  double available_bytes = 0;           // physical memory, or a lower process limit
  double substeps = 0;                  // substeps of the whole run, at the first step
  // Wall seconds: particles x substeps at `rate`, particle-substeps per
  // second measured here by a probe, or without one the fixed rate of the
  // project's 2-core machine (bench/RESULTS.md). Solving only: output and
  // the build come on top. For an order of magnitude, not a promise.
  double wall_seconds = 0;
  double rate = 0;
  RateProbe probe;  // probe.ran: the rate is this machine's
};

// Particle-substeps per second on the project's 2-core machine.
constexpr double kFixedRate = 9e6;

// Sets the estimate's rate and wall time from a probe, or where it did not
// run from kFixedRate (its why_not said in the estimate).
void applyRate(SceneEstimate& e, const RateProbe& probe);

// Estimates `scene` (meshes are read for their volume, not voxelized).
// Throws InputError for a mesh it cannot read.
SceneEstimate estimateScene(const SceneDesc& scene);

// Throws InputError (naming the object asking for the most, its count and
// bytes, and what to change) when the memory estimate exceeds what is
// available.
void requireFits(const SceneDesc& scene, const SceneEstimate& e);

// Whether the run also has room for a frame's copy, to write it while the
// next frame steps (within 90% of what is available).
bool overlapFits(const SceneEstimate& e);

// One line per object and a summary, for people; and as JSON, for tools.
std::string describeEstimate(const SceneEstimate& e);
std::string estimateJson(const SceneEstimate& e);

// Warnings worth printing at once (over 1e5 substeps a frame, over a day).
std::vector<std::string> extremeWarnings(const SceneDesc& scene, const SceneEstimate& e);

}  // namespace triad
