#pragma once
// One simulation over several MPI processes, by domain decomposition: the
// grid's blocks, in the order of their keys (x, then y, then z), are cut
// into one run per process so that each holds about as many particles; every
// particle lives on the process that owns its block, and grid blocks that particles of one process
// scatter into but another owns are summed by their owner, which sends the updated velocities back
// (sim/mpm/domain.h says when). Each process owns one run of keys, in
// process order, so whatever is gathered in process order is in key order,
// the order one process holds its blocks in: sums over gathered records,
// and particles' order, are then one process's, and a split run writes a
// single process's bytes. A cut into boxes instead of runs would have to
// sort what it gathers by key.
#include <mpi.h>

#include <cstdint>
#include <functional>
#include <vector>

#include "sim/mpm/domain.h"
#include "sim/mpm/transfer.h"
#include "sim/world.h"

namespace triad {

class MpiDomain final : public DomainExchange, public ParticleShare {
 public:
  MpiDomain(MPI_Comm comm, const TransferParams& params);

  int rank() const { return rank_; }
  int size() const { return size_; }

  // Cuts the blocks so that each process holds about the same
  // number of particles (or, after followWork(), does about the same work),
  // from every process's particles, then moves each particle to its new
  // owner. Called with every process holding the whole world, `whole`
  // keeps only this process's share without any exchange. Where the cut
  // falls changes no result (the sums keep one order).
  void balance(std::vector<ParticleSet>& sets, bool whole = false);
  // The first cut, from the positions of every particle the scene makes
  // (the same on every process, so no exchange), for a build that keeps
  // only this process's share; then adopt() takes that share and its
  // places in the whole world (World::share_index) instead of balance().
  void plan(const std::vector<const std::vector<Vec3f>*>& positions) override;
  bool keeps(const Vec3f& x) const override;
  void adopt(std::vector<ParticleSet>& sets, std::vector<std::vector<uint64_t>>&& index);
  // From now on each cut moves towards equal work (each process's time
  // outside exchanges since the last cut) rather than equal particle counts.
  void followWork() { by_work_ = true; }
  // Every process's particles, set by set in the order one process holds
  // them in, on process 0 (`all` holds the sets' descriptions and no
  // particles on the others), sent in chunks of 4 MiB.
  void gather(const std::vector<ParticleSet>& sets, std::vector<ParticleSet>& all);
  double sum(double value);
  // Collective: per set, the positions of other processes' particles that
  // lie within `reach` (m, along each axis) of a point this process owns
  // (ownsPoint), and maybe a few more (a block's worth).
  std::vector<std::vector<Vec3f>> haloPositions(const std::vector<ParticleSet>& sets, double reach);
  // Collective: every other process's `bytes` at `data`, records of
  // `record` bytes, to process 0, in process order and chunks of whole
  // records (at most 4 MiB), each handed to `take` (the process it came
  // from, the chunk) as it arrives; process 0's own are not.
  void gatherChunks(const void* data, size_t bytes, size_t record,
                    const std::function<void(int, const unsigned char*, size_t)>& take);
  // Collective: `mine` from every process, on process 0 (empty on the
  // others), in process order.
  std::vector<std::vector<unsigned char>> gatherBytes(const std::vector<unsigned char>& mine);
  // Per set, each particle's sequence number: gather() puts the particles
  // of each set in ascending order of these. Below 2^56.
  std::vector<std::vector<uint64_t>> sequences(const std::vector<ParticleSet>& sets) const;
  // Per set, each particle's index in the whole world as gather() orders
  // it, so that each process can write its own particles into a file of
  // the whole world; and per set the whole world's count. False (nothing
  // set) if the particles' sequence numbers have gaps, which no step
  // leaves.
  bool wholeIndex(const std::vector<ParticleSet>& sets, std::vector<std::vector<uint64_t>>& index,
                  std::vector<uint64_t>& counts);

  // Time spent in exchanges with other processes, and bytes sent, so far.
  double commSeconds() const { return comm_seconds_; }
  uint64_t bytesSent() const { return bytes_sent_; }
  // Time spent moving the cut after the first split (counting, cutting and
  // moving the particles), so far.
  double balanceSeconds() const { return balance_seconds_; }
  // Particles that arrived here from other processes, so far.
  uint64_t particlesReceived() const { return received_; }

  void extendLayout(GridLayout& layout) override;
  void sumGhosts(const GridLayout& layout, std::vector<GridNode>& grid,
                 std::vector<GridNode>& layers) override;
  void returnHalo(const GridLayout& layout, std::vector<GridNode>& grid) override;
  void migrate(std::vector<ParticleSet>& sets) override;
  const BinOrder* binOrder() const override { return &bin_order_; }
  void maxOverProcesses(std::vector<double>& values) override;
  bool owns(uint64_t key) const override { return ownerOf(key) == rank_; }
  int process() const override { return rank_; }
  bool ownsPoint(const Vec3f& x) const override { return owns(keyOf(x)); }
  std::vector<unsigned char> allGather(const std::vector<unsigned char>& mine) override;
  void minGhosts(const GridLayout& layout, std::vector<float>& per_node) override;
  int ownerOf(uint64_t key) const override;
  uint64_t cuts() const override { return cuts_; }
  std::vector<std::vector<unsigned char>> exchangeBytes(
      const std::vector<std::vector<unsigned char>>& out) override;

 private:
  uint64_t keyOf(const Vec3f& x) const;
  // (key, count) pairs of `keys` (sorted here), in key order.
  static std::vector<uint64_t> countByKey(std::vector<uint64_t>& keys);
  // Cuts so that process r's keys start where the running count of `pairs`
  // comes nearest target[r].
  void cutAt(const std::vector<uint64_t>& pairs, const std::vector<double>& target);
  // Sends the nodes of blocks send[r] of `per_node` (64 per block) to each
  // process r, and combines what each sent here into blocks receive[r].
  template <typename T, typename F>
  void exchangeBlocks(std::vector<T>& per_node, const std::vector<std::vector<uint32_t>>& send,
                      const std::vector<std::vector<uint32_t>>& receive, F&& combine);
  // Sends out[dest] to each process it is not empty for, and returns what
  // each sent here (empty where nothing came).
  std::vector<std::vector<unsigned char>> exchange(
      const std::vector<std::vector<unsigned char>>& out);

  // Puts each set's particles in the order of their sequence numbers.
  void sortBySequence(std::vector<ParticleSet>& sets);

  MPI_Comm comm_;
  // Per set and particle, where it stands in the order one process would
  // hold the particles in: its index in the whole world at the start, then
  // (process << 40 | index) as of the last binning. Valid from a split or
  // a migration to the next binning; `seq_fresh_` once the particles were
  // binned again (their order is then the bins', by process).
  std::vector<std::vector<uint64_t>> seq_;
  bool seq_fresh_ = true;
  BinOrder bin_order_;
  int rank_ = 0, size_ = 1;
  TransferParams params_;
  std::vector<uint64_t> cut_;  // size_ + 1 entries: process r owns keys [cut_[r], cut_[r + 1])
  uint64_t cuts_ = 0;          // cuts made so far
  // Grid blocks this process scattered into that others own (per owner), and
  // blocks it owns that others scattered into (per process): their keys and
  // their indices in this step's layout.
  std::vector<std::vector<uint64_t>> send_keys_, recv_keys_;
  std::vector<std::vector<uint32_t>> send_index_, recv_index_;
  double comm_seconds_ = 0.0;
  uint64_t bytes_sent_ = 0;
  uint64_t received_ = 0;
  double balance_seconds_ = 0.0;
  size_t gather_chunk_ = size_t(4) << 20;   // bytes of particles per message to process 0
  static constexpr int kExchangeTag = 100;  // and 101: exchange() alternates
  uint64_t round_ = 0;                      // exchanges so far
  bool by_work_ = false;
  bool planned_ = false;                    // plan() made the first cut
  double cut_time_ = 0.0, cut_comm_ = 0.0;  // when the last cut was made, and comm_seconds_ then
};

}  // namespace triad
