// A split run's frame files that every process writes at once, each its own
// particles, into one file of the whole world (MPI-IO): the particle cache
// and the checkpoint; and the volumes, which each process splats of its own
// particles for process 0 to add up. Process 0 then holds no other
// process's particles for them. The files are the bytes a single process
// writes.
#include <unistd.h>

#include <algorithm>
#include <climits>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <stdexcept>

#include "app/run_split.h"
#include "export/checkpoint.h"
#include "export/ply_writer.h"
#include "export/vdb_writer.h"
#include "export/vtk_writer.h"
#include "sim/world.h"

#ifdef TRIAD_HAVE_MPI
#include "dist/mpi_domain.h"
#endif

namespace triad {

#ifdef TRIAD_HAVE_MPI

namespace {

namespace fs = std::filesystem;

__extension__ typedef unsigned __int128 Wide;  // GCC and clang's 128-bit integer

constexpr size_t kChunkBytes = size_t(1) << 20;  // what each process packs before a write

// One file that every process writes into at once, each its own bytes.
class SharedFile {
 public:
  // `path`: the file the temporary `tmp` becomes, for messages.
  SharedFile(const std::string& tmp, const std::string& path, uint64_t bytes) : path_(path) {
    open_ = MPI_File_open(MPI_COMM_WORLD, tmp.c_str(), MPI_MODE_CREATE | MPI_MODE_WRONLY,
                          MPI_INFO_NULL, &file_) == MPI_SUCCESS;
    int all = open_;
    MPI_Allreduce(MPI_IN_PLACE, &all, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
    if (!all) {
      // Not closed where it opened: closing is collective, and the
      // processes where it failed hold no handle to close.
      open_ = false;
      throw SplitFailure(path + ": a process cannot open its temporary " + tmp + " for writing");
    }
    // Exactly this long, whatever a file of the name held before.
    ok_ = MPI_File_set_size(file_, MPI_Offset(bytes)) == MPI_SUCCESS;
    // Tests make one process fail its writes, as a full disk would:
    // TRIAD_FAULT_SHARED_WRITE=R:K fails process R's K-th file (from 0).
    static int files = 0;
    int rank = 0;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    if (const char* f = std::getenv("TRIAD_FAULT_SHARED_WRITE")) {
      const char* colon = std::strchr(f, ':');
      if (colon && std::atoi(f) == rank && std::atoi(colon + 1) == files) ok_ = false;
    }
    ++files;
  }
  ~SharedFile() {
    if (open_) MPI_File_close(&file_);
  }
  SharedFile(const SharedFile&) = delete;
  SharedFile& operator=(const SharedFile&) = delete;

  void write(uint64_t offset, const void* data, size_t n) {
    const auto* p = static_cast<const char*>(data);
    for (size_t done = 0; ok_ && done < n;) {
      const size_t m = std::min(n - done, size_t(1) << 30);  // MPI counts are ints
      MPI_Status status;
      ok_ = MPI_File_write_at(file_, MPI_Offset(offset + done), p + done, int(m), MPI_BYTE,
                              &status) == MPI_SUCCESS;
      done += m;
    }
  }
  // Closes the file on every process; throws on all of them if any failed
  // to write its part (the caller removes the file).
  void close() {
    ok_ = MPI_File_close(&file_) == MPI_SUCCESS && ok_;
    open_ = false;
    int all = ok_;
    MPI_Allreduce(MPI_IN_PLACE, &all, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
    if (!all)
      throw SplitFailure(path_ + ": a process could not write its part of the file (disk full?)");
  }

 private:
  std::string path_;
  MPI_File file_{};
  bool open_ = false, ok_ = false;
};

// Writes into `file` and `sum` runs of entries that lie next to each other
// in the whole world: entry `place` at base + place * entry bytes, packed
// a chunk at a time. `order`: this process's entries by place.
template <typename Get>
void writeRuns(SharedFile& file, FileChecksum& sum, uint64_t base, size_t entry,
               const std::vector<uint64_t>& places, const std::vector<uint32_t>& order, Get get) {
  std::vector<unsigned char> chunk;
  uint64_t first = 0;
  auto flush = [&] {
    if (chunk.empty()) return;
    file.write(base + first * entry, chunk.data(), chunk.size());
    sum.add(base + first * entry, chunk.data(), chunk.size());
    chunk.clear();
  };
  for (size_t k = 0; k < order.size(); ++k) {
    const uint64_t place = places[order[k]];
    if (chunk.empty() || place != first + chunk.size() / entry || chunk.size() >= kChunkBytes) {
      flush();
      first = place;
    }
    const size_t at = chunk.size();
    chunk.resize(at + entry);
    get(order[k], chunk.data() + at);
  }
  flush();
}

// The temporary beside `path` that process 0's writer renames into place:
// named by process 0's id, as a single process names its temporaries.
std::string sharedTemporary(MpiDomain& domain, bool root, const std::string& path) {
  std::vector<int64_t> pid;
  if (root) pid.push_back(int64_t(::getpid()));
  pid = allGatherValues(domain, pid);
  return path + ".tmp" + std::to_string(pid.at(0));
}

// Has every process write its part of the file `tmp` of `bytes` bytes
// through write(file); if any fails, process 0 removes the file and every
// process throws.
template <typename Write>
void writeTogether(const std::string& tmp, const std::string& path, uint64_t bytes, bool root,
                   Write&& write) {
  try {
    SharedFile file(tmp, path, bytes);
    write(file);
    file.close();
  } catch (const std::exception&) {
    if (root) {
      std::error_code ignored;
      fs::remove(tmp, ignored);
    }
    throw;
  }
}

// Collective: the whole world's particles as PLY records, their ids cut
// into runs of about equal count, one per process in order; this
// process's run, sorted by id, the whole count and how many come before it.
struct IdRun {
  std::vector<PlyParticle> run;
  uint64_t total = 0, before = 0;
};
IdRun particlesByIdRun(const World& world, size_t procs, bool root) {
  // Each process sorts the particles it is sent; the runs lie in the files
  // in process order, so that the files list every particle by id.
  const size_t buckets = 256 * procs;
  uint64_t top = 0, mine = 0;
  for (const ParticleSet& s : world.sets)
    for (const uint32_t id : s.id) top = std::max<uint64_t>(top, id + 1);
  std::vector<uint64_t> limit{top};
  MPI_Allreduce(MPI_IN_PLACE, limit.data(), 1, MPI_UINT64_T, MPI_MAX, MPI_COMM_WORLD);
  const uint64_t span = std::max<uint64_t>(1, limit[0]);
  auto bucketOf = [&](uint32_t id) { return size_t(Wide(id) * buckets / span); };
  std::vector<uint64_t> per_bucket(buckets, 0);
  for (const ParticleSet& s : world.sets)
    for (const uint32_t id : s.id) ++per_bucket[bucketOf(id)];
  MPI_Allreduce(MPI_IN_PLACE, per_bucket.data(), int(buckets), MPI_UINT64_T, MPI_SUM,
                MPI_COMM_WORLD);
  const uint64_t total = std::accumulate(per_bucket.begin(), per_bucket.end(), uint64_t(0));
  std::vector<int> owner(buckets);
  for (size_t b = 0, before = 0; b < buckets; before += per_bucket[b], ++b)
    owner[b] = int(std::min<uint64_t>(procs - 1, total ? before * procs / total : 0));
  // Each particle's record to the process of its id's run, packed by
  // destination in one array.
  std::vector<int> send(procs, 0), recv(procs), sdisp(procs), rdisp(procs);
  std::vector<size_t> fill(procs, 0);
  for (const ParticleSet& s : world.sets)
    for (const uint32_t id : s.id) ++fill[size_t(owner[bucketOf(id)])];
  for (size_t r = 0, at = 0; r < procs; ++r) {
    const size_t count = fill[r];
    if ((at + count) * sizeof(PlyParticle) > size_t(INT_MAX))
      throw std::runtime_error("MPI: a process's particle records pass 2 GiB");
    sdisp[r] = int(at * sizeof(PlyParticle));
    send[r] = int(count * sizeof(PlyParticle));
    fill[r] = at;  // where the next record for r goes
    at += count;
  }
  std::vector<PlyParticle> packed;
  for (const ParticleSet& s : world.sets) mine += s.size();
  packed.resize(mine);
  for (const ParticleSet& s : world.sets)
    for (size_t i = 0; i < s.size(); ++i)
      packed[fill[size_t(owner[bucketOf(s.id[i])])]++] = plyParticle(s, i);
  MPI_Alltoall(send.data(), 1, MPI_INT, recv.data(), 1, MPI_INT, MPI_COMM_WORLD);
  size_t received = 0;
  for (size_t r = 0; r < procs; ++r) {
    rdisp[r] = int(received);
    received += size_t(recv[r]);
  }
  if (received > size_t(INT_MAX)) throw std::runtime_error("MPI: particle records pass 2 GiB");
  std::vector<PlyParticle> run(received / sizeof(PlyParticle));
  MPI_Alltoallv(packed.data(), send.data(), sdisp.data(), MPI_BYTE, run.data(), recv.data(),
                rdisp.data(), MPI_BYTE, MPI_COMM_WORLD);
  packed = {};
  std::sort(run.begin(), run.end(),
            [](const PlyParticle& a, const PlyParticle& b) { return a.id < b.id; });
  uint64_t count = run.size(), before = 0;
  MPI_Exscan(&count, &before, 1, MPI_UINT64_T, MPI_SUM, MPI_COMM_WORLD);
  if (root) before = 0;  // MPI_Exscan leaves process 0's undefined
  return {std::move(run), total, before};
}

}  // namespace

void RunSplit::checkSharedFolder(const std::string& out_dir) {
  shared_files_ = false;
  if (!domain_) return;
  // Tests take the other way, as on machines that share no file system.
  if (const char* e = std::getenv("TRIAD_MPI_SHARED_FILES"); e && std::string(e) == "0") return;
  // Process 0 leaves a note in the folder; every process must read it.
  const std::string note = sharedTemporary(*domain_, root(), out_dir + "/.processes");
  std::string token = std::to_string(::getpid()) + " " + std::to_string(MPI_Wtime());
  std::vector<char> sent(token.begin(), token.end());
  if (root()) std::ofstream(note) << token;
  sent = allGatherValues(*domain_, root() ? sent : std::vector<char>());
  token.assign(sent.begin(), sent.end());
  MPI_Barrier(MPI_COMM_WORLD);
  std::string seen;
  std::getline(std::ifstream(note), seen);
  int all = seen == token;
  MPI_Allreduce(MPI_IN_PLACE, &all, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
  if (root()) {
    std::error_code ignored;
    fs::remove(note, ignored);
  }
  shared_files_ = all != 0;
}

std::string RunSplit::writeCheckpointShared(const std::string& path, int frame,
                                            const std::string& scene_hash, const World& world,
                                            const SolverState& state, const StepRecord& record) {
  std::vector<std::vector<uint64_t>> places;
  std::vector<uint64_t> counts;
  if (!domain_->wholeIndex(world.sets, places, counts))
    throw std::logic_error("MPI: the particles' places in the whole world have gaps");
  // Where process 0 puts the particle arrays, for everyone.
  CheckpointLayout layout;
  std::vector<uint64_t> where;
  if (root()) {
    layout = layoutCheckpoint(frame, scene_hash, world, state, record, counts);
    for (const auto& a : layout.arrays) where.insert(where.end(), a.begin(), a.end());
    where.push_back(layout.bytes);
  }
  where = allGatherValues(*domain_, where);
  const uint64_t bytes = where.back();
  const std::string tmp = sharedTemporary(*domain_, root(), path);
  FileChecksum sum;
  writeTogether(tmp, path, bytes, root(), [&](SharedFile& file) {
    if (root())
      for (const CheckpointLayout::Piece& p : layout.pieces) {
        file.write(p.offset, p.bytes.data(), p.bytes.size());
        sum.add(p.offset, p.bytes.data(), p.bytes.size());
      }
    for (size_t s = 0; s < world.sets.size(); ++s) {
      const ParticleSet& set = world.sets[s];
      std::vector<uint32_t> order(set.size());
      std::iota(order.begin(), order.end(), 0u);
      std::sort(order.begin(), order.end(),
                [&](uint32_t a, uint32_t b) { return places[s][a] < places[s][b]; });
      const void* data[7] = {set.x.data(), set.v.data(),  set.C.data(),     set.F.data(),
                             set.J.data(), set.id.data(), set.object.data()};
      const bool has[7] = {true, true, true, !set.F.empty(), !set.J.empty(), true, true};
      for (size_t a = 0; a < 7; ++a) {
        if (!has[a] || set.size() == 0) continue;
        const size_t e = size_t(kCheckpointEntryBytes[a]);
        const auto* src = static_cast<const unsigned char*>(data[a]);
        writeRuns(
            file, sum, where[s * 7 + a], e, places[s], order,
            [&](uint32_t i, unsigned char* out) { std::memcpy(out, src + size_t(i) * e, e); });
      }
    }
    // The trailer, from every process's part of the checksum.
    const std::vector<uint64_t> parts =
        allGatherValues(*domain_, std::vector<uint64_t>{sum.part()});
    if (root()) {
      FileChecksum whole;
      for (const uint64_t p : parts) whole.merge(p);
      const auto trailer = checkpointTrailer(whole, bytes - 16);
      file.write(bytes - 16, trailer.data(), trailer.size());
    }
  });
  return tmp;
}

void RunSplit::writeParticlesShared(const std::string& ply, const std::string& vtp,
                                    const World& world, SharedParticles& written) {
  const IdRun ids = particlesByIdRun(world, size_t(size_), root());
  const std::vector<PlyParticle>& run = ids.run;
  if (!ply.empty()) {
    const std::string header = particlesPlyHeader(size_t(ids.total), world.time);
    const uint64_t bytes = header.size() + ids.total * sizeof(PlyParticle);
    written.ply = sharedTemporary(*domain_, root(), ply);
    writeTogether(written.ply, ply, bytes, root(), [&](SharedFile& file) {
      if (root()) file.write(0, header.data(), header.size());
      file.write(header.size() + ids.before * sizeof(PlyParticle), run.data(),
                 run.size() * sizeof(PlyParticle));
    });
  }
  if (vtp.empty()) return;
  // Array by array, each process its run's entries, a chunk at a time.
  const ParticlesVtpLayout layout = particlesVtpLayout(size_t(ids.total));
  written.vtp = sharedTemporary(*domain_, root(), vtp);
  writeTogether(written.vtp, vtp, layout.bytes, root(), [&](SharedFile& file) {
    if (root())
      for (const auto& [offset, bytes] : layout.fixed)
        file.write(offset, bytes.data(), bytes.size());
    std::vector<unsigned char> chunk;
    for (int a = 0; a < ParticlesVtpLayout::kArrays; ++a) {
      const uint64_t entry = layout.entry[a];
      const size_t per_chunk = std::max<size_t>(1, kChunkBytes / entry);
      for (size_t k = 0; k < run.size(); k += per_chunk) {
        const size_t count = std::min(per_chunk, run.size() - k);
        chunk.resize(count * entry);
        packParticlesVtp(ParticlesVtpLayout::Array(a), run.data() + k, count, ids.before + k,
                         chunk.data());
        file.write(layout.values[a] + (ids.before + k) * entry, chunk.data(), chunk.size());
      }
    }
  });
}

std::vector<VoxelSum> RunSplit::splatVolumesShared(const World& world, double h,
                                                   VolumeScale& scale) {
  // One scale for all, from the largest mass and momentum of any process.
  double largest[2];
  largestMassAndMomentum(world, largest[0], largest[1]);
  MPI_Allreduce(MPI_IN_PLACE, largest, 2, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
  scale = volumeScale(largest[0], largest[1]);
  std::vector<VoxelSum> sums = splatVolumeSums(world, h, scale);
  // To process 0 a chunk at a time, where the voxels that several
  // processes' particles reach are added up (exactly, in fixed point).
  constexpr int kTag = 9;
  const size_t per_chunk = kChunkBytes / sizeof(VoxelSum);
  uint64_t count = sums.size();
  std::vector<uint64_t> counts(root() ? size_t(size_) : 0);
  MPI_Gather(&count, 1, MPI_UINT64_T, counts.data(), 1, MPI_UINT64_T, 0, MPI_COMM_WORLD);
  if (!root()) {
    for (size_t first = 0; first < sums.size(); first += per_chunk) {
      const size_t n = std::min(per_chunk, sums.size() - first);
      MPI_Send(sums.data() + first, int(n * sizeof(VoxelSum)), MPI_BYTE, 0, kTag, MPI_COMM_WORLD);
    }
    return {};
  }
  for (int r = 1; r < size_; ++r)
    for (size_t first = 0; first < counts[size_t(r)]; first += per_chunk) {
      const size_t n = std::min<size_t>(per_chunk, counts[size_t(r)] - first);
      const size_t at = sums.size();
      sums.resize(at + n);
      MPI_Recv(sums.data() + at, int(n * sizeof(VoxelSum)), MPI_BYTE, r, kTag, MPI_COMM_WORLD,
               MPI_STATUS_IGNORE);
    }
  addVolumeSums(sums);
  return sums;
}

#else  // built without MPI: a run is never split

void RunSplit::checkSharedFolder(const std::string&) {}
std::string RunSplit::writeCheckpointShared(const std::string&, int, const std::string&,
                                            const World&, const SolverState&, const StepRecord&) {
  throw std::logic_error("writeCheckpointShared without MPI");
}
void RunSplit::writeParticlesShared(const std::string&, const std::string&, const World&,
                                    SharedParticles&) {
  throw std::logic_error("writeParticlesShared without MPI");
}
std::vector<VoxelSum> RunSplit::splatVolumesShared(const World&, double, VolumeScale&) {
  throw std::logic_error("splatVolumesShared without MPI");
}

#endif

}  // namespace triad
