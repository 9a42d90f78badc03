#include "sim/mpm/particles.h"

#include <cstring>

namespace triad {

namespace {

// Gather one attribute array through the permutation into scratch, then copy back.
template <class T>
void permuteArray(std::vector<T>& a, const std::vector<uint32_t>& src,
                  std::vector<unsigned char>& scratch) {
  if (a.empty()) return;
  const size_t n = a.size();
  scratch.resize(std::max(scratch.size(), n * sizeof(T)));
  T* tmp = reinterpret_cast<T*>(scratch.data());
#pragma omp parallel for schedule(static)
  for (int64_t i = 0; i < static_cast<int64_t>(n); ++i) tmp[i] = a[src[i]];
  std::memcpy(static_cast<void*>(a.data()), tmp, n * sizeof(T));
}

template <class T>
size_t capacityBytes(const std::vector<T>& a) {
  return a.capacity() * sizeof(T);
}

}  // namespace

bool ParticleSet::usesF() const {
  return std::visit([](const auto& m) { return std::decay_t<decltype(m)>::kUsesF; }, model);
}

bool ParticleSet::usesJ() const {
  return std::visit(
      [](const auto& m) {
        using M = std::decay_t<decltype(m)>;
        return !M::kUsesF || M::kUsesPlasticJ;
      },
      model);
}

void ParticleSet::push(const Vec3f& pos, const Vec3f& vel, uint32_t pid, uint16_t obj) {
  x.push_back(pos);
  v.push_back(vel);
  C.push_back(Mat3f::Zero());
  if (usesF()) F.push_back(Mat3f::Identity());
  if (usesJ()) J.push_back(1.0f);
  id.push_back(pid);
  object.push_back(obj);
}

float ParticleSet::volumeRatio(size_t i) const {
  float r = F.empty() ? 1.0f : F[i].determinant();
  if (!J.empty()) r *= J[i];
  return r;
}

void ParticleSet::permute(const std::vector<uint32_t>& src, std::vector<unsigned char>& scratch) {
  permuteArray(x, src, scratch);
  permuteArray(v, src, scratch);
  permuteArray(C, src, scratch);
  permuteArray(F, src, scratch);
  permuteArray(J, src, scratch);
  permuteArray(id, src, scratch);
  permuteArray(object, src, scratch);
}

size_t ParticleSet::bytes() const {
  return capacityBytes(x) + capacityBytes(v) + capacityBytes(C) + capacityBytes(F) +
         capacityBytes(J) + capacityBytes(id) + capacityBytes(object);
}

}  // namespace triad
