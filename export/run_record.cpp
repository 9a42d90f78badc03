#include "export/run_record.h"

#include <ctime>
#include <fstream>
#include <iomanip>
#include <nlohmann/json.hpp>
#include <sstream>

#include "export/atomic_file.h"

namespace triad {

void writeRunRecord(const std::string& path, const RunRecord& rec) {
  nlohmann::ordered_json j;
  j["triad_version"] = "0.1.0";
  j["scene"] = {{"name", rec.scene_name}, {"path", rec.scene_path}, {"hash", rec.scene_hash}};
  j["finished"] = rec.finished;
  j["error"] = rec.error.empty() ? nlohmann::ordered_json(nullptr) : nlohmann::ordered_json(rec.error);
  if (!rec.interrupted_by.empty())
    j["interrupted"] = {{"signal", rec.interrupted_by}, {"frame", rec.interrupted_frame}};
  if (rec.resume)
    j["resumed"] = {{"from_frame", rec.resumed_from_frame >= 0
                                       ? nlohmann::ordered_json(rec.resumed_from_frame)
                                       : nlohmann::ordered_json(nullptr)}};
  j["started_utc"] = rec.started_utc;
  j["ended_utc"] = rec.ended_utc;
  j["threads"] = rec.threads;
  j["omp_wait_policy"] = rec.omp_wait_policy;
  if (!rec.omp_spin_count.empty()) j["omp_spin_count"] = rec.omp_spin_count;
  j["output_overlap"] = rec.output_overlap;
  if (rec.threads_while_writing > 0) {
    j["threads_while_writing"] = rec.threads_while_writing;
    j["steps_while_writing"] = rec.steps_while_writing;
  }
  if (rec.mpi_ranks > 0)
    j["mpi"] = {{"ranks", rec.mpi_ranks},
                {"particles_per_frame", rec.mpi_particles},
                {"comm_seconds", rec.mpi_comm_seconds},
                {"rebalance_seconds", rec.mpi_balance_seconds},
                {"bytes_sent", rec.mpi_bytes_sent},
                {"particles_received", rec.mpi_received},
                {"peak_rss_bytes", rec.mpi_peak_rss},
                {"particles_at_start", rec.mpi_built},
                {"written_by_every_process", rec.mpi_files_together},
                {"gathered_for", rec.mpi_gathered_for},
                {"gathered", rec.mpi_gathered}};
  j["quality"] = {{"preset", rec.quality.empty() ? nlohmann::ordered_json(nullptr)
                                                 : nlohmann::ordered_json(rec.quality)},
                  {"dx", rec.dx},
                  {"particles_per_cell", rec.particles_per_cell},
                  {"cfl", rec.cfl},
                  {"transfer", rec.transfer}};
  if (!rec.solver.empty()) j["solver"] = nlohmann::ordered_json::parse(rec.solver);
  nlohmann::ordered_json per_object = nlohmann::ordered_json::object();
  for (const auto& [name, n] : rec.object_particles) per_object[name] = n;
  j["particles"] = {{"total", rec.particles}, {"per_object", per_object}};
  // Sources and sinks: particles made and removed per object so far.
  if (!rec.emitted.empty() || !rec.removed.empty()) {
    nlohmann::ordered_json emitted = nlohmann::ordered_json::object(),
                           removed = nlohmann::ordered_json::object();
    for (const auto& [name, n] : rec.emitted) emitted[name] = n;
    for (const auto& [name, n] : rec.removed) removed[name] = n;
    j["particles"]["emitted"] = emitted;
    j["particles"]["removed"] = removed;
  }
  j["bodies"] = rec.bodies;
  j["frames"] = {{"requested", rec.frames_requested}, {"written", rec.frames_written},
                 {"fps", rec.fps}};
  nlohmann::ordered_json materials = nlohmann::ordered_json::object();
  for (const auto& [name, rho] : rec.material_density) materials[name] = {{"density", rho}};
  j["materials"] = materials;
  j["domain"] = {{"min", rec.domain_min}, {"max", rec.domain_max}};
  j["simulated_time"] = rec.simulated_time;
  j["steps"] = rec.steps;
  j["dt"] = {{"min", rec.dt_min}, {"max", rec.dt_max}};
  nlohmann::ordered_json phases = nlohmann::ordered_json::object();
  for (const auto& [name, s] : rec.phase_seconds) phases[name] = s;
  j["wall_seconds"] = {{"total", rec.wall_seconds}, {"phases", phases}};
  if (!rec.solids_seconds.empty()) {
    nlohmann::ordered_json parts = nlohmann::ordered_json::object();
    for (const auto& [name, s] : rec.solids_seconds) parts[name] = s;
    j["wall_seconds"]["solids_parts"] = parts;
  }
  j["estimate"] = {{"wall_seconds", rec.estimated_wall_seconds},
                   {"rate_particle_substeps_per_s", rec.estimated_rate},
                   {"rate_from", rec.rate_from},
                   {"probe_seconds", rec.probe_seconds}};
  const double solve = rec.phase_seconds.count("solve") ? rec.phase_seconds.at("solve") : 0.0;
  j["particle_substeps"] = rec.particle_steps;
  j["sleeping_particle_substeps"] = rec.sleeping_steps;
  j["particle_substeps_per_second"] = solve > 0.0 ? double(rec.particle_steps) / solve : 0.0;
  j["memory"] = {{"peak_rss_bytes", rec.peak_rss_bytes},
                 {"particle_bytes", rec.particle_bytes},
                 {"grid_bytes", rec.grid_bytes}};
  writeFileAtomically(path, [&](std::ostream& out) { out << j.dump(2) << "\n"; });
}

std::string hashFile(const std::string& path) { return hashFiles({path}); }

std::string hashFiles(const std::vector<std::string>& paths) {
  uint64_t h = 1469598103934665603ull;
  char buf[65536];
  for (const std::string& path : paths) {
    std::ifstream in(path, std::ios::binary);
    while (in) {
      in.read(buf, sizeof(buf));
      for (std::streamsize i = 0; i < in.gcount(); ++i) {
        h ^= static_cast<unsigned char>(buf[i]);
        h *= 1099511628211ull;
      }
    }
  }
  std::ostringstream s;
  s << "fnv1a64:" << std::hex << std::setw(16) << std::setfill('0') << h;
  return s.str();
}

size_t peakResidentBytes() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("VmHWM:", 0) == 0) return std::stoull(line.substr(6)) * 1024;
  }
  return 0;
}

std::string utcNow() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  std::ostringstream s;
  s << std::put_time(&tm, "%Y-%m-%dT%H:%M:%SZ");
  return s.str();
}

}  // namespace triad
