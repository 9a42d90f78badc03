#pragma once
// The hooks through which one simulation runs split over several processes
// (domain decomposition). The solver calls them at fixed points of its step;
// an implementation (dist/, over MPI) moves grid data and particles between
// the processes. sim/ itself stays free of any transport.
#include <cstring>
#include <vector>

#include "sim/mpm/sparse_grid.h"

namespace triad {

struct ParticleSet;

class DomainExchange {
 public:
  virtual ~DomainExchange() = default;

  // After binning: add to `layout` the grid blocks this process owns that
  // other processes' particles scatter into, learn which of its own grid
  // blocks other processes own, and mark both kinds layered.
  virtual void extendLayout(GridLayout& layout) = 0;
  // After P2G: the layered blocks' sums, a layer per colour (`layers`, see
  // particlesToGrid), go to each block's owner, which adds every colour's
  // layer in colour order, wherever it was scattered: each node's sum is the
  // one a single process makes, bit for bit.
  virtual void sumGhosts(const GridLayout& layout, std::vector<GridNode>& grid,
                         std::vector<GridNode>& layers) = 0;
  // After the grid update: owners send the updated nodes back to every
  // process that scattered into them, for its G2P.
  virtual void returnHalo(const GridLayout& layout, std::vector<GridNode>& grid) = 0;
  // After G2P: particles move to the process that owns their block.
  virtual void migrate(std::vector<ParticleSet>& sets) = 0;
  // The order in which the next binning visits each set's particles, so
  // that particles of one block keep the order one process would give them
  // (arrivals from processes of lower blocks first); null: array order.
  virtual const BinOrder* binOrder() const = 0;
  // The largest of `values` (element-wise) over every process.
  virtual void maxOverProcesses(std::vector<double>& values) = 0;

  // What solids need (they are whole on every process: each process steps
  // the same bodies from the same sums, so they stay the same everywhere).
  // This process's number (0 .. processes - 1).
  virtual int process() const = 0;
  // Whether this process owns grid block `key`, or the block of a particle at x.
  virtual bool owns(uint64_t key) const = 0;
  virtual bool ownsPoint(const Vec3f& x) const = 0;
  // Every process's bytes, concatenated in process order, on every process.
  virtual std::vector<unsigned char> allGather(const std::vector<unsigned char>& mine) = 0;
  // Per grid node values (layout.gridBlocks() * 64): the owner of each
  // block takes the smallest of its own and every other process's value.
  virtual void minGhosts(const GridLayout& layout, std::vector<float>& per_node) = 0;
  // The process that owns grid block `key`. Each process owns one run of
  // keys, in process order.
  virtual int ownerOf(uint64_t key) const = 0;
  // How many times the blocks have been cut between the processes so far:
  // the same on every process at the same step.
  virtual uint64_t cuts() const = 0;
  // Sends out[p] to each process p it is not empty for (`out` may end
  // before the last process); returns what each process sent here (empty
  // where nothing came). Collective.
  virtual std::vector<std::vector<unsigned char>> exchangeBytes(
      const std::vector<std::vector<unsigned char>>& out) = 0;
};

// Every process's elements of `mine`, concatenated in process order, on
// every process (T trivially copyable).
template <typename T>
std::vector<T> allGatherValues(DomainExchange& domain, const std::vector<T>& mine) {
  std::vector<unsigned char> bytes(mine.size() * sizeof(T));
  if (!bytes.empty())
    std::memcpy(bytes.data(), static_cast<const void*>(mine.data()), bytes.size());
  const std::vector<unsigned char> all = domain.allGather(bytes);
  std::vector<T> out(all.size() / sizeof(T));
  if (!out.empty()) std::memcpy(static_cast<void*>(out.data()), all.data(), out.size() * sizeof(T));
  return out;
}

// Sends out[p] (T trivially copyable) to each process p, and returns what
// every process sent here, concatenated in process order.
template <typename T>
std::vector<T> exchangeValues(DomainExchange& domain, const std::vector<std::vector<T>>& out) {
  std::vector<std::vector<unsigned char>> bytes(out.size());
  for (size_t p = 0; p < out.size(); ++p) {
    bytes[p].resize(out[p].size() * sizeof(T));
    if (!bytes[p].empty())
      std::memcpy(bytes[p].data(), static_cast<const void*>(out[p].data()), bytes[p].size());
  }
  std::vector<T> in;
  for (const std::vector<unsigned char>& from : domain.exchangeBytes(bytes)) {
    const size_t at = in.size();
    in.resize(at + from.size() / sizeof(T));
    if (!from.empty())
      std::memcpy(static_cast<void*>(in.data() + at), from.data(),
                  from.size() / sizeof(T) * sizeof(T));
  }
  return in;
}

// Adds grid blocks (sorted or not) to a layout: grid_keys stays sorted and
// the particle blocks' neighbour indices follow. Keys already present are
// ignored.
void addGridBlocks(GridLayout& layout, std::vector<uint64_t> keys);

}  // namespace triad
