#pragma once
// A run split over several MPI processes (dist/), or not: without a launcher
// that started more than one process every call here does nothing, so the
// pipeline reads the same either way. Process 0 writes the cache; the
// others simulate their share and send their particles to it each frame.
#include <cstdint>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace triad {

struct World;
struct SceneDesc;
class ParticleShare;
class Solver;
struct RunRecord;
struct OutputDesc;
struct SolverState;
struct StepRecord;
struct VoxelSum;
struct VolumeScale;
class MpiDomain;
struct LevelSetParts;
namespace render {
class PreviewRenderer;
struct Image;
}  // namespace render

// A failure that every process of a split run meets together (they agreed
// on it in an exchange): each process can end on its own, none waits in an
// exchange for the others.
class SplitFailure : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class RunSplit {
 public:
  // Starts MPI when a launcher (mpirun) started more than one process.
  // Throws when it did but this program was built without MPI.
  RunSplit();
  ~RunSplit();
  RunSplit(const RunSplit&) = delete;
  RunSplit& operator=(const RunSplit&) = delete;

  bool active() const { return size_ > 1; }
  bool root() const { return rank_ == 0; }
  int rank() const { return rank_; }
  int size() const { return size_; }

  // What a split run builds (or reads from a checkpoint) of the particles
  // on this process: pass it to the world's build and the resume. Null when
  // the run is not split.
  ParticleShare* share(const SceneDesc& scene);
  // Splits the world between the processes and has the solver exchange
  // through them. The world holds this process's share (built or resumed
  // with share()) or the whole world (each process then keeps its share);
  // `follow_work`: later cuts move towards equal work, not equal counts.
  void attach(World& world, Solver& solver, bool follow_work = false);
  // Moves the split to where the particles are now (each frame).
  void rebalance(World& world);
  // What process 0 needs of every particle for a frame's files.
  enum class Gather {
    None,  // nothing: a copy of its world without particles
    Whole  // every attribute
  };
  // What process 0 gathers of every particle for the frames' files that
  // `output` asks for: every attribute for VTK files, a particle cache or
  // checkpoint that process 0 writes alone (sharedFiles() false); else
  // nothing. The volumes' density and velocity each process splats itself,
  // previews each process draws (renderPreview), level sets and surfaces
  // each makes in parts (surfaceParts). Says so in `rec`'s mpi fields.
  Gather planOutput(const OutputDesc& output, RunRecord& rec) const;
  // The world with every process's particles, on process 0 (null on the
  // others). The world's own particles are set aside while it is copied,
  // not copied.
  std::shared_ptr<const World> gather(World& world, Gather what = Gather::Whole);
  // Whether every process sees the cache folder (a file system they share):
  // each then writes its own particles into the frame's particle cache and
  // checkpoint (app/split_files.cpp), and process 0 gathers none for them.
  // Asked once, after process 0 made the folder; collective.
  void checkSharedFolder(const std::string& out_dir);
  bool sharedFiles() const { return shared_files_; }
  // Collective: every process writes its particles into one file of the
  // whole world, the bytes a single process writes at `path`, under a
  // temporary name beside it, which is returned (process 0 renames it into
  // place once the frame's other files are written). Throws on every
  // process if one of them failed, the temporary removed.
  std::string writeCheckpointShared(const std::string& path, int frame,
                                    const std::string& scene_hash, const World& world,
                                    const SolverState& state, const StepRecord& record);
  // Collective, the same for the particles' PLY (at `ply`) and their VTK
  // file (at `vtp`), each left out where its path is empty. Each
  // temporary's name goes into `written` as it is made (empty for a file
  // not written), so that the caller can remove those already written when
  // a later one fails.
  struct SharedParticles {
    std::string ply, vtp;
  };
  void writeParticlesShared(const std::string& ply, const std::string& vtp, const World& world,
                            SharedParticles& written);
  // Collective: the volumes' sums (export/vdb_writer.h) of every process's
  // particles on voxels of size h, added up on process 0 (empty on the
  // others), and the scale they share.
  std::vector<VoxelSum> splatVolumesShared(const World& world, double h, VolumeScale& scale);
  // Collective: the frame's preview of every process's particles, each
  // process drawing its own with `renderer` (solids and the rest alike on
  // every process) and process 0 compositing the layers by depth and draw
  // order (render/preview_layers.h): the image one process draws of the
  // whole world, byte for byte. No process holds another's particles, and
  // each sends only the pixels where its particles show. On process 0;
  // empty on the others.
  render::Image renderPreview(render::PreviewRenderer& renderer, const World& world);
  // Collective: the particle level sets of `materials` (scene material
  // indices; -1: every material) on voxels bounded by `voxel`, made in parts
  // (export/particle_surface.h): each process from its own particles and
  // the other processes' within reach of its region, keeping the leaves it
  // owns. On process 0 every process's leaves (empty on the others): put
  // together, they are one process's level sets, byte for byte, and no
  // process holds another's particles beyond that reach.
  std::map<int, LevelSetParts> surfaceParts(const World& world, const std::vector<int>& materials,
                                            double voxel);
  // Sums over processes.
  double sum(double value);
  // The largest pending signal of any process (0: none).
  int anyInterrupt(int local);
  // Adds this frame's particles per process and the exchanges' cost to the
  // record (process 0); throws if the rigid bodies differ between processes.
  void record(RunRecord& rec, const World& world);
  void barrier();
  // Ends every process of the run at once (a failure on one of them).
  [[noreturn]] void abort(int code);

 private:
  int rank_ = 0, size_ = 1;
  std::unique_ptr<MpiDomain> domain_;
  double built_ = 0.0;  // particles this process held when the split began
  bool shared_files_ = false;
};

}  // namespace triad
