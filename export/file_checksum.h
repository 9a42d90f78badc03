#pragma once
// A file checksum that writers can take in pieces, in any order: each
// little-endian 8-byte word w_j of the file (the tail zero-padded) counts
// as w_j * r^(j+1) modulo the prime 2^61 - 1, and the file's length is
// added last. The processes of a split run each sum the bytes they write,
// wherever those lie, and their sums add up to the whole file's. (FNV, which
// the checkpoints used before, has to run through the file in order.)
#include <cstddef>
#include <cstdint>

namespace triad {

class FileChecksum {
 public:
  // Adds n bytes that lie at byte `offset` of the file.
  void add(uint64_t offset, const void* data, size_t n);
  // Adds n bytes right after the last ones added (writers and readers that
  // run through the file in order).
  void append(const void* data, size_t n) { add(end_, data, n); }
  // This sum of the bytes added so far, for another process to merge().
  uint64_t part() const { return sum_; }
  // Adds another writer's part() (of other bytes of the same file).
  void merge(uint64_t part);
  // The checksum of a file of `bytes` bytes whose every byte was added
  // here or merged (bytes never added count as zeros).
  uint64_t value(uint64_t bytes) const;
  // The value of the bytes appended so far.
  uint64_t value() const { return value(end_); }
  // One past the last byte added here (not merged).
  uint64_t end() const { return end_; }

 private:
  uint64_t sum_ = 0;
  uint64_t end_ = 0;  // one past the last byte added
};

}  // namespace triad
