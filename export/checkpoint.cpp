#include "export/checkpoint.h"

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "export/atomic_file.h"
#include "export/file_checksum.h"
#include "sim/frame_name.h"

namespace triad {

namespace {

namespace fs = std::filesystem;

static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "checkpoints assume little-endian");
static_assert(sizeof(Vec3f) == 12 && sizeof(Mat3f) == 36, "Eigen fixed types must be packed");

constexpr char kMagic[8] = {'T', 'R', 'I', 'A', 'D', 'C', 'K', 'P'};
constexpr char kEndMagic[8] = {'T', 'R', 'I', 'A', 'D', 'E', 'N', 'D'};
constexpr uint32_t kHeaderBytes = 64;
constexpr uint32_t kMaxNameBytes = 4096;
constexpr uint32_t kMaxObjects = 65535;  // as the scene loader allows
constexpr size_t kTrailerBytes = 16;

#pragma pack(push, 1)
struct Header {
  char magic[8];
  uint32_t version;
  uint32_t header_bytes;
  uint64_t payload_bytes;
  int32_t frame;
  uint32_t sets;
  double time;
  int64_t steps;
  uint8_t reserved[16];
};
struct SetHeader {
  int32_t material;
  float mass;
  float volume;
  uint64_t n;
  uint8_t has_F, has_J;
  uint16_t pad;
};
// A RigidState as doubles, the quaternion as w x y z (Eigen's own storage
// order is x y z w, which the file does not depend on).
struct BodyRecord {
  double x[3], q[4], v[3], L[3];
};
#pragma pack(pop)
static_assert(sizeof(Header) == kHeaderBytes, "checkpoint header is 64 bytes");
static_assert(sizeof(SetHeader) == 24, "set header is 24 bytes");
static_assert(sizeof(BodyRecord) == 104, "body record is 13 doubles");

BodyRecord toRecord(const RigidState& s) {
  const Quatd& q = s.q_principal;
  return {{s.x.x(), s.x.y(), s.x.z()},
          {q.w(), q.x(), q.y(), q.z()},
          {s.v.x(), s.v.y(), s.v.z()},
          {s.L.x(), s.L.y(), s.L.z()}};
}

RigidState fromRecord(const BodyRecord& r) {
  RigidState s;
  s.x = Vec3d(r.x[0], r.x[1], r.x[2]);
  s.q_principal = Quatd(r.q[0], r.q[1], r.q[2], r.q[3]);  // (w, x, y, z)
  s.v = Vec3d(r.v[0], r.v[1], r.v[2]);
  s.L = Vec3d(r.L[0], r.L[1], r.L[2]);
  return s;
}

template <class T>
size_t arrayBytes(const std::vector<T>& a) {
  return a.size() * sizeof(T);
}

// Bytes of each of a set's particle arrays in a file that holds `n` of its
// particles (x v C F J id object).
std::array<uint64_t, 7> arraySizes(const ParticleSet& s, uint64_t n) {
  // F and J only where the set has them; none at all for an empty set (as
  // a single process writes one).
  const bool has_F = n > 0 && (s.size() > 0 ? !s.F.empty() : s.usesF());
  const bool has_J = n > 0 && (s.size() > 0 ? !s.J.empty() : s.usesJ());
  std::array<uint64_t, 7> b{};
  for (size_t a = 0; a < b.size(); ++a) b[a] = n * kCheckpointEntryBytes[a];
  if (!has_F) b[3] = 0;
  if (!has_J) b[4] = 0;
  return b;
}

size_t payloadBytes(const std::string& scene_hash, const World& world, const SolverState& st,
                    const std::vector<uint64_t>& counts) {
  size_t n = 4 + scene_hash.size() + 8 + 40;
  n += 8 + arrayBytes(st.sleep.keys) + arrayBytes(st.sleep.counts) + arrayBytes(st.sleep.still);
  n += 8 + arrayBytes(st.sleep.body_still);
  for (size_t k = 0; k < world.sets.size(); ++k) {
    n += sizeof(SetHeader);
    for (const uint64_t b : arraySizes(world.sets[k], counts[k])) n += size_t(b);
  }
  n += 4;
  for (const RigidBody& b : world.bodies) n += 4 + b.name.size() + sizeof(BodyRecord);
  n += 4;
  for (const ElasticSolid& e : world.elastics)
    n += 4 + e.name.size() + 8 + arrayBytes(e.fem.x) + arrayBytes(e.fem.v);
  n += 4 + 4 + 8 * (world.sources.size() + world.sinks.size());
  return n;
}

// What the writer walks the file with, in order.
class ByteSink {
 public:
  virtual ~ByteSink() = default;
  virtual void bytes(const void* p, size_t n) = 0;
  // Set k's particle array a (x v C F J id object), n bytes of the whole
  // world's; `p` holds them when this writer has them all.
  virtual void particles(size_t k, int a, const void* p, size_t n) = 0;
  template <class T>
  void pod(const T& v) {
    bytes(&v, sizeof(T));
  }
  template <class T>
  void array(const std::vector<T>& a) {
    bytes(a.data(), arrayBytes(a));
  }
};

// The whole file to a stream, with its checksum.
class StreamSink final : public ByteSink {
 public:
  explicit StreamSink(std::ostream& out) : out_(out) {}
  void bytes(const void* p, size_t n) override {
    out_.write(static_cast<const char*>(p), std::streamsize(n));
    sum_.append(p, n);
  }
  void particles(size_t, int, const void* p, size_t n) override { bytes(p, n); }
  const FileChecksum& checksum() const { return sum_; }

 private:
  std::ostream& out_;
  FileChecksum sum_;
};

// Everything but the particles' arrays as pieces at their offsets, and
// where those arrays begin.
class LayoutSink final : public ByteSink {
 public:
  explicit LayoutSink(CheckpointLayout& layout) : layout_(layout) {}
  void bytes(const void* p, size_t n) override {
    if (n == 0) return;
    std::vector<CheckpointLayout::Piece>& pieces = layout_.pieces;
    // Adjacent bytes join the piece before.
    if (pieces.empty() || pieces.back().offset + pieces.back().bytes.size() != at_)
      pieces.push_back({at_, {}});
    const auto* c = static_cast<const unsigned char*>(p);
    pieces.back().bytes.insert(pieces.back().bytes.end(), c, c + n);
    at_ += n;
  }
  void particles(size_t k, int a, const void*, size_t n) override {
    if (layout_.arrays.size() <= k) layout_.arrays.resize(k + 1);
    layout_.arrays[k][size_t(a)] = at_;
    at_ += n;
  }
  uint64_t at() const { return at_; }

 private:
  CheckpointLayout& layout_;
  uint64_t at_ = 0;
};

// Reads the payload in order straight from the file, one array (or one
// chunk of an array read in part) at a time, checking every length against
// what is left of the payload.
class Reader {
 public:
  Reader(std::istream& in, uint64_t n) : in_(in), left_(n) {}
  void bytes(void* dst, size_t n) {
    if (left_ < n) throw CheckpointError("payload shorter than its contents");
    if (n == 0) return;  // an empty array may have a null data pointer
    if (!in_.read(static_cast<char*>(dst), std::streamsize(n)))
      throw CheckpointError("read failed");
    left_ -= n;
  }
  template <class T>
  T pod() {
    T v;
    bytes(&v, sizeof(T));
    return v;
  }
  template <class T>
  void array(std::vector<T>& a, size_t n) {
    if (n > left_ / sizeof(T)) throw CheckpointError("payload shorter than its arrays");
    a.resize(n);
    bytes(a.data(), n * sizeof(T));
  }
  // Of an array of n, only the `count` entries `keep` marks.
  template <class T>
  void kept(std::vector<T>& a, size_t n, const std::vector<uint8_t>& keep, size_t count) {
    if (n > left_ / sizeof(T)) throw CheckpointError("payload shorter than its arrays");
    constexpr size_t kChunk = size_t(1) << 16;
    a.clear();
    a.reserve(count);
    std::vector<T> chunk;
    for (size_t i = 0; i < n; i += kChunk) {
      chunk.resize(std::min(kChunk, n - i));
      bytes(chunk.data(), chunk.size() * sizeof(T));
      for (size_t j = 0; j < chunk.size(); ++j)
        if (keep[i + j]) a.push_back(chunk[j]);
    }
  }
  void skip(uint64_t n) {
    if (left_ < n) throw CheckpointError("payload shorter than its arrays");
    if (!in_.seekg(std::streamoff(n), std::ios::cur)) throw CheckpointError("read failed");
    left_ -= n;
  }
  // Where the reader stands, to come back to.
  std::pair<std::streampos, uint64_t> mark() { return {in_.tellg(), left_}; }
  void seek(const std::pair<std::streampos, uint64_t>& m) {
    if (!in_.seekg(m.first)) throw CheckpointError("read failed");
    left_ = m.second;
  }
  uint64_t left() const { return left_; }
  bool atEnd() const { return left_ == 0; }

 private:
  std::istream& in_;
  uint64_t left_;
};

// Bytes of a set's arrays after its positions.
uint64_t bytesAfterPositions(uint64_t n, bool has_F, bool has_J) {
  return n * (sizeof(Vec3f) + sizeof(Mat3f) + (has_F ? sizeof(Mat3f) : 0) +
              (has_J ? sizeof(float) : 0) + sizeof(uint32_t) + sizeof(uint16_t));
}

}  // namespace

void writeCheckpoint(const std::string& path, int frame, const std::string& scene_hash,
                     const World& world, const Solver& solver, const StepRecord& record) {
  writeCheckpoint(path, frame, scene_hash, world, solver.state(), record);
}

namespace {

// The file in order, but for its trailer. `counts`: the particles of each
// set in the whole world, which `world`'s sets hold all of or (a split
// run's process 0, with a LayoutSink) only a share of.
void walkCheckpoint(ByteSink& w, int frame, const std::string& scene_hash, const World& world,
                    const SolverState& st, const StepRecord& record,
                    const std::vector<uint64_t>& counts) {
  // Header: what and when.
  Header h{};
  std::memcpy(h.magic, kMagic, 8);
  h.version = kCheckpointVersion;
  h.header_bytes = kHeaderBytes;
  h.payload_bytes = payloadBytes(scene_hash, world, st, counts);
  h.frame = frame;
  h.sets = uint32_t(world.sets.size());
  h.time = world.time;
  h.steps = world.steps;
  w.pod(h);

  // Payload: scene hash, solver state, step statistics, particle sets.
  w.pod(uint32_t(scene_hash.size()));
  w.bytes(scene_hash.data(), scene_hash.size());
  w.pod(st.max_speed);
  w.pod(st.max_stiffness_scale);
  w.pod(record.steps);
  w.pod(record.dt_min);
  w.pod(record.dt_max);
  w.pod(record.particle_steps);
  w.pod(record.sleeping_steps);
  w.pod(uint64_t(st.sleep.keys.size()));
  w.array(st.sleep.keys);
  w.array(st.sleep.counts);
  w.array(st.sleep.still);
  w.pod(uint64_t(st.sleep.body_still.size()));
  w.array(st.sleep.body_still);
  for (size_t k = 0; k < world.sets.size(); ++k) {
    const ParticleSet& s = world.sets[k];
    const std::array<uint64_t, 7> sizes = arraySizes(s, counts[k]);
    const SetHeader sh{
        s.material, s.mass, s.volume, counts[k], uint8_t(sizes[3] > 0), uint8_t(sizes[4] > 0), 0};
    w.pod(sh);
    const void* data[7] = {s.x.data(), s.v.data(),  s.C.data(),     s.F.data(),
                           s.J.data(), s.id.data(), s.object.data()};
    for (int a = 0; a < 7; ++a) w.particles(k, a, data[a], size_t(sizes[size_t(a)]));
  }
  w.pod(uint32_t(world.bodies.size()));
  for (const RigidBody& b : world.bodies) {
    w.pod(uint32_t(b.name.size()));
    w.bytes(b.name.data(), b.name.size());
    w.pod(toRecord(b.state));
  }
  w.pod(uint32_t(world.elastics.size()));
  for (const ElasticSolid& e : world.elastics) {
    w.pod(uint32_t(e.name.size()));
    w.bytes(e.name.data(), e.name.size());
    w.pod(uint64_t(e.fem.nodes()));
    w.array(e.fem.x);
    w.array(e.fem.v);
  }
  w.pod(world.next_id);
  w.pod(uint32_t(world.sources.size() + world.sinks.size()));
  for (const Source& src : world.sources) w.pod(uint64_t(src.emitted));
  for (const Sink& k : world.sinks) w.pod(uint64_t(k.removed));
}

}  // namespace

void writeCheckpoint(const std::string& path, int frame, const std::string& scene_hash,
                     const World& world, const SolverState& st, const StepRecord& record) {
  std::vector<uint64_t> counts;
  for (const ParticleSet& s : world.sets) counts.push_back(s.size());
  writeFileAtomically(path, [&](std::ostream& out) {
    StreamSink w(out);
    walkCheckpoint(w, frame, scene_hash, world, st, record, counts);
    // Trailer: checksum of all the above.
    const auto trailer = checkpointTrailer(w.checksum(), w.checksum().end());
    out.write(reinterpret_cast<const char*>(trailer.data()), std::streamsize(trailer.size()));
  });
}

CheckpointLayout layoutCheckpoint(int frame, const std::string& scene_hash, const World& world,
                                  const SolverState& st, const StepRecord& record,
                                  const std::vector<uint64_t>& counts) {
  if (counts.size() != world.sets.size())
    throw std::logic_error("layoutCheckpoint: one count per particle set");
  CheckpointLayout layout;
  LayoutSink w(layout);
  walkCheckpoint(w, frame, scene_hash, world, st, record, counts);
  layout.arrays.resize(world.sets.size());
  layout.bytes = w.at() + kTrailerBytes;
  return layout;
}

std::array<unsigned char, 16> checkpointTrailer(const FileChecksum& sum, uint64_t bytes) {
  std::array<unsigned char, 16> t{};
  const uint64_t value = sum.value(bytes);
  std::memcpy(t.data(), &value, 8);
  std::memcpy(t.data() + 8, kEndMagic, 8);
  return t;
}

Checkpoint readCheckpoint(const std::string& path, ParticleShare* share) {
  // The file is checked whole (size, marks, checksum) before anything is
  // parsed, reading it a MiB at a time: a process never holds the file.
  std::ifstream in(path, std::ios::binary);
  if (!in) throw CheckpointError("cannot open");
  in.seekg(0, std::ios::end);
  const uint64_t size = uint64_t(in.tellg());
  in.seekg(0);
  if (!in || size < kHeaderBytes + kTrailerBytes)
    throw CheckpointError("truncated (" + std::to_string(size) + " bytes)");
  Header h;
  in.read(reinterpret_cast<char*>(&h), kHeaderBytes);
  if (!in) throw CheckpointError("read failed");
  if (std::memcmp(h.magic, kMagic, 8) != 0) throw CheckpointError("not a triad checkpoint");
  if (h.version != kCheckpointVersion)
    throw CheckpointError("format version " + std::to_string(h.version) + ", expected " +
                          std::to_string(kCheckpointVersion));
  if (h.header_bytes != kHeaderBytes || h.payload_bytes > size ||
      size != kHeaderBytes + h.payload_bytes + kTrailerBytes)
    throw CheckpointError("truncated or padded: " + std::to_string(size) + " bytes, header says " +
                          std::to_string(kHeaderBytes + h.payload_bytes + kTrailerBytes));
  FileChecksum sum;
  sum.append(&h, kHeaderBytes);
  {
    std::vector<char> buffer(size_t(1) << 20);
    for (uint64_t left = h.payload_bytes; left > 0;) {
      const size_t m = size_t(std::min<uint64_t>(left, buffer.size()));
      if (!in.read(buffer.data(), std::streamsize(m))) throw CheckpointError("read failed");
      sum.append(buffer.data(), m);
      left -= m;
    }
  }
  char trailer[kTrailerBytes];
  if (!in.read(trailer, kTrailerBytes)) throw CheckpointError("read failed");
  uint64_t stored;
  std::memcpy(&stored, trailer, 8);
  if (std::memcmp(trailer + 8, kEndMagic, 8) != 0) throw CheckpointError("no end marker");
  if (sum.value() != stored) throw CheckpointError("checksum mismatch (corrupt file)");

  // Parse the payload.
  Checkpoint c;
  c.frame = h.frame;
  c.time = h.time;
  c.steps = h.steps;
  in.seekg(kHeaderBytes);
  Reader r(in, h.payload_bytes);
  const uint32_t hash_len = r.pod<uint32_t>();
  if (hash_len > 256) throw CheckpointError("scene hash too long");
  c.scene_hash.resize(hash_len);
  r.bytes(c.scene_hash.data(), hash_len);
  c.solver.max_speed = r.pod<float>();
  c.solver.max_stiffness_scale = r.pod<float>();
  c.record.steps = r.pod<int64_t>();
  c.record.dt_min = r.pod<double>();
  c.record.dt_max = r.pod<double>();
  c.record.particle_steps = r.pod<uint64_t>();
  c.record.sleeping_steps = r.pod<uint64_t>();
  const uint64_t sleep_blocks = r.pod<uint64_t>();
  if (sleep_blocks > h.payload_bytes / 20) throw CheckpointError("sleep block count too large");
  r.array(c.solver.sleep.keys, size_t(sleep_blocks));
  r.array(c.solver.sleep.counts, size_t(sleep_blocks));
  r.array(c.solver.sleep.still, size_t(sleep_blocks));
  const uint64_t sleep_bodies = r.pod<uint64_t>();
  if (sleep_bodies > h.payload_bytes / 8) throw CheckpointError("sleep body count too large");
  r.array(c.solver.sleep.body_still, size_t(sleep_bodies));
  // With a share, every set's positions first: the share is cut from
  // them, and then only its particles' other arrays are kept.
  std::vector<std::vector<Vec3f>> positions;
  if (share) {
    const auto sets_at = r.mark();
    positions.resize(h.sets);
    std::vector<const std::vector<Vec3f>*> all;
    for (uint32_t k = 0; k < h.sets; ++k) {
      const SetHeader sh = r.pod<SetHeader>();
      r.array(positions[k], size_t(sh.n));
      if (sh.n > r.left() / sizeof(Mat3f)) throw CheckpointError("payload shorter than its arrays");
      r.skip(bytesAfterPositions(sh.n, sh.has_F, sh.has_J));
      all.push_back(&positions[k]);
    }
    share->plan(all);
    r.seek(sets_at);
    c.share_index.assign(h.sets, {});
  }
  for (uint32_t k = 0; k < h.sets; ++k) {
    const SetHeader sh = r.pod<SetHeader>();
    ParticleSet s;
    s.material = sh.material;
    s.mass = sh.mass;
    s.volume = sh.volume;
    const size_t n = size_t(sh.n);
    c.whole_particles += n;
    c.has_F.push_back(sh.has_F);
    c.has_J.push_back(sh.has_J);
    if (!share) {
      r.array(s.x, n);
      r.array(s.v, n);
      r.array(s.C, n);
      r.array(s.F, sh.has_F ? n : 0);
      r.array(s.J, sh.has_J ? n : 0);
      r.array(s.id, n);
      r.array(s.object, n);
    } else {
      std::vector<uint8_t> keep(n, 0);
      std::vector<uint64_t>& index = c.share_index[k];
      for (size_t i = 0; i < n; ++i)
        if ((keep[i] = share->keeps(positions[k][i]))) index.push_back(i);
      s.x.reserve(index.size());
      for (uint64_t i : index) s.x.push_back(positions[k][size_t(i)]);
      positions[k] = std::vector<Vec3f>();
      r.skip(uint64_t(n) * sizeof(Vec3f));
      r.kept(s.v, n, keep, index.size());
      r.kept(s.C, n, keep, index.size());
      r.kept(s.F, sh.has_F ? n : 0, keep, index.size());
      r.kept(s.J, sh.has_J ? n : 0, keep, index.size());
      r.kept(s.id, n, keep, index.size());
      r.kept(s.object, n, keep, index.size());
    }
    c.sets.push_back(std::move(s));
  }
  const uint32_t bodies = r.pod<uint32_t>();
  for (uint32_t k = 0; k < bodies; ++k) {
    const uint32_t name_len = r.pod<uint32_t>();
    if (name_len > kMaxNameBytes) throw CheckpointError("body name too long");
    std::string name(name_len, '\0');
    r.bytes(name.data(), name_len);
    c.bodies.emplace_back(std::move(name), fromRecord(r.pod<BodyRecord>()));
  }
  const uint32_t elastics = r.pod<uint32_t>();
  for (uint32_t k = 0; k < elastics; ++k) {
    const uint32_t name_len = r.pod<uint32_t>();
    if (name_len > kMaxNameBytes) throw CheckpointError("elastic solid name too long");
    Checkpoint::Elastic e;
    e.name.assign(name_len, '\0');
    r.bytes(e.name.data(), name_len);
    const uint64_t n = r.pod<uint64_t>();
    r.array(e.x, n);
    r.array(e.v, n);
    c.elastics.push_back(std::move(e));
  }
  c.next_id = r.pod<uint32_t>();
  const uint32_t counts = r.pod<uint32_t>();
  if (counts > kMaxObjects) throw CheckpointError("more sources and sinks than objects");
  for (uint32_t k = 0; k < counts; ++k) c.shot_counts.push_back(r.pod<uint64_t>());
  if (!r.atEnd()) throw CheckpointError("payload longer than its contents");
  return c;
}

void restoreCheckpoint(Checkpoint&& c, World& world, Solver& solver) {
  // Check that the sets are those the scene builds, then move the arrays in.
  if (c.sets.size() != world.sets.size())
    throw CheckpointError(std::to_string(c.sets.size()) + " particle sets, the scene builds " +
                          std::to_string(world.sets.size()));
  const size_t objects = world.scene.objects.size();
  for (size_t k = 0; k < c.sets.size(); ++k) {
    const ParticleSet& from = c.sets[k];
    const ParticleSet& to = world.sets[k];
    if (from.material != to.material || from.mass != to.mass || from.volume != to.volume ||
        (c.has_F[k] != 0) != to.usesF() || (c.has_J[k] != 0) != to.usesJ())
      throw CheckpointError("particle set " + std::to_string(k) +
                            " does not match the scene's (material, mass, volume or state)");
    for (uint16_t o : from.object)
      if (o >= objects) throw CheckpointError("particle of object index " + std::to_string(o) +
                                              " beyond the scene's " + std::to_string(objects));
  }
  // Bodies are matched by name: a scene whose rigid objects were renamed or
  // reordered is another scene (its hash differs too, but say what differs).
  if (c.bodies.size() != world.bodies.size())
    throw CheckpointError(std::to_string(c.bodies.size()) + " rigid bodies, the scene has " +
                          std::to_string(world.bodies.size()));
  for (size_t k = 0; k < c.bodies.size(); ++k)
    if (c.bodies[k].first != world.bodies[k].name)
      throw CheckpointError("rigid body " + std::to_string(k) + " is \"" + c.bodies[k].first +
                            "\", the scene's is \"" + world.bodies[k].name + "\"");
  if (c.elastics.size() != world.elastics.size())
    throw CheckpointError(std::to_string(c.elastics.size()) + " elastic solids, the scene has " +
                          std::to_string(world.elastics.size()));
  for (size_t k = 0; k < c.elastics.size(); ++k)
    if (c.elastics[k].name != world.elastics[k].name ||
        c.elastics[k].x.size() != world.elastics[k].fem.nodes())
      throw CheckpointError("elastic solid " + std::to_string(k) + " (\"" + c.elastics[k].name +
                            "\") does not match the scene's");
  if (c.shot_counts.size() != world.sources.size() + world.sinks.size())
    throw CheckpointError(std::to_string(c.shot_counts.size()) +
                          " sources and sinks, the scene has " +
                          std::to_string(world.sources.size() + world.sinks.size()));
  if (c.next_id < world.next_id)
    throw CheckpointError("next particle id " + std::to_string(c.next_id) +
                          " is below the scene's first " + std::to_string(world.next_id));
  for (size_t k = 0; k < world.sources.size(); ++k) world.sources[k].emitted = c.shot_counts[k];
  for (size_t k = 0; k < world.sinks.size(); ++k)
    world.sinks[k].removed = c.shot_counts[world.sources.size() + k];
  world.next_id = c.next_id;
  for (size_t k = 0; k < c.elastics.size(); ++k) {
    world.elastics[k].fem.x = std::move(c.elastics[k].x);
    world.elastics[k].fem.v = std::move(c.elastics[k].v);
  }
  for (size_t k = 0; k < c.sets.size(); ++k) {
    ParticleSet& to = world.sets[k];
    ParticleSet& from = c.sets[k];
    to.x = std::move(from.x);
    to.v = std::move(from.v);
    to.C = std::move(from.C);
    to.F = std::move(from.F);
    to.J = std::move(from.J);
    to.id = std::move(from.id);
    to.object = std::move(from.object);
  }
  // A split run's share of the checkpoint, or every particle of it (each
  // process then keeps its share when the split begins).
  world.share_index = std::move(c.share_index);
  world.whole_particles = c.whole_particles;
  for (size_t k = 0; k < c.bodies.size(); ++k) world.bodies[k].state = c.bodies[k].second;
  world.time = c.time;
  // Animated colliders: the pose and its velocities follow from the clock.
  for (RigidBody& b : world.bodies)
    if (b.animated) b.poseAt(world.time);
  world.steps = c.steps;
  solver.restore(c.solver);
}

std::vector<std::pair<int, std::string>> listCheckpoints(const std::string& dir) {
  std::vector<std::pair<int, std::string>> found;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    FrameName n;
    if (e.is_regular_file(ec) && parseFrameName(e.path().filename().string(), n, 4, 6) &&
        n.stem == "state" && n.ext == "bin")
      found.emplace_back(n.frame, e.path().string());
  }
  std::sort(found.begin(), found.end(), std::greater<>());
  return found;
}

}  // namespace triad
