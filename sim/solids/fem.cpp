#include "sim/solids/fem.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <type_traits>

#include "sim/errors.h"

namespace triad {

Mat3d edges(const std::vector<Vec3d>& p, const std::array<int, 4>& n) {
  Mat3d D;
  for (int k = 0; k < 3; ++k) D.col(k) = p[n[k + 1]] - p[n[0]];
  return D;
}

ElasticModel makeElasticModel(const MaterialDesc& d) {
  switch (d.model) {
    case MaterialModel::FixedCorotated:
      return FixedCorotated<double>::fromYoungPoisson(d.youngs_modulus, d.poisson_ratio);
    case MaterialModel::NeoHookean:
      return NeoHookean<double>::fromYoungPoisson(d.youngs_modulus, d.poisson_ratio);
    default:
      throw InputError("", "elastic solids take a fixed_corotated or neo_hookean material");
  }
}

FemBody makeFemBody(TetMesh mesh, const MaterialDesc& material) {
  FemBody b;
  b.model = makeElasticModel(material);
  b.density = material.density;
  const Lame<double> l = lameFromYoungPoisson(material.youngs_modulus, material.poisson_ratio);
  b.wave_speed = std::sqrt((l.lambda + 2 * l.mu) / material.density);
  b.x = mesh.nodes;
  b.v.assign(mesh.nodes.size(), Vec3d::Zero());
  b.mass.assign(mesh.nodes.size(), 0.0);
  b.pinned.assign(mesh.nodes.size(), 0);
  for (size_t t = 0; t < mesh.tets.size(); ++t) {
    const Mat3d D = edges(mesh.nodes, mesh.tets[t]);
    b.dm_inv.push_back(D.inverse());
    b.volume.push_back(D.determinant() / 6.0);
    for (int k = 0; k < 4; ++k) b.mass[mesh.tets[t][k]] += 0.25 * material.density * b.volume.back();
  }
  // Smallest element height 3V / (largest face area), at rest: the
  // explicit step's length scale (Kuhn tetrahedra of a cube of side h have
  // heights down to h / sqrt(3)).
  b.min_height = mesh.spacing;
  for (size_t t = 0; t < mesh.tets.size(); ++t) {
    const auto& n = mesh.tets[t];
    double face = 0.0;
    for (int k = 0; k < 4; ++k) {
      const Vec3d& a = mesh.nodes[n[(k + 1) % 4]];
      const Vec3d& p = mesh.nodes[n[(k + 2) % 4]];
      const Vec3d& c = mesh.nodes[n[(k + 3) % 4]];
      face = std::max(face, 0.5 * (p - a).cross(c - a).norm());
    }
    b.min_height = std::min(b.min_height, 3.0 * b.volume[t] / face);
  }
  b.mesh = std::move(mesh);
  return b;
}

double FemBody::totalMass() const {
  double m = 0.0;
  for (double mi : mass) m += mi;
  return m;
}

Vec3d FemBody::centreOfMass() const {
  Vec3d mx = Vec3d::Zero();
  for (size_t i = 0; i < x.size(); ++i) mx += mass[i] * x[i];
  return mx / totalMass();
}

namespace {

// Below this many elements their forces take less time (about 40 ns an
// element) than waking the other threads and moving the nodes' positions
// and the forces between cores: a solid of a few thousand elements ran
// slower on two threads than on one.
constexpr size_t kParallelTets = 4096;

#if defined(__GNUC__)
// H = -V P Dm^-T of every fixed-corotated element, P = 2 mu (F - R) +
// lambda (J - 1) cof(F) (FixedCorotated::firstPiola), eight elements at a
// time in vector lanes from the nodes' positions on: F = D Dm^-1, its polar
// rotation, P and H. Column-major lanes: [3 j + i] is entry (i, j).
void fixedCorotatedForces(const FemBody& b, const FixedCorotated<double>& mat,
                          const std::vector<Vec3d>& y, bool keep) {
  using svd3_detail::PackD;
  constexpr int L = 8;
  const auto& tets = b.mesh.tets;
  const int64_t n = int64_t(tets.size()), groups = (n + L - 1) / L;
  // The rest shape in lanes, once; lanes past the last element repeat
  // the group's first.
  if (b.minus_v_lanes_.size() != size_t(groups) * L) {
    b.dm_lanes_.assign(size_t(groups) * 9 * L, 0.0);
    b.minus_v_lanes_.assign(size_t(groups) * L, 0.0);
    for (int64_t g = 0; g < groups; ++g)
      for (int l = 0; l < L; ++l) {
        const int64_t t = g * L + l < n ? g * L + l : g * L;
        b.minus_v_lanes_[size_t(g * L + l)] = -b.volume[size_t(t)];
        for (int e = 0; e < 9; ++e)
          b.dm_lanes_[size_t((g * 9 + e) * L + l)] = b.dm_inv[size_t(t)].data()[e];
      }
  }
  // F = D Dm^-1 of group g's elements in lanes, from the nodes' edges D
  // (columns x1 - x0, x2 - x0, x3 - x0).
  auto deformation = [&](int64_t g, int count, PackD(&f)[9]) {
    alignas(64) double edge[9][L];
    for (int l = 0; l < L; ++l) {
      const auto& nd = tets[size_t(g * L + (l < count ? l : 0))];
      const Vec3d& p0 = y[size_t(nd[0])];
      for (int k = 0; k < 3; ++k) {
        const Vec3d d = y[size_t(nd[k + 1])] - p0;
        for (int i = 0; i < 3; ++i) edge[3 * k + i][l] = d[i];
      }
    }
    PackD D[9], d[9];
    std::memcpy(D, edge, sizeof(D));
    std::memcpy(d, &b.dm_lanes_[size_t(g * 9 * L)], sizeof(d));
    // F(i, j) = sum_k D(i, k) Dm^-1(k, j).
    for (int j = 0; j < 3; ++j)
      for (int i = 0; i < 3; ++i)
        f[3 * j + i] = D[i] * d[3 * j] + D[3 + i] * d[3 * j + 1] + D[6 + i] * d[3 * j + 2];
  };
  // P and H = -V P Dm^-T of group g from F and R, and the kept F^-T.
  auto forces = [&](int64_t g, int count, const PackD(&f)[9], const PackD(&r)[9]) {
    const int64_t t0 = g * L;
    PackD d[9], mv;
    std::memcpy(d, &b.dm_lanes_[size_t(g * 9 * L)], sizeof(d));
    std::memcpy(&mv, &b.minus_v_lanes_[size_t(g * L)], sizeof(mv));
    // cof(F), column-major, and J along its first column.
    PackD c[9];
    svd3_detail::cofactorLanes(f, c);
    const PackD J = f[0] * c[0] + f[1] * c[1] + f[2] * c[2];
    const PackD volumetric = mat.lambda * (J - 1.0);
    PackD P[9];
    for (int e = 0; e < 9; ++e) P[e] = 2.0 * mat.mu * (f[e] - r[e]) + volumetric * c[e];
    // H(i, k) = -V sum_j P(i, j) Dm^-1(k, j).
    PackD H[9];
    for (int kk = 0; kk < 3; ++kk)
      for (int i = 0; i < 3; ++i)
        H[3 * kk + i] = mv * (P[i] * d[kk] + P[3 + i] * d[3 + kk] + P[6 + i] * d[6 + kk]);
    alignas(64) double edge[9][L];
    std::memcpy(edge, H, sizeof(H));
    for (int l = 0; l < count; ++l)
      for (int e = 0; e < 9; ++e) b.h_[size_t(t0 + l)].data()[e] = edge[e][l];
    // F^-T = cof(F) / J of the elements whose F^-T is asked for.
    bool kept = false;
    for (int l = 0; keep && l < count; ++l) kept |= b.kept_slot_[size_t(t0 + l)] >= 0;
    if (kept) {
      const PackD inv_j = 1.0 / J;
      for (int e = 0; e < 9; ++e) c[e] *= inv_j;
      std::memcpy(edge, c, sizeof(c));
      for (int l = 0; l < count; ++l)
        if (const int32_t slot = b.kept_slot_[size_t(t0 + l)]; slot >= 0)
          for (int e = 0; e < 9; ++e) b.kept_inv_t_[size_t(slot)].data()[e] = edge[e][l];
    }
  };
  // Groups in pairs, whose polar iterations run side by side (a third less
  // time per element than one group at a time); pairs are fixed by index,
  // so the results do not depend on the thread count.
  const int64_t pairs = (groups + 1) / 2;
#pragma omp parallel for schedule(static) if (tets.size() > kParallelTets)
  for (int64_t q = 0; q < pairs; ++q) {
    const int64_t g0 = 2 * q, m = std::min<int64_t>(2, groups - g0);
    int count[2] = {0, 0};
    PackD f[2][9], r[2][9];
    for (int64_t k = 0; k < m; ++k) {
      count[k] = int(std::min<int64_t>(L, n - (g0 + k) * L));
      deformation(g0 + k, count[k], f[k]);
    }
    if (m == 2)
      polarRotationOfLaneGroups<2>(count, f, r);
    else
      polarRotationOfLanes(count[0], f[0], r[0]);
    for (int64_t k = 0; k < m; ++k) forces(g0 + k, count[k], f[k], r[k]);
  }
}
#endif

// Element stresses in parallel (the polar decomposition is the cost), then
// a serial scatter in element order: the same sums on any number of
// threads. With velocities, each element adds the Kelvin-Voigt stress
// sigma = 2 eta D, D = sym(dF/dt F^-1), so that a rigid motion (dF/dt F^-1
// skew) is not damped: P_v = J sigma F^-T.
void elementForces(const FemBody& b, const std::vector<Vec3d>& y, const std::vector<Vec3d>* vel,
                   std::vector<Vec3d>& f) {
  const auto& tets = b.mesh.tets;
  b.h_.resize(tets.size());
  b.kept_fresh_ = false;
  // The material is visited once for the whole body, not per element.
  std::visit(
      [&](const auto& mat) {
        using Model = std::decay_t<decltype(mat)>;
        // Fixed-corotated elements without damping (the common case), eight
        // at a time: the polar rotation and then P and H = -V P Dm^-T
        // across vector lanes.
        if constexpr (std::is_same_v<Model, FixedCorotated<double>>) {
#if defined(__GNUC__)
          if (!vel) {
            const bool keep = &y == &b.x && !b.kept_slot_.empty();
            fixedCorotatedForces(b, mat, y, keep);
            b.kept_fresh_ = keep;
            return;
          }
#endif
        }
        // Fixed-corotated elements in chunks: their polar rotations go
        // through the batched Newton iteration, eight at a time.
        constexpr int64_t kChunk = std::is_same_v<Model, FixedCorotated<double>> ? 64 : 1;
        const int64_t chunks = (int64_t(tets.size()) + kChunk - 1) / kChunk;
#pragma omp parallel for schedule(static) if (tets.size() > kParallelTets)
        for (int64_t k = 0; k < chunks; ++k) {
          const int64_t t0 = k * kChunk, t1 = std::min(int64_t(tets.size()), t0 + kChunk);
          Mat3d Fs[kChunk], Rs[kChunk];
          for (int64_t t = t0; t < t1; ++t) Fs[t - t0] = edges(y, tets[t]) * b.dm_inv[t];
          if constexpr (kChunk > 1) polarRotationBatch(int(t1 - t0), Fs, Rs);
          for (int64_t t = t0; t < t1; ++t) {
            const Mat3d& F = Fs[t - t0];
            Mat3d P;
            if constexpr (kChunk > 1)
              P = mat.firstPiola(F, Rs[t - t0]);
            else
              P = mat.firstPiola(F);
            if (vel) {
              const Mat3d Finv = F.inverse();
              const Mat3d L = edges(*vel, tets[t]) * b.dm_inv[t] * Finv;
              P += F.determinant() * b.damping * (L + L.transpose()) * Finv.transpose();
            }
            // H = -V P Dm^-T: the forces on nodes 1..3; node 0 takes minus their sum.
            b.h_[t] = -b.volume[t] * P * b.dm_inv[t].transpose();
          }
        }
      },
      b.model);
  // Each node gathers its elements' forces (H's columns on corners 1..3,
  // minus their sum on corner 0), in element order: the sums of a serial
  // scatter over the elements, bit for bit, on any number of threads.
  if (b.incidence_start_.size() != y.size() + 1) {
    b.incidence_start_.assign(y.size() + 1, 0);
    for (const auto& n : tets)
      for (int k = 0; k < 4; ++k) ++b.incidence_start_[size_t(n[k]) + 1];
    for (size_t i = 0; i < y.size(); ++i) b.incidence_start_[i + 1] += b.incidence_start_[i];
    b.incidence_.resize(b.incidence_start_.back());
    std::vector<uint32_t> cursor(b.incidence_start_.begin(), b.incidence_start_.end() - 1);
    for (size_t t = 0; t < tets.size(); ++t)
      for (int k = 0; k < 4; ++k) b.incidence_[cursor[size_t(tets[t][k])]++] = uint32_t(4 * t + k);
  }
  f.resize(y.size());
#pragma omp parallel for schedule(static) if (y.size() > 2048)
  for (int64_t i = 0; i < int64_t(y.size()); ++i) {
    Vec3d sum = Vec3d::Zero();
    for (uint32_t e = b.incidence_start_[size_t(i)]; e < b.incidence_start_[size_t(i) + 1]; ++e) {
      const Mat3d& h = b.h_[b.incidence_[e] >> 2];
      const uint32_t corner = b.incidence_[e] & 3;
      if (corner == 0) {
        sum -= h.col(0);
        sum -= h.col(1);
        sum -= h.col(2);
      } else {
        sum += h.col(int(corner) - 1);
      }
    }
    f[size_t(i)] = sum;
  }
}

}  // namespace

void FemBody::forces(std::vector<Vec3d>& f) const {
  elementForces(*this, x, damping > 0.0 ? &v : nullptr, f);
}

void FemBody::forcesAt(const std::vector<Vec3d>& y, std::vector<Vec3d>& f) const {
  elementForces(*this, y, nullptr, f);
}

void FemBody::keepInverseTransposes(const std::vector<int>& elements) {
  kept_slot_.assign(mesh.tets.size(), -1);
  int32_t slots = 0;
  for (const int t : elements)
    if (kept_slot_[size_t(t)] < 0) kept_slot_[size_t(t)] = slots++;
  kept_inv_t_.assign(size_t(slots), Mat3d::Zero());
  kept_fresh_ = false;
}

const Mat3d* FemBody::keptInverseTranspose(size_t t) const {
  if (!kept_fresh_ || kept_slot_.empty() || kept_slot_[t] < 0) return nullptr;
  return &kept_inv_t_[size_t(kept_slot_[t])];
}

double FemBody::elasticEnergy() const {
  double e = 0.0;
  std::visit(
      [&](const auto& mat) {
        for (size_t t = 0; t < mesh.tets.size(); ++t)
          e += volume[t] * mat.psi(edges(x, mesh.tets[t]) * dm_inv[t]);
      },
      model);
  return e;
}

double FemBody::kineticEnergy() const {
  double e = 0.0;
  for (size_t i = 0; i < x.size(); ++i) e += 0.5 * mass[i] * v[i].squaredNorm();
  return e;
}

double FemBody::stableDt(double cfl) const {
  const double elastic = cfl * min_height / wave_speed;
  if (damping <= 0.0) return elastic;
  return std::min(elastic, cfl * density * min_height * min_height / (6.0 * damping));
}

void FemBody::stepExplicit(double dt, const Vec3d& gravity, std::vector<Vec3d>& f) {
  forces(f);
  for (size_t i = 0; i < x.size(); ++i) {
    if (pinned[i]) {
      v[i].setZero();
      continue;
    }
    v[i] += dt * (f[i] / mass[i] + gravity);
    x[i] += dt * v[i];
  }
}

}  // namespace triad
