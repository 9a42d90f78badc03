// Microbenchmark for sim/svd3.h, run by hand (not part of the CMake build):
//   g++ -std=c++17 -O3 -march=native -I. -I/usr/include/eigen3
//       bench/bench_svd3.cpp -o /tmp/bench_svd3 && /tmp/bench_svd3
// Reports ns per call over a batch of independent matrices (the solver's
// access pattern: one decomposition per particle).
#include <chrono>
#include <cstdio>
#include <random>
#include <vector>

#include <Eigen/Geometry>
#include <Eigen/SVD>

#include "sim/svd3.h"

using triad::Mat3f;
using triad::Vec3f;

namespace {

// Deformation gradients as the solver sees them: rotation times a stretch
// near identity, with a few percent of random shear.
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

template <class Fn>
double timeNs(const std::vector<Mat3f>& in, int reps, Fn&& fn) {
  float sink = 0.0f;
  double best = 1e30;
  for (int r = 0; r < reps; ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    for (const Mat3f& F : in) sink += fn(F);
    const auto t1 = std::chrono::steady_clock::now();
    best = std::min(best, std::chrono::duration<double, std::nano>(t1 - t0).count() / in.size());
  }
  volatile float keep = sink;
  (void)keep;
  return best;
}

}  // namespace

int main() {
  const int n = 1 << 14;
  for (const float noise : {0.05f, 1.0f}) {
    const std::vector<Mat3f> in = makeInputs(n, noise, 7);
    const double t_svd = timeNs(in, 20, [](const Mat3f& F) {
      Mat3f U, V;
      Vec3f s;
      triad::svd3(F, U, s, V);
      return U(0, 1) + V(2, 0) + s(2);
    });
    const double t_polar = timeNs(in, 20, [](const Mat3f& F) {
      const Mat3f R = triad::polarRotation(F);
      return R(0, 1) + R(2, 2);
    });
    const double t_eigen = timeNs(in, 5, [](const Mat3f& F) {
      const Eigen::JacobiSVD<Mat3f> svd(F, Eigen::ComputeFullU | Eigen::ComputeFullV);
      return svd.matrixU()(0, 1) + svd.matrixV()(2, 0) + svd.singularValues()(2);
    });
    std::vector<Mat3f> U(n), V(n), R(n);
    std::vector<Vec3f> S(n);
    double t_batch = 1e30, t_polar_batch = 1e30;
    for (int r = 0; r < 20; ++r) {
      auto t0 = std::chrono::steady_clock::now();
      triad::svd3Batch(n, in.data(), U.data(), S.data(), V.data());
      auto t1 = std::chrono::steady_clock::now();
      triad::polarRotationBatch(n, in.data(), R.data());
      auto t2 = std::chrono::steady_clock::now();
      t_batch = std::min(t_batch, std::chrono::duration<double, std::nano>(t1 - t0).count() / n);
      t_polar_batch =
          std::min(t_polar_batch, std::chrono::duration<double, std::nano>(t2 - t1).count() / n);
    }
    float worst = 0.0f;
    for (int i = 0; i < n; ++i) {
      const Mat3f E = U[i] * S[i].asDiagonal() * V[i].transpose() - in[i];
      worst = std::max(worst, E.norm() / in[i].norm());
    }
    std::printf(
        "noise %.2f: svd3Batch %.1f ns  polarRotationBatch %.1f ns  (worst rel. error %.1e)\n",
        noise, t_batch, t_polar_batch, worst);
    std::printf(
        "noise %.2f: svd3<float> %.1f ns  polarRotation<float> %.1f ns  "
        "Eigen JacobiSVD<Matrix3f> %.1f ns\n",
        noise, t_svd, t_polar, t_eigen);
  }
  return 0;
}
