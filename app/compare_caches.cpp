#include "app/compare_caches.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <stdexcept>
#include <vector>

#include "app/run_scene.h"
#include "export/atomic_file.h"
#include "render/image.h"
#include "render/particle_ply_reader.h"
#include "render/png_writer.h"
#include "render/preview_settings_io.h"
#include "sim/errors.h"

namespace triad {

namespace {

namespace fs = std::filesystem;

// The default particle tolerance: 1e-4 of the domain's diagonal (from
// run.json), or 1e-4 m without one.
double defaultRms(const fs::path& cache) {
  std::ifstream in(cache / "run.json");
  if (!in) return 1e-4;
  try {
    const nlohmann::json j = nlohmann::json::parse(in);
    double d2 = 0.0;
    for (int k = 0; k < 3; ++k) {
      const double e =
          j.at("domain").at("max")[k].get<double>() - j.at("domain").at("min")[k].get<double>();
      d2 += e * e;
    }
    return d2 > 0.0 ? 1e-4 * std::sqrt(d2) : 1e-4;
  } catch (const std::exception&) {
    return 1e-4;
  }
}

struct ParticleDiff {
  size_t matched = 0, only_a = 0, only_b = 0;
  double rms = 0.0, max = 0.0;
};

// Particles matched by id.
ParticleDiff compareParticles(const std::string& a_path, const std::string& b_path) {
  render::PreviewFrame a, b;
  std::vector<uint32_t> ia, ib;
  render::readParticlesPly(a_path, a, &ia);
  render::readParticlesPly(b_path, b, &ib);
  std::vector<std::pair<uint32_t, size_t>> sb;
  sb.reserve(ib.size());
  for (size_t i = 0; i < ib.size(); ++i) sb.emplace_back(ib[i], i);
  std::sort(sb.begin(), sb.end());
  ParticleDiff d;
  double sum2 = 0.0;
  std::vector<bool> used(ib.size(), false);
  for (size_t i = 0; i < ia.size(); ++i) {
    const auto it = std::lower_bound(sb.begin(), sb.end(), std::make_pair(ia[i], size_t(0)));
    if (it == sb.end() || it->first != ia[i]) {
      ++d.only_a;
      continue;
    }
    used[it->second] = true;
    double e2 = 0.0;
    for (int k = 0; k < 3; ++k) {
      const double e = double(a.xyz[3 * i + size_t(k)]) - double(b.xyz[3 * it->second + size_t(k)]);
      e2 += e * e;
    }
    sum2 += e2;
    d.max = std::max(d.max, std::sqrt(e2));
    ++d.matched;
  }
  d.only_b = size_t(std::count(used.begin(), used.end(), false));
  d.rms = d.matched ? std::sqrt(sum2 / double(d.matched)) : 0.0;
  return d;
}

}  // namespace

int compareCaches(const CompareOptions& o) {
  try {
    for (const std::string& dir : {o.a, o.b})
      if (!fs::is_directory(dir))
        throw InputError(dir,
                         "no such cache directory (expected a run's output or a golden folder)");
    const fs::path a(o.a), b(o.b);
    const fs::path out = o.out.empty() ? a / "compare" : fs::path(o.out);
    const double max_rms = o.max_rms >= 0 ? o.max_rms : defaultRms(b);
    const double max_position = o.max_position >= 0 ? o.max_position : 10.0 * max_rms;

    const auto pa = render::listFrameFiles((a / "preview").string(), "preview", "png"),
               pb = render::listFrameFiles((b / "preview").string(), "preview", "png");
    const auto qa = render::listFrameFiles((a / "particles").string(), "particles", "ply"),
               qb = render::listFrameFiles((b / "particles").string(), "particles", "ply");
    // Previews are compared where either has them; particles where both
    // caches hold particle files at all (a golden folder may keep previews only).
    const bool particles = !qa.empty() && !qb.empty();
    std::set<int> frames;
    for (const auto* m : {&pa, &pb})
      for (const auto& [f, p] : *m) frames.insert(f);
    if (particles)
      for (const auto* m : {&qa, &qb})
        for (const auto& [f, p] : *m) frames.insert(f);
    if (frames.empty())
      throw InputError(o.b, "nothing to compare: neither cache has preview/preview.FFFF.png files" +
                                std::string(particles ? "" : " or particles in both"));
    makeDirectories(out.string());

    std::printf(
        "compare %s against %s: pixel threshold %d, at most %.3g%% of pixels and a mean "
        "of %.3g; particles RMS %.3g m, largest %.3g m\n",
        o.a.c_str(), o.b.c_str(), o.pixel_threshold, 100 * o.max_fraction, o.max_mean, max_rms,
        max_position);
    std::vector<render::Image> diffs;
    std::vector<int> labels;
    int failed = 0;
    for (const int f : frames) {
      bool ok = true;
      char buf[512];
      std::string line;
      std::snprintf(buf, sizeof(buf), "frame %04d", f);
      line = buf;
      // The preview against the reference.
      const auto ia = pa.find(f), ib = pb.find(f);
      if (pa.empty() && pb.empty()) {
        // Neither cache has previews (output.png false): particles alone.
      } else if (ia == pa.end() || ib == pb.end()) {
        line += ia == pa.end() ? "  preview: missing in A" : "  preview: missing in B";
        ok = false;
      } else {
        const render::Image x = render::readPng(ia->second), y = render::readPng(ib->second);
        const render::ImageDiff d = render::compareImages(x, y, o.pixel_threshold);
        if (!d.same_size) {
          std::snprintf(buf, sizeof(buf), "  preview: sizes differ (%dx%d, %dx%d)", x.width,
                        x.height, y.width, y.height);
          ok = false;
        } else {
          const bool pass = d.fraction_over <= o.max_fraction && d.mean_abs <= o.max_mean;
          std::snprintf(buf, sizeof(buf), "  preview: %.3f%% over, mean %.3f, max %d%s",
                        100 * d.fraction_over, d.mean_abs, d.max_abs, pass ? "" : " (over)");
          ok = ok && pass;
          render::Image diff = render::diffImage(x, y, o.pixel_threshold);
          char name[32];
          std::snprintf(name, sizeof(name), "diff.%04d.png", f);
          render::writePng((out / name).string(), diff);
          diffs.push_back(std::move(diff));
          labels.push_back(f);
        }
        line += buf;
      }
      // The particles, matched by id.
      if (particles) {
        const auto ja = qa.find(f), jb = qb.find(f);
        if (ja == qa.end() || jb == qb.end()) {
          line += ja == qa.end() ? "  particles: missing in A" : "  particles: missing in B";
          ok = false;
        } else {
          const ParticleDiff d = compareParticles(ja->second, jb->second);
          const bool pass =
              d.only_a == 0 && d.only_b == 0 && d.rms <= max_rms && d.max <= max_position;
          std::snprintf(buf, sizeof(buf), "  particles: %zu matched, rms %.3g m, max %.3g m",
                        d.matched, d.rms, d.max);
          line += buf;
          if (d.only_a || d.only_b) {
            std::snprintf(buf, sizeof(buf), ", ids only in A %zu, only in B %zu", d.only_a,
                          d.only_b);
            line += buf;
          }
          if (!pass) line += " (over)";
          ok = ok && pass;
        }
      }
      line += ok ? "  ok" : "  DIFFERS";
      std::printf("%s\n", line.c_str());
      if (!ok) ++failed;
    }
    if (!diffs.empty())
      render::writePng((out / "contact_sheet.png").string(), render::contactSheet(diffs, labels));
    std::printf("%zu frames, %d differ%s; diff images in %s\n", frames.size(), failed,
                failed ? "" : " (all within tolerance)", out.string().c_str());
    return failed ? kExitRunFailed : kExitOk;
  } catch (const InputError& e) {
    std::fprintf(stderr, "triad: error: %s\n", e.what());
    return kExitBadInput;
  } catch (const std::runtime_error& e) {
    std::fprintf(stderr, "triad: error: %s\n", e.what());
    return kExitBadInput;
  }
}

}  // namespace triad
