// Deterministic sampling of primitive shapes.
#include <gtest/gtest.h>

#include <cmath>

#include "sim/mpm/sampling.h"

namespace triad {
namespace {

DomainDesc unitDomain(double dx) {
  DomainDesc d;
  d.dx = dx;
  return d;
}

TEST(Sampling, BoxGetsExactlyPpcPerCell) {
  const DomainDesc d = unitDomain(0.01);
  const auto pts = sampleShape(BoxDesc{{0.1, 0.2, 0.3}, {0.4, 0.5, 0.5}}, d, 8);
  EXPECT_EQ(pts.size(), size_t(30 * 30 * 20 * 8));
  for (const Vec3f& p : pts) {
    ASSERT_GE(p.x(), 0.1f);
    ASSERT_LT(p.x(), 0.4f);
  }
}

TEST(Sampling, SphereVolumeConvergesWithDx) {
  for (int ppc : {8, 5}) {
    const double r = 0.2, dx = 0.02;
    const auto pts = sampleShape(SphereDesc{{0.5, 0.5, 0.5}, r}, unitDomain(dx), ppc);
    const double volume = pts.size() * dx * dx * dx / ppc;
    EXPECT_NEAR(volume, 4.0 / 3.0 * M_PI * r * r * r, 0.01 * 4.0 / 3.0 * M_PI * r * r * r)
        << "ppc " << ppc;
  }
}

TEST(Sampling, DeterministicAndClippedToDomain) {
  const DomainDesc d = unitDomain(0.02);
  const auto a = sampleShape(SphereDesc{{0.95, 0.5, 0.5}, 0.2}, d, 6);
  const auto b = sampleShape(SphereDesc{{0.95, 0.5, 0.5}, 0.2}, d, 6);
  ASSERT_EQ(a, b);
  for (const Vec3f& p : a) ASSERT_LT(p.x(), 1.0f);
}

TEST(Sampling, OffsetsFillTheCell) {
  for (int ppc : {1, 4, 8, 27, 12}) {
    const auto o = cellSampleOffsets(ppc);
    ASSERT_EQ(int(o.size()), ppc);
    Vec3d mean = Vec3d::Zero();
    for (const Vec3d& p : o) {
      ASSERT_TRUE((p.array() >= 0.0).all() && (p.array() < 1.0).all());
      mean += p / ppc;
    }
    // Evenly spread: the centroid is near the cell centre.
    EXPECT_LT((mean - Vec3d::Constant(0.5)).norm(), ppc >= 8 ? 0.06 : 0.2) << "ppc " << ppc;
  }
}

}  // namespace
}  // namespace triad
