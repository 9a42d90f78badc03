#pragma once
// MPM particles stored as arrays of attributes (SoA), one ParticleSet per
// material and sampling volume, so that the material variant is visited once
// per set and every particle of a set has the same mass and rest volume.
#include <cstdint>
#include <vector>

#include "sim/materials/materials.h"
#include "sim/math.h"

namespace triad {

struct ParticleSet {
  int material = -1;  // index into SceneDesc::materials
  Material model;
  float mass = 0.0f;    // per particle, kg
  float volume = 0.0f;  // rest volume per particle, m^3

  std::vector<Vec3f> x;  // position, m
  std::vector<Vec3f> v;  // velocity, m/s
  // APIC affine velocity matrix. Between the stress pass and P2G of one step
  // it holds the combined affine momentum instead (see transfer.cpp).
  std::vector<Mat3f> C;
  std::vector<Mat3f> F;          // (elastic) deformation gradient; empty for water
  std::vector<float> J;          // water: volume ratio; snow: plastic volume ratio Jp
  std::vector<uint32_t> id;      // stable particle id across frames
  std::vector<uint16_t> object;  // index into SceneDesc::objects

  size_t size() const { return x.size(); }
  bool usesF() const;
  bool usesJ() const;
  // Append one particle at rest state.
  void push(const Vec3f& pos, const Vec3f& vel, uint32_t pid, uint16_t obj);
  // Room for n particles in every attribute this material uses.
  void reserve(size_t n);
  // Total volume ratio det(F) * J (or J alone for water) of particle i.
  float volumeRatio(size_t i) const;
  // Reorders every attribute by `src` (new[i] = old[src[i]]) through
  // `scratch`, which holds at least kPermuteScratch bytes per particle.
  static constexpr size_t kPermuteScratch = 12;
  void permute(const std::vector<uint32_t>& src, unsigned char* scratch);
  // Removes the particles whose flag in `gone` is set; the others keep
  // their order.
  void removeFlagged(const std::vector<uint8_t>& gone);
  // The set's description (material, model, mass, volume), no particles.
  ParticleSet withoutParticles() const;
  // Gives back the attribute arrays' unused capacity.
  void shrinkToFit();
  // Bytes held by the attribute arrays (capacity, not size).
  size_t bytes() const;
};

}  // namespace triad
