#pragma once
// run.json: what ran, how long each phase took, and whether it finished.
#include <array>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace triad {

struct RunRecord {
  std::string scene_name;
  std::string scene_path;
  std::string scene_hash;  // "fnv1a64:<hex>" of the scene file's bytes
  int threads = 1;
  std::string omp_wait_policy;  // as the OpenMP runtime was started with
  std::string omp_spin_count;   // GOMP_SPINCOUNT as started with; empty: the runtime's own
  bool output_overlap = false;  // frames written on their own thread while the next steps
  // With overlap and a solver thread on every core: the solver's threads
  // while a frame is being written (0: it never gives one up), and the
  // steps it took so.
  int threads_while_writing = 0;
  uint64_t steps_while_writing = 0;
  size_t particles = 0;  // now (sources and sinks change it)
  std::vector<std::pair<std::string, size_t>> object_particles;  // in scene order, at t = 0
  // Particles made by each source and removed by each sink so far, scene order.
  std::vector<std::pair<std::string, uint64_t>> emitted, removed;
  size_t bodies = 0;  // rigid bodies (bodies/NAME.FFFF.ply, bodies/rigid_states.csv)
  int frames_requested = 0;
  int frames_written = 0;  // frames 0..frames_written-1 are complete on disk
  double fps = 0.0;        // frame k is at time k / fps
  // For tools that open the cache without the scene file (the Blender
  // add-on scales density by it and frames the domain): each MPM material's
  // density, kg/m^3, and the domain's box, m.
  std::vector<std::pair<std::string, double>> material_density;
  std::array<double, 3> domain_min{0, 0, 0}, domain_max{0, 0, 0};
  double simulated_time = 0.0;
  int64_t steps = 0;
  double dt_min = 0.0, dt_max = 0.0;
  uint64_t particle_steps = 0;
  uint64_t sleeping_steps = 0;  // particle-substeps skipped by sleeping material
  std::map<std::string, double> phase_seconds;  // solver phases, output, setup
  // The solids phase by part, in the step's order (empty without solids).
  std::vector<std::pair<std::string, double>> solids_seconds;
  double wall_seconds = 0.0;
  // The estimate made before the first frame: solving wall time at the
  // rate of the probe ("probe") or the fixed one ("fixed"), and what the
  // probe itself took (0 without one).
  double estimated_wall_seconds = 0.0, estimated_rate = 0.0, probe_seconds = 0.0;
  std::string rate_from;
  size_t peak_rss_bytes = 0;
  size_t particle_bytes = 0;
  size_t grid_bytes = 0;
  // The resolution the run used: --quality's preset ("" when the scene ran
  // as written) and the grid spacing and solver settings after it.
  std::string quality;
  double dx = 0.0;
  int particles_per_cell = 0;
  double cfl = 0.0;
  std::string transfer;
  // Every solver setting the run used, defaults included, as a JSON object
  // in the scene's `solver` keys (empty: not recorded).
  std::string solver;
  bool resume = false;           // run with --resume
  int resumed_from_frame = -1;    // the checkpoint's frame; -1: started over
  bool finished = false;
  std::string error;  // empty when finished
  // A run stopped by SIGINT or SIGTERM: the signal's name and the frame in
  // progress (dropped); empty and -1 otherwise.
  std::string interrupted_by;
  int interrupted_frame = -1;
  std::string started_utc, ended_utc;
  // A run split over MPI processes: their number (0: not split), each
  // frame's particles per process, and each process's seconds in exchanges
  // (moving the cut included, and that alone), bytes sent and particles
  // received from the others so far.
  int mpi_ranks = 0;
  std::vector<std::vector<uint64_t>> mpi_particles;
  std::vector<double> mpi_comm_seconds, mpi_balance_seconds;
  std::vector<uint64_t> mpi_bytes_sent, mpi_received;
  std::vector<uint64_t> mpi_peak_rss;  // per process (peak_rss_bytes is process 0's)
  std::vector<uint64_t> mpi_built;     // per process: particles it held when the split began
  // The frame files every process writes its own particles into (or
  // splats them for), and what process 0 gathers every particle for.
  std::vector<std::string> mpi_files_together, mpi_gathered_for;
  std::string mpi_gathered;  // of each particle: "nothing", "positions and objects", ...
};

void writeRunRecord(const std::string& path, const RunRecord& rec);

// FNV-1a 64-bit hash of a file's bytes, as "fnv1a64:<16 hex digits>".
std::string hashFile(const std::string& path);
// The same over several files' bytes in turn (a scene and its mesh sequences).
std::string hashFiles(const std::vector<std::string>& paths);

// Peak resident set size of this process (VmHWM), bytes; 0 if unknown.
size_t peakResidentBytes();

// Current UTC time as ISO 8601.
std::string utcNow();

}  // namespace triad
