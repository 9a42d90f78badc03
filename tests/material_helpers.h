#pragma once
// Deformation gradients and comparisons shared by the material tests.
#include <algorithm>
#include <cmath>
#include <random>

#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include "sim/math.h"
#include "sim/svd3.h"

namespace triad::test {

template <class A, class B>
inline double relErr(const A& a, const B& b) {
  return double((a - b).norm() / std::max(b.norm(), decltype(b.norm())(1e-30)));
}

inline Mat3d randomRotation(std::mt19937& rng) {
  std::normal_distribution<double> g(0, 1);
  return Eigen::Quaterniond(g(rng), g(rng), g(rng), g(rng)).normalized().toRotationMatrix();
}

inline Mat3d nearIdentity(std::mt19937& rng, double amount = 0.1) {
  std::normal_distribution<double> g(0, 1);
  Mat3d F = Mat3d::Identity();
  for (int k = 0; k < 9; ++k) F.data()[k] += amount * g(rng);
  return F;
}

// The signed singular values of svd3.
inline Vec3d singularValues(const Mat3d& F) {
  Mat3d U, V;
  Vec3d s;
  svd3(F, U, s, V);
  return s;
}

inline Vec3d henckyStrain(const Mat3d& F) {
  return singularValues(F).array().abs().log();
}

// A random rotation of the principal log strains eps.
inline Mat3d withStrain(std::mt19937& rng, const Vec3d& eps) {
  return randomRotation(rng) * eps.array().exp().matrix().asDiagonal() * randomRotation(rng);
}

// A sand model leaves states inside its yield surface alone, bit for bit:
// mostly volumetric compression with a little shear.
template <class M>
void expectInsideStatesUnchanged(const M& model, unsigned seed) {
  std::mt19937 rng(seed);
  for (int i = 0; i < 50; ++i) {
    Mat3d F = withStrain(rng, Vec3d(-0.02, -0.021, -0.019));
    ASSERT_LT(model.yield(F), 0);
    const Mat3d before = F;
    EXPECT_FALSE(model.project(F));
    EXPECT_EQ(F, before);
  }
}

}  // namespace triad::test
