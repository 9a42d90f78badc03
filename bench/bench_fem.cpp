// Explicit (symplectic Euler) against implicit (backward Euler) finite
// elements on one problem with a known answer (issue 5): a column pinned at
// its base and released from rest under gravity, nu = 0 (a 1D bar). The top
// oscillates between 0 and twice the static sag rho g H^2 / (2 E) with the
// bar's period 4 H / c; undamped, the mean over whole periods is the sag.
//   bench_fem [--cells N] [--time T] [--repeats R] [--threads N]   (2, 0.5 s, 3, all)
// N: cells across the column (its height is 5 N cells). Every run is
// deterministic; R repeats time it, the median is reported.
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <string>
#include <vector>

#include "sim/solids/fem.h"
#include "sim/solids/tet_mesh.h"

namespace {

using triad::FemBody;
using triad::Vec3d;

constexpr double kRho = 1000, kE = 2e5, kH = 0.2, kG = 9.81;

struct Config {
  const char* integrator;  // "explicit" or "implicit"
  double factor;           // step in units of the explicit limit h_min / c
};

struct Result {
  double dt = 0.0;
  long steps = 0;
  long newton = 0;      // Newton iterations over the run (implicit)
  int newton_max = 0;   // most in one step
  bool unstable = false;
  double unstable_at = 0.0;          // simulated time of the blow-up
  std::vector<double> t, u;          // top displacement (downward) at each step
  double energy_end = 0.0, energy_max = 0.0;  // total energy change, end and largest |.|
  double wall = 0.0, cpu = 0.0;      // seconds of stepping: wall clock, process CPU
};

FemBody makeColumn(int n) {
  const double h = kH / (5 * n);
  std::vector<Vec3d> cells;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < 5 * n; ++j)
      for (int k = 0; k < n; ++k) cells.push_back(h * (Vec3d(i, j, k) + Vec3d::Constant(0.5)));
  triad::MaterialDesc m;
  m.model = triad::MaterialModel::FixedCorotated;
  m.density = kRho;
  m.youngs_modulus = kE;
  m.poisson_ratio = 0.0;
  FemBody b = triad::makeFemBody(triad::tetsFromVoxels(cells, h), m);
  for (size_t i = 0; i < b.nodes(); ++i) b.pinned[i] = b.x[i].y() < 1e-9;
  return b;
}

// Kinetic + elastic + gravitational potential energy.
double totalEnergy(const FemBody& b) {
  double e = b.kineticEnergy() + b.elasticEnergy();
  for (size_t i = 0; i < b.nodes(); ++i) e += b.mass[i] * kG * b.x[i].y();
  return e;
}

Result simulate(int n, const Config& c, double sim_time, bool record) {
  FemBody b = makeColumn(n);
  std::vector<size_t> top;
  for (size_t i = 0; i < b.nodes(); ++i)
    if (std::abs(b.mesh.nodes[i].y() - kH) < 1e-9) top.push_back(i);
  Result r;
  r.dt = c.factor * b.stableDt(1.0);
  const bool implicit = !std::strcmp(c.integrator, "implicit");
  const Vec3d g(0, -kG, 0);
  const double e0 = totalEnergy(b);
  std::vector<Vec3d> scratch;
  auto topDisplacement = [&]() {
    double y = 0.0;
    for (size_t i : top) y += b.x[i].y();
    return kH - y / double(top.size());
  };
  if (record) r.t.push_back(0.0), r.u.push_back(0.0);
  double t = 0.0;
  const double t0 = omp_get_wtime();
  const std::clock_t c0 = std::clock();
  while (t < sim_time - 1e-12) {
    const double dt = std::min(r.dt, sim_time - t);
    if (implicit) {
      // As the solver does: velocities from Newton, then x += dt v.
      const int it = b.implicitVelocities(dt, g, scratch);
      r.newton += it;
      r.newton_max = std::max(r.newton_max, it);
      b.v.swap(scratch);
      for (size_t i = 0; i < b.nodes(); ++i) b.x[i] += dt * b.v[i];
    } else {
      b.stepExplicit(dt, g, scratch);
    }
    t += dt;
    ++r.steps;
    // Unstable: a node left the column's neighbourhood, or went non-finite.
    double worst = 0.0;
    for (size_t i = 0; i < b.nodes(); ++i) {
      const double d = (b.x[i] - b.mesh.nodes[i]).norm();
      worst = std::isfinite(d) ? std::max(worst, d) : 1e300;
    }
    if (worst > 0.5 * kH) {
      r.unstable = true;
      r.unstable_at = t;
      break;
    }
    if (record) {
      r.t.push_back(t);
      r.u.push_back(topDisplacement());
      const double de = totalEnergy(b) - e0;
      r.energy_end = de;
      r.energy_max = std::max(r.energy_max, std::abs(de));
    }
  }
  r.wall = omp_get_wtime() - t0;
  r.cpu = double(std::clock() - c0) / CLOCKS_PER_SEC;
  return r;
}

// Piecewise-linear value of a recorded trajectory at time s.
double at(const Result& r, double s) {
  const auto it = std::lower_bound(r.t.begin(), r.t.end(), s);
  if (it == r.t.begin()) return r.u.front();
  if (it == r.t.end()) return r.u.back();
  const size_t k = size_t(it - r.t.begin());
  const double a = (s - r.t[k - 1]) / (r.t[k] - r.t[k - 1]);
  return (1 - a) * r.u[k - 1] + a * r.u[k];
}

}  // namespace

int main(int argc, char** argv) {
  int n = 2, repeats = 3;
  double sim_time = 0.5;
  for (int i = 1; i + 1 < argc; i += 2) {
    if (!std::strcmp(argv[i], "--cells")) n = std::atoi(argv[i + 1]);
    else if (!std::strcmp(argv[i], "--time")) sim_time = std::atof(argv[i + 1]);
    else if (!std::strcmp(argv[i], "--repeats")) repeats = std::atoi(argv[i + 1]);
    else if (!std::strcmp(argv[i], "--threads")) omp_set_num_threads(std::atoi(argv[i + 1]));
    else {
      std::fprintf(stderr, "usage: %s [--cells N] [--time T] [--repeats R] [--threads N]\n",
                   argv[0]);
      return 2;
    }
  }
  if (n < 1 || repeats < 1 || !(sim_time > 0)) {
    std::fprintf(stderr, "bench_fem: --cells, --repeats and --time must be positive\n");
    return 2;
  }

  // The analytic answers: static sag, the bar's period, and the elastic
  // energy stored at the static sag (the scale of energy errors).
  const double sag = kRho * kG * kH * kH / (2 * kE);
  const double c = std::sqrt(kE / kRho), period = 4 * kH / c;
  const double area = std::pow(kH / 5, 2);
  const double e_static = area * kRho * kRho * kG * kG * std::pow(kH, 3) / (6 * kE);
  const FemBody probe = makeColumn(n);
  const double dt1 = probe.stableDt(1.0);
  std::printf("column %dx%dx%d cells (h = %.4g m), %zu nodes, %zu tets; threads %d\n", n, 5 * n, n,
              kH / (5 * n), probe.nodes(), probe.mesh.tets.size(), omp_get_max_threads());
  std::printf("E = %g Pa, nu = 0, rho = %g, H = %g m: sag %.4f mm, period 4H/c %.4f s, "
              "explicit limit h_min/c = %.3e s, simulated %.2f s\n",
              kE, kRho, kH, sag * 1e3, period, dt1, sim_time);

  // Reference: explicit at a tenth of its limit.
  const Result ref = simulate(n, {"explicit", 0.1}, sim_time, true);
  // The mean over the last whole periods that fit in the second half.
  const int periods = std::max(1, int(std::floor(0.5 * sim_time / period)));
  const double w0 = sim_time - periods * period;
  auto meanSag = [&](const Result& r) {
    const int samples = 2000;
    double s = 0.0;
    for (int k = 0; k < samples; ++k) s += at(r, w0 + (k + 0.5) * (sim_time - w0) / samples);
    return s / samples;
  };
  std::printf("reference (explicit, 0.1 x limit): %ld steps, mean sag over %d periods %.4f mm "
              "(%+.2f%% of analytic)\n",
              ref.steps, periods, meanSag(ref) * 1e3, 100 * (meanSag(ref) / sag - 1));

  // Where symplectic Euler stops being stable, in units of the limit: the
  // largest factor whose 1000 steps stay bounded (bisection to 1%).
  double stable = 0.25, unstable = 2.0;
  while (unstable - stable > 0.01) {
    const double f = 0.5 * (stable + unstable);
    (simulate(n, {"explicit", f}, 1000 * f * dt1, false).unstable ? unstable : stable) = f;
  }
  std::printf("explicit: stable up to %.2f x the limit over 1000 steps (the solver takes "
              "solver.cfl x the limit, 0.4 by default)\n\n",
              stable);

  const Config configs[] = {{"explicit", 0.5}, {"explicit", 1.0}, {"explicit", 2.0},
                            {"implicit", 1.0}, {"implicit", 5.0}, {"implicit", 20.0},
                            {"implicit", 100.0}};
  std::printf("| integrator | dt / limit | dt (s) | steps | Newton its (mean / max per step) "
              "| wall (CPU) s per simulated s, median of %d | sag error vs analytic "
              "| trajectory error (RMS / sag) | oscillation left (last period, / 2 sag) "
              "| energy change end (max) / E_static | stable |\n",
              repeats);
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (const Config& cfg : configs) {
    // One recording run, untimed (energies cost a pass over the elements),
    // then the timed repeats.
    Result r = simulate(n, cfg, sim_time, true);
    std::vector<double> walls, cpus;
    for (int k = 0; k < repeats; ++k) {
      const Result timed = simulate(n, cfg, sim_time, false);
      walls.push_back(timed.wall);
      cpus.push_back(timed.cpu);
    }
    std::sort(walls.begin(), walls.end());
    std::sort(cpus.begin(), cpus.end());
    // Scaled by the simulated time actually reached (a blow-up stops early).
    const double reached = r.unstable ? r.unstable_at : sim_time;
    const double rate = walls[walls.size() / 2] / reached;
    const double cpu_rate = cpus[cpus.size() / 2] / reached;
    char newton[64] = "-";
    if (r.newton > 0)
      std::snprintf(newton, sizeof newton, "%.2f / %d", double(r.newton) / double(r.steps),
                    r.newton_max);
    if (r.unstable) {
      std::printf("| %s | %g | %.3e | %ld | %s | %.3f (%.3f) | - | - | - | - | **no**: blew up "
                  "at t = %.4f s |\n",
                  cfg.integrator, cfg.factor, r.dt, r.steps, newton, rate, cpu_rate, r.unstable_at);
      continue;
    }
    // Trajectory: RMS difference from the reference at 4000 instants.
    double se = 0.0;
    const int samples = 4000;
    for (int k = 1; k <= samples; ++k) {
      const double s = sim_time * k / samples;
      se += std::pow(at(r, s) - at(ref, s), 2);
    }
    const double rms = std::sqrt(se / samples);
    double lo = 1e300, hi = -1e300;
    for (size_t k = 0; k < r.t.size(); ++k)
      if (r.t[k] >= sim_time - period) lo = std::min(lo, r.u[k]), hi = std::max(hi, r.u[k]);
    std::printf("| %s | %g | %.3e | %ld | %s | %.3f (%.3f) | %+.2f%% | %.3f | %.3f | %+.3f (%.3f) "
                "| yes |\n",
                cfg.integrator, cfg.factor, r.dt, r.steps, newton, rate, cpu_rate,
                100 * (meanSag(r) / sag - 1), rms / sag, (hi - lo) / (2 * sag),
                r.energy_end / e_static, r.energy_max / e_static);
  }
  return 0;
}
