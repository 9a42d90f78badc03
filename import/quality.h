#pragma once
// Quality presets of `triad run --quality draft|preview|final`: one switch
// that trades accuracy for cost. A preset scales the scene's domain.dx by a
// factor (and an object's own sample_spacing with it) and sets
// solver.particles_per_cell, solver.cfl and solver.transfer, and the
// preview's supersampling; everything else
// stays as the scene writes it. Without a preset the scene
// runs as written. The numbers come from the validation study of issue 7
// (bench/validation/, bench/RESULTS.md "Validation: accuracy against cost").
#include <optional>
#include <string>
#include <vector>

#include "sim/scene_desc.h"

namespace triad {

struct QualityPreset {
  std::string name;
  double dx_factor = 1.0;  // new dx = factor x the scene's dx
  int particles_per_cell = 8;
  double cfl = 0.4;
  TransferScheme transfer = TransferScheme::Apic;
  // The preview's supersampling (render.supersample): a draft's previews
  // are for layout and timing, and at 3x their rendering took longer than
  // the draft's simulation.
  int preview_supersample = 3;
};

// The presets, coarsest first.
const std::vector<QualityPreset>& qualityPresets();

// The preset called `name`, or nothing when there is none.
std::optional<QualityPreset> findQualityPreset(const std::string& name);

// "draft, preview, final": for messages and --help.
std::string qualityPresetNames();

// Applies the preset `name` to a loaded scene. The scaled dx is capped so
// that the domain still spans at least 4 cells along every axis (a quasi-2D
// slab of 4 cells keeps its 4 cells in draft). An unknown name, or a finer
// dx that would exceed the domain's cell limit, is an InputError naming
// "--quality".
void applyQuality(SceneDesc& scene, const std::string& name);

// The name of a transfer scheme as the scene format writes it.
std::string transferName(TransferScheme t);

}  // namespace triad
