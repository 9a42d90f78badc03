#pragma once
// Checkpoints: the complete solver state at the end of a frame, so that
// `triad run --resume` continues a killed run and writes the same bytes an
// uninterrupted run would. Materials are not stored: they are rebuilt from
// the scene, whose hash the checkpoint records.
//
// File (checkpoints/state.FFFF.bin), little-endian, version 6:
//   header   char[8] "TRIADCKP", u32 format version, u32 header bytes (= 64),
//            u64 payload bytes, i32 frame, u32 set count, f64 time,
//            i64 steps, u8[16] reserved (zero)
//   payload  scene hash   (u32 length, bytes: "fnv1a64:<hex>")
//            solver state (f32 max_speed, f32 max_stiffness_scale)
//            step record  (i64 steps, f64 dt_min, f64 dt_max, u64 particle steps,
//                         u64 of them asleep)
//            sleep state  (u64 block count k, then u64 keys[k], u32 particle
//                         counts[k], f64 still seconds[k]; k = 0 without sleep;
//                         u64 rigid body count r, f64 still seconds[r])
//            per set:     i32 material, f32 mass, f32 volume, u64 n,
//                         u8 has_F, u8 has_J, u16 0, then the arrays in order
//                         x v (3 f32 each), C F (9 f32, column-major),
//                         J (f32), id (u32), object (u16), F/J only if present
//            bodies       (u32 count; per rigid body, in world order: u32 name
//                         length, name bytes, then f64 x[3], q_principal[4]
//                         as w x y z, v[3], L[3]: its RigidState, exactly)
//            elastics     (u32 count; per elastic solid, in world order: u32
//                         name length, name bytes, u64 node count n, then
//                         f64 x[3 n] and v[3 n]: node positions, velocities)
//            shot         (u32 next particle id; u32 count; per source then
//                         per sink, in world order: u64 particles emitted or
//                         removed so far)
//   trailer  u64 checksum of header and payload (export/file_checksum.h:
//            one that the processes of a split run take in parts),
//            char[8] "TRIADEND"
// Other versions are refused (a resume then starts over from frame 0).
#include <array>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "export/file_checksum.h"
#include "sim/solver.h"
#include "sim/world.h"

namespace triad {

// A checkpoint that cannot be used: unreadable, truncated, corrupt, of another
// format version, or not matching the scene's particle sets or rigid bodies.
class CheckpointError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct Checkpoint {
  int frame = 0;
  std::string scene_hash;
  double time = 0.0;
  int64_t steps = 0;
  SolverState solver;
  StepRecord record;  // the solver's step statistics up to this frame
  std::vector<ParticleSet> sets;  // arrays, material index, mass, volume (no model)
  // Per set, whether the file holds F and J (a share may hold no particle).
  std::vector<uint8_t> has_F, has_J;
  // Read with a share: per set, the index in the file of each particle kept.
  std::vector<std::vector<uint64_t>> share_index;
  size_t whole_particles = 0;                              // particles in the file
  std::vector<std::pair<std::string, RigidState>> bodies;  // name and state, world order
  struct Elastic {
    std::string name;
    std::vector<Vec3d> x, v;  // node positions and velocities
  };
  std::vector<Elastic> elastics;  // world order
  uint32_t next_id = 0;            // the world's next particle id
  std::vector<uint64_t> shot_counts;  // emitted per source, then removed per sink
};

constexpr uint32_t kCheckpointVersion = 6;
// Bytes of one particle's entry in each of a set's arrays, in file order:
// x v C F J id object.
constexpr std::array<uint64_t, 7> kCheckpointEntryBytes{12, 12, 36, 36, 4, 4, 2};

// Writes the world's particle sets, rigid body states and clock, the solver
// state and the frame atomically to `path`. Throws std::runtime_error naming
// the file.
void writeCheckpoint(const std::string& path, int frame, const std::string& scene_hash,
                     const World& world, const Solver& solver, const StepRecord& record);
// The same from the solver's state as taken at the frame's end (a frame
// written on another thread while the solver steps on).
void writeCheckpoint(const std::string& path, int frame, const std::string& scene_hash,
                     const World& world, const SolverState& solver, const StepRecord& record);

// A split run's checkpoint, which every process writes at once, each its
// own particles (app/run_split.cpp). The file is the one writeCheckpoint
// makes of the whole world: the layout gives the bytes that process 0
// writes besides the particles (`world` holds only its share) and where
// each particle array begins; `counts`: each set's particles in the whole
// world.
struct CheckpointLayout {
  struct Piece {
    uint64_t offset = 0;
    std::vector<unsigned char> bytes;
  };
  std::vector<Piece> pieces;  // header and payload but the particle arrays
  // Per set, where entry 0 of each array lies (kCheckpointEntryBytes' order;
  // an array the file does not hold, F or J, takes no bytes).
  std::vector<std::array<uint64_t, 7>> arrays;
  uint64_t bytes = 0;  // the file's size, trailer included
};
CheckpointLayout layoutCheckpoint(int frame, const std::string& scene_hash, const World& world,
                                  const SolverState& solver, const StepRecord& record,
                                  const std::vector<uint64_t>& counts);
// The last 16 bytes of a checkpoint from the checksum of the `bytes` bytes
// before them (every one of them added to `sum` or merged into it).
std::array<unsigned char, 16> checkpointTrailer(const FileChecksum& sum, uint64_t bytes);

// Reads and verifies (size, magic, version, checksum, array sizes) a
// checkpoint. Throws CheckpointError saying what is wrong. With `share`,
// only the particles it keeps are read (their places in `share_index`).
Checkpoint readCheckpoint(const std::string& path, ParticleShare* share = nullptr);

// Moves a checkpoint's state into `world` (built from the same scene) and
// `solver`. Throws CheckpointError, changing nothing, if the particle sets do
// not match the world's (set count, material, mass, volume, F/J presence,
// object indices) or the rigid bodies do not (count, names in order).
void restoreCheckpoint(Checkpoint&& ckpt, World& world, Solver& solver);

// Checkpoint files in `dir` as (frame, path), newest first. Ignores other files.
std::vector<std::pair<int, std::string>> listCheckpoints(const std::string& dir);

}  // namespace triad
