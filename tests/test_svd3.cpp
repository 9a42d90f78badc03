// Tests for sim/svd3.h: the rotation-variant SVD and polar decomposition in
// float (the McAdams-style kernel, scalar and batched) and double (Eigen).
#include "sim/lane_math.h"
#include "sim/svd3.h"

#include <cmath>
#include <cstdio>
#include <cstring>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Geometry>
#include <Eigen/SVD>

namespace triad {
namespace {

// Tolerances relative to |F|: the float kernel reaches ~1e-6 (measured
// worst case over 6e5 random matrices: 1.1e-6), Eigen in double ~1e-15.
template <class T>
constexpr T kTol = std::is_same_v<T, float> ? T(1e-5) : T(1e-12);

template <class T>
Mat3<T> randomRotation(std::mt19937& rng) {
  std::normal_distribution<T> g(0, 1);
  Eigen::Quaternion<T> q(g(rng), g(rng), g(rng), g(rng));
  return q.normalized().toRotationMatrix();
}

template <class T>
Mat3<T> randomMatrix(std::mt19937& rng, T scale = 1) {
  std::normal_distribution<T> g(0, 1);
  Mat3<T> F;
  for (int k = 0; k < 9; ++k) F.data()[k] = scale * g(rng);
  return F;
}

// Every property of the decomposition that the solver relies on.
template <class T>
void checkSvd(const Mat3<T>& F, const Mat3<T>& U, const Vec3<T>& sigma, const Mat3<T>& V) {
  const T tol = kTol<T>;
  const T norm = std::max(F.norm(), std::numeric_limits<T>::min());
  const Mat3<T> I = Mat3<T>::Identity();
  EXPECT_LE((U * sigma.asDiagonal() * V.transpose() - F).norm(), tol * norm) << F;
  EXPECT_LE((U.transpose() * U - I).norm(), tol) << F;
  EXPECT_LE((V.transpose() * V - I).norm(), tol) << F;
  EXPECT_NEAR(U.determinant(), T(1), tol) << F;
  EXPECT_NEAR(V.determinant(), T(1), tol) << F;
  // The ordering is exact by construction, not up to a tolerance.
  EXPECT_GE(sigma(0), sigma(1)) << F;
  EXPECT_GE(sigma(1), std::abs(sigma(2))) << F;
  // The reflection, if any, is carried by the smallest singular value.
  const T det = F.determinant();
  if (std::abs(det) > 1e-3 * norm * norm * norm) {
    EXPECT_EQ(det < 0, sigma(2) < 0) << F;
  }
  // |sigma| are the singular values (Eigen's, computed in double).
  const Eigen::JacobiSVD<Mat3d> ref(F.template cast<double>());
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(std::abs(double(sigma(i))), ref.singularValues()(i), double(tol) * norm) << F;
  }
}

template <class T>
void checkMatrix(const Mat3<T>& F) {
  Mat3<T> U, V;
  Vec3<T> sigma;
  svd3(F, U, sigma, V);
  checkSvd(F, U, sigma, V);
  const Mat3<T> R = polarRotation(F);
  EXPECT_LE((R - U * V.transpose()).norm(), kTol<T>) << F;
}

template <class T>
class Svd3Test : public ::testing::Test {};
using Scalars = ::testing::Types<float, double>;
TYPED_TEST_SUITE(Svd3Test, Scalars, );

TYPED_TEST(Svd3Test, Identity) {
  using T = TypeParam;
  const Mat3<T> I = Mat3<T>::Identity();
  Mat3<T> U, V;
  Vec3<T> sigma;
  svd3(I, U, sigma, V);
  checkSvd(I, U, sigma, V);
  EXPECT_LE((sigma - Vec3<T>::Ones()).norm(), kTol<T>);
  EXPECT_LE((polarRotation(I) - I).norm(), kTol<T>);
}

TYPED_TEST(Svd3Test, DiagonalMatricesAreSortedWithSigns) {
  using T = TypeParam;
  struct Case {
    Vec3<T> diag, sigma;
  };
  const Case cases[] = {
      {{3, 2, 1}, {3, 2, 1}},          {{1, 2, 3}, {3, 2, 1}},
      {{0.5, 3, -2}, {3, 2, -0.5}},     // one reflection: smallest gets the sign
      {{-1, -2, 4}, {4, 2, 1}},         // two reflections are a rotation
      {{-1, -2, -3}, {3, 2, -1}},       // three are a reflection
      {{2, 0, 5}, {5, 2, 0}},           // rank 2
      {{7, 7, 7}, {7, 7, 7}},           // fully degenerate
      {{1, 1e-3, 1e3}, {1e3, 1, 1e-3}}  // wide spread
  };
  for (const Case& c : cases) {
    const Mat3<T> F = c.diag.asDiagonal();
    Mat3<T> U, V;
    Vec3<T> sigma;
    svd3(F, U, sigma, V);
    checkSvd(F, U, sigma, V);
    EXPECT_LE((sigma - c.sigma).norm(), kTol<T> * c.sigma.norm()) << c.diag.transpose();
  }
}

TYPED_TEST(Svd3Test, RankDeficient) {
  using T = TypeParam;
  std::mt19937 rng(11);
  // Zero: any rotations, zero singular values, and nothing non-finite.
  Mat3<T> U, V;
  Vec3<T> sigma;
  svd3(Mat3<T>::Zero().eval(), U, sigma, V);
  checkSvd(Mat3<T>::Zero().eval(), U, sigma, V);
  EXPECT_EQ(sigma, Vec3<T>::Zero());
  for (int t = 0; t < 200; ++t) {
    std::normal_distribution<T> g(0, 1);
    const Vec3<T> a(g(rng), g(rng), g(rng)), b(g(rng), g(rng), g(rng)), c(g(rng), g(rng), g(rng));
    const Mat3<T> rank1 = a * b.transpose();
    checkMatrix(rank1);
    svd3(rank1, U, sigma, V);
    EXPECT_NEAR(sigma(0), a.norm() * b.norm(), kTol<T> * rank1.norm());
    EXPECT_LE(sigma.tail(2).norm(), kTol<T> * rank1.norm());
    const Mat3<T> rank2 = a * b.transpose() + c * a.transpose();
    checkMatrix(rank2);
    svd3(rank2, U, sigma, V);
    EXPECT_LE(std::abs(sigma(2)), kTol<T> * rank2.norm());
  }
}

TYPED_TEST(Svd3Test, NearDegenerateSingularValues) {
  using T = TypeParam;
  std::mt19937 rng(12);
  const T eps = std::is_same_v<T, float> ? T(1e-6) : T(1e-12);
  const Vec3<T> spectra[] = {
      {1, 1 + eps, 1 - eps}, {1 + eps, 1, 1}, {2, 2, 1}, {2, 1, 1}, {1, 1, -1},
      {1, 1 - eps, -1},      {1, 1, 0},       {1, 0, 0}};
  for (const Vec3<T>& s : spectra) {
    for (int t = 0; t < 100; ++t) {
      const Mat3<T> F = randomRotation<T>(rng) * s.asDiagonal() * randomRotation<T>(rng);
      checkMatrix(F);
    }
  }
}

TYPED_TEST(Svd3Test, ReflectionsCarryTheSignInSigma2) {
  using T = TypeParam;
  std::mt19937 rng(13);
  for (int t = 0; t < 1000; ++t) {
    Mat3<T> F = randomMatrix<T>(rng);
    if (F.determinant() > 0) F.col(0) = -F.col(0);
    Mat3<T> U, V;
    Vec3<T> sigma;
    svd3(F, U, sigma, V);
    checkSvd(F, U, sigma, V);
    EXPECT_LT(sigma(2), 0) << F;
    // The polar rotation is proper even though F is not.
    EXPECT_NEAR(polarRotation(F).determinant(), T(1), kTol<T>);
  }
}

TYPED_TEST(Svd3Test, LargeAndTinyScales) {
  using T = TypeParam;
  std::mt19937 rng(14);
  for (const T scale : {T(1e-6), T(1e-3), T(1e3), T(1e6)}) {
    for (int t = 0; t < 200; ++t) {
      checkMatrix(randomMatrix<T>(rng, scale));
      const Mat3<T> nearRotation =
          scale * randomRotation<T>(rng) * (Mat3<T>::Identity() + randomMatrix<T>(rng, T(0.1)));
      checkMatrix(nearRotation);
    }
  }
}

TYPED_TEST(Svd3Test, RandomMatrices) {
  using T = TypeParam;
  std::mt19937 rng(15);
  for (int t = 0; t < 20000; ++t) checkMatrix(randomMatrix<T>(rng));
  // The deformation gradients MPM produces: rotations times small stretches,
  // where A^T A has nearly equal eigenvalues.
  for (int t = 0; t < 20000; ++t) {
    checkMatrix(
        (randomRotation<T>(rng) * (Mat3<T>::Identity() + randomMatrix<T>(rng, T(0.02)))).eval());
  }
}

TYPED_TEST(Svd3Test, PolarRotationGivesSymmetricStretch) {
  using T = TypeParam;
  std::mt19937 rng(16);
  for (int t = 0; t < 1000; ++t) {
    const Mat3<T> F = randomMatrix<T>(rng);
    const Mat3<T> R = polarRotation(F);
    EXPECT_LE((R.transpose() * R - Mat3<T>::Identity()).norm(), kTol<T>);
    EXPECT_NEAR(R.determinant(), T(1), kTol<T>);
    const Mat3<T> S = R.transpose() * F;
    EXPECT_LE((S - S.transpose()).norm(), kTol<T> * F.norm()) << F;
    // A rotation is its own polar factor.
    const Mat3<T> Q = randomRotation<T>(rng);
    EXPECT_LE((polarRotation(Q) - Q).norm(), kTol<T>);
  }
}

TEST(Svd3Batch, MatchesScalarIncludingShortTails) {
  std::mt19937 rng(17);
  for (const int n : {0, 1, 5, 16, 17, 40, 257}) {
    std::vector<Mat3f> F(n), U(n), V(n), R(n);
    std::vector<Vec3f> sigma(n);
    for (int i = 0; i < n; ++i) {
      F[i] =
          i % 3 == 0
              ? randomMatrix<float>(rng)
              : (randomRotation<float>(rng) * (Mat3f::Identity() + randomMatrix<float>(rng, 0.05f)))
                    .eval();
    }
    svd3Batch(n, F.data(), U.data(), sigma.data(), V.data());
    polarRotationBatch(n, F.data(), R.data());
    for (int i = 0; i < n; ++i) {
      checkSvd(F[i], U[i], sigma[i], V[i]);
      Mat3f Us, Vs;
      Vec3f ss;
      svd3(F[i], Us, ss, Vs);
      EXPECT_LE((sigma[i] - ss).norm(), 1e-5f * F[i].norm());
      EXPECT_LE((R[i] - Us * Vs.transpose()).norm(), 1e-5f);
    }
  }
}

TEST(PolarBatch, DoubleMatchesScalarNewtonAndSvd) {
  // The FEM's batched Newton iteration: the scalar polarRotation<double>
  // to rounding, for small and large strains, rotations, nearly singular
  // and inverted elements (those through the SVD), and short tails.
  std::mt19937 rng(19);
  for (const int n : {0, 1, 7, 8, 9, 64, 131}) {
    std::vector<Mat3d> F(static_cast<size_t>(n)), R(static_cast<size_t>(n));
    for (int i = 0; i < n; ++i) {
      const Mat3d Q = randomRotation<double>(rng);
      switch (i % 5) {
        case 0:
          F[size_t(i)] = Q * (Mat3d::Identity() + randomMatrix<double>(rng, 1e-3));
          break;
        case 1:
          F[size_t(i)] = Q * (Mat3d::Identity() + randomMatrix<double>(rng, 0.3));
          break;
        case 2:
          F[size_t(i)] = 50.0 * randomMatrix<double>(rng);
          break;
        case 3:
          F[size_t(i)] = Q * Vec3d(1.0, 1e-5, 0.5).asDiagonal();
          break;  // nearly flat
        default:
          F[size_t(i)] = Q * Vec3d(1.2, 0.8, -0.6).asDiagonal();
          break;  // inverted
      }
    }
    polarRotationBatch(n, F.data(), R.data());
    for (int i = 0; i < n; ++i) {
      const Mat3d& A = F[size_t(i)];
      const Mat3d& Rb = R[size_t(i)];
      EXPECT_LE((Rb - polarRotation(A)).norm(), 1e-12) << "matrix " << i << " of " << n;
      EXPECT_LE((Rb.transpose() * Rb - Mat3d::Identity()).norm(), 1e-12);
      EXPECT_NEAR(Rb.determinant(), 1.0, 1e-12);
      // R^T F is the symmetric stretch.
      const Mat3d S = Rb.transpose() * A;
      EXPECT_LE((S - S.transpose()).norm(), 1e-10 * A.norm());
    }
  }
}

TEST(PolarLanes, FloatNewtonMatchesTheRotationOfTheSvd) {
  // The stress kernel's polar rotation in lanes: the Newton iteration for
  // well-conditioned F (near rotations, strong stretches, large and tiny
  // scales), the SVD for a pass holding an inverted or nearly flat F, each
  // against the double-precision rotation, with short tails. Counted: how
  // many passes the Newton path served, so that neither path goes untested.
  std::mt19937 rng(20);
  int newton_passes = 0, svd_passes = 0;
  for (const int n : {1, 7, svd3_detail::kLanes, 40, 131}) {
    for (const bool with_inverted : {false, true}) {
      std::vector<Mat3f> F(static_cast<size_t>(n));
      for (int i = 0; i < n; ++i) {
        const Mat3d Q = randomRotation<double>(rng);
        Mat3d A;
        switch (i % 4) {
          case 0:
            A = Q * (Mat3d::Identity() + randomMatrix<double>(rng, 1e-3));
            break;
          case 1:
            A = Q * (Mat3d::Identity() + randomMatrix<double>(rng, 0.3));
            break;
          case 2:
            A = Q * Vec3d(4.0, 0.4, 1.0).asDiagonal() * randomRotation<double>(rng);
            break;  // ten to one
          default:
            A = (i % 8 == 3 ? 1e3 : 1e-3) * Q *
                (Mat3d::Identity() + randomMatrix<double>(rng, 0.1));
            break;
        }
        if (with_inverted && i == n / 2) A = Q * Vec3d(1.2, 0.8, -0.6).asDiagonal();
        if (with_inverted && i == n / 3) A = Q * Vec3d(1.0, 1e-5, 0.5).asDiagonal();
        F[size_t(i)] = A.cast<float>();
      }
      std::vector<Mat3f> R(static_cast<size_t>(n));
      polarRotationLanes(
          n, F.data(),
          [&](int b, int count, const svd3_detail::Pack(&f)[9], const svd3_detail::Pack(&r)[9]) {
            Mat3f back[svd3_detail::kLanes];
            svd3_detail::storeLanes(count, f, back);
            bool flat = false;
            for (int l = 0; l < count; ++l) {
              EXPECT_EQ(back[l], F[size_t(b + l)]);
              const Mat3d A = back[l].cast<double>();
              flat = flat || A.determinant() <= 1e-3 * std::pow(A.norm(), 3.0);
            }
            // Newton serves every pass without such an F.
            svd3_detail::Pack x[9];
            EXPECT_EQ(svd3_detail::newtonPolar(f, x), !flat);
            svd3_detail::storeLanes(count, r, R.data() + b);
            (flat ? svd_passes : newton_passes)++;
          });
      for (int i = 0; i < n; ++i) {
        const Mat3f& A = F[size_t(i)];
        const Mat3f& Rl = R[size_t(i)];
        const Mat3d ref = polarRotation(Mat3d(A.cast<double>()));
        EXPECT_LE((Rl.cast<double>() - ref).norm(), 2e-6) << "matrix " << i << " of " << n << "\n"
                                                          << A;
        EXPECT_LE((Rl.transpose() * Rl - Mat3f::Identity()).norm(), 2e-6f);
        EXPECT_NEAR(Rl.determinant(), 1.0f, 2e-6f);
      }
    }
  }
  EXPECT_GT(newton_passes, 5);
  EXPECT_GT(svd_passes, 5);
}

TEST(Svd3Batch, OutputsMayAliasInput) {
  std::mt19937 rng(18);
  std::vector<Mat3f> F(20), R(20);
  for (Mat3f& A : F) A = randomMatrix<float>(rng);
  polarRotationBatch(20, F.data(), R.data());
  polarRotationBatch(20, F.data(), F.data());
  for (int i = 0; i < 20; ++i) EXPECT_EQ(F[i], R[i]);
}

}  // namespace
}  // namespace triad

namespace triad {
namespace {

// The lanes' log and exp against libm over their ranges: log over every
// binade of positive normal floats, exp over [-87, 88], where a sand
// particle's return takes them.
TEST(LaneMath, LogAndExpMatchLibm) {
  std::mt19937 rng(21);
  std::uniform_real_distribution<float> mantissa(1.0f, 2.0f), power(-87.0f, 88.0f);
  constexpr int L = svd3_detail::kLanes;
  double worst_log = 0, worst_exp = 0;
  for (int pass = 0; pass < 2000; ++pass) {
    alignas(64) float x[L], y[L], lx[L], ey[L];
    for (int l = 0; l < L; ++l) {
      x[l] = std::ldexp(mantissa(rng), int(pass % 250) - 125 + l % 2);
      y[l] = power(rng);
    }
    if (pass == 0) x[0] = 1.0f, y[0] = 0.0f;
    svd3_detail::Pack px, py;
    std::memcpy(&px, x, sizeof(px));
    std::memcpy(&py, y, sizeof(py));
    const svd3_detail::Pack lp = svd3_detail::logv(px), ep = svd3_detail::expv(py);
    std::memcpy(lx, &lp, sizeof(lx));
    std::memcpy(ey, &ep, sizeof(ey));
    for (int l = 0; l < L; ++l) {
      const double ref_log = std::log(double(x[l])), ref_exp = std::exp(double(y[l]));
      // log: absolute near x = 1 (where it passes zero), else relative.
      worst_log = std::max(worst_log, std::abs(lx[l] - ref_log) / std::max(1.0, std::abs(ref_log)));
      worst_exp = std::max(worst_exp, std::abs(ey[l] - ref_exp) / ref_exp);
    }
  }
  std::printf("log: %.2e, exp: %.2e relative\n", worst_log, worst_exp);
  EXPECT_LT(worst_log, 2.5e-7);
  EXPECT_LT(worst_exp, 2.5e-7);
}

}  // namespace
}  // namespace triad
