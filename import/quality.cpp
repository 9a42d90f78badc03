#include "import/quality.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "sim/errors.h"

namespace triad {

namespace {

constexpr double kMinCells = 4.0;        // the scene loader's limits
constexpr double kMaxCells = 4194304.0;

std::string number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.6g", v);
  return buf;
}

}  // namespace

const std::vector<QualityPreset>& qualityPresets() {
  // Chosen from the validation study (bench/RESULTS.md, "Validation:
  // accuracy against cost"): see the table there for each one's cost and error.
  static const std::vector<QualityPreset> presets = {
      {"draft", 2.0, 8, 0.6, TransferScheme::Apic, 1},
      {"preview", 1.0, 8, 0.4, TransferScheme::Apic, 3},
      {"final", 0.5, 8, 0.2, TransferScheme::Apic, 3},
  };
  return presets;
}

std::optional<QualityPreset> findQualityPreset(const std::string& name) {
  for (const QualityPreset& p : qualityPresets())
    if (p.name == name) return p;
  return std::nullopt;
}

std::string qualityPresetNames() {
  std::string s;
  for (const QualityPreset& p : qualityPresets()) s += (s.empty() ? "" : ", ") + p.name;
  return s;
}

std::string transferName(TransferScheme t) {
  switch (t) {
    case TransferScheme::Apic: return "apic";
    case TransferScheme::Pic: return "pic";
    case TransferScheme::Flip: return "flip";
  }
  return "?";
}

void applyQuality(SceneDesc& scene, const std::string& name) {
  const std::optional<QualityPreset> p = findQualityPreset(name);
  if (!p)
    throw InputError("--quality", "expected one of " + qualityPresetNames() + ", got \"" + name +
                                      "\"");
  double dx = scene.domain.dx * p->dx_factor;
  double min_extent = 1e300, max_extent = 0.0;
  for (int a = 0; a < 3; ++a) {
    const double e = scene.domain.max[a] - scene.domain.min[a];
    min_extent = std::min(min_extent, e);
    max_extent = std::max(max_extent, e);
  }
  // A coarser grid keeps at least 4 cells along every axis.
  if (dx > scene.domain.dx) dx = std::max(scene.domain.dx, std::min(dx, min_extent / kMinCells));
  if (max_extent / dx > kMaxCells)
    throw InputError("--quality", "\"" + name + "\" would make domain.dx " + number(dx) +
                                      " m, more than " + number(kMaxCells) +
                                      " cells along the domain's longest axis");
  // Solids sampled at a spacing of their own keep it in proportion to dx,
  // so that it stays within the loader's [dx/8, dx].
  for (ObjectDesc& o : scene.objects)
    if (o.sample_spacing > 0.0) o.sample_spacing *= dx / scene.domain.dx;
  scene.domain.dx = dx;
  scene.solver.particles_per_cell = p->particles_per_cell;
  scene.solver.cfl = p->cfl;
  scene.solver.transfer = p->transfer;
  scene.render.supersample = p->preview_supersample;
}

}  // namespace triad
