#include "app/run_split.h"

#include <algorithm>
#include <cstdlib>
#include <stdexcept>

#include "export/run_record.h"
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

void RunSplit::attach(World& world, Solver& solver) {
  if (!active()) return;
  domain_ = std::make_unique<MpiDomain>(MPI_COMM_WORLD, solver.transferParams());
  domain_->balance(world.sets, /*whole=*/true);
  solver.setDomain(domain_.get());
}

void RunSplit::rebalance(World& world) {
  if (domain_) domain_->balance(world.sets);
}

std::shared_ptr<const World> RunSplit::gather(const World& world) {
  if (!domain_) return nullptr;
  std::vector<ParticleSet> all;
  domain_->gather(world.sets, all);
  if (!root()) return nullptr;
  // A copy of everything else (bodies, sources: none run split) with the
  // gathered particles in place of this process's share.
  auto copy = std::make_shared<World>();
  copy->scene = world.scene;
  copy->bodies = world.bodies;
  copy->elastics = world.elastics;
  copy->sources = world.sources;
  copy->sinks = world.sinks;
  copy->object_particles = world.object_particles;
  copy->time = world.time;
  copy->steps = world.steps;
  copy->next_id = world.next_id;
  copy->sets = std::move(all);
  return copy;
}

double RunSplit::sum(double value) {
  return domain_ ? domain_->sum(value) : value;
}

int RunSplit::anyInterrupt(int local) {
  if (!active()) return local;
  int any = local;
  MPI_Allreduce(MPI_IN_PLACE, &any, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
  return any;
}

void RunSplit::record(RunRecord& rec, const World& world) {
  if (!domain_) return;
  // Every process steps the same bodies and elastic solids from the same
  // sums: their states must agree bit for bit, or the split has a bug.
  // Checked every frame.
  std::vector<unsigned char> mine;
  for (const RigidBody& b : world.bodies) {
    const RigidState& s = b.state;
    for (const double* d : {s.x.data(), s.v.data(), s.L.data(), s.q_principal.coeffs().data()}) {
      const auto* p = reinterpret_cast<const unsigned char*>(d);
      mine.insert(mine.end(), p, p + (d == s.q_principal.coeffs().data() ? 4 : 3) * sizeof(double));
    }
  }
  for (const ElasticSolid& e : world.elastics)
    for (const std::vector<Vec3d>* a : {&e.fem.x, &e.fem.v}) {
      const auto* p = reinterpret_cast<const unsigned char*>(a->data());
      mine.insert(mine.end(), p, p + a->size() * sizeof(Vec3d));
    }
  const std::vector<unsigned char> all = domain_->allGather(mine);
  for (int r = 1; r < size_; ++r)
    if (!std::equal(mine.begin(), mine.end(), all.begin() + ptrdiff_t(size_t(r) * mine.size())))
      throw std::runtime_error("the solids' states differ between process 0 and process " +
                               std::to_string(r) + " at t = " + std::to_string(world.time) +
                               " s: the split run went wrong (please report it)");
  const std::vector<double> counts = domain_->gatherValues(double(world.particleCount()));
  const std::vector<double> comm = domain_->gatherValues(domain_->commSeconds());
  const std::vector<double> balance = domain_->gatherValues(domain_->balanceSeconds());
  const std::vector<double> bytes = domain_->gatherValues(double(domain_->bytesSent()));
  const std::vector<double> received = domain_->gatherValues(double(domain_->particlesReceived()));
  if (!root()) return;
  rec.mpi_ranks = size_;
  rec.mpi_particles.emplace_back(counts.begin(), counts.end());
  rec.mpi_comm_seconds = comm;
  rec.mpi_balance_seconds = balance;
  rec.mpi_bytes_sent.assign(bytes.begin(), bytes.end());
  rec.mpi_received.assign(received.begin(), received.end());
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
void RunSplit::attach(World&, Solver&) {}
void RunSplit::rebalance(World&) {}
std::shared_ptr<const World> RunSplit::gather(const World&) {
  return nullptr;
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

std::string RunSplit::unsupported(const World& world) const {
  if (!active()) return "";
  const SceneDesc& s = world.scene;
  if (!world.bodies.empty() && s.solver.coupling == CouplingScheme::SingleGrid)
    return "solver.coupling \"single\" with solids";
  if (!world.bodies.empty() && s.solver.solid_readback == SolidReadback::Combined)
    return "solver.solid_readback \"combined\"";
  if (s.solver.sleep.enabled) return "solver.sleep";
  return "";
}

}  // namespace triad
