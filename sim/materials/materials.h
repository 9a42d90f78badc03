#pragma once
// Constitutive models for the MPM solver, as small value types templated on
// the scalar (ziran2020 style): float in the solver, double in tests.
//
//   FixedCorotated, NeoHookean, StvkHencky   sim/elastic_models.h
//   Snow, DruckerPrager, MohrCoulomb         sim/plastic_models.h
//   Water                                    below
//
// Each model says what per-particle state it needs: kUsesF (a deformation
// gradient F, else only J = det F) and kUsesPlasticJ (a plastic volume Jp).
// The solver's per-substep calls are kirchhoff(...) for the stress and, for
// the plastic models, project(...) on the trial elastic F, or
// projectAndKirchhoff(...), which does both with one SVD. The *Batch
// functions at the end run those over arrays several times faster than a
// loop of single calls (see sim/svd3.h).
#include <algorithm>
#include <cmath>
#include <variant>

#include "sim/materials/elastic_models.h"
#include "sim/math.h"
#include "sim/materials/plastic_models.h"
#include "sim/scene_desc.h"

namespace triad {

// Weakly compressible fluid with the Tait equation of state and Newtonian
// viscosity. Per-particle state: J only (the solver integrates J <- J (1 +
// dt tr grad v)); the stress needs the velocity gradient instead of F.
//   p(J) = K / gamma (J^-gamma - 1),  psi(J) with -dpsi/dJ = p, psi(1) = 0.
// J is clamped to [kMinJ, kMaxJ] for the pressure: J^-7 at the lower end is
// 1e7, still well inside float range, and a fluid squeezed tenfold is lost
// anyway. Outside the range psi continues linearly so that -dpsi/dJ = p
// holds everywhere.
template <class T>
struct Water {
  static constexpr bool kUsesF = false;
  static constexpr bool kUsesPlasticJ = false;
  static constexpr T kMinJ = T(0.1);
  static constexpr T kMaxJ = T(10);

  T bulk = 0;       // K, pascals
  T gamma = T(7);   // Tait exponent
  T viscosity = 0;  // dynamic, pascal seconds

  static T clampJ(T J) { return std::clamp(J, kMinJ, kMaxJ); }

  T pressure(T J) const { return bulk / gamma * (std::pow(clampJ(J), -gamma) - T(1)); }
  // The J whose pressure is p (the inverse of pressure()), within the clamp.
  T jAtPressure(T p) const {
    return clampJ(std::pow(std::max(T(1) + gamma * p / bulk, T(1e-12)), T(-1) / gamma));
  }

  T psi(T J) const {
    const T Jc = clampJ(J);
    T e;
    if (std::abs(gamma - T(1)) < T(1e-6)) {
      e = bulk * (Jc - T(1) - std::log(Jc));
    } else {
      e = bulk / gamma * (Jc - T(1) + (std::pow(Jc, T(1) - gamma) - T(1)) / (gamma - T(1)));
    }
    return e - pressure(Jc) * (J - Jc);
  }

  // tau = J sigma = -J p I + J viscosity (grad v + grad v^T), J clamped.
  Mat3<T> kirchhoff(T J, const Mat3<T>& grad_v) const {
    const T Jc = clampJ(J);
    Mat3<T> tau = Jc * viscosity * (grad_v + grad_v.transpose());
    tau.diagonal().array() -= Jc * pressure(Jc);
    return tau;
  }
};

// The solver's materials, one alternative per MaterialModel.
using Material = std::variant<FixedCorotated<float>, NeoHookean<float>, Snow<float>,
                              DruckerPrager<float>, MohrCoulomb<float>, Water<float>>;

// The model for a validated description (scene loader output).
Material makeMaterial(const MaterialDesc& desc);

// P-wave speed at rest, sqrt((lambda + 2 mu) / rho) (water: sqrt(K / rho)),
// in m/s: the CFL bound on the time step. Snow stiffens with compaction by
// up to Snow::stiffnessScale(min_jp); that is not included.
float waveSpeed(const MaterialDesc& desc);

// "fixed_corotated", "neo_hookean", "snow", "drucker_prager", "mohr_coulomb",
// "water".
const char* modelName(MaterialModel model);

// Batched hot paths over n particles. Inputs and outputs are arrays of n;
// the results equal the single calls up to float rounding.
// tau[i] = m.kirchhoff(F[i]).
void kirchhoffBatch(const FixedCorotated<float>& m, int n, const Mat3f* F, Mat3f* tau);
// tau[i] = m.kirchhoff(J[i], grad_v[i]).
void kirchhoffBatch(const Water<float>& m, int n, const float* J, const Mat3f* grad_v, Mat3f* tau);
// tau[i] = m.projectAndKirchhoff(Fe[i], Jp[i]); Fe and Jp are updated.
void projectAndKirchhoffBatch(const Snow<float>& m, int n, Mat3f* Fe, float* Jp, Mat3f* tau);
// tau[i] = m.projectAndKirchhoff(F[i]); F is updated.
void projectAndKirchhoffBatch(const DruckerPrager<float>& m, int n, Mat3f* F, Mat3f* tau);
void projectAndKirchhoffBatch(const MohrCoulomb<float>& m, int n, Mat3f* F, Mat3f* tau);
// The same under mu(I): grad_v[i] is particle i's velocity gradient.
void projectAndKirchhoffBatch(const MohrCoulomb<float>& m, int n, Mat3f* F, const Mat3f* grad_v,
                              Mat3f* tau);

}  // namespace triad
