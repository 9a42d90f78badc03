#pragma once
// Rigid body caches, as the cache contract says:
//   bodies/NAME.FFFF.ply      world-space surface of each rigid body
//                             (binary little-endian: float x y z, faces as
//                             `list uchar int vertex_indices`)
//   bodies/rigid_states.csv   one row per rigid body per frame
//   bodies/forces.csv         one row per rigid body per frame after the first
// Each CSV is a single file for the whole run, so each frame rewrites it
// whole (atomically).
#include <string>
#include <utility>
#include <vector>

#include "sim/solids/elastic_solid.h"
#include "sim/solids/rigid_body.h"
#include "sim/solver.h"

namespace triad {

// Writes `surface` (world space) atomically to `path`; `comment` goes into
// the header (one line, no newline). Throws std::runtime_error naming the file.
void writeSurfacePly(const std::string& path, const TriSurface& surface,
                     const std::string& comment = "");

// The body's surface where it is now (worldSurface), with its name and the
// time in the header comment.
void writeBodyPly(const std::string& path, const RigidBody& body, double time);
// The same for an elastic solid's deformed surface.
void writeElasticPly(const std::string& path, const ElasticSolid& solid, double time);

// A table with one row per rigid body per frame, written whole (atomically)
// each frame: `frame,time,name,` then numbers. It keeps its rows between
// frames and, for `triad run --resume`, takes them back from the file an
// earlier run wrote.
class BodyTable {
 public:
  // `header`: the first line of the file, without its newline; rows start
  // at `first_frame` (0 for states, 1 for forces, which cover a frame's steps).
  BodyTable(std::string header, int first_frame);

  const std::string& header() const { return header_; }

  // Appends the rows (one per body, no newlines) of `frame`, first dropping
  // the rows of `frame` and later frames (a frame written again replaces
  // its rows).
  void record(int frame, const std::vector<std::string>& rows);

  // Replaces the rows with those of the file at `path` for frames
  // first_frame..last_frame, which must hold one row per name of `names`,
  // in that order, for every one of those frames (what this class writes).
  // Rows of later frames are dropped. Returns what is wrong, empty on
  // success; on failure the table is left as it was.
  std::string load(const std::string& path, int last_frame, const std::vector<std::string>& names);

  // Writes the header and every row atomically. Throws std::runtime_error.
  void write(const std::string& path) const;

  // Empties the table (a fresh run starts the file over).
  void clear() { rows_.clear(); }
  size_t rows() const { return rows_.size(); }
  // Frame of the last row, -1 when empty.
  int lastFrame() const { return rows_.empty() ? -1 : rows_.back().first; }

 private:
  std::string header_;
  int first_frame_;
  size_t columns_;
  // (frame, the row's text without its newline), in file order. Rows are
  // kept as text so that rows taken back from a file are written again byte
  // for byte, whatever the formatting of the run that wrote them.
  std::vector<std::pair<int, std::string>> rows_;
};

// bodies/rigid_states.csv: each body's state at frames 0..count.
class RigidStateLog : public BodyTable {
 public:
  RigidStateLog();
  void record(int frame, double time, const std::vector<RigidBody>& bodies);
};

// bodies/forces.csv: for frames 1..count, the mean force and torque (about
// the centre of mass) that MPM material and elastic solids exerted on each
// body over the frame's steps.
class BodyForceLog : public BodyTable {
 public:
  BodyForceLog();
  // loads[k] (the solver's, over the frame) for bodies[k].
  void record(int frame, double time, const std::vector<RigidBody>& bodies,
              const std::vector<BodyLoad>& loads);
};

// One CSV row (no newline) of body state at `time`: centre of mass,
// orientation from the rest frame (w x y z), linear and angular velocity.
std::string rigidStateRow(int frame, double time, const RigidBody& body);

}  // namespace triad
