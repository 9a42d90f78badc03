#include "sim/mpm/particles.h"

#include <cstring>

namespace triad {

namespace {

// Gather one attribute array through the permutation into scratch, then copy
// back, a slice of at most 12 bytes of each element at a time: the slices of
// an element are independent, so gathering slice k after slice k-1 was
// written back still reads the unpermuted slice k. Matrices go in three
// column passes and the scratch holds 12 bytes per particle instead of 36.
constexpr size_t kParallelCopy = 32768;

template <class T>
void permuteArray(std::vector<T>& a, const std::vector<uint32_t>& src, unsigned char* tmp,
                  size_t begin, size_t end) {
  if (a.empty()) return;
  constexpr size_t kSlice = sizeof(T) % 12 == 0 ? 12 : sizeof(T);
  static_assert(kSlice <= ParticleSet::kPermuteScratch);
  unsigned char* base = reinterpret_cast<unsigned char*>(a.data());
  // Below this many particles a loop takes less than waking the other
  // threads for it (ten such loops a step: a draft-size scene's binning
  // was mostly wake-ups).
  const bool parallel = end - begin > kParallelCopy;
  const auto b = static_cast<int64_t>(begin), e = static_cast<int64_t>(end);
  for (size_t at = 0; at < sizeof(T); at += kSlice) {
#pragma omp parallel for schedule(static) if (parallel)
    for (int64_t i = b; i < e; ++i)
      std::memcpy(tmp + size_t(i - b) * kSlice, base + size_t(src[size_t(i)]) * sizeof(T) + at,
                  kSlice);
#pragma omp parallel for schedule(static) if (parallel)
    for (int64_t i = b; i < e; ++i)
      std::memcpy(base + size_t(i) * sizeof(T) + at, tmp + size_t(i - b) * kSlice, kSlice);
  }
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

void ParticleSet::reserve(size_t n) {
  x.reserve(n);
  v.reserve(n);
  C.reserve(n);
  if (usesF()) F.reserve(n);
  if (usesJ()) J.reserve(n);
  id.reserve(n);
  object.reserve(n);
}

float ParticleSet::volumeRatio(size_t i) const {
  float r = F.empty() ? 1.0f : F[i].determinant();
  if (!J.empty()) r *= J[i];
  return r;
}

void ParticleSet::permute(const std::vector<uint32_t>& src, unsigned char* scratch) {
  // A step's sort moves few particles: only the span between the first and
  // the last one that moves is copied (a settling pile's often is a part).
  size_t begin = 0, end = src.size();
  while (begin < end && src[begin] == begin) ++begin;
  while (end > begin && src[end - 1] == end - 1) --end;
  if (begin == end) return;
  permuteArray(x, src, scratch, begin, end);
  permuteArray(v, src, scratch, begin, end);
  permuteArray(C, src, scratch, begin, end);
  permuteArray(F, src, scratch, begin, end);
  permuteArray(J, src, scratch, begin, end);
  permuteArray(id, src, scratch, begin, end);
  permuteArray(object, src, scratch, begin, end);
}

namespace {

template <typename T>
void compact(std::vector<T>& a, const std::vector<uint8_t>& gone) {
  if (a.empty()) return;  // an attribute this material does not use
  size_t o = 0;
  for (size_t i = 0; i < a.size(); ++i)
    if (!gone[i]) a[o++] = a[i];
  a.resize(o);
}

}  // namespace

void ParticleSet::removeFlagged(const std::vector<uint8_t>& gone) {
  compact(x, gone);
  compact(v, gone);
  compact(C, gone);
  compact(F, gone);
  compact(J, gone);
  compact(id, gone);
  compact(object, gone);
}

ParticleSet ParticleSet::withoutParticles() const {
  ParticleSet e;
  e.material = material;
  e.model = model;
  e.mass = mass;
  e.volume = volume;
  return e;
}

void ParticleSet::shrinkToFit() {
  x.shrink_to_fit();
  v.shrink_to_fit();
  C.shrink_to_fit();
  F.shrink_to_fit();
  J.shrink_to_fit();
  id.shrink_to_fit();
  object.shrink_to_fit();
}

size_t ParticleSet::bytes() const {
  return capacityBytes(x) + capacityBytes(v) + capacityBytes(C) + capacityBytes(F) +
         capacityBytes(J) + capacityBytes(id) + capacityBytes(object);
}

}  // namespace triad
