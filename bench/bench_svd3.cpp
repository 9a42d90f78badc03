// Microbenchmark for sim/svd3.h and the material stress paths, run by hand
// (deliberately not in the CMake build):
//   g++ -std=c++17 -O3 -march=native -I. -isystem /usr/include/eigen3
//       bench/bench_svd3.cpp sim/materials/materials.cpp -o /tmp/bench_svd3
//   /tmp/bench_svd3
// Reports the best of several runs, in ns per matrix, over 16k independent
// matrices: the solver's access pattern (one decomposition per particle).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <random>
#include <vector>

#include <Eigen/Geometry>
#include <Eigen/SVD>

#include "sim/materials/materials.h"
#include "sim/svd3.h"

using triad::Mat3f;
using triad::Vec3f;

namespace {

// Deformation gradients as the solver sees them: a rotation times a stretch
// near identity (noise ~0.05), or general matrices (noise 1).
std::vector<Mat3f> makeInputs(int n, float noise, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> g(0.0f, 1.0f);
  std::vector<Mat3f> out(n);
  for (auto& F : out) {
    const Eigen::Quaternionf q(g(rng), g(rng), g(rng), g(rng));
    Mat3f E;
    for (int k = 0; k < 9; ++k) E.data()[k] = noise * g(rng);
    F = q.normalized().toRotationMatrix() * (Mat3f::Identity() + E);
  }
  return out;
}

// Best time per element of `run` (which processes all n elements).
template <class Run>
double bestNs(int n, int reps, Run&& run) {
  double best = 1e30;
  for (int r = 0; r < reps; ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    run();
    const auto t1 = std::chrono::steady_clock::now();
    best = std::min(best, std::chrono::duration<double, std::nano>(t1 - t0).count() / n);
  }
  return best;
}

// Per-call loop over the inputs; the sink keeps the work alive.
template <class Fn>
double perCallNs(const std::vector<Mat3f>& in, int reps, Fn&& fn) {
  float sink = 0.0f;
  const double t = bestNs(int(in.size()), reps, [&] {
    for (const Mat3f& F : in) sink += fn(F);
  });
  volatile float keep = sink;
  (void)keep;
  return t;
}

}  // namespace

int main() {
  const int n = 1 << 14;
  for (const float noise : {0.05f, 1.0f}) {
    const std::vector<Mat3f> in = makeInputs(n, noise, 7);
    std::printf("inputs: rotation * (I + %.2f * gaussian)\n", noise);

    // Decompositions, one call per matrix
    const double t_svd = perCallNs(in, 20, [](const Mat3f& F) {
      Mat3f U, V;
      Vec3f s;
      triad::svd3(F, U, s, V);
      return U(0, 1) + V(2, 0) + s(2);
    });
    const double t_polar = perCallNs(in, 20, [](const Mat3f& F) {
      const Mat3f R = triad::polarRotation(F);
      return R(0, 1) + R(2, 2);
    });
    const double t_eigen = perCallNs(in, 5, [](const Mat3f& F) {
      const Eigen::JacobiSVD<Mat3f> svd(F, Eigen::ComputeFullU | Eigen::ComputeFullV);
      return svd.matrixU()(0, 1) + svd.matrixV()(2, 0) + svd.singularValues()(2);
    });
    std::printf("  svd3<float>              %6.1f ns\n", t_svd);
    std::printf("  polarRotation<float>     %6.1f ns\n", t_polar);
    std::printf("  Eigen JacobiSVD<Matrix3f> %5.1f ns\n", t_eigen);

    // Decompositions, batched
    std::vector<Mat3f> U(n), V(n), R(n), tau(n), work(n);
    std::vector<Vec3f> S(n);
    std::vector<float> jp(n);
    const double t_svd_batch =
        bestNs(n, 20, [&] { triad::svd3Batch(n, in.data(), U.data(), S.data(), V.data()); });
    const double t_polar_batch =
        bestNs(n, 20, [&] { triad::polarRotationBatch(n, in.data(), R.data()); });
    float worst = 0.0f;
    for (int i = 0; i < n; ++i) {
      const Mat3f E = U[i] * S[i].asDiagonal() * V[i].transpose() - in[i];
      worst = std::max(worst, E.norm() / in[i].norm());
    }
    std::printf("  svd3Batch                %6.1f ns  (worst |USV^T - F| / |F| = %.1e)\n",
                t_svd_batch, worst);
    std::printf("  polarRotationBatch       %6.1f ns\n", t_polar_batch);

    // Material stress paths, single calls versus batches
    const auto fc = triad::FixedCorotated<float>::fromYoungPoisson(1e5f, 0.3f);
    triad::Snow<float> snow;
    snow.elastic = fc;
    const triad::DruckerPrager<float> sand(1e5f, 0.3f, 30.0f, 0.0f);
    const double t_fc = perCallNs(in, 10, [&](const Mat3f& F) { return fc.kirchhoff(F)(0, 1); });
    const double t_fc_batch =
        bestNs(n, 10, [&] { triad::kirchhoffBatch(fc, n, in.data(), tau.data()); });
    const double t_snow = bestNs(n, 10, [&] {
      work = in;
      std::fill(jp.begin(), jp.end(), 1.0f);
      for (int i = 0; i < n; ++i) tau[i] = snow.projectAndKirchhoff(work[i], jp[i]);
    });
    const double t_snow_batch = bestNs(n, 10, [&] {
      work = in;
      std::fill(jp.begin(), jp.end(), 1.0f);
      triad::projectAndKirchhoffBatch(snow, n, work.data(), jp.data(), tau.data());
    });
    const double t_sand = bestNs(n, 10, [&] {
      work = in;
      for (int i = 0; i < n; ++i) tau[i] = sand.projectAndKirchhoff(work[i]);
    });
    const double t_sand_batch = bestNs(n, 10, [&] {
      work = in;
      triad::projectAndKirchhoffBatch(sand, n, work.data(), tau.data());
    });
    std::printf("  FixedCorotated::kirchhoff             %6.1f ns, kirchhoffBatch %6.1f ns\n", t_fc,
                t_fc_batch);
    std::printf("  Snow::projectAndKirchhoff             %6.1f ns, batch %6.1f ns\n", t_snow,
                t_snow_batch);
    std::printf("  DruckerPrager::projectAndKirchhoff    %6.1f ns, batch %6.1f ns\n", t_sand,
                t_sand_batch);

#if defined(__GNUC__)
    // The FEM's double polar rotation in vector lanes: eight matrices a
    // group, one group at a time or two side by side.
    using triad::svd3_detail::PackD;
    const int groups = n / 8;
    std::vector<PackD> lanes(size_t(groups) * 9);
    for (int g = 0; g < groups; ++g)
      for (int l = 0; l < 8; ++l)
        for (int e = 0; e < 9; ++e) lanes[size_t(g) * 9 + e][l] = in[size_t(g * 8 + l)].data()[e];
    double sink = 0.0;
    const double t_one = bestNs(n, 20, [&] {
      for (int g = 0; g < groups; ++g) {
        PackD f[9], r[9];
        std::copy_n(&lanes[size_t(g) * 9], 9, f);
        triad::polarRotationOfLanes(8, f, r);
        sink += r[0][0];
      }
    });
    const double t_two = bestNs(n, 20, [&] {
      for (int g = 0; g + 1 < groups; g += 2) {
        const int count[2] = {8, 8};
        PackD f[2][9], r[2][9];
        std::copy_n(&lanes[size_t(g) * 9], 18, &f[0][0]);
        triad::polarRotationOfLaneGroups<2>(count, f, r);
        sink += r[0][0][0] + r[1][0][0];
      }
    });
    volatile double keep = sink;
    (void)keep;
    std::printf("  polar rotation, double lanes: one group %6.1f ns, two side by side %6.1f ns\n",
                t_one, t_two);
#endif
  }
  return 0;
}
