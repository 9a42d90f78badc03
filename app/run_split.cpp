#include "app/run_split.h"

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <tuple>

#include "export/particle_surface.h"
#include "export/run_record.h"
#include "render/preview_renderer.h"
#include "render/preview_writer.h"
#include "sim/solver.h"
#include "sim/world.h"

#ifdef TRIAD_HAVE_MPI
#include "dist/mpi_domain.h"
#endif

namespace triad {

namespace {

// Processes the launcher started, from the environment Open MPI, MPICH and
// PMIx launchers set (1 when none did).
int launchedProcesses() {
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMIX_SIZE", "PMI_SIZE", "MPI_LOCALNRANKS"})
    if (const char* v = std::getenv(name)) return std::max(1, std::atoi(v));
  return 1;
}

}  // namespace

#ifdef TRIAD_HAVE_MPI

RunSplit::RunSplit() {
  if (launchedProcesses() <= 1) return;
  int provided = 0;
  // Only the main thread calls MPI (OpenMP workers and the writer never do).
  MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided);
  MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
  MPI_Comm_size(MPI_COMM_WORLD, &size_);
}

RunSplit::~RunSplit() {
  domain_.reset();
  int started = 0, ended = 0;
  MPI_Initialized(&started);
  MPI_Finalized(&ended);
  if (started && !ended) MPI_Finalize();
}

ParticleShare* RunSplit::share(const SceneDesc& scene) {
  if (!active()) return nullptr;
  if (!domain_) domain_ = std::make_unique<MpiDomain>(MPI_COMM_WORLD, transferParamsFor(scene));
  return domain_.get();
}

void RunSplit::attach(World& world, Solver& solver, bool follow_work) {
  if (!active()) return;
  if (!domain_) domain_ = std::make_unique<MpiDomain>(MPI_COMM_WORLD, solver.transferParams());
  if (follow_work) domain_->followWork();
  // Built as this process's share, or whole (read from a checkpoint).
  if (!world.share_index.empty())
    domain_->adopt(world.sets, std::move(world.share_index));
  else
    domain_->balance(world.sets, /*whole=*/true);
  world.share_index.clear();
  built_ = double(world.particleCount());
  solver.setDomain(domain_.get());
}

void RunSplit::rebalance(World& world) {
  if (domain_) domain_->balance(world.sets);
}

std::shared_ptr<const World> RunSplit::gather(World& world, Gather what) {
  if (!domain_) return nullptr;
  std::vector<ParticleSet> all;
  const bool particles = what != Gather::None;
  if (particles) domain_->gather(world.sets, all);
  if (!root()) return nullptr;
  // Everything else is whole on every process: a copy of this one's world
  // with the gathered particles (or none) in place of its share, which is
  // not copied.
  std::vector<ParticleSet> share = std::move(world.sets);
  std::shared_ptr<World> copy;
  try {
    // The sets' descriptions without their particles.
    world.sets.clear();
    for (const ParticleSet& s : share) world.sets.push_back(s.withoutParticles());
    copy = std::make_shared<World>(world);
  } catch (...) {
    world.sets = std::move(share);
    throw;
  }
  world.sets = std::move(share);
  if (particles) copy->sets = std::move(all);
  return copy;
}

render::Image RunSplit::renderPreview(render::PreviewRenderer& renderer, const World& world) {
  // This process's particles in the order process 0 would draw them all:
  // set by set, each by sequence number (the gather's order).
  std::vector<uint64_t> sorted;
  std::vector<float> xyz;
  std::vector<uint16_t> object;
  {
    const std::vector<std::vector<uint64_t>> seq = domain_->sequences(world.sets);
    std::vector<std::pair<uint64_t, std::pair<uint32_t, uint32_t>>> by_key;  // (set, index)
    // The set in the top byte: sets number under 255, sequence numbers
    // stay under 2^56 (MpiDomain::sequences).
    if (seq.size() >= 255)
      throw std::runtime_error("previews: more than 254 particle sets to composite");
    for (size_t s = 0; s < seq.size(); ++s)
      for (size_t i = 0; i < seq[s].size(); ++i)
        by_key.push_back({uint64_t(s + 1) << 56 | seq[s][i], {uint32_t(s), uint32_t(i)}});
    std::sort(by_key.begin(), by_key.end());
    sorted.reserve(by_key.size());
    xyz.reserve(3 * by_key.size());
    object.reserve(by_key.size());
    for (const auto& [key, at] : by_key) {
      const ParticleSet& set = world.sets[at.first];
      const Vec3f& x = set.x[at.second];
      xyz.insert(xyz.end(), {x.x(), x.y(), x.z()});
      object.push_back(set.object[at.second]);
      sorted.push_back(render::kFirstParticleKey + key);
    }
  }
  const std::vector<render::PreviewMesh> meshes = render::previewMeshesFromWorld(world);
  const render::PreviewParticles particles{xyz.data(), object.data(), object.size()};
  // Process 0 takes each other process's particle pixels in turn, a
  // chunk at a time: no process holds more than its own pixels and one
  // chunk besides.
  if (!root()) {
    const std::vector<render::LayerPixel> px =
        renderer.renderParticlePixels(particles, meshes, sorted.data());
    domain_->gatherChunks(px.data(), px.size() * sizeof(px[0]), sizeof(px[0]), {});
    return {};
  }
  render::PreviewLayer layer = renderer.renderLayer(particles, meshes, sorted.data());
  std::vector<render::LayerPixel> chunk;
  domain_->gatherChunks(nullptr, 0, sizeof(render::LayerPixel),
                        [&](int, const unsigned char* p, size_t n) {
                          chunk.resize(n / sizeof(render::LayerPixel));
                          std::memcpy(static_cast<void*>(chunk.data()), p, n);
                          render::mergePixels(layer, chunk.data(), chunk.size());
                        });
  return renderer.finish(layer);
}

std::map<int, LevelSetParts> RunSplit::surfaceParts(const World& world,
                                                    const std::vector<int>& materials,
                                                    double voxel) {
  // The sampling of the whole world: its sets' whole counts.
  std::vector<uint64_t> counts;
  for (const ParticleSet& set : world.sets) counts.push_back(set.size());
  MPI_Allreduce(MPI_IN_PLACE, counts.data(), int(counts.size()), MPI_UINT64_T, MPI_SUM,
                MPI_COMM_WORLD);
  std::map<int, SurfaceSampling> sampling;
  double reach = 0.0;
  for (const int m : materials) {
    sampling[m] = surfaceSampling(world, voxel, m, &counts);
    reach = std::max(reach, levelSetReach(sampling[m]));
  }
  // This process's particles and the others' within reach: positions alone.
  World near;
  {
    std::vector<std::vector<Vec3f>> halo = domain_->haloPositions(world.sets, reach);
    for (size_t s = 0; s < world.sets.size(); ++s) {
      near.sets.push_back(world.sets[s].withoutParticles());
      std::vector<Vec3f>& x = near.sets.back().x;
      x.reserve(world.sets[s].size() + halo[s].size());
      x.insert(x.end(), world.sets[s].x.begin(), world.sets[s].x.end());
      x.insert(x.end(), halo[s].begin(), halo[s].end());
      halo[s] = {};
    }
  }
  std::map<int, LevelSetParts> parts;
  for (const int m : materials) {
    const std::vector<unsigned char> leaves = particleLevelSetLeaves(
        near, sampling[m], m, [&](const Vec3d& o) { return domain_->ownsPoint(o.cast<float>()); });
    std::vector<std::vector<unsigned char>> all = domain_->gatherBytes(leaves);
    if (!root()) continue;
    parts[m].sampling = sampling[m];
    parts[m].leaves = std::move(all);
  }
  return parts;
}

double RunSplit::sum(double value) {
  return domain_ ? domain_->sum(value) : value;
}

int RunSplit::anyInterrupt(int local) {
  if (!active()) return local;
  if (domain_) {
    // Through the domain, so that waiting here counts as communication.
    std::vector<double> any{double(local)};
    domain_->maxOverProcesses(any);
    return int(any[0]);
  }
  int any = local;
  MPI_Allreduce(MPI_IN_PLACE, &any, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
  return any;
}

void RunSplit::record(RunRecord& rec, const World& world) {
  if (!domain_) return;
  // Every process steps the same bodies and elastic solids from the same
  // sums: their states must agree bit for bit, or the split has a bug.
  // Checked every frame.
  std::vector<double> state;
  for (const RigidBody& b : world.bodies) {
    const RigidState& s = b.state;
    state.insert(state.end(), s.x.data(), s.x.data() + 3);
    state.insert(state.end(), s.v.data(), s.v.data() + 3);
    state.insert(state.end(), s.L.data(), s.L.data() + 3);
    state.insert(state.end(), s.q_principal.coeffs().data(), s.q_principal.coeffs().data() + 4);
  }
  for (const ElasticSolid& e : world.elastics)
    for (const std::vector<Vec3d>* a : {&e.fem.x, &e.fem.v})
      for (const Vec3d& x : *a) state.insert(state.end(), x.data(), x.data() + 3);
  const std::vector<double> states = allGatherValues(*domain_, state);
  for (int r = 1; r < size_ && !state.empty(); ++r)
    if (std::memcmp(state.data(), states.data() + size_t(r) * state.size(),
                    state.size() * sizeof(double)) != 0)
      throw std::runtime_error("the solids' states differ between process 0 and process " +
                               std::to_string(r) + " at t = " + std::to_string(world.time) +
                               " s: the split run went wrong (please report it)");
  // Each process's figures for run.json, seven per process.
  const std::vector<double> mine{double(world.particleCount()),
                                 domain_->commSeconds(),
                                 domain_->balanceSeconds(),
                                 double(domain_->bytesSent()),
                                 double(domain_->particlesReceived()),
                                 double(peakResidentBytes()),
                                 built_};
  const std::vector<double> all = allGatherValues(*domain_, mine);
  if (!root()) return;
  auto column = [&](size_t k) {
    std::vector<double> c;
    for (size_t r = 0; r < size_t(size_); ++r) c.push_back(all[r * mine.size() + k]);
    return c;
  };
  const std::vector<double> counts = column(0), bytes = column(3), received = column(4);
  rec.mpi_ranks = size_;
  rec.mpi_particles.emplace_back(counts.begin(), counts.end());
  rec.mpi_comm_seconds = column(1);
  rec.mpi_balance_seconds = column(2);
  rec.mpi_bytes_sent.assign(bytes.begin(), bytes.end());
  rec.mpi_received.assign(received.begin(), received.end());
  const std::vector<double> rss = column(5), built = column(6);
  rec.mpi_peak_rss.assign(rss.begin(), rss.end());
  rec.mpi_built.assign(built.begin(), built.end());
}

void RunSplit::barrier() {
  if (active()) MPI_Barrier(MPI_COMM_WORLD);
}

void RunSplit::abort(int code) {
  if (active()) MPI_Abort(MPI_COMM_WORLD, code);
  std::exit(code);
}

#else  // built without MPI

class MpiDomain {};  // never made: a run is never split

RunSplit::RunSplit() {
  if (launchedProcesses() > 1)
    throw std::runtime_error(
        "started as one of several processes (mpirun -np N), but this triad was built without "
        "MPI: install libopenmpi-dev (scripts/setup.sh) and rebuild, or run it alone");
}
RunSplit::~RunSplit() = default;
ParticleShare* RunSplit::share(const SceneDesc&) {
  return nullptr;
}
void RunSplit::attach(World&, Solver&, bool) {}
void RunSplit::rebalance(World&) {}
std::shared_ptr<const World> RunSplit::gather(World&, Gather) {
  return nullptr;
}
render::Image RunSplit::renderPreview(render::PreviewRenderer&, const World&) {
  return {};
}
std::map<int, LevelSetParts> RunSplit::surfaceParts(const World&, const std::vector<int>&, double) {
  return {};
}
double RunSplit::sum(double value) {
  return value;
}
int RunSplit::anyInterrupt(int local) {
  return local;
}
void RunSplit::record(RunRecord&, const World&) {}
void RunSplit::barrier() {}
void RunSplit::abort(int code) {
  std::exit(code);
}

#endif

RunSplit::Gather RunSplit::planOutput(const OutputDesc& o, RunRecord& rec) const {
  if (!active()) return Gather::None;
  const bool together = shared_files_;
  const bool whole = !together && (o.ply || o.vtk || o.checkpoints);
  for (const auto& [on, each, name] : {std::tuple{o.ply, together, "particles"},
                                       {o.vdb, true, "volumes"},
                                       {o.vdb && o.vdb_surface, true, "volumes' surface"},
                                       {o.surface_mesh, true, "surfaces"},
                                       {o.vtk, together, "vtk particles"},
                                       {o.checkpoints, together, "checkpoints"},
                                       {o.png, true, "previews"}})
    if (on && each) rec.mpi_files_together.push_back(name);
  for (const auto& [on, name] : {std::pair{o.vtk && !together, "vtk particles"},
                                 {o.ply && !together, "particles"},
                                 {o.checkpoints && !together, "checkpoints"}})
    if (on) rec.mpi_gathered_for.push_back(name);
  rec.mpi_gathered = whole ? "every attribute" : "nothing";
  return whole ? Gather::Whole : Gather::None;
}

}  // namespace triad
