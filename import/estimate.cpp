#include "import/estimate.h"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>

#include <nlohmann/json.hpp>

#include "import/mesh_loader.h"
#include "import/param_dict.h"
#include "sim/errors.h"
#include "sim/materials/materials.h"
#include "sim/mpm/particles.h"
#include "sim/mpm/sampling.h"

namespace triad {

namespace {

// Bytes per MPM particle besides its state, at the peak: binning (source
// index 4, and the first step's runs of unsorted particles), the reorder's
// scratch and the sparse grid, which share one buffer (12), and what the
// process holds besides (bench/RESULTS.md, "Where the bytes go" and
// "Estimates before work": peak growth 143 bytes per jelly particle of
// 102 bytes of state).
constexpr double kParticleOverhead = 60.0;
// A rigid or collider sample: its rest data and its points each step.
constexpr double kSampleBytes = 90.0;
// An elastic sample (a FEM node and its six tetrahedra); implicit solids
// also keep each element's 12 x 12 stiffness.
constexpr double kElasticSampleBytes = 1000.0, kImplicitSampleBytes = 8000.0;

// Lattice points of one axis in [lo, hi) of the domain, at in-cell offsets o.
double axisPoints(double lo, double hi, double dmin, double dmax, double dx,
                  const std::vector<double>& offsets) {
  lo = std::max(lo, dmin);
  hi = std::min(hi, dmax);
  double n = 0;
  for (double o : offsets) {
    const double a = std::ceil((lo - dmin) / dx - o), b = std::ceil((hi - dmin) / dx - o);
    n += std::max(0.0, b - a);
  }
  return n;
}

// A shape's volume and the extent of its bounding box (inside the domain
// for boxes).
struct ShapeSize {
  double volume = 0;
  Vec3d extent = Vec3d::Zero();
};

ShapeSize shapeSize(const ShapeDesc& shape, const DomainDesc& d) {
  ShapeSize z;
  if (const auto* b = std::get_if<BoxDesc>(&shape)) {
    z.volume = 1;
    for (int a = 0; a < 3; ++a) {
      z.extent[a] = std::max(0.0, std::min(b->max[a], d.max[a]) - std::max(b->min[a], d.min[a]));
      z.volume *= z.extent[a];
    }
    return z;
  }
  if (const auto* s = std::get_if<SphereDesc>(&shape)) {
    z.volume = 4.0 / 3.0 * M_PI * std::pow(s->radius, 3);
    z.extent = Vec3d::Constant(2 * s->radius);
    return z;
  }
  MeshDesc m = std::get<MeshDesc>(shape);
  if (m.sequence_digits > 0) {
    m.resolved_path = sequenceFrame(m.resolved_path, m.sequence_digits, 0);
    m.sequence_digits = 0;
  }
  const TriangleMesh mesh = loadMesh(m).mesh;
  Vec3d lo, hi;
  mesh.bounds(lo, hi);
  z.volume = std::abs(mesh.signedVolume());
  z.extent = hi - lo;
  return z;
}

double shapeVolume(const ShapeDesc& shape, const DomainDesc& d) { return shapeSize(shape, d).volume; }

// The speed at which a source's material leaves it along one axis: seeded
// at v on the sites it empties, accelerated by a along the axis over the
// shape's length L. Kept full while new material enters all along it,
// steady flow leaves at u with u (u - v) = k a L: with a = 0, u = v (rho A
// v); with v = 0 material seeded from rest evenly over the length falls
// out in a mean (2/3) sqrt(2 L / a), so that k = 9/8 (u = 1.06 sqrt(a L)).
// Measured on water and sand sources 2-8 cells tall over 0.25-1 s
// (tests/test_estimate.cpp): v = 0 within 10% (sand, which has no
// tension, 0.2%); v = 1 m/s down 2-6% at 4 cells tall, 17% at 8, 29% at
// 2; v = 3 m/s 20% (the old |v| A estimate: 33% and 86% under).
double exitSpeed(double v, double a, double L) {
  constexpr double k = 9.0 / 8.0;
  if (a < 0) v = -v, a = -a;
  if (a == 0 || L <= 0) return std::abs(v);
  // Against the acceleration and fast enough, the material leaves upstream.
  if (v < 0 && v * v >= 4 * k * a * L) return 0.5 * (-v + std::sqrt(v * v - 4 * k * a * L));
  return 0.5 * (v + std::sqrt(v * v + 4 * k * a * L));
}

// What a source emits after its fill: along each axis of its bounding box,
// its material leaves through a face of area V / L at exitSpeed, from
// emit.start to emit.end or the scene's end.
double emittedParticles(const SceneDesc& scene, const ObjectDesc& o, double fill) {
  const double end = std::min(o.emit->end, scene.frames.count / scene.frames.fps);
  const double seconds = end - o.emit->start;
  if (seconds <= 0) return 0;
  const ShapeSize z = shapeSize(o.shape, scene.domain);
  double per_second = 0;
  for (int a = 0; a < 3; ++a)
    if (z.extent[a] > 0)
      per_second += exitSpeed(o.velocity[a], scene.gravity[a], z.extent[a]) / z.extent[a];
  return fill * per_second * seconds;
}

// MPM particles a shape gets: exact for boxes on a k x k x k lattice.
double mpmParticles(const ShapeDesc& shape, const DomainDesc& d, int ppc) {
  const int k = int(std::lround(std::cbrt(double(ppc))));
  if (const auto* b = std::get_if<BoxDesc>(&shape); b && k * k * k == ppc) {
    std::vector<double> offsets;
    for (int a = 0; a < k; ++a) offsets.push_back((a + 0.5) / k);
    double n = 1;
    for (int a = 0; a < 3; ++a) n *= axisPoints(b->min[a], b->max[a], d.min[a], d.max[a], d.dx, offsets);
    return n;
  }
  return shapeVolume(shape, d) * ppc / std::pow(d.dx, 3);
}

// What the process holds already (code, libraries): part of its peak.
double residentBytes() {
  std::ifstream statm("/proc/self/statm");
  double pages_total = 0, pages_resident = 0;
  if (!(statm >> pages_total >> pages_resident)) return 0;
  return pages_resident * double(sysconf(_SC_PAGE_SIZE));
}

double availableBytes() {
  double avail = double(sysconf(_SC_PHYS_PAGES)) * double(sysconf(_SC_PAGE_SIZE));
  rlimit r{};
  if (getrlimit(RLIMIT_AS, &r) == 0 && r.rlim_cur != RLIM_INFINITY) avail = std::min(avail, double(r.rlim_cur));
  std::ifstream cg("/sys/fs/cgroup/memory.max");
  double limit = 0;
  if (cg >> limit && limit > 0) avail = std::min(avail, limit);
  return avail;
}

std::string bytesText(double b) {
  char buf[32];
  const char* unit[] = {"B", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"};
  int u = 0;
  while (b >= 1024 && u < 6) b /= 1024, ++u;
  std::snprintf(buf, sizeof buf, "%.3g %s", b, unit[u]);
  return buf;
}

std::string countText(double n) {
  char buf[32];
  std::snprintf(buf, sizeof buf, n < 1e6 ? "%.0f" : "%.3g", n);
  return buf;
}

}  // namespace

SceneEstimate estimateScene(const SceneDesc& scene) {
  SceneEstimate e;
  const DomainDesc& d = scene.domain;
  const int ppc = scene.solver.particles_per_cell;
  double c = 0;  // fastest wave
  double dt_solid = scene.solver.max_dt;
  for (size_t i = 0; i < scene.objects.size(); ++i) {
    const ObjectDesc& o = scene.objects[i];
    ObjectEstimate oe;
    oe.name = o.name;
    try {
      if (o.kind == ObjectKind::Mpm) {
        const MaterialDesc& m = scene.materials[size_t(o.material)];
        ParticleSet probe;
        probe.model = makeMaterial(m);
        const double per = 66.0 + (probe.usesF() ? 36 : 0) + (probe.usesJ() ? 4 : 0) + kParticleOverhead;
        oe.particles = mpmParticles(o.shape, d, ppc);
        if (o.emit) {
          // A source: its fill (if it starts within the run), then what
          // flows out of it while it runs.
          if (o.emit->start >= scene.frames.count / scene.frames.fps) oe.particles = 0;
          else oe.particles += emittedParticles(scene, o, oe.particles);
        }
        oe.bytes = oe.particles * per;
        e.output_copy_bytes += oe.particles * (per - kParticleOverhead);
        e.particles += oe.particles;
        c = std::max(c, double(waveSpeed(m)));
      } else if (o.kind != ObjectKind::Sink) {
        const double h = o.sample_spacing > 0 ? o.sample_spacing : 0.5 * d.dx;
        oe.particles = shapeVolume(o.shape, d) / (h * h * h);
        double per = kSampleBytes;
        if (o.kind == ObjectKind::Elastic) {
          const MaterialDesc& m = scene.materials[size_t(o.material)];
          per = o.integrator == ElasticIntegrator::Implicit ? kImplicitSampleBytes : kElasticSampleBytes;
          // The explicit elements' step: a wave crossing an element's height,
          // and with damping the viscous limit rho h^2 / (6 eta).
          if (o.integrator == ElasticIntegrator::Explicit) {
            const double cfl = std::min(scene.solver.cfl, 0.5), height = h / std::sqrt(3.0);
            dt_solid = std::min(dt_solid, cfl * height / double(waveSpeed(m)));
            if (o.damping > 0)
              dt_solid = std::min(dt_solid, cfl * m.density * height * height / (6.0 * o.damping));
          }
        }
        oe.bytes = oe.particles * per;
        e.output_copy_bytes += oe.bytes;
      }
    } catch (const InputError& err) {
      if (!err.where().empty()) throw;
      throw InputError(scene.source_path + ": objects[" + std::to_string(i) + "].shape", err.what());
    }
    e.memory_bytes += oe.bytes;
    e.objects.push_back(oe);
  }
  e.baseline_bytes = residentBytes();
  e.memory_bytes += e.baseline_bytes;
  e.first_dt = scene.solver.max_dt;
  if (c > 0) e.first_dt = std::min(e.first_dt, scene.solver.cfl * d.dx / c);
  e.first_dt = std::min(e.first_dt, dt_solid);
  e.substeps_per_frame = 1.0 / (scene.frames.fps * e.first_dt);
  e.substeps = e.substeps_per_frame * scene.frames.count;
  RateProbe fixed;
  fixed.why_not = "not probed";
  applyRate(e, fixed);
  if (scene.output.ply) e.disk_bytes_per_frame += 36.0 * e.particles;
  if (scene.output.vdb) e.disk_bytes_per_frame += 16.0 * e.particles / ppc;
  e.available_bytes = availableBytes();
  return e;
}

void applyRate(SceneEstimate& e, const RateProbe& probe) {
  e.probe = probe;
  e.rate = probe.ran && probe.rate > 0 ? probe.rate : kFixedRate;
  e.wall_seconds = std::max(e.particles, 1.0) * e.substeps / e.rate;
}

void requireFits(const SceneDesc& scene, const SceneEstimate& e) {
  if (e.memory_bytes <= e.available_bytes) return;
  size_t worst = 0;
  for (size_t i = 1; i < e.objects.size(); ++i)
    if (e.objects[i].bytes > e.objects[worst].bytes) worst = i;
  const ObjectEstimate& o = e.objects[worst];
  throw InputError(
      scene.source_path + ": objects[" + std::to_string(worst) + "]",
      "'" + o.name + "' needs about " + countText(o.particles) + " particles or samples, " +
          bytesText(o.bytes) + "; the scene needs about " + bytesText(e.memory_bytes) +
          " in all, more than the " + bytesText(e.available_bytes) +
          " of memory available. Raise domain.dx (particles go as 1/dx^3; dx = " +
          formatNumber(scene.domain.dx) + ") or lower solver.particles_per_cell (" +
          std::to_string(scene.solver.particles_per_cell) + ")");
}

bool overlapFits(const SceneEstimate& e) {
  return e.memory_bytes + e.output_copy_bytes <= 0.9 * e.available_bytes;
}

std::string describeEstimate(const SceneEstimate& e) {
  std::string s;
  char buf[512];
  for (const ObjectEstimate& o : e.objects) {
    if (o.particles == 0) continue;
    std::snprintf(buf, sizeof buf, "  %-20s %12s particles or samples, %s\n", o.name.c_str(),
                  countText(o.particles).c_str(), bytesText(o.bytes).c_str());
    s += buf;
  }
  std::snprintf(buf, sizeof buf,
                "  memory about %s (the process's own included), and %s more to write a frame while "
                "the next steps, of %s available; first step %.3g s, %.3g substeps a frame; "
                "disk about %s a frame\n",
                bytesText(e.memory_bytes).c_str(), bytesText(e.output_copy_bytes).c_str(),
                bytesText(e.available_bytes).c_str(), e.first_dt,
                e.substeps_per_frame, bytesText(e.disk_bytes_per_frame).c_str());
  s += buf;
  const RateProbe& p = e.probe;
  if (p.ran)
    std::snprintf(buf, sizeof buf,
                  "  wall time about %.3g s solving, at %.3g particle-substeps/s measured here "
                  "(probe: dx %.3g, %s particles, %lld substeps, %.2f s)\n",
                  e.wall_seconds, e.rate, p.dx, countText(p.particles).c_str(), p.steps, p.seconds);
  else
    std::snprintf(buf, sizeof buf,
                  "  wall time about %.3g s solving, at the 2-core machine's fixed %.3g "
                  "particle-substeps/s (no probe: %s)\n",
                  e.wall_seconds, e.rate, p.why_not.c_str());
  return s + buf;
}

std::string estimateJson(const SceneEstimate& e) {
  nlohmann::ordered_json j;
  nlohmann::ordered_json objs = nlohmann::ordered_json::array();
  for (const ObjectEstimate& o : e.objects)
    objs.push_back({{"name", o.name}, {"particles", o.particles}, {"bytes", o.bytes}});
  j["objects"] = objs;
  j["particles"] = e.particles;
  j["memory_bytes"] = e.memory_bytes;
  j["output_copy_bytes"] = e.output_copy_bytes;
  j["baseline_bytes"] = e.baseline_bytes;
  j["available_bytes"] = e.available_bytes;
  j["first_dt"] = e.first_dt;
  j["substeps_per_frame"] = e.substeps_per_frame;
  j["disk_bytes_per_frame"] = e.disk_bytes_per_frame;
  j["wall_seconds"] = e.wall_seconds;
  j["rate_particle_substeps_per_s"] = e.rate;
  j["rate_from"] = e.probe.ran ? "probe" : "fixed";
  const RateProbe& p = e.probe;
  if (p.ran)
    j["rate_probe"] = {{"dx", p.dx}, {"particles", p.particles}, {"steps", p.steps},
                       {"seconds", p.seconds}};
  else
    j["rate_probe"] = {{"skipped", p.why_not}};
  return j.dump(2);
}

std::vector<std::string> extremeWarnings(const SceneDesc& scene, const SceneEstimate& e) {
  std::vector<std::string> w;
  char buf[512];
  if (e.substeps_per_frame > 1e5) {
    std::snprintf(buf, sizeof buf,
                  "%s: about %.3g substeps a frame (first step %.3g s, from the stiffest "
                  "material's wave speed and solver.cfl): a frame will take long",
                  scene.source_path.c_str(), e.substeps_per_frame, e.first_dt);
    w.push_back(buf);
  }
  if (e.wall_seconds > 86400) {
    std::snprintf(buf, sizeof buf, "%s: the run may take about %.3g days %s (%.3g particles)",
                  scene.source_path.c_str(), e.wall_seconds / 86400,
                  e.probe.ran ? "on this machine" : "on 2 cores", e.particles);
    w.push_back(buf);
  }
  return w;
}

}  // namespace triad
