// The solids' scatter onto the MPM grid's nodes (contract steps 1 and 4),
// checked node by node against the sums written out point by point.
#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <random>
#include <unordered_map>

#include "sim/coupling/coupling.h"
#include "sim/coupling/node_index.h"
#include "sim/mpm/particles.h"
#include "sim/mpm/sparse_grid.h"
#include "sim/mpm/transfer.h"

namespace triad {
namespace {

// Water particles filling a cube, so that the grid has blocks there.
ParticleSet waterCube(float lo, float hi, float spacing) {
  ParticleSet s;
  s.model = Water<float>{1e3f, 7.0f, 0.0f};
  s.mass = 1e-3f;
  s.volume = 1e-6f;
  uint32_t id = 0;
  for (float x = lo; x < hi; x += spacing)
    for (float y = lo; y < hi; y += spacing)
      for (float z = lo; z < hi; z += spacing) s.push(Vec3f(x, y, z), Vec3f::Zero(), id++, 0);
  return s;
}

// What node i's record should hold: every point's contribution, in double,
// and the tags and largest distance as the contract defines them.
struct Expected {
  double m = 0, p[3] = {0, 0, 0}, n[3] = {0, 0, 0}, mu = 0;
  double fixed_m = 0, fixed_p[3] = {0, 0, 0}, on[3] = {0, 0, 0};
  double scale = 0;  // sum of |w m|, the sums' size for their tolerance
  float phi = -1e30f, second = -1e30f;
  Vec3f dn = Vec3f::Zero();
  int32_t solid = 0, fixed_solid = 0, owner = 0;
  bool reached = false;
};

int32_t join(int32_t a, int32_t b) {
  return a == 0 || a == b ? b : -1;
}

struct Scene {
  SolidPoints pts;
  std::vector<ParticleSet> sets;
  GridLayout layout;
  TransferParams p;
};

// Three solids over the edge of the water: a moving rigid body, a driven
// one and a fixed one, with random points, velocities, normals and
// distances (what a body's samples carry), `moved` shifting the first two.
void addPoints(Scene& s, unsigned seed, float moved) {
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  s.pts.clear();
  const SolidKind kinds[3] = {SolidKind::Moving, SolidKind::Driven, SolidKind::Static};
  const float centres[3] = {0.02f + moved, -0.06f - moved, 0.09f};
  // The fixed one also reaches below the others, into grid blocks that no
  // moving point reaches (slots of fixed solids alone).
  const float low[3] = {0.0f, 0.0f, -0.04f}, tall[3] = {0.05f, 0.05f, 0.06f};
  for (int k = 0; k < 3; ++k) {
    const float mass = 2e-4f * float(k + 1);
    s.pts.addSolid(mass, 0.2f + 0.1f * float(k), kinds[k],
                   kinds[k] == SolidKind::Moving ? 1.0 : 0.0);
    // The fixed solid is scattered once, at the first step: its points
    // stay the same.
    std::mt19937 rng(kinds[k] == SolidKind::Static ? 99u : seed + unsigned(k));
    for (int q = 0; q < 700; ++q) {
      s.pts.x.push_back(
          Vec3f(centres[k] + 0.05f * u(rng), low[k] + tall[k] * u(rng), 0.05f * u(rng)));
      s.pts.v.push_back(kinds[k] == SolidKind::Static ? Vec3f::Zero()
                                                      : Vec3f(u(rng), u(rng), u(rng)));
      s.pts.n.push_back(Vec3f(u(rng), u(rng), u(rng) + 2.0f).normalized());
      s.pts.phi.push_back(0.01f * u(rng) - 0.005f);
      s.pts.point_mass.push_back(mass);
    }
  }
}

Scene makeScene() {
  Scene s;
  s.sets.push_back(waterCube(-0.1f, 0.1f, 0.005f));
  s.p.dx = 0.01f;
  s.p.inv_dx = 100.0f;
  s.p.shifted_origin = Vec3f::Constant(-0.5f + 0.5f * s.p.dx);
  s.p.dt = 1e-4f;
  Binner().bin(s.sets, s.p.shifted_origin, s.p.inv_dx, s.layout);
  return s;
}

// Every node of the water's grid blocks, against the point-by-point sums.
void checkNodes(const Scene& s, const GridCoupling& c) {
  // The sums, point by point, into the nodes of each point's stencil.
  std::unordered_map<uint64_t, Expected> expected;
  for (size_t k = 0; k < s.pts.solids(); ++k) {
    const size_t end = k + 1 < s.pts.solids() ? s.pts.begin[k + 1] : s.pts.size();
    const bool infinite = s.pts.kind[k] != SolidKind::Moving;
    const int32_t tag = int32_t(k) + 1;
    for (size_t q = s.pts.begin[k]; q < end; ++q) {
      const Stencil st = stencilAt(s.pts.x[q], s.p.shifted_origin, s.p.inv_dx);
      const double m = s.pts.point_mass[q];
      const Vec3f& v = s.pts.v[q];
      const Vec3f& n = s.pts.n[q];
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b)
          for (int cc = 0; cc < 3; ++cc) {
            const Vec3i node = st.base + Vec3i(a, b, cc);
            Expected& e = expected[packBlock(node)];
            const double w = double(st.w[0][a]) * st.w[1][b] * st.w[2][cc];
            const Vec3f r(float(a) - st.fx[0], float(b) - st.fx[1], float(cc) - st.fx[2]);
            const float dist = s.pts.phi[q] + s.p.dx * n.dot(r);
            e.m += w * m;
            e.scale += w * m;
            for (int d = 0; d < 3; ++d) {
              e.p[d] += w * m * v[d];
              e.n[d] += w * n[d];
              if (infinite) e.fixed_p[d] += w * m * v[d];
              e.on[d] += w * std::max(dist, 0.0f) * n[d];
            }
            e.mu += w * m * s.pts.friction[k];
            if (infinite) e.fixed_m += w * m;
            if (dist > e.phi) {
              e.second = e.phi;
              e.phi = dist;
              e.dn = n;
            } else {
              e.second = std::max(e.second, dist);
            }
            e.solid = join(e.solid, infinite ? -1 : tag);
            if (infinite) e.fixed_solid = join(e.fixed_solid, tag);
            e.owner = join(e.owner, tag);
            e.reached = true;
          }
    }
  }
  size_t reached = 0, compared_dn = 0, several = 0;
  for (size_t gb = 0; gb < s.layout.grid_keys.size(); ++gb) {
    const Vec3i origin = unpackBlock(s.layout.grid_keys[gb]) * kBlockSize;
    for (int x = 0; x < kBlockSize; ++x)
      for (int y = 0; y < kBlockSize; ++y)
        for (int z = 0; z < kBlockSize; ++z) {
          const Vec3i node = origin + Vec3i(x, y, z);
          const auto it = expected.find(packBlock(node));
          const GridCoupling::SolidNode* g =
              c.solidNode(gb * kBlockNodes + size_t(localNode(x, y, z)));
          if (it == expected.end()) {
            if (g) {
              ASSERT_EQ(g->m, 0.0f) << "node " << node.transpose();
              ASSERT_EQ(g->owner, 0) << "node " << node.transpose();
            }
            continue;
          }
          const Expected& e = it->second;
          ++reached;
          several += e.owner == -1;
          ASSERT_NE(g, nullptr) << "node " << node.transpose() << " has no record";
          const double tol = 1e-5 * e.scale + 1e-12;
          ASSERT_NEAR(g->m, e.m, tol) << "node " << node.transpose();
          ASSERT_NEAR(g->mu, e.mu, tol);
          ASSERT_NEAR(g->fixed_m, e.fixed_m, tol);
          for (int d = 0; d < 3; ++d) {
            ASSERT_NEAR(g->p[d], e.p[d], tol);
            ASSERT_NEAR(g->fixed_p[d], e.fixed_p[d], tol);
            ASSERT_NEAR(g->n[d], e.n[d], 1e-5);
            ASSERT_NEAR(g->on[d], e.on[d], 1e-7);
          }
          ASSERT_NEAR(g->phi, e.phi, 1e-7) << "node " << node.transpose();
          // The normal of the farthest sample, where it is farthest by more
          // than the distances' rounding.
          if (e.phi - e.second > 1e-6f) {
            ++compared_dn;
            for (int d = 0; d < 3; ++d) ASSERT_EQ(g->dn[d], e.dn[d]) << "node " << node.transpose();
          }
          ASSERT_EQ(g->solid, e.solid) << "node " << node.transpose();
          ASSERT_EQ(g->fixed_solid, e.fixed_solid) << "node " << node.transpose();
          ASSERT_EQ(g->owner, e.owner) << "node " << node.transpose();
        }
  }
  // Nodes of one solid and of several, inside and beyond the water's blocks.
  EXPECT_GT(reached, 2000u);
  EXPECT_GT(several, 100u);
  EXPECT_GT(compared_dn, reached / 2);
}

// Each point's sums reach all 27 nodes of its stencil, across block and
// slot edges, however many threads add them; the same nodes again after
// the moving solids have moved (a step's records hold nothing of the
// last one's).
TEST(SolidScatter, EveryNodeHoldsTheSumsOfThePointsThatReachIt) {
  const int before = omp_get_max_threads();
  for (int threads : {1, 2}) {
    omp_set_num_threads(threads);
    Scene s = makeScene();
    SolverDesc desc;
    GridCoupling c(desc);
    addPoints(s, 7, 0.0f);
    c.scatter(s.pts, s.layout, s.p);
    checkNodes(s, c);
    addPoints(s, 8, 0.013f);
    c.scatter(s.pts, s.layout, s.p);
    checkNodes(s, c);
  }
  omp_set_num_threads(before);
}

}  // namespace
}  // namespace triad
