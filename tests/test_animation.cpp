// Prescribed motion: poses between keys as the contract defines them
// (linear: lerp and slerp; smooth: C1), their velocities the exact time
// derivative (checked against differences of poses), held outside the keys.
#include <gtest/gtest.h>

#include <cmath>

#include "sim/shot/animation.h"

namespace triad {
namespace {

AnimationDesc keys(Interpolation how, std::vector<AnimationKeyDesc> k) {
  AnimationDesc a;
  a.interpolation = how;
  a.keys = std::move(k);
  return a;
}

// The angular velocity a difference of two rotations implies.
Vec3d omegaByDifference(const Animation& a, double t, double h) {
  return rotationLog(a.at(t + h).rotation * a.at(t - h).rotation.conjugate()) / (2 * h);
}

TEST(Animation, EulerAnglesAreXThenYThenZAboutFixedAxes) {
  EXPECT_TRUE((eulerXYZDegrees({90, 0, 0}) * Vec3d::UnitY()).isApprox(Vec3d::UnitZ(), 1e-12));
  EXPECT_TRUE((eulerXYZDegrees({0, 90, 0}) * Vec3d::UnitZ()).isApprox(Vec3d::UnitX(), 1e-12));
  EXPECT_TRUE((eulerXYZDegrees({0, 0, 90}) * Vec3d::UnitX()).isApprox(Vec3d::UnitY(), 1e-12));
  // X first: +y goes to +z, then the Z turn leaves it there.
  EXPECT_TRUE((eulerXYZDegrees({90, 0, 90}) * Vec3d::UnitY()).isApprox(Vec3d::UnitZ(), 1e-12));
  EXPECT_TRUE((eulerXYZDegrees({90, 0, 90}) * Vec3d::UnitX()).isApprox(Vec3d::UnitY(), 1e-12));
}

TEST(Animation, LinearIsLerpAndSlerpWithConstantVelocity) {
  const Animation a(keys(Interpolation::Linear,
                         {{0.5, {0, 0, 0}, {0, 0, 0}}, {1.5, {0.3, 0, -0.1}, {0, 90, 0}}}));
  const Pose p = a.at(1.0);
  EXPECT_TRUE(p.translate.isApprox(Vec3d(0.15, 0, -0.05), 1e-12));
  EXPECT_TRUE(p.velocity.isApprox(Vec3d(0.3, 0, -0.1), 1e-12));
  // Half of a quarter turn about y, at pi/2 per second.
  EXPECT_NEAR(Eigen::AngleAxisd(p.rotation).angle(), M_PI / 4, 1e-12);
  EXPECT_TRUE(p.omega.isApprox(Vec3d(0, M_PI / 2, 0), 1e-12));
  EXPECT_TRUE(p.omega.isApprox(omegaByDifference(a, 1.0, 1e-5), 1e-8));
  // Held, at rest, outside the keys.
  for (double t : {0.0, 0.5, 1.5, 3.0}) {
    const Pose h = a.at(t);
    EXPECT_TRUE(h.velocity.isZero() && h.omega.isZero()) << t;
  }
  EXPECT_TRUE(a.at(0.2).translate.isZero());
  EXPECT_TRUE(a.at(2.0).translate.isApprox(Vec3d(0.3, 0, -0.1), 1e-12));
  EXPECT_NEAR(Eigen::AngleAxisd(a.at(2.0).rotation).angle(), M_PI / 2, 1e-12);
}

TEST(Animation, LinearRotationTakesTheShorterWayBetweenKeys) {
  // 270 degrees about z between two keys is a quarter turn back.
  const Animation a(keys(Interpolation::Linear, {{0, {0, 0, 0}, {0, 0, 0}}, {1, {0, 0, 0}, {0, 0, 270}}}));
  EXPECT_TRUE(a.at(0.5).omega.isApprox(Vec3d(0, 0, -M_PI / 2), 1e-12));
}

TEST(Animation, SmoothIsC1AndItsVelocityIsTheDerivativeOfThePose) {
  const Animation a(keys(Interpolation::Smooth, {{0.0, {0, 0, 0}, {0, 0, 0}},
                                                 {0.4, {0.2, 0.1, 0}, {30, 60, 0}},
                                                 {1.0, {0.5, -0.1, 0.2}, {60, 150, 20}},
                                                 {1.3, {0.6, 0, 0.2}, {90, 200, 40}}}));
  const double h = 1e-6;
  for (double t : {0.05, 0.2, 0.39, 0.41, 0.7, 0.99, 1.01, 1.2, 1.29}) {
    const Pose p = a.at(t);
    const Vec3d dT = (a.at(t + h).translate - a.at(t - h).translate) / (2 * h);
    EXPECT_LT((p.velocity - dT).norm(), 1e-6) << "t = " << t;
    EXPECT_LT((p.omega - omegaByDifference(a, t, h)).norm(), 1e-5) << "t = " << t;
  }
  // Continuous velocity and angular velocity across the interior keys.
  for (double k : {0.4, 1.0}) {
    const Pose before = a.at(k - 1e-9), after = a.at(k + 1e-9);
    EXPECT_LT((before.velocity - after.velocity).norm(), 1e-6) << "key " << k;
    EXPECT_LT((before.omega - after.omega).norm(), 1e-6) << "key " << k;
    EXPECT_GT(after.omega.norm(), 0.5) << "key " << k;  // moving through it
  }
  // Through the keys' poses, easing in and out of the held ends.
  EXPECT_TRUE(a.at(0.4).translate.isApprox(Vec3d(0.2, 0.1, 0), 1e-12));
  EXPECT_TRUE(a.at(1.0).rotation.isApprox(Quatd(eulerXYZDegrees({60, 150, 20})), 1e-12) ||
              a.at(1.0).rotation.isApprox(Quatd(-Quatd(eulerXYZDegrees({60, 150, 20})).coeffs()), 1e-12));
  EXPECT_LT(a.at(1e-9).velocity.norm(), 1e-6);
  EXPECT_LT(a.at(1.3 - 1e-9).omega.norm(), 1e-6);
}

TEST(Animation, SO3JacobiansAndExpLogInvertEachOther) {
  for (const Vec3d& phi : {Vec3d(1e-7, 0, 0), Vec3d(0.3, -0.2, 0.5), Vec3d(0, 3.0, 0.1)}) {
    EXPECT_TRUE((leftJacobian(phi) * leftJacobianInverse(phi)).isApprox(Mat3d::Identity(), 1e-9));
    EXPECT_TRUE(rotationLog(rotationExp(phi)).isApprox(phi, 1e-9));
  }
}

}  // namespace
}  // namespace triad
