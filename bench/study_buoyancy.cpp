// Buoyancy of thin and submerged solids, measured against Archimedes:
//   study_buoyancy [--start rest|submerged|dropped|film] [--thick CELLS]
//                  [--ratio RHO/RHO_WATER] [--dx M] [--time S]
//                  [--kind rigid|elastic] [--implicit] [--solver JSON] [--trace]
// A slab 0.30 m long, CELLS * 0.02 m thick and 0.12 m deep in water 0.2 m
// deep (bulk modulus 2e5 Pa), the setups. Prints the slab's bottom,
// the water level (from the water's volume) and the draft against
// Archimedes' over time, and a summary line.
//   --wide        water 0.1 m wide all round the slab (default: 2 cells in z)
//   --fixed       the slab is fixed: its force is the buoyancy
//   --implicit    an elastic slab integrated by backward Euler
//   --settle S    the slab is held in place for S seconds, then released
//   --drive V     the slab is moved up at V m/s, gravity off (STUDY_GRAVITY=1: on)
//   --start film  a block of water (STUDY_FILM_H m deep, default 0.04) on
//                 the slab's top (fixed: 0.12 m up; else on the floor); prints
//                 how much of it is still on the slab and how high it stands
// STUDY_BULK sets the water's bulk modulus (default 2e5 Pa); STUDY_FRICTION
// the slab's friction; STUDY_SHIFT moves the slab up by that many cells (the
// water stays where it was put for the unshifted slab); STUDY_FLOW=1
// prints the water's flux down past the slab against what an
// incompressible fluid must carry, and the water's speed under and over it.
// STUDY_VY starts the slab moving vertically at that speed (m/s).
// STUDY_DAMPING gives an elastic slab that Kelvin-Voigt viscosity (Pa s).
// STUDY_SPHERE=1 puts a sphere of diameter CELLS * 0.02 m in place of the
// slab; STUDY_SURFACE=1 prints the water surface across the slab and the
// spread of particle J by layer at the end.
// STUDY_HYDRO=1 starts the water at its hydrostatic pressure (the objects'
// "initial_pressure": "hydrostatic") instead of at none, so that the tank
// does not ring; STUDY_STEPS=1 prints the body's height and velocity every
// step; STUDY_FIELD=1 prints, at the end, the water's mean velocity (mm/s)
// and pressure (Pa) per cell in the slab's mid-plane; STUDY_DRIVE_X=1 makes
// --drive move the slab along its length (x) instead of up; STUDY_HOLD=1
// keeps a driven slab where it started (its faces move, it does not);
// STUDY_SPAN=1 makes the slab span the tank along x (no ends there);
// STUDY_FPS sets the frame rate of the trace (default 20), and
// STUDY_FIELD=all prints the field at every frame.
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <nlohmann/json.hpp>
#include <string>

#include "import/mesh_sampler.h"
#include "import/scene_loader.h"
#include "sim/solver.h"
#include <variant>

namespace {

using nlohmann::json;
using triad::Vec3d;

json box(const std::array<double, 3>& lo, const std::array<double, 3>& hi) {
  return {{"box", {{"min", lo}, {"max", hi}}}};
}

struct Setup {
  std::string start = "rest", kind = "rigid";
  double thick = 3, ratio = 0.5, dx = 0.02, time = 2.0;
  json solver = json::object();
  bool trace = false, fixed = false, implicit = false;
  double settle = 0;  // s the slab is held in place before it is released
  double drive = 0;   // m/s: the slab is moved up at this speed, gravity off
};

static double kX = 0.5, kY = 0.4, kZ = 0.2, kDepth = 0.2;
static double kSx0 = 0.1, kSx1 = 0.4, kSz0 = 0.04, kSz1 = 0.16;

}  // namespace

int main(int argc, char** argv) {
  Setup s;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() { return std::string(argv[++i]); };
    if (a == "--start") s.start = next();
    else if (a == "--kind") s.kind = next();
    else if (a == "--thick") s.thick = std::stod(next());
    else if (a == "--ratio") s.ratio = std::stod(next());
    else if (a == "--dx") s.dx = std::stod(next());
    else if (a == "--time") s.time = std::stod(next());
    else if (a == "--solver") s.solver = json::parse(next());
    else if (a == "--trace") s.trace = true;
    else if (a == "--fixed") s.fixed = true;
    else if (a == "--implicit") s.implicit = true;
    else if (a == "--settle") s.settle = std::stod(next());
    else if (a == "--drive") s.drive = std::stod(next());
    else if (a == "--wide") {  // gaps of 0.1 m all round
      kZ = 0.32;
      kSz0 = 0.1;
      kSz1 = 0.22;
      kX = 0.5;
    }
  }
  if (getenv("STUDY_SPAN")) {  // the slab spans the tank along x
    kSx0 = 0.0;
    kSx1 = kX;
  }
  const double t = s.thick * 0.02, rho = 1000 * s.ratio;
  const double area = kX * kZ, slab_area = (kSx1 - kSx0) * (kSz1 - kSz0);
  const double draft = s.ratio < 1 ? s.ratio * t : t;
  double sx0 = kSx0, sx1 = kSx1, y0 = 0;
  std::vector<json> water;
  if (s.start == "rest") {
    const double level = kDepth + draft * slab_area / area;
    y0 = level - draft;
    water = {box({0, 0, 0}, {kX, y0, kZ}), box({0, y0, 0}, {kSx0, level, kZ}),
             box({kSx1, y0, 0}, {kX, level, kZ}), box({kSx0, y0, 0}, {kSx1, level, kSz0}),
             box({kSx0, y0, kSz1}, {kSx1, level, kZ})};
  } else if (s.start == "submerged") {
    y0 = 0.5 * kDepth - 0.5 * t;
    const double y1 = y0 + t, top = kDepth + t * slab_area / area;
    water = {box({0, 0, 0}, {kX, y0, kZ}), box({0, y1, 0}, {kX, top, kZ}),
             box({0, y0, 0}, {kSx0, y1, kZ}), box({kSx1, y0, 0}, {kX, y1, kZ}),
             box({kSx0, y0, 0}, {kSx1, y1, kSz0}), box({kSx0, y0, kSz1}, {kSx1, y1, kZ})};
  } else if (s.start == "film") {  // a block of water on the slab's top, spreading off it
    y0 = s.fixed ? 0.12 : 0.0;
    const double film = getenv("STUDY_FILM_H") ? std::stod(getenv("STUDY_FILM_H")) : 0.04;
    water = {box({0.15, y0 + t, 0.06}, {0.35, y0 + t + film, 0.14})};
    if (getenv("STUDY_FLOOR")) water = {box({0.15, 0, 0.06}, {0.35, 0.04, 0.14})};
  } else {  // dropped: 1 cm onto a block of water that slumps
    water = {box({0, 0, 0}, {0.3, 0.3, kZ})};
    y0 = 0.31;
    sx0 = 0.0;
    sx1 = 0.3;
  }
  json j = {{"version", 1},
            {"name", "buoyancy"},
            {"domain", {{"min", {0, 0, 0}}, {"max", {kX, kY, kZ}}, {"dx", s.dx}}},
            {"solver", s.solver},
            {"materials",
             {{"water", {{"model", "water"}, {"density", 1000}, {"bulk_modulus", getenv("STUDY_BULK") ? std::stod(getenv("STUDY_BULK")) : 2e5}}},
              {"solid",
               {{"model", "fixed_corotated"}, {"density", rho}, {"youngs_modulus", 3e5},
                {"poisson_ratio", 0.3}}}}},
            {"objects", json::array()}};
  if (s.drive != 0 && !getenv("STUDY_GRAVITY")) j["gravity"] = {0, 0, 0};
  // Boxes of no volume (beside a slab that spans the tank) are left out.
  water.erase(
      std::remove_if(water.begin(), water.end(),
                     [](const json& b) {
                       for (int d = 0; d < 3; ++d)
                         if (b["box"]["max"][d].get<double>() <= b["box"]["min"][d].get<double>())
                           return true;
                       return false;
                     }),
      water.end());
  for (size_t k = 0; k < water.size(); ++k) {
    j["objects"].push_back({{"name", "w" + std::to_string(k)}, {"kind", "mpm"},
                            {"material", "water"}, {"shape", water[k]}});
    if (getenv("STUDY_HYDRO")) j["objects"].back()["initial_pressure"] = "hydrostatic";
  }
  if (getenv("STUDY_SHIFT")) y0 += std::stod(getenv("STUDY_SHIFT")) * s.dx;
  json slab = {{"name", "slab"}, {"kind", s.kind}, {"shape", box({sx0, y0, kSz0}, {sx1, y0 + t, kSz1})}};
  if (getenv("STUDY_SPHERE"))
    slab["shape"] = {{"sphere", {{"center", {0.5 * kX, y0 + 0.5 * t, 0.5 * kZ}}, {"radius", 0.5 * t}}}};
  if (s.kind == "rigid") slab["density"] = rho;
  else slab["material"] = "solid";
  if (s.fixed) slab["fixed"] = true;
  if (s.implicit) slab["integrator"] = "implicit";
  if (getenv("STUDY_VY")) slab["velocity"] = {0, std::stod(getenv("STUDY_VY")), 0};
  if (getenv("STUDY_DAMPING") && s.kind == "elastic")
    slab["damping"] = std::stod(getenv("STUDY_DAMPING"));
  if (getenv("STUDY_FRICTION")) slab["friction"] = std::stod(getenv("STUDY_FRICTION"));
  j["objects"].push_back(slab);

  triad::World w;
  try {
    w = triad::buildSceneWorld(triad::parseScene(j, "study_buoyancy.json"));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 1;
  }
  triad::Solver solver(w);

  // The slab's bottom and mean height; the water level from the water's
  // volume, the slab's submerged part displacing it.
  const int slab_object = int(j["objects"].size()) - 1;
  auto bottom = [&]() {
    if (!w.bodies.empty()) return w.bodies[0].state.x.y() - 0.5 * t;
    if (s.kind == "mpm") {
      double sum = 0;
      size_t cnt = 0;
      for (const triad::ParticleSet& set : w.sets)
        for (size_t i = 0; i < set.size(); ++i)
          if (set.object[i] == slab_object) {
            sum += set.x[i].y();
            ++cnt;
          }
      return sum / double(cnt) - 0.5 * t;
    }
    // An elastic slab's centre of mass less half its thickness: it bends
    // and tilts in moving water, where its lowest node is not its bottom.
    return w.elastics[0].fem.centreOfMass().y() - 0.5 * t;
  };
  auto level = [&]() {
    double v = 0;
    for (const triad::ParticleSet& set : w.sets)
      for (size_t i = 0; i < set.size(); ++i)
        if (set.object[i] != slab_object) v += set.volume * set.volumeRatio(i);
    const double b = bottom();
    double l = v / area;
    if (l > b) l = std::min((v - slab_area * b) / (area - slab_area), (v + slab_area * t) / area);
    return l;
  };
  if (s.settle > 0 && !w.bodies.empty()) {
    const triad::RigidState held = w.bodies[0].state;
    solver.advanceTo(s.settle, [&](double) { w.bodies[0].state = held; });
  }
  // Where the slab starts: its samples lie on the domain's lattice of
  // spacing dx / 2, so its faces move to the nearest lattice plane, up to a
  // quarter cell from the box's (and so does the water built round it).
  const double start_error = (level() - bottom() - draft) / s.dx;
  const double wall0 = omp_get_wtime();
  const triad::Mat3d rotation0 =
      w.bodies.empty() ? triad::Mat3d::Identity() : w.bodies[0].rotation();
  // Frames (20 a second; STUDY_FPS sets another rate).
  const double fps = getenv("STUDY_FPS") ? std::stod(getenv("STUDY_FPS")) : 20.0;
  const int n = int(std::round(s.time * fps));
  double mean_draft = 0;
  int counted = 0;
  const Vec3d held_x = w.bodies.empty() ? Vec3d::Zero() : w.bodies[0].state.x;
  for (int k = 1; k <= n; ++k) {
    solver.resetLoads();
    if (s.drive != 0)
      solver.advanceTo(s.settle + k / fps, [&](double) {
        if (getenv("STUDY_STEPS"))  // where the step left the body, before the drive resets it
          std::printf("    step x %.6f y %.6f v %.5f %.5f\n", w.bodies[0].state.x.x(),
                      w.bodies[0].state.x.y(), w.bodies[0].state.v.x(), w.bodies[0].state.v.y());
        if (getenv("STUDY_HOLD")) w.bodies[0].state.x = held_x;  // moving faces that stay put
        w.bodies[0].state.v = getenv("STUDY_DRIVE_X") ? Vec3d(s.drive, 0, 0) : Vec3d(0, s.drive, 0);
        w.bodies[0].state.L.setZero();
      });
    else if (getenv("STUDY_STEPS") && !w.bodies.empty())
      // Each step's body height and velocity, to see the motion inside a frame.
      solver.advanceTo(s.settle + k / fps, [&](double dt) {
        std::printf("    step dt %.2e y %.6f vy %.5f\n", dt, w.bodies[0].state.x.y(),
                    w.bodies[0].state.v.y());
      });
    else
      solver.advanceTo(s.settle + k / fps);
    const double b = bottom(), l = level(), d = l - b;
    if (getenv("STUDY_FIELD") && (k == n || std::string(getenv("STUDY_FIELD")) == "all")) {
      // The water's mean velocity (mm/s), and with `pressure` then its mean
      // pressure (Pa), per cell in a slice of the tank, y up and `along`
      // (0: x, 2: z) across the page, of the particles within `half` of
      // `centre` along the third axis.
      const int ny = int(std::round(0.24 / s.dx));
      auto slice = [&](char tag, int along, double centre, double half, bool pressure) {
        const int other = 2 - along, nu = int(std::round((along == 0 ? kX : kZ) / s.dx));
        std::vector<double> su(size_t(nu * ny)), sv(su.size()), sp(su.size()), cnt(su.size());
        for (const triad::ParticleSet& set : w.sets) {
          const auto* wat = std::get_if<triad::Water<float>>(&set.model);
          if (!wat) continue;
          for (size_t i = 0; i < set.size(); ++i) {
            const triad::Vec3f& x = set.x[i];
            if (std::abs(x[other] - centre) > half) continue;
            const int cu = int(x[along] / s.dx), cy = int(x.y() / s.dx);
            if (cu < 0 || cu >= nu || cy < 0 || cy >= ny) continue;
            const size_t c = size_t(cy * nu + cu);
            su[c] += set.v[i].x();
            sv[c] += set.v[i].y();
            sp[c] += wat->pressure(set.J[i]);
            cnt[c] += 1;
          }
        }
        for (const bool p : {false, true}) {
          if (p && !pressure) break;
          for (int cy = ny - 1; cy >= 0; --cy) {
            std::printf("%c%5.3f", p ? 'p' : tag, (cy + 0.5) * s.dx);
            for (int cu = 0; cu < nu; ++cu) {
              const size_t c = size_t(cy * nu + cu);
              if (cnt[c] == 0)
                std::printf(p ? "     ." : "    .    ");
              else if (p)
                std::printf(" %5.0f", sp[c] / cnt[c]);
              else
                std::printf(" %4.0f,%-4.0f", 1000 * su[c] / cnt[c], 1000 * sv[c] / cnt[c]);
            }
            std::printf("\n");
          }
        }
      };
      // The slab's mid-plane (0.04 m either side of it in z): vx, vy and
      // the pressure; across the tank at the slab's middle (0.02 m either
      // side in x): vx, vy.
      slice('y', 0, 0.5 * (kSz0 + kSz1), 0.04, true);
      slice('x', 2, 0.5 * (sx0 + sx1), 0.02, false);
    }
    // The water's force on the slab over the interval, in units of the
    // slab's weight.
    const double weight = w.bodies.empty() ? 1.0 : rho * t * slab_area * 9.81;
    const double fy = w.bodies.empty() ? 0.0 : solver.bodyLoads()[0].force().y() / weight;
    // Mean water pressure in layers one cell thick under and over the
    // slab, inside its footprint and far from it, at the same heights.
    double ps[4] = {0, 0, 0, 0};
    int pn[4] = {0, 0, 0, 0};
    for (const triad::ParticleSet& set : w.sets) {
      const auto* wat = std::get_if<triad::Water<float>>(&set.model);
      if (!wat) continue;
      for (size_t i = 0; i < set.size(); ++i) {
        const triad::Vec3f& x = set.x[i];
        const bool under = x.y() > b - 1.5 * s.dx && x.y() < b - 0.5 * s.dx;
        const bool over = x.y() > b + t + 0.5 * s.dx && x.y() < b + t + 1.5 * s.dx;
        if (!under && !over) continue;
        const bool inside = x.x() > sx0 + s.dx && x.x() < sx1 - s.dx && x.z() > kSz0 + s.dx &&
                            x.z() < kSz1 - s.dx;
        const bool far = x.x() < sx0 - 2 * s.dx || x.x() > sx1 + 2 * s.dx;
        if (!inside && !far) continue;
        const int m = (under ? 0 : 2) + (inside ? 0 : 1);
        ps[m] += wat->pressure(set.J[i]);
        pn[m]++;
      }
    }
    for (int m = 0; m < 4; ++m) ps[m] /= std::max(1, pn[m]);
    if (getenv("STUDY_FLOW")) {
      // Downward water flux through the slab's mid-plane outside it, against
      // what an incompressible fluid must carry (the slab's rise times its area).
      double flux = 0, vin = 0, vover = 0;
      int nin = 0, nover = 0;
      const double ym = b + 0.5 * t;
      for (const triad::ParticleSet& set : w.sets) {
        if (!std::get_if<triad::Water<float>>(&set.model)) continue;
        for (size_t i = 0; i < set.size(); ++i) {
          const triad::Vec3f& x = set.x[i];
          const bool foot = x.x() > sx0 && x.x() < sx1 && x.z() > kSz0 && x.z() < kSz1;
          if (std::abs(x.y() - ym) < 0.5 * s.dx && !foot) flux += set.v[i].y() * set.volume / s.dx;
          if (foot && x.y() > b - 1.0 * s.dx && x.y() < b) { vin += set.v[i].y(); ++nin; }
          if (foot && x.y() > b + t && x.y() < b + t + s.dx) { vover += set.v[i].y(); ++nover; }
        }
      }
      const double vb = w.bodies.empty() ? 0.0 : w.bodies[0].state.v.y();
      std::printf("  flux through gaps %.5f m3/s (needed %.5f); water v under %.3f over %.3f body %.3f\n",
                  flux, -vb * slab_area, vin / std::max(nin, 1), vover / std::max(nover, 1), vb);
    }

    if (s.trace) {
      // Water particles inside the slab's box (none should be), and how
      // many lie within half a cell outside its faces. A rigid slab's box
      // moves and turns with it (a dropped slab drifts and tilts); an
      // elastic one's is taken upright over its start, at its bottom.
      const Vec3d half(0.5 * (sx1 - sx0), 0.5 * t, 0.5 * (kSz1 - kSz0));
      const Vec3d centre = w.bodies.empty()
                               ? Vec3d(0.5 * (sx0 + sx1), b + 0.5 * t, 0.5 * (kSz0 + kSz1))
                               : w.bodies[0].state.x;
      // Back to the slab's frame at the start: the body's own frame is its
      // principal axes', which may order the box's axes otherwise.
      const triad::Mat3d turn = w.bodies.empty()
                                    ? triad::Mat3d::Identity()
                                    : (rotation0 * w.bodies[0].rotation().transpose()).eval();
      size_t inside = 0, skin = 0;
      for (const triad::ParticleSet& set : w.sets)
        for (size_t i = 0; i < set.size(); ++i) {
          if (set.object[i] == slab_object) continue;
          const Vec3d r = turn * (set.x[i].cast<double>() - centre);
          const double e = (r.cwiseAbs() - half).maxCoeff();
          inside += e < 0;
          skin += e >= 0 && e < 0.5 * s.dx;
        }
      std::printf("  p under %.0f (far %.0f) over %.0f (far %.0f); water inside the slab %zu, "
                  "within dx/2 of it %zu\n", ps[0], ps[1], ps[2], ps[3], inside, skin);
    }
    if (s.start == "film") {
      size_t on = 0, all = 0;
      double fvx = 0, fvy = 0, fj = 0;
      double hmax = 0;
      for (const triad::ParticleSet& set : w.sets)
        for (size_t i = 0; i < set.size(); ++i) {
          if (set.object[i] == slab_object) continue;
          ++all;
          const triad::Vec3f& x = set.x[i];
          if (x.y() > b + t - 0.5 * s.dx && x.x() > sx0 && x.x() < sx1 && x.z() > kSz0 && x.z() < kSz1) { ++on; fvx += std::abs(set.v[i].x()); fvy += set.v[i].y(); fj += set.volumeRatio(i); hmax = std::max(hmax, double(x.y()) - b - t); }
        }
      if (getenv("STUDY_FLOOR")) {
        on = 0; hmax = 0;
        for (const triad::ParticleSet& set : w.sets)
          for (size_t i = 0; i < set.size(); ++i) {
            const triad::Vec3f& x = set.x[i];
            if (set.object[i] != slab_object && x.x() > sx0 && x.x() < sx1 && x.z() > kSz0 && x.z() < kSz1) { ++on; hmax = std::max(hmax, double(x.y())); }
          }
      }
      std::printf("  film: %.3f of the water on the slab, highest %.4f above it, |vx| %.3f vy %.3f J %.4f\n", double(on) / double(all), hmax, fvx / on, fvy / on, fj / on);
    }
    if (s.trace) {
      // An elastic slab's mean vertical velocity, and the mass-weighted RMS
      // of its nodes' velocities about their mean (its vibration).
      double vy = w.bodies.empty() ? 0.0 : w.bodies[0].state.v.y(), vib = 0.0;
      if (w.bodies.empty() && !w.elastics.empty()) {
        const triad::FemBody& f = w.elastics[0].fem;
        Vec3d p = Vec3d::Zero();
        for (size_t i = 0; i < f.nodes(); ++i) p += f.mass[i] * f.v[i];
        const Vec3d mean = p / f.totalMass();
        for (size_t i = 0; i < f.nodes(); ++i) vib += f.mass[i] * (f.v[i] - mean).squaredNorm();
        vy = mean.y();
        vib = std::sqrt(vib / f.totalMass());
      }
      // Frames faster than 100 a second get their time to the 0.1 ms.
      std::printf("t %.*f bottom %.4f level %.4f draft %.4f (%+.2f dx) v %.3f F/mg %.3f%s\n",
                  fps > 100 ? 4 : 2, k / fps, b, l, d, (d - draft) / s.dx, vy, fy,
                  w.elastics.empty() ? "" : (" vibration " + std::to_string(vib)).c_str());
    }
    if (k > n / 2) {
      mean_draft += d;
      ++counted;
    }
  }
  mean_draft /= counted;
  if (getenv("STUDY_ROWS")) {
    // Mean pressure and vertical speed in half-cell rows under and over the
    // slab's footprint, against far from it at the same height.
    const double b = bottom();
    for (int r = -6; r < 6; ++r) {
      const bool under = r < 0;
      const double y0r = under ? b + r * 0.5 * s.dx : b + t + r * 0.5 * s.dx;
      double pin = 0, pfar = 0, vin = 0;
      int nin = 0, nfar = 0;
      for (const triad::ParticleSet& set : w.sets) {
        const auto* wat = std::get_if<triad::Water<float>>(&set.model);
        if (!wat) continue;
        for (size_t i = 0; i < set.size(); ++i) {
          const triad::Vec3f& x = set.x[i];
          if (x.y() < y0r || x.y() >= y0r + 0.5 * s.dx) continue;
          const bool inside = x.x() > sx0 + s.dx && x.x() < sx1 - s.dx && x.z() > kSz0 + s.dx &&
                              x.z() < kSz1 - s.dx;
          const bool far = x.x() < sx0 - 2 * s.dx || x.x() > sx1 + 2 * s.dx;
          if (inside) { pin += wat->pressure(set.J[i]); vin += set.v[i].y(); ++nin; }
          if (far) { pfar += wat->pressure(set.J[i]); ++nfar; }
        }
      }
      std::printf("row %s %+.1f dx: p %.0f (far %.0f) vy %.4f (%d)\n", under ? "under" : "over",
                  under ? r * 0.5 : r * 0.5, pin / std::max(nin, 1), pfar / std::max(nfar, 1),
                  vin / std::max(nin, 1), nin);
    }
  }
  if (getenv("STUDY_SURFACE")) {
    // Highest water particle per column of cells along x at the slab's middle z.
    const int nx = int(std::round(kX / s.dx));
    std::vector<double> top(size_t(nx), -1), over(size_t(nx), 0);
    for (const triad::ParticleSet& set : w.sets)
      for (size_t i = 0; i < set.size(); ++i) {
        if (set.object[i] == slab_object) continue;
        const int c = std::clamp(int(set.x[i].x() / s.dx), 0, nx - 1);
        if (std::abs(set.x[i].z() - 0.5 * kZ) > 1.5 * s.dx) continue;
        top[size_t(c)] = std::max(top[size_t(c)], double(set.x[i].y()));
        if (set.x[i].y() > bottom() + t) over[size_t(c)] += 1;
      }
    for (int c = 0; c < nx; ++c)
      std::printf("column x %.3f: top particle %.4f, particles over the slab top %.0f\n", (c + 0.5) * s.dx, top[size_t(c)], over[size_t(c)]);
    std::printf("slab top %.4f\n", bottom() + t);
    // Spread of J in layers: near the slab (within 2 cells) and far from it.
    for (double y = 0.01; y < 0.2; y += 0.02) {
      double sn = 0, sn2 = 0, sf = 0, sf2 = 0;
      int nn = 0, nf = 0;
      for (const triad::ParticleSet& set : w.sets)
        for (size_t i = 0; i < set.size(); ++i) {
          if (set.object[i] == slab_object || std::abs(set.x[i].y() - y) > 0.01) continue;
          const double J = set.volumeRatio(i);
          const bool near = set.x[i].x() > sx0 - 2 * s.dx && set.x[i].x() < sx1 + 2 * s.dx &&
                            set.x[i].z() > kSz0 - 2 * s.dx && set.x[i].z() < kSz1 + 2 * s.dx;
          if (near) { sn += J; sn2 += J * J; ++nn; } else { sf += J; sf2 += J * J; ++nf; }
        }
      auto sd = [](double a, double a2, int c) { return c > 1 ? std::sqrt(std::max(0.0, a2 / c - (a / c) * (a / c))) : 0.0; };
      std::printf("layer y %.2f: near J %.5f sd %.5f (%d)   far J %.5f sd %.5f (%d)\n", y, sn / std::max(nn, 1), sd(sn, sn2, nn), nn, sf / std::max(nf, 1), sd(sf, sf2, nf), nf);
    }
  }
  std::printf(
      "%s %s thick %.0f cells ratio %.2f dx %.3f: draft %.4f (Archimedes %.4f, %+.2f dx; at the "
      "start %+.2f dx), bottom %.4f, wall %.1f s\n",
      s.kind.c_str(), s.start.c_str(), s.thick, s.ratio, s.dx, mean_draft, draft,
      (mean_draft - draft) / s.dx, start_error, bottom(), omp_get_wtime() - wall0);
  {
    const triad::PhaseTimes& pt = solver.phaseTimes();
    std::printf("steps %lld dt %.2e..%.2e; bin %.2f p2g %.2f grid %.2f g2p %.2f solids %.2f:",
                (long long)solver.record().steps, solver.record().dt_min, solver.record().dt_max,
                pt.bin, pt.p2g, pt.grid, pt.g2p, pt.solids);
    for (const auto& [name, sec] : pt.solid_parts.parts()) std::printf(" %s %.2f", name, sec);
    std::printf("\n");
    if (s.implicit && !w.elastics.empty()) {
      const auto st = w.elastics[0].fem.lastSolve();
      std::printf("last implicit solve: %d Newton iterations, %d CG iterations, %d direct\n",
                  st.newton, st.cg_iterations, st.direct);
    }
  }
  return 0;
}
