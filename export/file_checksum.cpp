#include "export/file_checksum.h"

#include <algorithm>
#include <cstring>

namespace triad {

namespace {

static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "words are read little-endian");

constexpr uint64_t kPrime = (uint64_t(1) << 61) - 1;
constexpr uint64_t kRadix = 0x1bd11bdaa9fc1a22ull & kPrime;  // any fixed r in (1, p)

__extension__ typedef unsigned __int128 Wide;  // GCC and clang's 128-bit integer

uint64_t reduce(uint64_t a) {
  a = (a & kPrime) + (a >> 61);
  return a >= kPrime ? a - kPrime : a;
}

// a * b mod p for a, b < p: the product's bits above 61 fold back in,
// since 2^61 = 1 mod p.
uint64_t mulMod(uint64_t a, uint64_t b) {
  const Wide m = Wide(a) * b;
  return reduce(uint64_t(m & kPrime) + uint64_t(m >> 61));
}

uint64_t addMod(uint64_t a, uint64_t b) {
  const uint64_t s = a + b;  // both < 2^61: no overflow
  return s >= kPrime ? s - kPrime : s;
}

uint64_t powMod(uint64_t base, uint64_t e) {
  uint64_t r = 1;
  for (; e > 0; e >>= 1, base = mulMod(base, base))
    if (e & 1) r = mulMod(r, base);
  return r;
}

}  // namespace

void FileChecksum::add(uint64_t offset, const void* data, size_t n) {
  if (n == 0) return;  // an empty array may have a null data pointer
  const auto* p = static_cast<const unsigned char*>(data);
  end_ = std::max(end_, offset + n);
  uint64_t word = offset / 8;
  uint64_t power = powMod(kRadix, word + 1);
  uint64_t sum = sum_;
  // A word begun before `offset`: these bytes' share of it (a word's value
  // is linear in its bytes, so shares added by several writers make it up).
  if (const size_t lead = size_t(offset % 8); lead != 0) {
    const size_t take = std::min(n, 8 - lead);
    uint64_t w = 0;
    std::memcpy(reinterpret_cast<unsigned char*>(&w) + lead, p, take);
    sum = addMod(sum, mulMod(reduce(w), power));
    p += take;
    n -= take;
    ++word;
    power = mulMod(power, kRadix);
  }
  // Whole words four at a time, on four chains of powers (r^4 apart), so
  // that the multiplications do not wait on each other.
  if (n >= 64) {
    static const uint64_t r4 = powMod(kRadix, 4);
    uint64_t pw[4] = {power, 0, 0, 0}, acc[4] = {sum, 0, 0, 0};
    for (int k = 1; k < 4; ++k) pw[k] = mulMod(pw[k - 1], kRadix);
    for (; n >= 32; n -= 32, p += 32)
      for (int k = 0; k < 4; ++k) {
        uint64_t w;
        std::memcpy(&w, p + 8 * k, 8);
        acc[k] = addMod(acc[k], mulMod(reduce(w), pw[k]));
        pw[k] = mulMod(pw[k], r4);
      }
    sum = addMod(addMod(acc[0], acc[1]), addMod(acc[2], acc[3]));
    power = pw[0];
  }
  for (; n >= 8; n -= 8, p += 8) {
    uint64_t w;
    std::memcpy(&w, p, 8);
    sum = addMod(sum, mulMod(reduce(w), power));
    power = mulMod(power, kRadix);
  }
  if (n > 0) {  // the start of a word that others may finish
    uint64_t w = 0;
    std::memcpy(&w, p, n);
    sum = addMod(sum, mulMod(reduce(w), power));
  }
  sum_ = sum;
}

void FileChecksum::merge(uint64_t part) {
  sum_ = addMod(sum_, reduce(part));
}

uint64_t FileChecksum::value(uint64_t bytes) const {
  return addMod(sum_, reduce(bytes));
}

}  // namespace triad
