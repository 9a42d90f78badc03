#include "dist/mpi_domain.h"

#include <algorithm>
#include <climits>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <numeric>
#include <stdexcept>
#include <thread>
#include <unordered_map>

#include "sim/mpm/particles.h"

namespace triad {

namespace {

// Bytes of one particle of `set` in a message: every attribute it uses.
size_t recordBytes(const ParticleSet& set) {
  size_t b = sizeof(Vec3f) * 2 + sizeof(Mat3f) + sizeof(uint32_t) + sizeof(uint16_t) +
             sizeof(uint64_t);  // and its sequence number
  if (set.usesF()) b += sizeof(Mat3f);
  if (set.usesJ()) b += sizeof(float);
  return b;
}

template <typename T>
void put(std::vector<unsigned char>& out, const T& value) {
  const auto* p = reinterpret_cast<const unsigned char*>(&value);
  out.insert(out.end(), p, p + sizeof(T));
}

template <typename T>
T take(const unsigned char*& in) {
  T value;
  std::memcpy(static_cast<void*>(&value), in, sizeof(T));
  in += sizeof(T);
  return value;
}

void packParticle(const ParticleSet& set, size_t i, std::vector<unsigned char>& out) {
  put(out, set.x[i]);
  put(out, set.v[i]);
  put(out, set.C[i]);
  if (set.usesF()) put(out, set.F[i]);
  if (set.usesJ()) put(out, set.J[i]);
  put(out, set.id[i]);
  put(out, set.object[i]);
}

void packParticle(const ParticleSet& set, size_t i, uint64_t seq, std::vector<unsigned char>& out) {
  packParticle(set, i, out);
  put(out, seq);
}

void unpackParticle(ParticleSet& set, const unsigned char*& in) {
  set.x.push_back(take<Vec3f>(in));
  set.v.push_back(take<Vec3f>(in));
  set.C.push_back(take<Mat3f>(in));
  if (set.usesF()) set.F.push_back(take<Mat3f>(in));
  if (set.usesJ()) set.J.push_back(take<float>(in));
  set.id.push_back(take<uint32_t>(in));
  set.object.push_back(take<uint16_t>(in));
}

void unpackParticle(ParticleSet& set, std::vector<uint64_t>& seq, const unsigned char*& in) {
  unpackParticle(set, in);
  seq.push_back(take<uint64_t>(in));
}

// The indices of `seq` in ascending order of its values, stably.
std::vector<uint32_t> ascending(const std::vector<uint64_t>& seq) {
  std::vector<uint32_t> src(seq.size());
  std::iota(src.begin(), src.end(), 0u);
  std::stable_sort(src.begin(), src.end(), [&](uint32_t a, uint32_t b) { return seq[a] < seq[b]; });
  return src;
}

// Reorders `set` (and `seq` with it) by ascending sequence number, stably.
void sortSet(ParticleSet& set, std::vector<uint64_t>& seq) {
  if (std::is_sorted(seq.begin(), seq.end())) return;
  const std::vector<uint32_t> src = ascending(seq);
  std::vector<unsigned char> scratch(set.size() * ParticleSet::kPermuteScratch);
  set.permute(src, scratch.data());
  std::vector<uint64_t> sorted(seq.size());
  for (size_t i = 0; i < src.size(); ++i) sorted[i] = seq[src[i]];
  seq = std::move(sorted);
}

// Gives `set` room for `need` particles and an eighth more; `shrink`, or
// room for over twice the need (the material moved to other processes),
// gives the rest of its memory back. Arrays that double would hold up to
// twice a process's share.
void fitCapacity(ParticleSet& set, size_t need, bool shrink = false) {
  const size_t room = set.x.capacity();
  if (need <= room && room <= 2 * need + 4096 && !shrink) return;
  if (shrink || room > 2 * need + 4096) set.shrinkToFit();
  set.reserve(need + need / 8);
}

// Empty copies of the sets' descriptions (material, masses), no particles.
std::vector<ParticleSet> emptyLike(const std::vector<ParticleSet>& sets) {
  std::vector<ParticleSet> out;
  for (const ParticleSet& s : sets) out.push_back(s.withoutParticles());
  return out;
}

void check(int rc, const char* what) {
  if (rc != MPI_SUCCESS) throw std::runtime_error(std::string("MPI: ") + what + " failed");
}

}  // namespace

MpiDomain::MpiDomain(MPI_Comm comm, const TransferParams& params) : comm_(comm), params_(params) {
  // Tests shrink the gather's chunks to exercise them on small scenes.
  if (const char* c = std::getenv("TRIAD_MPI_GATHER_CHUNK"))
    if (const unsigned long long bytes = std::strtoull(c, nullptr, 10); bytes > 0)
      gather_chunk_ = std::min<size_t>(size_t(bytes), size_t(INT_MAX));
  MPI_Comm_rank(comm_, &rank_);
  MPI_Comm_size(comm_, &size_);
  cut_.assign(size_t(size_) + 1, UINT64_MAX);
  cut_[0] = 0;
  send_keys_.resize(size_t(size_));
  recv_keys_.resize(size_t(size_));
  send_index_.resize(size_t(size_));
  recv_index_.resize(size_t(size_));
}

uint64_t MpiDomain::keyOf(const Vec3f& x) const {
  const Vec3i base = baseNode(x, params_.shifted_origin, params_.inv_dx);
  return packBlock(Vec3i(blockOf(base.x()), blockOf(base.y()), blockOf(base.z())));
}

int MpiDomain::ownerOf(uint64_t key) const {
  // The last process whose first key is at or before this one.
  return int(std::upper_bound(cut_.begin() + 1, cut_.end() - 1, key) - (cut_.begin() + 1));
}

std::vector<std::vector<unsigned char>> MpiDomain::exchange(
    const std::vector<std::vector<unsigned char>>& out) {
  // A sparse exchange (Hoefler, Siebert and Lumsdaine's NBX): each process
  // sends only to those it has bytes for, receives whatever arrives, and
  // a non-blocking barrier, entered once its own sends were all received,
  // tells every process when nothing is left in flight. Its cost grows with
  // the neighbours a process has and the log of the process count, not
  // with the process count. Rounds alternate between two tags: a process
  // can be at most one round ahead of another.
  const double t0 = MPI_Wtime();
  const int tag = kExchangeTag + (round_++ & 1);
  const size_t n = size_t(size_);
  std::vector<MPI_Request> sends;
  for (size_t r = 0; r < n; ++r) {
    if (r == size_t(rank_) || out[r].empty()) continue;
    if (out[r].size() > size_t(INT_MAX)) throw std::runtime_error("MPI: message over 2 GiB");
    sends.emplace_back();
    check(
        MPI_Issend(out[r].data(), int(out[r].size()), MPI_BYTE, int(r), tag, comm_, &sends.back()),
        "Issend");
    bytes_sent_ += out[r].size();
  }
  std::vector<std::vector<unsigned char>> in(n);
  MPI_Request barrier = MPI_REQUEST_NULL;
  bool barrier_started = false;
  for (;;) {
    int arrived = 0;
    MPI_Status status;
    check(MPI_Iprobe(MPI_ANY_SOURCE, tag, comm_, &arrived, &status), "Iprobe");
    if (arrived) {
      int bytes = 0;
      check(MPI_Get_count(&status, MPI_BYTE, &bytes), "Get_count");
      std::vector<unsigned char>& into = in[size_t(status.MPI_SOURCE)];
      into.resize(size_t(bytes));
      check(
          MPI_Recv(into.data(), bytes, MPI_BYTE, status.MPI_SOURCE, tag, comm_, MPI_STATUS_IGNORE),
          "Recv");
    }
    int done = 0;
    if (!barrier_started) {
      check(MPI_Testall(int(sends.size()), sends.data(), &done, MPI_STATUSES_IGNORE), "Testall");
      if (done) {
        check(MPI_Ibarrier(comm_, &barrier), "Ibarrier");
        barrier_started = true;
      }
    } else {
      check(MPI_Test(&barrier, &done, MPI_STATUS_IGNORE), "Test");
      if (done) break;
    }
    // Waiting: let a process that shares this core run (more processes
    // than cores, or other work on the machine).
    if (!arrived) std::this_thread::yield();
  }
  comm_seconds_ += MPI_Wtime() - t0;
  return in;
}

std::vector<uint64_t> MpiDomain::countByKey(std::vector<uint64_t>& keys) {
  std::sort(keys.begin(), keys.end());
  std::vector<uint64_t> pairs;
  for (size_t i = 0; i < keys.size();) {
    size_t j = i;
    while (j < keys.size() && keys[j] == keys[i]) ++j;
    pairs.push_back(keys[i]);
    pairs.push_back(j - i);
    i = j;
  }
  return pairs;
}

void MpiDomain::cutAt(const std::vector<uint64_t>& pairs, const std::vector<double>& target) {
  // Cut before the block where the running count comes nearest each target.
  std::vector<uint64_t> cut(size_t(size_) + 1, UINT64_MAX);
  cut[0] = 0;
  uint64_t below = 0;  // particles in blocks before block b
  size_t b = 0, blocks = pairs.size() / 2;
  for (int r = 1; r < size_; ++r) {
    const double goal = target[size_t(r)];
    while (b < blocks && double(below + pairs[2 * b + 1]) <= goal) below += pairs[2 * b++ + 1];
    // Inside block b the count passes the target: cut before or after it.
    size_t c = b;
    if (b < blocks && double(below + pairs[2 * b + 1]) - goal < goal - double(below)) c = b + 1;
    cut[size_t(r)] = c < blocks ? pairs[2 * c] : UINT64_MAX;
    cut[size_t(r)] = std::max(cut[size_t(r)], cut[size_t(r - 1)]);
  }
  if (cut != cut_) ++cuts_;
  cut_ = cut;
}

void MpiDomain::plan(const std::vector<const std::vector<Vec3f>*>& positions) {
  // Every process sees every position: the same counts, the same cut as a
  // split of the whole world, without an exchange.
  std::vector<uint64_t> keys;
  for (const std::vector<Vec3f>* object : positions)
    for (const Vec3f& x : *object) keys.push_back(keyOf(x));
  const std::vector<uint64_t> pairs = countByKey(keys);
  uint64_t total = 0;
  for (size_t i = 1; i < pairs.size(); i += 2) total += pairs[i];
  std::vector<double> target(size_t(size_) + 1, 0.0);
  for (int r = 1; r < size_; ++r) target[size_t(r)] = double(total) * r / size_;
  cutAt(pairs, target);
  planned_ = true;
}

bool MpiDomain::keeps(const Vec3f& x) const {
  return ownsPoint(x);
}

void MpiDomain::adopt(std::vector<ParticleSet>& sets, std::vector<std::vector<uint64_t>>&& index) {
  // The balance at the start, done by the build: the particles on hand are
  // this process's share, in the order one process would hold them in.
  if (!planned_ || index.size() != sets.size())
    throw std::logic_error("MpiDomain::adopt: the world was not built with this share");
  for (size_t k = 0; k < sets.size(); ++k)
    if (index[k].size() != sets[k].size())
      throw std::logic_error("MpiDomain::adopt: a set's index does not match its particles");
  seq_ = std::move(index);
  seq_fresh_ = false;
  bin_order_.clear();
  cut_time_ = MPI_Wtime();
  cut_comm_ = comm_seconds_;
  // A checkpoint read after the build and then passed over cut anew from
  // its own particles: the share built before is then not that cut's. The
  // processes' particles are still the whole world once, each with its
  // place in it, so a balance (counts from every process, particles moved
  // to their owners in one process's order) puts them where a cut says.
  std::vector<double> stray{0.0};
  for (const ParticleSet& s : sets)
    if (!std::all_of(s.x.begin(), s.x.end(), [&](const Vec3f& x) { return ownsPoint(x); }))
      stray[0] = 1.0;
  maxOverProcesses(stray);
  if (stray[0] > 0.0) {
    const bool by_work = by_work_;
    by_work_ = false;  // equal counts, as the first cut
    balance(sets);
    by_work_ = by_work;
  }
}

void MpiDomain::balance(std::vector<ParticleSet>& sets, bool whole) {
  const double t0 = MPI_Wtime();
  // This process's own work since the last cut: the time between them less
  // the time spent in exchanges (waiting for the others included).
  const double work = (t0 - cut_time_) - (comm_seconds_ - cut_comm_);
  // Particles per block here, as (key, count) sorted by key.
  std::vector<uint64_t> keys;
  for (const ParticleSet& s : sets)
    for (const Vec3f& x : s.x) keys.push_back(keyOf(x));
  std::vector<uint64_t> pairs = countByKey(keys);
  // Every process's, merged: the whole material's blocks in key order.
  if (!whole) {
    const std::vector<uint64_t> all = allGatherValues(*this, pairs);
    std::vector<std::pair<uint64_t, uint64_t>> merged;
    for (size_t i = 0; i + 1 < all.size(); i += 2) merged.emplace_back(all[i], all[i + 1]);
    std::sort(merged.begin(), merged.end());
    pairs.clear();
    for (const auto& [key, n] : merged) {
      if (!pairs.empty() && pairs[pairs.size() - 2] == key) {
        pairs.back() += n;
      } else {
        pairs.push_back(key);
        pairs.push_back(n);
      }
    }
  }
  uint64_t total = 0;
  for (size_t i = 1; i < pairs.size(); i += 2) total += pairs[i];
  // Where each cut falls, in particles before it: equal shares, or, when
  // the split follows the work, each cut moved from where it is towards the
  // faster of its two processes by half their difference in work (a step
  // of diffusion: work every process repeats alike cancels out).
  std::vector<double> target(size_t(size_) + 1, 0.0);
  for (int r = 1; r < size_; ++r) target[size_t(r)] = double(total) * r / size_;
  if (by_work_ && !whole && seq_.size() == sets.size()) {
    const std::vector<double> works = allGatherValues(*this, std::vector<double>{work});
    std::vector<double> held(size_t(size_), 0.0);  // per process, under the cut in force
    for (size_t i = 0; i + 1 < pairs.size(); i += 2)
      held[size_t(ownerOf(pairs[i]))] += double(pairs[i + 1]);
    double before = 0.0;
    for (int r = 1; r < size_; ++r) {
      before += held[size_t(r - 1)];
      const double a = works[size_t(r - 1)], c = works[size_t(r)];
      const double shift =
          a + c > 0.0 ? 0.5 * (a - c) / (a + c) * 0.5 * (held[size_t(r - 1)] + held[size_t(r)])
                      : 0.0;
      target[size_t(r)] = std::clamp(before - shift, target[size_t(r - 1)], double(total));
    }
  }
  cutAt(pairs, target);
  comm_seconds_ += MPI_Wtime() - t0;
  if (!whole) {
    migrate(sets);
    balance_seconds_ += MPI_Wtime() - t0;
    cut_time_ = MPI_Wtime();
    cut_comm_ = comm_seconds_;
    return;
  }
  // Every process holds the whole world, in the order one process would.
  seq_.assign(sets.size(), {});
  for (size_t k = 0; k < sets.size(); ++k) {
    ParticleSet& s = sets[k];
    std::vector<uint8_t> gone(s.size());
    for (size_t i = 0; i < s.size(); ++i) {
      gone[i] = ownerOf(keyOf(s.x[i])) != rank_;
      if (!gone[i]) seq_[k].push_back(i);
    }
    s.removeFlagged(gone);
    fitCapacity(s, s.size(), /*shrink=*/true);  // the whole world's room, given back
    seq_[k].shrink_to_fit();
  }
  seq_fresh_ = false;
  bin_order_.clear();
  cut_time_ = MPI_Wtime();
  cut_comm_ = comm_seconds_;
}

void MpiDomain::sortBySequence(std::vector<ParticleSet>& sets) {
  for (size_t k = 0; k < sets.size(); ++k) sortSet(sets[k], seq_[k]);
  bin_order_.clear();
}

void MpiDomain::migrate(std::vector<ParticleSet>& sets) {
  // Straight after a step the particles are in the order of their bins:
  // number them by process and index.
  const bool fresh = seq_fresh_;
  seq_.resize(sets.size());
  for (size_t k = 0; k < sets.size(); ++k) {
    if (!fresh && seq_[k].size() == sets[k].size()) continue;
    if (!fresh) throw std::logic_error("MPI: particles changed without their sequence numbers");
    seq_[k].resize(sets[k].size());
    for (size_t i = 0; i < seq_[k].size(); ++i) seq_[k][i] = uint64_t(rank_) << 40 | i;
  }
  seq_fresh_ = false;
  // Per destination: for each set, a count and that many particles.
  const size_t n = size_t(size_);
  std::vector<std::vector<unsigned char>> out(n);
  std::vector<std::vector<uint32_t>> leaving(n);
  std::vector<size_t> moving(n, 0);
  for (size_t k = 0; k < sets.size(); ++k) {
    ParticleSet& s = sets[k];
    for (auto& l : leaving) l.clear();
    std::vector<uint8_t> gone(s.size(), 0);
    bool any = false;
    for (size_t i = 0; i < s.size(); ++i) {
      const int owner = ownerOf(keyOf(s.x[i]));
      if (owner == rank_) continue;
      leaving[size_t(owner)].push_back(uint32_t(i));
      gone[i] = 1;
      any = true;
    }
    for (size_t r = 0; r < n; ++r) {
      put(out[r], uint32_t(leaving[r].size()));
      for (uint32_t i : leaving[r]) packParticle(s, i, seq_[k][i], out[r]);
      moving[r] += leaving[r].size();
    }
    if (any) {
      s.removeFlagged(gone);
      size_t kept = 0;
      for (size_t i = 0; i < gone.size(); ++i)
        if (!gone[i]) seq_[k][kept++] = seq_[k][i];
      seq_[k].resize(kept);
    }
  }
  // Nothing for a process: no message at all (the exchange is sparse).
  for (size_t r = 0; r < n; ++r)
    if (moving[r] == 0) out[r].clear();
  const auto in = exchange(out);
  // Room for the arrivals.
  std::vector<size_t> arriving(sets.size(), 0);
  for (size_t r = 0; r < n; ++r) {
    if (r == size_t(rank_) || in[r].empty()) continue;
    const unsigned char* p = in[r].data();
    for (size_t k = 0; k < sets.size(); ++k) {
      const uint32_t count = take<uint32_t>(p);
      arriving[k] += count;
      p += size_t(count) * recordBytes(sets[k]);
    }
  }
  for (size_t k = 0; k < sets.size(); ++k) fitCapacity(sets[k], sets[k].size() + arriving[k]);
  // Arrivals join at the end, by sending process.
  std::vector<size_t> own(sets.size()), below(sets.size());
  for (size_t k = 0; k < sets.size(); ++k) own[k] = sets[k].size();
  for (size_t r = 0; r < n; ++r) {
    if (r == size_t(rank_)) {
      for (size_t k = 0; k < sets.size(); ++k) below[k] = sets[k].size();
      continue;
    }
    if (in[r].empty()) continue;
    const unsigned char* p = in[r].data();
    for (size_t k = 0; k < sets.size(); ++k) {
      const uint32_t count = take<uint32_t>(p);
      for (uint32_t j = 0; j < count; ++j) unpackParticle(sets[k], seq_[k], p);
      received_ += count;
    }
  }
  if (!fresh) {
    // The arrivals' numbers interleave with the ones here: sort.
    sortBySequence(sets);
    return;
  }
  // Numbered by process, the order one process would hold them in is the
  // arrivals from lower processes, then this one's, then the rest (and
  // whatever sources add before the next binning): the binning visits
  // them so.
  bin_order_.assign(sets.size(), {});
  for (size_t k = 0; k < sets.size(); ++k)
    bin_order_[k] = {{uint32_t(own[k]), uint32_t(below[k])},
                     {0u, uint32_t(own[k])},
                     {uint32_t(below[k]), UINT32_MAX}};
}

void MpiDomain::extendLayout(GridLayout& layout) {
  const size_t n = size_t(size_);
  for (auto& k : send_keys_) k.clear();
  for (const uint64_t key : layout.grid_keys) {
    const int owner = ownerOf(key);
    if (owner != rank_) send_keys_[size_t(owner)].push_back(key);
  }
  std::vector<std::vector<unsigned char>> out(n);
  for (size_t r = 0; r < n; ++r)
    for (uint64_t key : send_keys_[r]) put(out[r], key);
  const auto in = exchange(out);
  std::vector<uint64_t> extra;
  for (size_t r = 0; r < n; ++r) {
    recv_keys_[r].clear();
    const unsigned char* p = in[r].data();
    for (size_t j = 0; j < in[r].size() / sizeof(uint64_t); ++j)
      recv_keys_[r].push_back(take<uint64_t>(p));
    extra.insert(extra.end(), recv_keys_[r].begin(), recv_keys_[r].end());
  }
  addGridBlocks(layout, std::move(extra));
  auto indexOf = [&](uint64_t key) {
    return uint32_t(std::lower_bound(layout.grid_keys.begin(), layout.grid_keys.end(), key) -
                    layout.grid_keys.begin());
  };
  layout.layered.assign(layout.gridBlocks(), -1);
  layout.layered_blocks = 0;
  auto layer = [&](uint32_t gb) {
    if (layout.layered[gb] < 0) layout.layered[gb] = int32_t(layout.layered_blocks++);
  };
  for (size_t r = 0; r < n; ++r) {
    send_index_[r].clear();
    recv_index_[r].clear();
    for (uint64_t key : send_keys_[r]) send_index_[r].push_back(indexOf(key));
    for (uint64_t key : recv_keys_[r]) recv_index_[r].push_back(indexOf(key));
    for (uint32_t gb : send_index_[r]) layer(gb);
    for (uint32_t gb : recv_index_[r]) layer(gb);
  }
  seq_fresh_ = true;  // the particles were binned: their order is the bins'
  bin_order_.clear();
}

template <typename T, typename F>
void MpiDomain::exchangeBlocks(std::vector<T>& per_node,
                               const std::vector<std::vector<uint32_t>>& send,
                               const std::vector<std::vector<uint32_t>>& receive, F&& combine) {
  constexpr size_t kBytes = sizeof(T) * kBlockNodes;
  std::vector<std::vector<unsigned char>> out(static_cast<size_t>(size_));
  for (size_t r = 0; r < out.size(); ++r) {
    out[r].resize(send[r].size() * kBytes);
    for (size_t j = 0; j < send[r].size(); ++j)
      std::memcpy(out[r].data() + j * kBytes,
                  static_cast<const void*>(&per_node[size_t(send[r][j]) * kBlockNodes]), kBytes);
  }
  const auto in = exchange(out);
  // In process order: the same results on every run with this many processes.
  for (size_t r = 0; r < in.size(); ++r) {
    if (in[r].size() != receive[r].size() * kBytes)
      throw std::runtime_error("MPI: grid blocks of unexpected size");
    for (size_t j = 0; j < receive[r].size(); ++j)
      for (int k = 0; k < kBlockNodes; ++k) {
        T value;
        std::memcpy(static_cast<void*>(&value), in[r].data() + j * kBytes + size_t(k) * sizeof(T),
                    sizeof(T));
        combine(per_node[size_t(receive[r][j]) * kBlockNodes + size_t(k)], value);
      }
  }
}

void MpiDomain::sumGhosts(const GridLayout& layout, std::vector<GridNode>& grid,
                          std::vector<GridNode>& layers) {
  constexpr size_t kLayer = kBlockNodes * sizeof(GridNode);
  // The colours this process scattered into each layered block.
  std::vector<uint8_t> colours(layout.layered_blocks, 0);
  for (int c = 0; c < 8; ++c)
    for (uint32_t pb : layout.colour_blocks[size_t(c)]) {
      // Sleeping blocks scatter too: their sums at rest.
      for (uint32_t gb : layout.neighbours[pb])
        if (layout.layered[gb] >= 0) colours[size_t(layout.layered[gb])] |= uint8_t(1u << c);
    }
  auto layerAt = [&](uint32_t gb, int c) {
    return &layers[(size_t(layout.layered[gb]) * 8 + size_t(c)) * kBlockNodes];
  };
  // Each block others own: the colours scattered here, then their layers.
  std::vector<std::vector<unsigned char>> out(static_cast<size_t>(size_));
  for (size_t r = 0; r < out.size(); ++r)
    for (uint32_t gb : send_index_[r]) {
      const uint8_t mask = colours[size_t(layout.layered[gb])];
      out[r].push_back(mask);
      for (int c = 0; c < 8; ++c)
        if (mask & (1u << c)) {
          const auto* p = reinterpret_cast<const unsigned char*>(layerAt(gb, c));
          out[r].insert(out[r].end(), p, p + kLayer);
        }
    }
  const auto in = exchange(out);
  // Each colour's layer of a block comes from the one process that holds
  // the particle block of that colour next to it.
  std::vector<uint8_t> folded(layout.layered_blocks, 0);
  for (size_t r = 0; r < in.size(); ++r) {
    const unsigned char* p = in[r].data();
    const unsigned char* end = p + in[r].size();
    for (uint32_t gb : recv_index_[r]) {
      if (p >= end) throw std::runtime_error("MPI: layered grid blocks cut short");
      const uint8_t mask = *p++;
      uint8_t& mine = colours[size_t(layout.layered[gb])];
      for (int c = 0; c < 8; ++c) {
        if (!(mask & (1u << c))) continue;
        if ((mine & (1u << c)) || end - p < std::ptrdiff_t(kLayer))
          throw std::runtime_error("MPI: a grid block's colour scattered twice, or cut short");
        std::memcpy(static_cast<void*>(layerAt(gb, c)), p, kLayer);
        p += kLayer;
      }
      mine |= mask;
    }
    if (p != end) throw std::runtime_error("MPI: layered grid blocks of unexpected size");
  }
  // The owner adds the colours in order, as one process adds them.
  for (size_t r = 0; r < recv_index_.size(); ++r)
    for (uint32_t gb : recv_index_[r]) {
      const size_t slot = size_t(layout.layered[gb]);
      if (folded[slot]) continue;
      folded[slot] = 1;
      for (int k = 0; k < kBlockNodes; ++k) {
        GridNode& g = grid[size_t(gb) * kBlockNodes + size_t(k)];
        for (int c = 0; c < 8; ++c) {
          if (!(colours[slot] & (1u << c))) continue;
          const GridNode& a = layerAt(gb, c)[k];
          g.m += a.m;
          for (int d = 0; d < 3; ++d) g.v[d] += a.v[d];
        }
      }
    }
}

void MpiDomain::returnHalo(const GridLayout&, std::vector<GridNode>& grid) {
  exchangeBlocks(grid, recv_index_, send_index_, [](GridNode& g, const GridNode& a) { g = a; });
}

void MpiDomain::minGhosts(const GridLayout&, std::vector<float>& per_node) {
  exchangeBlocks(per_node, send_index_, recv_index_, [](float& g, float a) { g = std::min(g, a); });
}

void MpiDomain::maxOverProcesses(std::vector<double>& values) {
  const double t0 = MPI_Wtime();
  check(MPI_Allreduce(MPI_IN_PLACE, values.data(), int(values.size()), MPI_DOUBLE, MPI_MAX, comm_),
        "Allreduce");
  comm_seconds_ += MPI_Wtime() - t0;
}

std::vector<unsigned char> MpiDomain::allGather(const std::vector<unsigned char>& mine) {
  const double t0 = MPI_Wtime();
  if (mine.size() > size_t(INT_MAX)) throw std::runtime_error("MPI: message over 2 GiB");
  int bytes = int(mine.size());
  std::vector<int> counts(static_cast<size_t>(size_)), offsets(static_cast<size_t>(size_));
  check(MPI_Allgather(&bytes, 1, MPI_INT, counts.data(), 1, MPI_INT, comm_), "Allgather");
  size_t total = 0;
  for (size_t r = 0; r < counts.size(); ++r) {
    offsets[r] = int(total);
    total += size_t(counts[r]);
  }
  if (total > size_t(INT_MAX)) throw std::runtime_error("MPI: gathered data over 2 GiB");
  std::vector<unsigned char> all(total);
  check(MPI_Allgatherv(mine.data(), bytes, MPI_BYTE, all.data(), counts.data(), offsets.data(),
                       MPI_BYTE, comm_),
        "Allgatherv");
  bytes_sent_ += mine.size() * size_t(size_ - 1);
  comm_seconds_ += MPI_Wtime() - t0;
  return all;
}

bool MpiDomain::wholeIndex(const std::vector<ParticleSet>& sets,
                           std::vector<std::vector<uint64_t>>& index,
                           std::vector<uint64_t>& counts) {
  const double t0 = MPI_Wtime();
  // A particle's sequence number is (process << 40 | index) as of the last
  // binning, or its index in the whole world since the split began: in
  // either case the whole world's order is theirs, and within each value
  // of the top bits the indices run densely from 0. So its place is the
  // count of the groups before its own plus its index in the group.
  constexpr int kShift = 40;
  const size_t groups = size_t(size_), n = sets.size();
  // (And one more entry in each: whether any number lay outside the groups.)
  std::vector<uint64_t> count(n * groups + 1, 0), top(n * groups + 1, 0);
  const std::vector<std::vector<uint64_t>> seq = sequences(sets);
  for (size_t s = 0; s < n; ++s)
    for (size_t i = 0; i < sets[s].size(); ++i) {
      const uint64_t q = seq[s][i], g = q >> kShift;
      if (g >= groups) {
        top.back() = 1;
        continue;
      }
      count[s * groups + g] += 1;
      top[s * groups + g] = std::max(top[s * groups + g], (q & ((uint64_t(1) << kShift) - 1)) + 1);
    }
  check(MPI_Allreduce(MPI_IN_PLACE, count.data(), int(count.size()), MPI_UINT64_T, MPI_SUM, comm_),
        "Allreduce");
  check(MPI_Allreduce(MPI_IN_PLACE, top.data(), int(top.size()), MPI_UINT64_T, MPI_MAX, comm_),
        "Allreduce");
  comm_seconds_ += MPI_Wtime() - t0;
  if (top.back() != 0) return false;  // a number outside the groups
  if (count != top) return false;     // a gap: some group's indices are not dense
  index.assign(n, {});
  counts.assign(n, 0);
  for (size_t s = 0; s < n; ++s) {
    std::vector<uint64_t> before(groups, 0);
    for (size_t g = 0; g < groups; ++g) {
      before[g] = counts[s];
      counts[s] += count[s * groups + g];
    }
    index[s].resize(sets[s].size());
    for (size_t i = 0; i < sets[s].size(); ++i) {
      const uint64_t q = seq[s][i];
      index[s][i] = before[q >> kShift] + (q & ((uint64_t(1) << kShift) - 1));
    }
  }
  return true;
}

std::vector<std::vector<unsigned char>> MpiDomain::exchangeBytes(
    const std::vector<std::vector<unsigned char>>& out) {
  if (out.size() == size_t(size_)) return exchange(out);
  if (out.size() > size_t(size_))
    throw std::runtime_error("exchange: bytes for a process that does not exist");
  std::vector<std::vector<unsigned char>> all(out);  // those left out send nothing
  all.resize(size_t(size_));
  return exchange(all);
}

std::vector<std::vector<Vec3f>> MpiDomain::haloPositions(const std::vector<ParticleSet>& sets,
                                                         double reach) {
  // The processes near each particle block, found once per block: points
  // at most a block apart across the block's box grown by the reach meet
  // every block that the grown box meets.
  const double block = double(kBlockSize) / double(params_.inv_dx);
  const double eps = 1e-4 * block;  // rounding at a block's faces: a little more, never less
  std::unordered_map<uint64_t, std::vector<int>> near;
  std::vector<std::vector<unsigned char>> out(static_cast<size_t>(size_));
  for (size_t s = 0; s < sets.size(); ++s) {
    for (const Vec3f& x : sets[s].x) {
      const uint64_t key = keyOf(x);
      auto it = near.find(key);
      if (it == near.end()) {
        const Vec3i b = unpackBlock(key);
        Vec3d lo, width;
        int steps[3];
        for (int d = 0; d < 3; ++d) {
          lo[d] = double(params_.shifted_origin[d]) + double(b[d]) * block - reach - eps;
          width[d] = block + 2.0 * (reach + eps);
          steps[d] = std::max(1, int(std::ceil(width[d] / block)));
        }
        std::vector<uint8_t> seen(size_t(size_), 0);
        for (int i = 0; i <= steps[0]; ++i)
          for (int j = 0; j <= steps[1]; ++j)
            for (int k = 0; k <= steps[2]; ++k) {
              const Vec3d at = lo + Vec3d(i * width[0] / steps[0], j * width[1] / steps[1],
                                          k * width[2] / steps[2]);
              seen[size_t(ownerOf(keyOf(at.cast<float>())))] = 1;
            }
        std::vector<int> procs;
        for (int r = 0; r < size_; ++r)
          if (seen[size_t(r)] && r != rank_) procs.push_back(r);
        it = near.emplace(key, std::move(procs)).first;
      }
      for (const int r : it->second) {
        put(out[size_t(r)], uint32_t(s));
        put(out[size_t(r)], x);
      }
    }
  }
  const std::vector<std::vector<unsigned char>> in = exchange(out);
  std::vector<std::vector<Vec3f>> halo(sets.size());
  for (const std::vector<unsigned char>& bytes : in)
    for (const unsigned char* p = bytes.data(); p < bytes.data() + bytes.size();) {
      const uint32_t s = take<uint32_t>(p);
      const Vec3f x = take<Vec3f>(p);
      if (s >= halo.size()) throw std::runtime_error("halo positions: a set that is not here");
      halo[s].push_back(x);
    }
  return halo;
}

void MpiDomain::gatherChunks(const void* data, size_t bytes, size_t record,
                             const std::function<void(int, const unsigned char*, size_t)>& take) {
  const double t0 = MPI_Wtime();
  constexpr int kTag = 12;
  // Whole records of at most 4 MiB a message (MPI's counts are ints).
  const size_t chunk = std::max<size_t>(1, (size_t(4) << 20) / record) * record;
  if (rank_ != 0) {
    const auto* p = static_cast<const unsigned char*>(data);
    const uint64_t count = bytes;
    check(MPI_Send(&count, 1, MPI_UINT64_T, 0, kTag, comm_), "Send");
    for (size_t first = 0; first < bytes; first += chunk)
      check(MPI_Send(p + first, int(std::min(chunk, bytes - first)), MPI_BYTE, 0, kTag, comm_),
            "Send");
    bytes_sent_ += sizeof(count) + bytes;
  } else {
    std::vector<unsigned char> in;
    for (int r = 1; r < size_; ++r) {
      uint64_t count = 0;
      check(MPI_Recv(&count, 1, MPI_UINT64_T, r, kTag, comm_, MPI_STATUS_IGNORE), "Recv");
      for (size_t first = 0; first < count; first += chunk) {
        in.resize(std::min<size_t>(chunk, count - first));
        check(MPI_Recv(in.data(), int(in.size()), MPI_BYTE, r, kTag, comm_, MPI_STATUS_IGNORE),
              "Recv");
        take(r, in.data(), in.size());
      }
    }
  }
  comm_seconds_ += MPI_Wtime() - t0;
}

std::vector<std::vector<unsigned char>> MpiDomain::gatherBytes(
    const std::vector<unsigned char>& mine) {
  std::vector<std::vector<unsigned char>> all(rank_ == 0 ? size_t(size_) : 0);
  if (rank_ == 0) all[0] = mine;
  gatherChunks(mine.data(), mine.size(), 1, [&](int r, const unsigned char* p, size_t n) {
    all[size_t(r)].insert(all[size_t(r)].end(), p, p + n);
  });
  return all;
}

std::vector<std::vector<uint64_t>> MpiDomain::sequences(
    const std::vector<ParticleSet>& sets) const {
  std::vector<std::vector<uint64_t>> out(sets.size());
  for (size_t s = 0; s < sets.size(); ++s) {
    const bool numbered = !seq_fresh_ && s < seq_.size() && seq_[s].size() == sets[s].size();
    out[s].resize(sets[s].size());
    for (size_t i = 0; i < out[s].size(); ++i)
      out[s][i] = numbered ? seq_[s][i] : uint64_t(rank_) << 40 | i;
  }
  return out;
}

double MpiDomain::sum(double value) {
  const double t0 = MPI_Wtime();
  check(MPI_Allreduce(MPI_IN_PLACE, &value, 1, MPI_DOUBLE, MPI_SUM, comm_), "Allreduce");
  comm_seconds_ += MPI_Wtime() - t0;
  return value;
}

void MpiDomain::gather(const std::vector<ParticleSet>& sets, std::vector<ParticleSet>& all) {
  const double t0 = MPI_Wtime();
  constexpr int kTag = 7;
  all = emptyLike(sets);
  const std::vector<std::vector<uint64_t>> mine = sequences(sets);
  for (size_t s = 0; s < sets.size(); ++s) {
    const ParticleSet& set = sets[s];
    const size_t record = recordBytes(set);
    const size_t per_chunk = std::max<size_t>(1, gather_chunk_ / record);
    std::vector<unsigned char> chunk;
    auto pack = [&](size_t first, size_t n) {
      chunk.clear();
      for (size_t i = first; i < first + n; ++i) packParticle(set, i, mine[s][i], chunk);
    };
    uint64_t count = set.size();
    std::vector<uint64_t> counts(rank_ == 0 ? size_t(size_) : 0);
    check(MPI_Gather(&count, 1, MPI_UINT64_T, counts.data(), 1, MPI_UINT64_T, 0, comm_), "Gather");
    // In chunks of bounded size: no message passes MPI's int counts, and
    // no process holds more than its own share and one chunk besides.
    if (rank_ != 0) {
      for (size_t first = 0; first < set.size(); first += per_chunk) {
        pack(first, std::min(per_chunk, set.size() - first));
        check(MPI_Send(chunk.data(), int(chunk.size()), MPI_BYTE, 0, kTag, comm_), "Send");
      }
      continue;
    }
    ParticleSet& out = all[s];
    uint64_t total = 0;
    for (const uint64_t c : counts) total += c;
    out.reserve(total);
    std::vector<uint64_t> seq;
    seq.reserve(total);
    for (int r = 0; r < size_; ++r)
      for (size_t first = 0; first < counts[size_t(r)]; first += per_chunk) {
        const size_t n = std::min<size_t>(per_chunk, counts[size_t(r)] - first);
        if (r == 0) {
          pack(first, n);
        } else {
          chunk.resize(n * record);
          check(MPI_Recv(chunk.data(), int(chunk.size()), MPI_BYTE, r, kTag, comm_,
                         MPI_STATUS_IGNORE),
                "Recv");
        }
        const unsigned char* p = chunk.data();
        for (size_t j = 0; j < n; ++j) unpackParticle(out, seq, p);
      }
    // In the order one process would hold them in: its checkpoints and
    // volumes are then the same bytes.
    sortSet(out, seq);
  }
  comm_seconds_ += MPI_Wtime() - t0;
}

}  // namespace triad
